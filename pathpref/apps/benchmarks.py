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


def realistic_pushes(n: int, seed: int = 0, noise_deg: float = 10.0) -> list[tuple]:
    """``n`` pushes of the realistic benchmark on ``simple``: a random walk of legal moves and
    at each cell a push toward a random sector, peak U[10, 60] N over U[0.1, 0.5] s, heading
    noise ``noise_deg``; rows ``(cell, heading, angle, profile)``."""
    from ..sim.force_cue import HumanPush, PushProfile

    world = cached_world("simple")
    rng = np.random.default_rng(seed)
    cell, rows = world.cell((3, 3)), []
    for _ in range(n):
        moves = np.flatnonzero(~world.motion.blocked[cell])
        cell = int(world.motion.next_cell[cell, rng.choice(moves)])
        h = int(rng.integers(8))
        profile = PushProfile(peak_n=float(rng.uniform(10.0, 60.0)),
                              duration_s=float(rng.uniform(0.1, 0.5)), noise_deg=noise_deg)
        rows.append((cell, h, HumanPush.sample(h, 0.0, profile, rng).angle, profile))
    return rows


def run_pushes(pushes: list[tuple], sensor_model=None, seed: int = 0, rest_s: float = 0.3,
               estimator=None) -> dict[str, Any]:
    """Give ``pushes`` (from :func:`realistic_pushes`) to one base with ``sensor_model``:
    drive to each push's cell, wait ``rest_s``, push. Hits (detected sector = intended),
    onset latencies (push onset to the detector going active) and release latencies (push
    end to the cue)."""
    from ..sim.force_cue import HumanPush
    from ..sim.mobile_base import MobileBase

    world = cached_world("simple")
    base = MobileBase(scene_for(world), sensor_model=sensor_model,
                      rng=np.random.default_rng(seed + 1), estimator=estimator)
    base.reset(world.cell((3, 3)))
    hits, onset, release = [], [], []
    for cell, h, angle, profile in pushes:
        base.move_to(cell)
        t_end = base.data.time + rest_s
        while base.data.time < t_end:
            base.substep()
        push = HumanPush(angle, 0.0, profile, h)
        cue = base.receive_push(push)
        hits.append(cue is not None and cue.heading == h)
        if base.last_onset_s is not None:
            onset.append(base.last_onset_s)
        if cue is not None:
            release.append(float(base.data.time) - push.t0 - profile.duration_s)
    return {"hits": hits, "onset_s": onset, "release_s": release,
            "accuracy": float(np.mean(hits)) if hits else 0.0}


def cue_accuracy_realistic(n: int = 200, seed: int = 0) -> dict[str, Any]:
    """The same ``n`` pushes (:func:`realistic_pushes`) sensed by the ideal sensor and by
    ``SensorModel.realistic()`` (2 N noise per axis at 100 Hz, 6 N bias drifting by
    0.05 N/sqrt(s), inertia with 0.6 kg sensed) through the estimator and the filtered
    detector: both accuracies, their ratio, latencies (ms, medians)."""
    from ..sim.sensing import SensorModel

    pushes = realistic_pushes(n, seed)
    ideal = run_pushes(pushes, None, seed)
    real = run_pushes(pushes, SensorModel.realistic(), seed)

    def ms(xs: list[float]) -> float:
        return 1e3 * float(np.median(xs)) if xs else float("nan")

    return {
        "cue_accuracy_realistic": real["accuracy"] / max(ideal["accuracy"], 1e-12),
        "cue_accuracy_realistic_raw": real["accuracy"],
        "cue_accuracy_ideal_raw": ideal["accuracy"],
        "cue_latency_ms": ms(real["onset_s"]),
        "cue_latency_ideal_ms": ms(ideal["onset_s"]),
        "cue_latency_p90_ms": (1e3 * float(np.quantile(real["onset_s"], 0.9))
                               if real["onset_s"] else float("nan")),
        "cue_release_ms": ms(real["release_s"]),
        "cue_release_ideal_ms": ms(ideal["release_s"]),
        "cue_missed_realistic": int(n - len(real["release_s"])),
        "cue_missed_ideal": int(n - len(ideal["release_s"])),
        "cue_pushes_realistic": n,
    }


