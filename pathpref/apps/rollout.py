"""Record one physics episode as a video and/or a rerun file (``pathpref render``).

A frame is rendered every ``speed / VIDEO_FPS`` s of simulated time (the video plays ``speed``
times faster than real time), every ``1 / VIDEO_FPS`` s while the human pushes (pushes play in
real time). The push arrow stays on screen for ``HOLD_S`` of simulated time after the push
starts, the detected cue for ``HOLD_S`` after it is detected: at least one second of video
each. The frame: :class:`~pathpref.sim.render.RolloutRenderer`'s views with the overlays, and
the panel of :mod:`pathpref.viz.video`. A video ends with the final step's frame and then the
outcome card (:func:`pathpref.viz.video.outcome_card`) held for ``CARD_S`` seconds.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..episode import EpisodeResult, EpisodeRunner, EpisodeSpec, cached_world, simulator_rng
from ..errors import ConfigError
from ..geometry.world import World
from ..sim.body import MujocoBody
from ..sim.render import Overlay, PushTrace, RolloutRenderer, VideoWriter, applied_push
from ..viz.mapdraw import preference_arrows
from ..viz.video import (
    CARD_S,
    PanelInfo,
    belief_rgba,
    compose,
    info_panel,
    outcome_card,
    outcome_lines,
)

VIDEO_FPS = 25
#: the video's default size and the named ones ``--size`` offers
DEFAULT_SIZE = (960, 540)
HOLD_S = 2.0  # s of simulated time a push or cue stays drawn (>= 1 s of video at speed 2)
TRAIL_EVERY_S = 0.1
#: a trail point is kept only this far (m) from the last one: a standing robot adds none
TRAIL_MIN_STEP_M = 0.01
#: the rerun file's camera: every CAMERA_EVERY-th frame (5 per second of video), at the video's
#: size or, without a video, CAMERA_SIZE
CAMERA_EVERY = 5
CAMERA_SIZE = (640, 360)


def parse_size(text: str) -> tuple[int, int]:
    """``"WxH"`` as ``(W, H)``, each 16..4096, W >= H (the top view is H x H)."""
    parts = str(text).lower().split("x")
    try:
        w, h = (int(p) for p in parts)
        ok = len(parts) == 2 and 16 <= w <= 4096 and 16 <= h <= 4096
    except ValueError:
        ok = False
    if not ok:
        shown = str(text)[:40]
        raise ConfigError(f"--size must be WxH with W and H in 16..4096 (e.g. 960x540 or "
                          f"1280x720), got {shown!r}")
    return w, h


@dataclass
class Recording:
    """A rendered episode: its result, the number of frames and the files written."""

    result: EpisodeResult
    frames: int
    video: Path | None
    rerun: Path | None


class FrameMaker:
    """Builds the frames of an episode from the body's physics steps (module docstring)."""

    def __init__(self, world: World, body: MujocoBody, spec: EpisodeSpec, width: int,
                 height: int):
        self.world, self.body, self.spec = world, body, spec
        self.renderer = RolloutRenderer(body.scene, width, height)
        self.width, self.height = width, height
        self.polygons = world.arrangement.polygons
        self.trail: list[np.ndarray] = []
        self.last_trail_t = -1.0
        #: the push drawn: the force applied to the pushed body, whatever its timing
        self.pushes = PushTrace(HOLD_S)
        self.cue: tuple | None = None  # (t, origin, direction, heading)
        self.cue_seen = None
        self.runner: EpisodeRunner | None = None
        self.preference: list = []

    def attach(self, runner: EpisodeRunner) -> None:
        """The episode's runner (instance, belief, true preference)."""
        self.runner = runner
        self.preference = preference_arrows(self.world, runner.pref)
        self.goal_cells = self.world.cells[list(runner.instance.goals)]

    def track(self, b, push) -> None:
        """Follow every physics step: trail, push onset, detected cue."""
        t = float(b.data.time)
        if t - self.last_trail_t >= TRAIL_EVERY_S:
            self.last_trail_t = t
            p = b.position
            if not self.trail or math.hypot(p[0] - self.trail[-1][0],
                                            p[1] - self.trail[-1][1]) >= TRAIL_MIN_STEP_M:
                self.trail.append(p.copy())
        self.pushes.update(t, applied_push(b.data, b.pushed_body))
        cue = self.body.last_cue
        if cue is not None and cue is not self.cue_seen:
            self.cue_seen = cue
            self.cue = (t, b.position.copy(), np.asarray(cue.impulse, float), cue.heading)

    def frame(self, b, push) -> np.ndarray:
        """The frame of the current physics state."""
        r, t = self.runner, float(b.data.time)
        p = r.policy.belief.goal_marginal()
        o = Overlay(goal_cells=self.goal_cells, goal_rgba=belief_rgba(p),
                    true_goal=r.instance.true_goal, polygons=self.polygons,
                    current=int(self.world.cell_polytope[b.cell]), preference=self.preference,
                    trail=np.array(self.trail + [b.position.copy()]),
                    robot_xy=b.position.copy())
        push_n = None
        shown = self.pushes.shown(t)
        if shown is not None:
            o.push_origin = b.data.xpos[b.pushed_body].copy()  # it follows the robot
            o.push_force, o.push_alpha = shown
            push_n = float(np.linalg.norm(o.push_force))
        cue_heading = None
        if self.cue is not None and t - self.cue[0] <= HOLD_S:
            o.cue_origin, o.cue_direction, cue_heading = b.position.copy(), self.cue[2], \
                self.cue[3]
        top, persp = self.renderer.views(b.data, o)
        panel = None
        if self.renderer.column >= 16 and self.height - self.renderer.persp_h >= 16:
            info = PanelInfo(
                title=f"{self.spec.method}   ΔT = {self.spec.delta_t}   {self.spec.map}",
                step=r.t, t_max=r.spec.t_max, sim_time=t, belief=p,
                true_goal=r.instance.true_goal, pushes=r.result.inputs, push_n=push_n,
                cue_heading=cue_heading)
            panel = info_panel(self.renderer.column, self.height - self.renderer.persp_h, info)
        return compose(top, persp, panel, self.width, self.height)

    def close(self) -> None:
        """Release the renderer."""
        self.renderer.close()


