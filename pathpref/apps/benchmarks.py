"""Benchmarks behind ``pathpref bench --json`` and ``scripts/bench.py``, in sections:

* ``maps``: per map, setup (arrangement, cost tables), belief updates, POMCP decisions (paper
  and robust search) against the paper's Table II;
* ``scale``: the 200 x 200 floor plan (fresh process), Ray throughput, rotated 40 x 40 maps;
* ``physics`` and ``arm``: MuJoCo cue detection, false cues, episode time, rendering, IK.

They report numbers; they assert nothing (tests check behaviour). The JSON keys named in the
issues are a contract: add keys, never rename them. Layout::

    {"machine": {...},
     "maps": {"simple": {"arrangement_build_s": ..., "cost_tables_s": ...,
                         "belief_update_ms": ..., "goal_belief_update_ms": ..., ...}, ...},
     "physics": {...}, "arm": {...}, "scale": {...}}
"""

from __future__ import annotations

import os
import platform
import time
from statistics import median
from typing import Any

import numpy as np

from ..episode import EpisodeSpec, cached_world, run_episode, sample_instance
from ..experiments import paper
from ..geometry.maps import load_map
from ..geometry.world import World
from ..inference.belief import GoalBelief, PreferenceBelief
from ..inference.human import ObservationModel
from ..planning.pomcp import POMCP
from ..planning.pomdp import get_preset


# --- maps: setup, belief, POMCP ------------------------------------------------------------
def _timeit(fn, repeat: int) -> list[float]:
    """Wall times (s) of ``repeat`` calls of ``fn``."""
    out = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t)
    return out


def bench_map(name: str, quick: bool = False, seed: int = 0) -> dict[str, Any]:
    """Build, table and belief-update timings for one map (10 goal candidates)."""
    rng = np.random.default_rng(seed)
    spec = load_map(name)
    reps = 3 if quick else 7
    build = _timeit(lambda: World.from_spec(spec), reps)
    world = World.from_spec(spec)
    goals = rng.choice(world.n_cells, size=min(10, world.n_cells), replace=False)

    def tables():
        m = ObservationModel.build(world, goals)
        return m.likelihood, m.goal_likelihood

    tab = _timeit(tables, reps)
    model = ObservationModel.build(world, goals)
    n_upd = 200 if quick else 1000
    cells = rng.integers(0, world.n_cells, size=n_upd)
    heads = rng.integers(0, 8, size=n_upd)
    pb, gb = PreferenceBelief(model), GoalBelief(model)
    pb.update(0, 0)
    gb.update(0, 0)  # warm the cached tables
    t_pref, t_goal = [], []
    for c, h in zip(cells.tolist(), heads.tolist(), strict=True):
        t = time.perf_counter()
        pb.update(c, h)
        t_pref.append(time.perf_counter() - t)
        t = time.perf_counter()
        gb.update(c, h)
        t_goal.append(time.perf_counter() - t)
    planning = bench_pomcp(world, name, quick=quick, seed=seed)
    return {
        "polytopes": world.n_polytopes,
        "edges": world.graph.n_edges,
        "free_cells": world.n_cells,
        "arrangement_build_s": median(build),
        "cost_tables_s": median(tab),
        "setup_s": median(build) + median(tab),
        "belief_update_ms": 1e3 * median(t_pref),
        "belief_update_p99_ms": 1e3 * float(np.percentile(t_pref, 99)),
        "goal_belief_update_ms": 1e3 * median(t_goal),
        "belief_updates": n_upd,
        "paper_belief_update_ms": paper.update_ms(name),
        **planning,
    }


def bench_pomcp(world: World, name: str, quick: bool = False, seed: int = 0) -> dict[str, Any]:
    """First-decision POMCP time: 5000 queries at depth T_max, median over random instances."""
    preset = get_preset("paper")
    robust = get_preset("robust")
    depth = world.spec.t_max
    n = 5 if quick else 20
    rng = np.random.default_rng(seed + 1)
    t_pp, t_go, t_rb, t_rb_go = [], [], [], []
    for i in range(n + 1):
        goals = rng.choice(world.n_cells, size=10, replace=False)
        start = int(rng.integers(world.n_cells))
        model = ObservationModel.build(world, goals)
        pushed = PreferenceBelief(model, coupling=False)
        pushed.update(start, int(rng.integers(8)))  # one push: the start polytope is known
        for planner, belief, out in (
            (POMCP(world, goals, preset.path_preference), PreferenceBelief(model), t_pp),
            (POMCP(world, goals, preset.goal_only), GoalBelief(model), t_go),
            (POMCP(world, goals, robust.path_preference.for_mission(depth),
                   tables=model.tables), pushed, t_rb),
            (POMCP(world, goals, robust.goal_only.for_mission(depth), tables=model.tables),
             GoalBelief(model), t_rb_go),
        ):
            t = time.perf_counter()
            planner.search(start, belief, depth, seed=i)
            if i > 0:  # the first search compiles or loads the kernel
                out.append(time.perf_counter() - t)
    return {
        "pomcp_queries": preset.queries,
        "pomcp_depth": depth,
        "pomcp_decision_ms": 1e3 * median(t_pp),
        "pomcp_goal_only_decision_ms": 1e3 * median(t_go),
        "pomcp_queries_per_s": preset.queries / median(t_pp),
        "pomcp_decisions": n,
        "paper_pomcp_decision_ms": paper.solve_ms(name),
        "robust_decision_ms": 1e3 * median(t_rb),
        "robust_goal_only_decision_ms": 1e3 * median(t_rb_go),
    }


