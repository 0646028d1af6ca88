"""``scale`` section: the 200 x 200 floor plan (setup in a fresh process, one episode), Ray
throughput, reachable space on rotated 40 x 40 maps."""

from __future__ import annotations

import os
import time
from typing import Any

import numpy as np

from ...episode import EpisodeSpec, run_episode, sample_instance
from ...geometry.maps import load_map
from ...geometry.world import World
from ...planning.pomdp import DEFAULT_PRESET
from .peak import peak_rss_mb


# --- scale: Ray, big maps -------------------------------------------------------------------
def bench_ray(n: int = 40, queries: int = 5000) -> dict[str, Any]:
    """Episode throughput: one worker in-process vs Ray on a local 2-CPU cluster.

    The same ``n`` goal-only episodes on ``simple`` (the paper's 5000 queries per decision)
    both ways; Ray's start-up and a warm-up batch (workers importing pathpref and loading the
    compiled kernel) are not timed.
    """
    try:
        import ray
    except ImportError:
        return {"ray_speedup": None, "ray_note": "ray not installed (pip install pathpref[ray])"}
    from ...experiments.backends import iter_local, iter_ray
    from ...experiments.sweep import sweep_specs

    specs = sweep_specs("simple", ["goal_only"], [5], instances=n, runs=1, seed=3,
                        queries=queries)
    list(iter_local(specs[:2], workers=1))  # warm this process
    t = time.perf_counter()
    list(iter_local(specs, workers=1))
    t_local = time.perf_counter() - t
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, configure_logging=False)
    try:
        list(iter_ray(specs[:4]))  # warm the workers
        t = time.perf_counter()
        list(iter_ray(specs))
        t_ray = time.perf_counter() - t
    finally:
        ray.shutdown()
    return {"ray_speedup": t_local / t_ray, "ray_episodes": n,
            "single_worker_episodes_per_s": n / t_local, "ray_episodes_per_s": n / t_ray}


#: the 40 x 40 plan of the first-decision keys: 32 rotated obstacles, seed 1, a loop preference
ROTATED_40 = {"width": 40, "height": 40, "n_rotated": 32, "seed": 1}


def rotated_40() -> dict[str, Any]:
    """The 40 x 40 plan of :data:`ROTATED_40` with a loop preference (``rotated_40``)."""
    from ...geometry.generate import random_floor_plan, with_loop_preference

    return with_loop_preference(random_floor_plan(name="rotated_40", **ROTATED_40))


def bench_robust_40(instances: int = 5, queries: int = 5000, episodes: int = 2
                    ) -> dict[str, Any]:
    """The 40 x 40 plan of :func:`rotated_40`, CPU time (ms), path preference, ΔT = 5,
    ``queries`` per decision:

    * ``robust_first_decision_40x40_ms``: the median of the first decision step under the
      default preset (:data:`~pathpref.planning.pomdp.DEFAULT_PRESET`: the first push, the
      search, the crossing check and the wait budget) over ``instances`` instances, after one
      warm-up instance; ``robust-check_first_decision_40x40_ms`` the same under
      ``robust-check`` (the preset this key timed until the default became ``robust-slack``);
    * ``robust_pool_40x40``: the root pool there
      (:meth:`~pathpref.planning.pomcp.POMCP.pool_size`; the same under both);
    * ``default_decision_40x40_ms``, ``_p95_ms``, ``_max_ms``: median, 95th percentile and
      maximum of every decision step of ``episodes`` whole episodes under the default preset
      (instances 1 to ``episodes``, the warm-up instance 0 first)."""
    import json
    import statistics
    import tempfile

    from ...episode.runner import EpisodeRunner

    res: dict[str, Any] = {"robust_first_decision_40x40_preset": DEFAULT_PRESET}
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "rotated_40.json")
        with open(path, "w") as f:
            json.dump(rotated_40(), f)
        t_max = load_map(path).t_max
        world = World.from_spec(load_map(path))

        def runner(preset: str, i: int) -> EpisodeRunner:
            return EpisodeRunner(EpisodeSpec(
                map=path, method="path_preference", delta_t=5, instance=i, run=0,
                instance_seed=100 + i, run_seed=7, queries=queries, t_max=t_max,
                preset=preset), world=world)

        for preset, key in ((DEFAULT_PRESET, "robust_first_decision_40x40_ms"),
                            ("robust-check", "robust-check_first_decision_40x40_ms")):
            times = []
            for i in range(instances + 1):
                run = runner(preset, i)
                c = time.process_time()
                run.step()
                times.append((time.process_time() - c) * 1000)
            res[key] = statistics.median(times[1:])
            res["robust_pool_40x40"] = run.policy.planner.pool_size()
        steps = []
        for i in range(episodes + 1):
            run = runner(DEFAULT_PRESET, i)
            while not run.done:
                c = time.process_time()
                run.step()
                if i > 0:
                    steps.append((time.process_time() - c) * 1000)
    res.update(default_decision_40x40_ms=statistics.median(steps),
               default_decision_40x40_p95_ms=float(np.percentile(steps, 95)),
               default_decision_40x40_max_ms=max(steps), default_decisions_40x40=len(steps))
    return res