def print_progress(runner: EpisodeRunner, frames: int, started: float) -> None:
    """One line per decision on stderr: step, P(true goal), pushes, frames, seconds."""
    p = float(runner.policy.belief.goal_marginal()[runner.instance.true_goal])
    print(f"step {runner.t}/{runner.spec.t_max}: P(true goal) = {p:.2f}, "
          f"{runner.result.inputs} pushes, {frames} frames, "
          f"{time.perf_counter() - started:.0f} s", file=sys.stderr, flush=True)


def record_rollout(spec: EpisodeSpec, video: str | Path | None = None,
                   rerun: str | Path | None = None, width: int = DEFAULT_SIZE[0],
                   height: int = DEFAULT_SIZE[1], speed: float = 2.0,
                   progress: Callable[[EpisodeRunner, int, float], None] | None = None
                   ) -> Recording:
    """Run ``spec`` in MuJoCo; render frames (module docstring) and log to rerun;
    ``progress(runner, frames, started)`` after every decision."""
    world = cached_world(spec.map)
    body = MujocoBody(world, spec, simulator_rng(spec))
    base = body.base
    every = max(1, int(round(speed / VIDEO_FPS / base.dt)))
    every_push = max(1, int(round(1.0 / VIDEO_FPS / base.dt)))  # pushes play in real time
    # the rerun file's camera shows the video's frames, or frames of its own without a video
    size = (width, height) if video else CAMERA_SIZE
    maker = FrameMaker(world, body, spec, *size) if video or rerun else None
    writer = VideoWriter(video, VIDEO_FPS) if video else None
    state: dict = {"k": 0, "frames": 0, "slot": 0}
    logger = None

    def hook(b, push) -> None:
        if maker is not None:
            maker.track(b, push)
        state["k"] += 1
        pushing = push is not None or (maker is not None and maker.pushes.acting)
        if state["k"] % (every_push if pushing else every):
            return
        camera = logger is not None and state["slot"] % CAMERA_EVERY == 0
        state["slot"] += 1
        frame = None
        if maker is not None and maker.runner is not None and (writer is not None or camera):
            frame = maker.frame(b, push)
            if writer is not None:
                writer.append(frame)
                state["frames"] += 1
        if logger is not None:
            sensing = b.sensing
            force = sensing.sensor.force_xy(b.data) if sensing.sensor_model is None else \
                sensing.force_estimate
            logger.log_frame(b.data.time, b.position, b.end_effector, force=force,
                             detector_active=b.sensing.detector.active,
                             image=frame if camera else None)

    base.on_substep.append(hook)
    runner = EpisodeRunner(spec, world, body)
    if maker is not None:
        maker.attach(runner)
    if rerun:
        from ..viz.rerun_log import RerunLogger

        logger = RerunLogger(world, world.cells[list(runner.instance.goals)],
                             runner.instance.true_goal, rerun, body.scene.cell_size,
                             preference=runner.pref)

    def log_step() -> None:
        if logger is None:
            return
        cue = body.last_cue if runner.pending_heading is not None else None
        b = runner.policy.belief
        logger.log_step(runner.t, base.position, b.goal_marginal(),
                        float(b.goal_marginal()[runner.instance.true_goal]), b.goal_entropy(),
                        None if cue is None else cue.impulse, sim_time=float(base.data.time))

    started = time.perf_counter()
    try:
        runner.begin()
        log_step()
        while not runner.done:
            runner.step()
            log_step()
            if progress is not None:
                progress(runner, state["frames"], started)
    except BaseException as e:  # the recording is to be removed: it must not hold the process
        if logger is None:
            raise
        logger.abandon()
        if isinstance(e, RuntimeError) and "(os error " in str(e):  # rerun's failed write
            raise logger.unwritten(str(e)) from None
        raise
    if writer is not None and maker is not None:
        # the final step's frame (the hook last drew the step before), then the outcome card
        # held for CARD_S seconds
        last = maker.frame(base, None)
        writer.append(last)
        card = outcome_card(last, outcome_lines(runner.result))
        for _ in range(int(round(CARD_S * VIDEO_FPS))):
            writer.append(card)
        state["frames"] += 1 + int(round(CARD_S * VIDEO_FPS))
    if maker is not None:
        maker.close()
    if logger is not None:
        logger.close()
    out_video = writer.close() if writer is not None else None
    return Recording(runner.result, state["frames"], out_video, Path(rerun) if rerun else None)
