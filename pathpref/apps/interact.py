"""Study mode (``pathpref interact``): a person pushes the robot's handle in the MuJoCo viewer
and the robot infers and replans live.

The viewer's mouse perturbation (double-click the orange handle, then Ctrl + right-drag)
becomes ``xfrc_applied`` on the handle when the viewer syncs; the robot senses it exactly like a
simulated push: handle force sensor -> cue detector -> heading -> belief update. Cues detected
while the base drives are given to the belief before the next decision, and the planner plans
from the updated belief. The simulated human is not used.

:class:`InteractiveSession` holds the loop without any window, so it is tested headlessly with a
scripted perturbation (``mjv_applyPerturbForce``, as the viewer does).
"""

from __future__ import annotations

import time

import numpy as np

from ..episode import EpisodeRunner, EpisodeSpec, cached_world, simulator_rng
from ..sim.body import MujocoBody
from ..sim.mobile_base import MobileBase


class ViewerBody(MujocoBody):
    """The MuJoCo body pushed by the person at the viewer, not by the simulated human: every
    cue it reads reaches the runner's door as it is read (the one cue stream)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.base.external_forces = True

    def attach_human(self, heading_at, probs, watch=None) -> bool:
        """The person at the viewer gives every input: the runner gives none at decision
        steps."""
        return True

    def inputs_given(self) -> int:
        """The cues read from the person's pushes."""
        return len(self.base.felt)

    def push(self, heading: int) -> None:
        """Not used: the person pushes."""


class InteractiveSession:
    """A live episode on ``map`` whose human is the person at the viewer (window-free)."""

    def __init__(self, map: str = "office", method: str = "path_preference", seed: int = 0,
                 queries: int = 2000, t_max: int = 200):
        world = cached_world(map)
        self.spec = EpisodeSpec.single(map, method, 1, seed=seed, sim="mujoco",
                                       queries=queries, t_max=t_max)
        self.body = ViewerBody(world, self.spec, simulator_rng(self.spec))
        self.runner = EpisodeRunner(self.spec, world, self.body)
        self.observed: list[int] = []

    @property
    def base(self) -> MobileBase:
        """The physical base the person pushes."""
        return self.body.base

    def step(self) -> None:
        """One decision: plan from the belief, drive; pushes felt on the way update it."""
        self.runner.begin()
        self.runner.step()
        if self.runner.pending_heading is not None:
            self.observed.append(self.runner.pending_heading)


def run_viewer(session: InteractiveSession, realtime: bool = True) -> None:
    """Open the MuJoCo viewer on the session (needs a display); on exit, wait for the
    viewer's thread (:func:`~pathpref.study.viewer.close_viewer`)."""
    from ..study.viewer import close_viewer, frame_map, launch_viewer

    base = session.base
    viewer, threads = launch_viewer(base.model, base.data, panels=True)
    with viewer.lock():  # the whole map in view, not a close-up of a wall
        frame_map(viewer.cam, session.runner.world, base.scene.cell_size)
    clock = {"wall": time.perf_counter(), "sim": float(base.data.time), "k": 0}

    def sync(b, push) -> None:
        clock["k"] += 1
        if clock["k"] % 8:
            return
        viewer.sync()
        if realtime:
            ahead = (b.data.time - clock["sim"]) - (time.perf_counter() - clock["wall"])
            if ahead > 0:
                time.sleep(ahead)

    base.on_substep.append(sync)
    try:
        while viewer.is_running() and not session.runner.done:
            session.step()
            r = session.runner
            print(f"t={r.t:3d} cell={tuple(int(v) for v in r.world.cells[r.cell])} "
                  f"P(goal)={np.round(r.policy.belief.goal_marginal(), 2)}", flush=True)
    finally:
        close_viewer(viewer, threads)
