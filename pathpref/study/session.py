"""One trial of a study on the episode loop, in MuJoCo physics, with a person's pushes.

Whatever the front end (browser drag, MuJoCo viewer, script), a push is a force on the robot's
handle: a :class:`PushSource` gives the force (N, world x-y) for every physics step and it is
written into ``xfrc_applied`` of the handle before the step (the viewer writes it itself). The
robot feels it only through its handle force sensor -> cue detector -> heading, exactly as a
simulated push; each cue is given to the belief the moment it is detected (at the cell the base
is in), so the next decision plans from it.

The trial's physics and robot (:meth:`~.plan.Trial.episode_spec`) build the body as at every
door (:class:`~pathpref.sim.body.MujocoBody`: the sensing chain, detector, drive and, for
``carry``, the arm whose tray the participant pushes).

The robot is told nothing else: not the trial's goal, not its route. It infers over the trial's
goal candidates and plans with a receding horizon of the map's ``t_max`` decision steps. No
candidate is ruled out when the robot drives over it.

**The trial's end.** At the end of each decision step (the base has settled on its target cell,
after at least :data:`MIN_STEP_S` of simulated time so that a person always has time to push,
or after the controller's 3 s limit) the trial ends with *success* when the base is on the
trial's goal cell and the time limit has not passed, and with *failure* (``timeout``) when
the simulated time since the start reaches the limit. A person's trial runs in real time
(:class:`Pacer`), so simulated and wall seconds agree; a scripted one runs as fast as the
machine allows.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Protocol

import numpy as np

from ..episode import EpisodeRunner, Felt, simulator_rng
from ..geometry.grid import STAY
from ..sim.body import MujocoBody
from ..sim.mobile_base import MobileBase
from .intent import policy_path
from .plan import Trial

#: shortest decision step (simulated s): the base holds its cell at least this long
MIN_STEP_S = 0.5


class PushSource(Protocol):
    """What a participant's front end gives the physics: the force on the handle now."""

    def force(self) -> np.ndarray:
        """The force (N, world x-y) to apply during the next physics step."""


class StudyBody(MujocoBody):
    """The MuJoCo base pushed by a participant: the :class:`PushSource`'s force goes into the
    handle's ``xfrc_applied`` before every physics step (with ``source=None`` someone else
    writes it: the MuJoCo viewer's perturbation). Decision steps last at least
    :data:`MIN_STEP_S`."""

    def __init__(self, world, spec, rng, source: PushSource | None = None):
        super().__init__(world, spec, rng)
        self.source = source
        self.base.external_forces = True
        self.applied = np.zeros(2)  # the source's force, set for the coming physics step
        if source is not None:
            self.base.on_substep.insert(0, self._apply)

    def _apply(self, base: MobileBase, push) -> None:
        """Set the handle's force for the next physics step from the source."""
        f = np.asarray(self.source.force(), float)
        self.applied = f
        base.data.xfrc_applied[base.pushed_body, :] = 0.0
        base.data.xfrc_applied[base.pushed_body, :2] = f

    def felt_force(self) -> np.ndarray:
        """The participant's force (N, world x-y) on the handle now: read by a physics-step
        hook that runs first, it is the force that acted during the step just taken."""
        if self.source is not None:
            return self.applied
        return self.base.data.xfrc_applied[self.base.pushed_body, :2].copy()

    def attach_human(self, heading_at, probs, watch=None) -> bool:
        """No simulated human: the participant pushes. With ``timing`` ``guidance`` the base
        complies to the participant's push (Bajcsy-style guidance, :mod:`pathpref.sim.guidance`)
        and the trial is judged along its path."""
        if self.physics is not None and self.physics.human.timing == "guidance":
            self.enable_guidance()
        return False

    def push(self, heading: int) -> None:
        """Not used in a trial: the person pushes, and the cues reach the runner's door as
        they are read."""

    def move(self, action: int) -> int:
        """Drive to the grid neighbour (at least :data:`MIN_STEP_S`; a guided trial's step is
        every door's guided step); the cell reached."""
        self.cell = self.base.cell
        target = self.cell if action == STAY else int(self.world.motion.next_cell[self.cell,
                                                                                  action])
        if self.path is not None:
            return self.guided_move(target)
        self.cell = self.base.move_to(target, min_s=MIN_STEP_S)
        return self.cell


