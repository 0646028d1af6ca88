"""The decision step of a physical base, one physics step at a time: the one machine every door
runs (the ``--sim mujoco`` body, the study's trials and ``interact`` run it to completion, the
dm_control tasks advance it from their Environment's physics steps).

A decision step is a sequence of phases, each started by one call and advanced by
:meth:`DecisionStep.advance` (one physics step, ``base.substep``) until it ends:

* **push** (:meth:`DecisionStep.push`): the human's push acts for its profile's duration while
  the base holds its cell (``hold=False``: it keeps its command, the control-rate tasks); the
  detector may release up to :data:`RELEASE_WINDOW_S` after the push. It ends at the first
  detected cue or then; the detector is reset. ``cue`` is the detected cue (None: missed),
  ``onset_s`` the time from the push's start to the detector going active.
* **move** (:meth:`DecisionStep.move`): the base drives to a cell centre. It ends when the base
  has settled on it (after at least ``min_s``) and is not yielding to a push, when
  ``max(limit_s, min_s)`` has passed, or, with ``base.stop_on_cue`` (pushes at any time), at a
  cue: the base then holds the cell it is in (a guided base: where the push left it). A
  *timed* move (``steps``, guidance: every door runs a guided decision step for exactly that
  many physics steps, :func:`timed_steps`) holds where it ended, a person's pushes still
  deforming the hold, until its last step.
* **hold** (:meth:`DecisionStep.hold`): the base stands at its cell's centre for ``seconds``
  (forever by default: until the caller starts another phase); with ``base.stop_on_cue`` (or
  ``until_cue``) a cue ends it.

Every cue the detector gives, in any phase, is recorded by the base (``base.felt``) and given
to its one listener, the episode runner's door (:mod:`.mobile_base`); a phase only decides when
it ends. Time limits compare simulated time with the phase's end, ``t >= t_end``, after each
physics step.
"""

from __future__ import annotations

import math

import numpy as np

from ..episode.physics import RELEASE_WINDOW_S
from ..errors import ConfigError

MOVE, PUSH, HOLD = "move", "push", "hold"


def timed_steps(step_s: float, dt: float) -> int:
    """The physics steps of a decision step of ``step_s`` seconds at the timestep ``dt``
    (the count dm_control's Environment takes for a control timestep, ``round(step_s /
    dt)``): a timed move (guidance) lasts exactly this many in every door."""
    return max(1, int(round(step_s / dt)))


def move_limit(limit_s: float, step_s: float, push_window_s: float, dt: float) -> float:
    """The longest move of a decision step of ``step_s`` seconds: the drive's ``limit_s``,
    within what the step leaves after the push window (and two physics steps)."""
    return min(limit_s, step_s - push_window_s - 2 * dt)