SCALE_MAP = {"width": 200, "height": 200, "n_rotated": 20, "n_boxes": 40, "seed": 0,
             "size_range": (2.0, 12.0)}


def scale_map() -> dict[str, Any]:
    """The 200 x 200 benchmark floor plan: 60 obstacles, a third of them rotated, with a loop
    preference around the map."""
    from ...geometry.generate import random_floor_plan, with_loop_preference

    return with_loop_preference(random_floor_plan(name="floor_200", **SCALE_MAP))


#: the forced 500 x 500 map: the bench floor plan's obstacle density (per area) at 500 x 500,
#: 1,122 distinct lines over 232,643 free cells (above the polytope limit: built with force)
MAP_500 = dict(SCALE_MAP, width=500, height=500, n_rotated=125, n_boxes=250)


def map_500() -> dict[str, Any]:
    """The 500 x 500 floor plan of :data:`MAP_500`, with a loop preference."""
    from ...geometry.generate import random_floor_plan, with_loop_preference

    return with_loop_preference(random_floor_plan(name="floor_500", **MAP_500))


def _map_500_child(queries: int = 1000, steps: int = 1) -> None:
    """Run in a fresh interpreter: the 500 x 500 map built (forced), the robust preset's
    episode set up for instance 0 (10 goals: cost tables, route prior, search), its likelihood
    tables and its first decision. Prints JSON: the CPU seconds and the process's own peak RSS
    (MB, ``VmHWM``: :func:`.peak.peak_rss_mb`, which only grows) after each stage (``world``,
    ``policy``, ``tables``, ``decision``), polytopes, lines, cells and the maximum degree.
    With ``steps > 1`` the episode goes on to at most ``steps`` decisions (``episode`` stage;
    ``episode_steps`` run, ``observed_polytopes`` of the belief then)."""
    import json
    import tempfile

    from ...episode.runner import EpisodeRunner

    out: dict[str, Any] = {}
    c0 = time.process_time()

    def stage(name: str) -> None:
        out[f"{name}_cpu_s"] = time.process_time() - c0
        out[f"{name}_peak_mb"] = peak_rss_mb()

    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "floor_500.json")
        with open(path, "w") as f:
            json.dump(map_500(), f)
        spec = load_map(path)
        world = World.from_spec(spec)
        stage("world")
        ep = EpisodeSpec(map=path, method="path_preference", delta_t=5, instance=0, run=0,
                         instance_seed=1, run_seed=2, queries=queries, t_max=spec.t_max,
                         preset="robust")
        runner = EpisodeRunner(ep, world=world)
        stage("policy")
        model = runner.model
        _ = (model.cell_likelihood, model.goal_likelihood)
        stage("tables")
        log = runner.step()
        stage("decision")
        done = 1
        while done < steps and not runner.done:
            runner.step()
            done += 1
        if steps > 1:
            stage("episode")
            out.update(episode_steps=done, observed_polytopes=len(
                runner.policy.belief.observed_polytopes()))
    out.update(polytopes=world.n_polytopes, lines=len(world.arrangement.normals),
               max_degree=world.graph.max_degree, cells=world.n_cells, action=int(log.action))
    print(json.dumps(out))


def _scale_setup_child() -> None:
    """Run in a fresh interpreter: arrangement + graph + cost tables for 10 goals on the
    benchmark floor plan; prints ``wall_seconds peak_MB`` (the process's own peak,
    :func:`.peak.peak_rss_mb`), then the route update's CPU ms, median and mean."""
    from ...inference.costs import build_cost_tables

    raw = scale_map()
    World.from_spec(load_map({"width": 12, "height": 12, "obstacles": []}))  # JIT warm-up
    t = time.perf_counter()
    world = World.from_spec(load_map(raw))
    build_cost_tables(world, np.array(sample_instance(world, 0, 10).goals))
    dt = time.perf_counter() - t
    print(dt, peak_rss_mb())
    from ...inference.human import ObservationModel
    from .maps import bench_route_update

    goals = np.random.default_rng(0).choice(world.n_cells, size=10, replace=False)
    r = bench_route_update(ObservationModel.build(world, goals), pushes=40)
    print(r["route_update_ms"], r["route_update_mean_ms"])