def machine_info() -> dict[str, Any]:
    """Python version, CPU count and platform of this machine."""
    return {
        "python": platform.python_version(),
        "cpu_count": os.cpu_count(),
        "platform": platform.platform(),
    }


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
    from ..experiments.backends import iter_local, iter_ray
    from ..experiments.sweep import sweep_specs

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


SCALE_MAP = {"width": 200, "height": 200, "n_rotated": 20, "n_boxes": 40, "seed": 0,
             "size_range": (2.0, 12.0)}


def scale_map() -> dict[str, Any]:
    """The 200 x 200 benchmark floor plan: 60 obstacles, a third of them rotated, with a loop
    preference around the map."""
    from ..geometry.generate import random_floor_plan, with_loop_preference

    return with_loop_preference(random_floor_plan(name="floor_200", **SCALE_MAP))


def _scale_setup_child() -> None:
    """Run in a fresh interpreter: arrangement + graph + cost tables for 10 goals on the
    benchmark floor plan; prints ``seconds peak_MB``."""
    import resource

    from ..inference.costs import build_cost_tables

    raw = scale_map()
    World.from_spec(load_map({"width": 12, "height": 12, "obstacles": []}))  # JIT warm-up
    t = time.perf_counter()
    world = World.from_spec(load_map(raw))
    build_cost_tables(world, np.array(sample_instance(world, 0, 10).goals))
    dt = time.perf_counter() - t
    print(dt, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)


def bench_scale(queries: int = 1000) -> dict[str, Any]:
    """Large-map figures: the 200 x 200 floor plan's setup time and peak memory (fresh process),
    one path-preference episode on it, and the 40 x 40 rotated maps' reachable fraction."""
    import json
    import subprocess
    import sys
    import tempfile

    from ..geometry.generate import four_connected_components, random_floor_plan
    from ..geometry.maps import free_cell_mask

    code = "from pathpref.apps.benchmarks import _scale_setup_child; _scale_setup_child()"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.split()
    res: dict[str, Any] = {"map_200_setup_s": float(out[0]), "map_200_peak_mb": float(out[1])}
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "floor_200.json")
        with open(path, "w") as f:
            json.dump(scale_map(), f)
        spec = EpisodeSpec(map=path, method="path_preference", delta_t=5, instance=0, run=0,
                           instance_seed=1, run_seed=2, queries=queries,
                           t_max=load_map(path).t_max)
        t = time.perf_counter()
        ep = run_episode(spec)
        res["map_200_episode_s"] = time.perf_counter() - t
        res["map_200_episode_steps"] = ep.steps
        res["map_200_episode_goal_reached"] = ep.goal_reached
    fractions = []
    for n in (32, 64):
        for seed in range(3):
            world = World.from_spec(load_map(random_floor_plan(40, 40, n, seed=seed)))
            lab, _ = four_connected_components(free_cell_mask(world.spec))
            largest4 = np.bincount(lab[lab > 0]).max()
            fractions.append(np.bincount(world.motion.components()).max() / largest4)
    res["rotated_40_reachable_fraction"] = float(min(fractions))
    return res


# --- physics: MuJoCo sensing, episodes, rendering, arm --------------------------------------
def scene_for(world: World, cell_size: float = 0.5, task: str = "navigate"):
    """The compiled MuJoCo scene (imports the simulator on first use)."""
    from ..sim.body import scene_for as build

    return build(world, cell_size, task)


def cue_accuracy(n: int = 200, noise_deg: float = 10.0, seed: int = 0) -> float:
    """Share of ``n`` pushes whose detected sector equals the human's intended one."""
    from ..sim.force_cue import HumanPush, PushProfile
    from ..sim.mobile_base import MobileBase

    world = cached_world("simple")
    base = MobileBase(scene_for(world))
    rng = np.random.default_rng(seed)
    profile = PushProfile(noise_deg=noise_deg)
    hits = 0
    for _ in range(n):
        base.reset(int(rng.integers(world.n_cells)))
        h = int(rng.integers(8))
        cue = base.receive_push(HumanPush.sample(h, 0.0, profile, rng))
        hits += cue is not None and cue.heading == h
    return hits / n


