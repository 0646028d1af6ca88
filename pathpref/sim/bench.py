"""Physics benchmark figures (``"physics"`` in ``pathpref bench --json``)."""

from __future__ import annotations

import time
from statistics import median
from typing import Any

import numpy as np

from ..experiments.episode import EpisodeSpec, cached_world, run_episode
from ..experiments.instances import seed_for
from .force_cue import HumanPush, PushProfile
from .mobile_base import MobileBase
from .mover import scene_for
from .render import RolloutRenderer


def cue_accuracy(n: int = 200, noise_deg: float = 10.0, seed: int = 0) -> float:
    """Share of ``n`` pushes whose detected sector equals the human's intended one."""
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
    world = cached_world("office")
    base = MobileBase(scene_for(world))
    rng = np.random.default_rng(seed)
    base.reset(world.cell((1, 1)))
    while base.data.time < seconds:
        s = base.cell
        moves = np.flatnonzero(~world.motion.blocked[s])
        base.move_to(int(world.motion.next_cell[s, rng.choice(moves)]))
    return base.false_cues, float(base.data.time)


def render_fps(width: int = 640, height: int = 480, frames: int = 60) -> float:
    import mujoco

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
    n_push = 50 if quick else 200
    secs = 100.0 if quick else 1000.0
    n_cues, sim_s = false_cues(secs)
    times = []
    for i in range(2 if quick else 5):
        spec = EpisodeSpec(map="simple", method="path_preference", delta_t=5, instance=i, run=0,
                           instance_seed=seed_for(11, i), run_seed=seed_for(11, i, 0),
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
    from .arm import ArmBase

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
        spec = EpisodeSpec(map="simple", method="path_preference", delta_t=3, instance=i,
                           run=0, instance_seed=seed_for(13, i), run_seed=seed_for(13, i, 0),
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
