"""Record one physics episode as a video and/or a rerun file (``pathpref render``)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..episode import EpisodeResult, EpisodeRunner, EpisodeSpec, cached_world, simulator_rng
from ..sim.body import MujocoBody
from ..sim.render import RolloutRenderer, write_video

VIDEO_FPS = 25


@dataclass
class Recording:
    """A rendered episode: its result, the number of frames and the files written."""

    result: EpisodeResult
    frames: int
    video: Path | None
    rerun: Path | None


def record_rollout(spec: EpisodeSpec, video: str | Path | None = None,
                   rerun: str | Path | None = None, width: int = 480, height: int = 360,
                   speed: float = 2.0) -> Recording:
    """Run ``spec`` in MuJoCo; render a frame every ``speed / VIDEO_FPS`` s of simulated time
    (the video plays ``speed`` times faster than real time, pushes in real time) and log to
    rerun."""
    world = cached_world(spec.map)
    body = MujocoBody(world, spec, simulator_rng(spec))
    base = body.base
    every = max(1, int(round(speed / VIDEO_FPS / base.dt)))
    every_push = max(1, int(round(1.0 / VIDEO_FPS / base.dt)))  # pushes play in real time
    frames: list[np.ndarray] = []
    renderer = RolloutRenderer(body.scene, width, height) if video else None
    state: dict = {"runner": None, "k": 0}
    polygons = world.arrangement.polygons

    def hook(b, push) -> None:
        state["k"] += 1
        if state["k"] % (every_push if push is not None else every):
            return
        r = state["runner"]
        if logger is not None:
            logger.log_frame(b.data.time, b.position, b.end_effector)
        if renderer is None or r is None:
            return
        force = push.force(float(b.data.time)) if push is not None else None
        frames.append(renderer.frame(
            b.data, goal_cells=world.cells[list(r.instance.goals)],
            belief=r.policy.belief.goal_marginal(), true_goal=r.instance.true_goal,
            polygon=polygons[world.cell_polytope[b.cell]],
            push_origin=b.data.xpos[b.pushed_body].copy(),  # handle or tray
            push_force=force))

    logger = None
    base.on_substep.append(hook)
    runner = EpisodeRunner(spec, world, body)
    state["runner"] = runner
    if rerun:
        from ..viz.rerun_log import RerunLogger

        logger = RerunLogger(world, world.cells[list(runner.instance.goals)],
                             runner.instance.true_goal, rerun, body.scene.cell_size)

    def log_step() -> None:
        if logger is None:
            return
        cue = body.last_cue if runner.pending_heading is not None else None
        b = runner.policy.belief
        logger.log_step(runner.t, base.position, b.goal_marginal(),
                        float(b.goal_marginal()[runner.instance.true_goal]), b.goal_entropy(),
                        None if cue is None else cue.impulse)

    runner.begin()
    log_step()
    while not runner.done:
        runner.step()
        log_step()
    if renderer is not None:
        renderer.close()
    if logger is not None:
        logger.close()
    out_video = write_video(frames, video, VIDEO_FPS) if video else None
    return Recording(runner.result, len(frames), out_video, Path(rerun) if rerun else None)