class DecisionStep:
    """The phases of a decision step on ``base`` (a :class:`~.mobile_base.MobileBase`; module
    docstring). ``phase`` is the phase under way (None: none)."""

    def __init__(self, base):
        self.base = base
        self.phase: str | None = None
        #: the cue that ended the last push phase (None: the push was missed)
        self.cue = None
        #: seconds from the last push's start to the detector going active (None: it did not)
        self.onset_s: float | None = None
        self._push = None
        self._t0 = self._t_end = self._min_s = 0.0
        self._until_cue = False
        #: a timed move's physics steps (None: the move ends when it ends) and count so far
        self._steps: int | None = None
        self._n = 0
        self._driving = False
        #: the move's target while the base first returns to a clear waypoint (None: none)
        self.final: np.ndarray | None = None

    def push(self, push, hold: bool = True) -> DecisionStep:
        """Start the push phase: ``push`` begins now (its ``t0`` is set)."""
        b = self.base
        if hold:
            b.target = b.scene.cell_centre(b.cell)
        push.t0 = float(b.data.time)
        self._push, self.phase, self.cue, self.onset_s = push, PUSH, None, None
        self._t_end = push.t0 + push.profile.duration_s + RELEASE_WINDOW_S
        return self

    def move(self, cell: int, limit_s: float, min_s: float = 0.0,
             steps: int | None = None) -> DecisionStep:
        """Start the move phase toward the centre of ``cell``. A base that a person moved off
        its cells' centres (guidance, a yield) may stand where the straight way to that
        centre is not clear of obstacles (the footprint rule, :meth:`.scene.Scene.clear`):
        it then drives first to the centre of the cell it stands in (a clear waypoint: the
        grid's moves start there) and on to the target from there (:attr:`final`). A move
        that starts off its cell's centre or still moving (:func:`off_the_grid`: a tap
        stopped the last move, a yield, guidance) is not the grid's straight clear move: the
        safety filter acts on all of it (:attr:`.mobile_base.MobileBase.keep_clear`).
        ``steps``: a timed move of exactly that many physics steps (module docstring)."""
        b = self.base
        target = b.scene.cell_centre(cell)
        pos = b.data.qpos[b.xy]
        self.final = None
        b.keep_clear = off_the_grid(b, pos)
        if not b.scene.clear(pos, target):
            here = b.scene.cell_centre(b.scene.cell_at(pos))
            if b.scene.clear(pos, here):
                self.final, target = target, here
        b.target = target
        # views into MjData (its buffers stay put; navigate.xml's slide joints are adjacent)
        q, v = int(b.xy[0]), int(b.vxy[0])
        if b.xy[1] != q + 1 or b.vxy[1] != v + 1:  # pragma: no cover - navigate.xml's order
            raise ConfigError("the base's joints slide_x and slide_y must be adjacent")
        self._pos, self._vel = b.data.qpos[q:q + 2], b.data.qvel[v:v + 2]
        self._t0 = float(b.data.time)
        self._min_s = float(min_s)
        self._t_end = self._t0 + max(float(limit_s), self._min_s)
        self._steps, self._n, self._driving = steps, 0, True
        self.phase = MOVE
        return self

    def hold(self, seconds: float = math.inf, until_cue: bool | None = None) -> DecisionStep:
        """Start the hold phase at the current cell's centre; a cue ends it when ``until_cue``
        (default: ``base.stop_on_cue``)."""
        b = self.base
        b.target = b.scene.cell_centre(b.cell)
        self._t_end = float(b.data.time) + seconds
        self._until_cue = b.stop_on_cue if until_cue is None else bool(until_cue)
        self.phase = HOLD
        return self

    def advance(self) -> bool:
        """One physics step of the phase under way; True when it ended with this step."""
        b, phase = self.base, self.phase
        if phase == PUSH:
            return self.push_ended(b.substep(self._push))
        if phase == MOVE:
            return self.move_ended(b.substep())
        if phase == HOLD:
            cue = b.substep()
            if not (cue is not None and self._until_cue) and b.data.time < self._t_end:
                return False
        else:
            b.substep()
            return True
        self.phase = None
        return True

    def push_ended(self, cue) -> bool:
        """The push phase's check after a physics step that gave ``cue``: note when the
        detector went active; True (the detector reset, :attr:`cue` set, no phase under way)
        at a cue or once the release window is over."""
        b = self.base
        if self.onset_s is None and b.sensing.detector.active:
            self.onset_s = float(b.data.time) - self._push.t0
        if cue is None and b.data.time < self._t_end:
            return False
        b.sensing.detector.reset()
        self.cue = cue
        self.phase = None
        return True

    def move_ended(self, cue) -> bool:
        """The move's end check after a physics step that gave ``cue`` (module docstring);
        True (and no phase under way) when the move ended; a timed move holds the cell the
        drive ended in until its last physics step."""
        if self._steps is None:
            return self._drive_ended(cue)
        self._n += 1
        if self._driving and self._drive_ended(cue):
            self.hold_after_drive(cue)
        return self.timed_out()

    @property
    def current_push(self):
        """The push of the push phase (a :class:`~.force_cue.HumanPush`; the last one after
        it, None before the first)."""
        return self._push

    def kernel_bounds(self) -> tuple[float, float, float, int | None]:
        """The phase under way as the compiled steps (:mod:`.coasting`) take it: ``(t0,
        min_s, t_end, steps)``, the move's end check (settled after ``min_s`` s from ``t0``,
        or ``t >= t_end``) and the physics steps left of a timed move (None: untimed). A
        timed move holding after its drive and a push phase have no settle check
        (``min_s`` infinite); the hold has no end by time either (``t_end`` infinite: its
        steps end it)."""
        if self.phase == PUSH:
            return 0.0, math.inf, self._t_end, None
        if self._steps is None:
            return self._t0, self._min_s, self._t_end, None
        left = self._steps - self._n
        if self._driving:
            return self._t0, self._min_s, self._t_end, left
        return 0.0, math.inf, math.inf, left

    def add_steps(self, n: int) -> None:
        """``n`` physics steps of a timed move taken without :meth:`advance` (the compiled
        steps, :mod:`.coasting`; their end checks were the kernel's)."""
        self._n += n

    def hold_after_drive(self, cue) -> None:
        """A timed move's drive ended (with ``cue``, None: settled or out of time): the rest
        of its steps hold the cell the base is in (a cue already set the target)."""
        self._driving, self.phase = False, MOVE
        if cue is None:
            b = self.base
            b.target = b.scene.cell_centre(b.cell)

    def timed_out(self) -> bool:
        """Whether a timed move has taken all its steps (then no phase is under way)."""
        if self._n < self._steps:
            return False
        self.phase, self._steps = None, None
        return True

    def _drive_ended(self, cue) -> bool:
        """The drive's end check (module docstring): True (and no phase under way) when the
        base has settled, the time is out or a cue stopped it."""
        b = self.base
        t = b.data.time
        if cue is not None and b.stop_on_cue:
            if b.guidance is None:  # stop here: the planner replans
                b.target = b.scene.cell_centre(b.cell)
            # guided: the base keeps where the person took it (the deformed target, which
            # the admittance's tail still moves), not its cell's centre
            self.final = None
        elif self.final is not None and t < self._t_end and not b.yielding() and \
                b.controller.settled(self._pos, self._vel, b.target):
            b.target, self.final = self.final, None  # at the waypoint: on to the target
            return False
        elif not ((t - self._t0 >= self._min_s and
                   b.controller.settled(self._pos, self._vel, b.target) and
                   not b.yielding()) or t >= self._t_end):
            return False
        self.final = None
        self.phase = None
        return True

    def run(self) -> DecisionStep:
        """Advance until the phase under way ends (a blocking caller). The steps of a move
        with nothing pushing and of a push phase go through the compiled kernel of
        :mod:`.coasting` where it applies (the same numbers), the others through
        :meth:`advance`."""
        coaster = self.base.coaster
        while True:  # every pass takes at least one physics step
            if coaster is not None and self.phase in (MOVE, PUSH) and coaster.ready():
                if self.phase == MOVE:
                    if coaster.move(self):
                        return self
                    continue
                steps, _, ended = coaster.push(self)
                if ended:
                    return self
                if steps:
                    continue  # (none: the kernel left this step to Python, e.g. to refuse it)
            if self.advance():
                return self


#: how far from its cell's centre (m) and how fast (m/s) a base may stand for its next move to
#: be the grid's own straight clear move (the controller's arrival tolerance, ``tol_m`` 0.02 m
#: and ``still_mps`` 0.05 m/s, doubled)
ON_GRID_M = 0.04
ON_GRID_MPS = 0.1


def off_the_grid(b, pos) -> bool:
    """Whether base ``b`` at ``pos`` (m) stands more than :data:`ON_GRID_M` from the centre of
    the cell it is in, or moves faster than :data:`ON_GRID_MPS`: its next move is then not the
    grid's straight clear move from a cell's centre, and the safety filter acts on it."""
    here = b.scene.cell_centre(b.scene.cell_at(pos))
    v = b.data.qvel[b.vxy]
    return bool(math.hypot(pos[0] - here[0], pos[1] - here[1]) > ON_GRID_M
                or math.hypot(v[0], v[1]) > ON_GRID_MPS)