def hard_driving(base, seconds: float, rng: np.random.Generator) -> list:
    """Drive ``base`` hard for ``seconds`` of simulated time: an aggressive controller (gain
    8, 1 m/s: the actuators saturate at 120 N, about 10 m/s^2) whose target jumps every
    U[0.2, 1.0] s to a random legal neighbour of the current cell (hard starts, braking and
    reversals). Returns the cues detected (all false: nobody pushes)."""
    from ..sim.controller import TrackingController

    world = base.scene.world
    base.controller = TrackingController(kp=8.0, v_max=1.0)
    cues, t_end = [], base.data.time + seconds
    while base.data.time < t_end:
        s = base.cell
        moves = np.flatnonzero(~world.motion.blocked[s])
        base.target = base.scene.cell_centre(int(world.motion.next_cell[s, rng.choice(moves)]))
        t_switch = base.data.time + rng.uniform(0.2, 1.0)
        while base.data.time < min(t_switch, t_end):
            cue = base.substep()
            if cue is not None:
                cues.append(cue)
    return cues


def false_cues_realistic(seconds: float = 1000.0, seed: int = 0, sensor_model=None,
                         estimator=None) -> tuple[int, float, float]:
    """False cues during :func:`hard_driving` on ``office`` with ``sensor_model`` (default
    ``SensorModel.realistic()``): count, simulated seconds, peak |push estimate| (N)."""
    from ..sim.mobile_base import MobileBase
    from ..sim.sensing import SensorModel

    world = cached_world("office")
    model = SensorModel.realistic() if sensor_model is None else sensor_model
    base = MobileBase(scene_for(world), sensor_model=model, rng=np.random.default_rng(seed + 1),
                      estimator=estimator)
    base.reset(world.cell((1, 1)))
    peak = [0.0]

    def watch(b, _push):
        f = b.force_estimate if b.sensor_model is not None else b.sensor.force_xy(b.data)
        peak[0] = max(peak[0], float(np.hypot(f[0], f[1])))

    base.on_substep.append(watch)
    t0 = base.data.time
    cues = hard_driving(base, seconds, np.random.default_rng(seed))
    return len(cues), float(base.data.time - t0), peak[0]


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
    """Cue detection (with and without heading noise), false cues, episode time, rendering;
    the same with realistic sensing (``*_realistic``, :func:`cue_accuracy_realistic`,
    :func:`false_cues_realistic`; ``docs/sensing.md``)."""
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
    from ..sim.estimator import EstimatorConfig
    from ..sim.sensing import SensorModel

    drive = 120.0 if quick else 1000.0
    n_real, real_s, real_peak = false_cues_realistic(drive)
    n_unc, unc_s, unc_peak = false_cues_realistic(
        drive, estimator=EstimatorConfig(compensate_inertia=False))
    inertia_only = SensorModel(extra_mass_kg=0.4)  # no noise, no bias: the inertia alone
    _, _, raw_peak = false_cues_realistic(30.0, sensor_model=inertia_only,
                                          estimator=EstimatorConfig(compensate_inertia=False))
    _, _, comp_peak = false_cues_realistic(30.0, sensor_model=inertia_only)
    return {
        **cue_accuracy_realistic(100 if quick else 400),
        "false_cues_per_hour_realistic": n_real / real_s * 3600.0,
        "false_cue_drive_realistic_s": real_s,
        "force_estimate_peak_driving_n": real_peak,
        "false_cues_per_hour_realistic_uncompensated": n_unc / unc_s * 3600.0,
        "force_estimate_peak_driving_uncompensated_n": unc_peak,
        "inertia_peak_raw_n": raw_peak,
        "inertia_peak_compensated_n": comp_peak,
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