def _episode_child(preset: str, queries: int) -> None:
    """Run in a fresh interpreter: one path-preference episode on the benchmark floor plan
    (ΔT = 5, instance 0) under ``preset``; prints JSON: wall and CPU seconds of the episode
    (world, cost and likelihood tables, every decision), the process's own peak RSS in MB
    (tables included; ``VmHWM``, :func:`.peak.peak_rss_mb`), steps, goal reached."""
    import json
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "floor_200.json")
        with open(path, "w") as f:
            json.dump(scale_map(), f)
        spec = EpisodeSpec(map=path, method="path_preference", delta_t=5, instance=0, run=0,
                           instance_seed=1, run_seed=2, queries=queries,
                           t_max=load_map(path).t_max, preset=preset)
        c, t = time.process_time(), time.perf_counter()
        ep = run_episode(spec)
        print(json.dumps({"wall_s": time.perf_counter() - t, "cpu_s": time.process_time() - c,
                          "peak_mb": peak_rss_mb(),
                          "steps": ep.steps, "goal_reached": bool(ep.goal_reached)}))


def bench_map_500(queries: int = 1000) -> dict[str, Any]:
    """The forced 500 x 500 map (:func:`_map_500_child`, fresh process): ``map_500_peak_mb``
    (the whole process's peak RSS: map, tables, one robust decision), ``map_500_cpu_s``
    (CPU seconds of all of it) and the stages' peaks."""
    import json
    import subprocess
    import sys

    code = ("from pathpref.apps.benchmarks.scale import _map_500_child; "
            f"_map_500_child({int(queries)})")
    d = json.loads(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                                  check=True).stdout.splitlines()[-1])
    return {"map_500_peak_mb": d["decision_peak_mb"], "map_500_cpu_s": d["decision_cpu_s"],
            "map_500_world_peak_mb": d["world_peak_mb"],
            "map_500_policy_peak_mb": d["policy_peak_mb"],
            "map_500_tables_peak_mb": d["tables_peak_mb"], "map_500_polytopes": d["polytopes"]}


def bench_scale(queries: int = 1000, map_500: bool = True) -> dict[str, Any]:
    """Large-map figures: the 200 x 200 floor plan's setup time and peak memory and the route
    prior's update on it (:func:`.maps.bench_route_update`; fresh process), one
    path-preference episode on it per preset (``paper``, ``robust``, ``robust-wait`` and the
    default, :data:`~pathpref.planning.pomdp.DEFAULT_PRESET`: CPU seconds and peak RSS with the
    likelihood tables, each in a fresh process; ``map_200_episode_s``, its steps, goal and
    ``map_200_episode_peak_mb`` are the default preset's, as ``EpisodeSpec`` runs it),
    the 40 x 40 rotated maps' reachable fraction and (``map_500``) :func:`bench_map_500`."""
    import json
    import subprocess
    import sys

    from ...geometry.generate import four_connected_components, random_floor_plan
    from ...geometry.maps import free_cell_mask

    code = "from pathpref.apps.benchmarks.scale import _scale_setup_child; _scale_setup_child()"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.split()
    res: dict[str, Any] = {"map_200_setup_s": float(out[0]), "map_200_peak_mb": float(out[1]),
                           "map_200_route_update_ms": float(out[2]),
                           "map_200_route_update_mean_ms": float(out[3])}
    # one episode per preset, each in a fresh process (its peak RSS is the episode's); every
    # preset that has been the default keeps its keys
    for preset in dict.fromkeys(("paper", "robust", "robust-wait", "robust-check",
                                 DEFAULT_PRESET)):
        code = ("from pathpref.apps.benchmarks.scale import _episode_child; "
                f"_episode_child({preset!r}, {int(queries)})")
        ep = json.loads(subprocess.run([sys.executable, "-c", code], capture_output=True,
                                       text=True, check=True).stdout.splitlines()[-1])
        if preset == DEFAULT_PRESET:  # the keys as they were: the default preset, wall time
            res["map_200_episode_s"] = ep["wall_s"]
            res["map_200_episode_steps"] = ep["steps"]
            res["map_200_episode_goal_reached"] = ep["goal_reached"]
            res["map_200_episode_peak_mb"] = ep["peak_mb"]
        res[f"map_200_{preset}_episode_cpu_s"] = ep["cpu_s"]
        res[f"map_200_{preset}_episode_peak_mb"] = ep["peak_mb"]
        res[f"map_200_{preset}_episode_steps"] = ep["steps"]
        res[f"map_200_{preset}_episode_goal_reached"] = ep["goal_reached"]
    fractions = []
    for n in (32, 64):
        for seed in range(3):
            world = World.from_spec(load_map(random_floor_plan(40, 40, n, seed=seed)))
            lab, _ = four_connected_components(free_cell_mask(world.spec))
            largest4 = np.bincount(lab[lab > 0]).max()
            fractions.append(np.bincount(world.motion.components()).max() / largest4)
    res["rotated_40_reachable_fraction"] = float(min(fractions))
    if map_500:
        res.update(bench_map_500(queries))
    return res