def false_cues(seconds: float = 1000.0, seed: int = 0) -> tuple[int, float]:
    """Cues detected while driving random legal moves for ``seconds`` of simulated time."""
    from ..sim.mobile_base import MobileBase

    world = cached_world("office")
    base = MobileBase(scene_for(world))
    rng = np.random.default_rng(seed)
    base.reset(world.cell((1, 1)))
    while base.data.time < seconds:
        s = base.cell
        moves = np.flatnonzero(~world.motion.blocked[s])
        base.move_to(int(world.motion.next_cell[s, rng.choice(moves)]))
    return len(base.cues_while_driving), float(base.data.time)


def render_fps(width: int = 640, height: int = 480, frames: int = 60) -> float:
    """Frames per second of the top view of ``simple`` (one bare view, no episode)."""
    import mujoco

    from ..sim.render import RolloutRenderer

    scene = scene_for(cached_world("simple"))
    data = mujoco.MjData(scene.model)
    mujoco.mj_forward(scene.model, data)
    r = RolloutRenderer(scene, width, height)
    r.renderer.update_scene(data, camera="top")
    r.renderer.render()
    t = time.perf_counter()
    for _ in range(frames):
        r.renderer.update_scene(data, camera="top")
        r.renderer.render()
    fps = frames / (time.perf_counter() - t)
    r.close()
    return fps


def bench_physics(quick: bool = False) -> dict[str, Any]:
    """Cue detection (with and without heading noise), false cues, episode time, rendering."""
    n_push = 50 if quick else 200
    secs = 100.0 if quick else 1000.0
    n_cues, sim_s = false_cues(secs)
    times = []
    for i in range(2 if quick else 5):
        spec = EpisodeSpec.single("simple", "path_preference", 5, seed=11, instance=i,
                                  sim="mujoco", t_max=30)
        t = time.perf_counter()
        run_episode(spec)
        times.append(time.perf_counter() - t)
    return {
        "cue_sector_accuracy": cue_accuracy(n_push, 10.0),
        "cue_sector_accuracy_no_noise": cue_accuracy(n_push, 0.0),
        "cue_pushes": n_push,
        "false_cues_per_hour": n_cues / sim_s * 3600.0,
        "false_cue_drive_s": sim_s,
        "episode_s": median(times),
        "episode_max_s": max(times),
        "render_fps": render_fps(frames=20 if quick else 60),
    }


def bench_arm(quick: bool = False) -> dict[str, Any]:
    """IK rate, tray tilt over pushed episodes, detection through the end-effector."""
    from ..sim.arm import ArmBase
    from ..sim.force_cue import HumanPush, PushProfile

    world = cached_world("simple")
    arm = ArmBase(scene_for(world, 0.5, "carry"))
    arm.reset(world.cell((3, 3)))
    n = 200 if quick else 1000
    t = time.perf_counter()
    for _ in range(n):
        arm.solve_ik()
    ik_rate = n / (time.perf_counter() - t)
    rng = np.random.default_rng(0)
    pushes, hits = (40 if quick else 200), 0
    for _ in range(pushes):
        h = int(rng.integers(8))
        cue = arm.receive_push(HumanPush.sample(h, 0.0, PushProfile(), rng))
        hits += cue is not None and cue.heading == h
        arm.move_to(arm.cell)
    tilts, pens, times = [], [], []
    for i in range(2 if quick else 5):
        spec = EpisodeSpec.single("simple", "path_preference", 3, seed=13, instance=i,
                                  sim="mujoco", task="carry")
        t = time.perf_counter()
        res = run_episode(spec)
        times.append(time.perf_counter() - t)
        tilts.append(res.metrics["tilt_rms_deg"])
        pens.append(res.metrics["max_penetration_mm"])
    return {
        "ik_solves_per_s": ik_rate,
        "cue_sector_accuracy": hits / pushes,
        "cue_pushes": pushes,
        "tilt_rms_deg": max(tilts),
        "tilt_rms_deg_mean": float(np.mean(tilts)),
        "max_penetration_mm": max(pens),
        "episode_s": median(times),
    }


def run_benchmarks(maps: list[str] | None = None, quick: bool = False,
                   physics: bool = True) -> dict[str, Any]:
    """All benchmarks as one JSON-ready dictionary (``scale`` is skipped with ``quick``)."""
    maps = maps or ["simple", "office", "classroom"]
    out = {"machine": machine_info(), "maps": {m: bench_map(m, quick=quick) for m in maps}}
    if physics:
        out["physics"] = bench_physics(quick=quick)
        out["arm"] = bench_arm(quick=quick)
    if not quick:
        out["scale"] = {**bench_ray(), **bench_scale()}
    return out