class TrialRunner(EpisodeRunner):
    """The episode loop for a trial (module docstring): no simulated human, no rule-out, the
    route's preference scores the moves, the goal cell or the time limit ends it."""

    def __init__(self, trial: Trial, seed: int, source: PushSource | None = None):
        world = trial.world
        spec = trial.episode_spec(seed)
        self.trial = trial
        body = StudyBody(world, spec, simulator_rng(spec), source)
        self.cues: list[tuple[float, int, Felt]] = []  # (trial time, cell, cue)
        #: told of every cue after it reached the belief (the recorder, the front end)
        self.on_cue: list[Callable[[Felt], None]] = []
        super().__init__(spec, world, body)
        # the episode layer hands every policy the goal and the preference (for the reference
        # methods, refused in studies); a trial's robot gets neither
        self.policy.ctx.true_goal, self.policy.ctx.true_preference = -1, None
        self.goal_cell = world.cell(trial.goal)
        self.t_start = float(self.body.base.data.time)
        self.on_belief: list[Callable[[str], None]] = []
        #: the move under way (None: the robot holds its cell between decisions)
        self.intended_action: int | None = None
        self._plan: list[int] | None = None

    def planned_path(self) -> list[int]:
        """The cells (indices) the robot intends to visit, from its cell: the decided move
        under way, then the belief's most likely route (:mod:`.intent`). Computed once per
        decision, move or cue (the belief or the move changed), not per call."""
        if self._plan is None:
            self._plan = policy_path(self.world, self.model.goals, self.policy, self.cell,
                                     self.intended_action)
        return self._plan

    def _preference(self, free_goal: bool) -> np.ndarray:
        """The route's preference (the map's own is not used, and may be absent)."""
        return self.trial.route_preference()

    @property
    def base(self) -> MobileBase:
        """The physical base the participant pushes."""
        return self.body.base

    @property
    def time_s(self) -> float:
        """Simulated seconds since the trial began."""
        return float(self.base.data.time) - self.t_start

    @property
    def timed_out(self) -> bool:
        """The time limit has passed."""
        return self.time_s >= self.trial.time_limit_s

    @property
    def done(self) -> bool:
        """The goal is reached or the time limit has passed."""
        return self.result.goal_reached or self.timed_out

    def observe(self, felt: Felt) -> None:
        """A cue read by the robot's own sensing enters the belief at once through the
        runner's one door (the heading shown to the policy at the next decision is the last
        cue since the previous one); then the trial's listeners are told. A guided push's
        partial records (:class:`~pathpref.episode.body.Felt`) move the belief (cause
        ``guidance``) but are not cues."""
        if self.done:
            return
        super().observe(felt)
        self._plan = None
        if felt.partial:  # guidance: a push under way moved the belief; not a cue
            for hook in self.on_belief:
                hook("guidance")
            return
        self.cues.append((self.time_s, felt.cell, felt))
        for hook in self.on_cue:
            hook(felt)
        for hook in self.on_belief:
            hook("cue")

    def _human_phase(self) -> None:
        """No simulated human: the person's cues arrive through :meth:`observe`."""

    def _arrive(self, cell: int) -> None:
        """The trial's goal cell ends the trial (before the limit); nothing is ruled out."""
        if cell == self.goal_cell and not self.timed_out:
            self.result.goal_reached = True
            self.result.homotopic = self._homotopic(cell)

    def decide(self) -> None:
        """One decision: plan (receding horizon) from the belief, drive; cues on the way go
        to the belief as they come."""
        self.begin()
        action = int(self.policy.act(1, self.cell, self.pending_heading))
        self.intended_action, self._plan = action, None
        try:
            self.step(action)
        finally:
            self.intended_action, self._plan = None, None
        for hook in self.on_belief:
            hook("move")


class Pacer:
    """Keeps simulated time from running ahead of the wall clock (a person's trial). Time the
    physics stood still (while the robot planned) is not caught up: a lag over ``slack_s``
    moves the reference instead, so a push is never replayed faster than it was made."""

    def __init__(self, slack_s: float = 0.05, every: int = 10):
        self.slack_s, self.every = slack_s, every
        self.k = 0
        self.ref: tuple[float, float] | None = None

    def __call__(self, base: MobileBase, push=None) -> None:
        """A physics-step hook: sleep while simulated time is ahead of the wall clock."""
        self.k += 1
        if self.k % self.every:
            return
        now, sim = time.perf_counter(), float(base.data.time)
        if self.ref is None:
            self.ref = (now, sim)
        ahead = (sim - self.ref[1]) - (now - self.ref[0])
        if ahead > 0:
            time.sleep(ahead)
        elif ahead < -self.slack_s:
            self.ref = (now, sim)
