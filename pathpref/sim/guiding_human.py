"""A simulated person who guides the robot the way Bajcsy et al.'s participants corrected theirs:
closed-loop, pushing while the robot goes the wrong way and letting go once it behaves
(``docs/physics.md``, section 9; ``../shared/PHRI_NOTES.md`` section 4).

**When.** By default the person takes the handle on the ``interval``
clock of :class:`~.pushing_human.PushingHuman` (the first grasp ``reaction_s`` after the
start, then every ``I (1 + j u)`` seconds, ``u ~ U[-1, 1]``; a grasp that falls due while the
person still holds the handle waits for the release), so guidance and taps get the same
number of interventions. Corrective (the episode's ``--push-rule corrective delay=D
miss=M``, the rule the tapping corrective person follows): when the robot starts a move that
would leave the person's route (or is about to, or heads away from the goal along it), after
the reaction delay ``reaction_s (1 + 0.25 z)`` (0.4 s median: a visual reaction of 0.2-0.25 s
and the force's build-up, ``PHRI_NOTES`` section 5) plus ``D`` steps
(:class:`~.pushing_human.PushingHuman`); the person then holds until the robot heads their
way again and lets go (below).

**Where to.** The person aims where their own route wants the robot, chosen as the tapping
person chooses a tap's heading: a heading ``h(c) ~ P(h | c, g, p)`` drawn from the human
model at the base's cell ``c`` with its rationality ``gamma_h`` (SPEC 4: Boltzmann over the
extra length of the way to the true goal that keeps the preference; ``heading_at``, the
tapping person's own draw), at the grasp and again whenever the base enters another cell,
plus a motor noise ``eps ~ N(0, noise_deg)`` drawn once per push: ``u = (cos(a(h) + eps),
sin(a(h) + eps))``. So guidance and taps compare at one rationality: ``gamma_h`` 100 is the
person who always takes the best heading (the guiding person's only choice before, whatever
``gamma_h`` said), the default 1.5 the paper's.

**How hard.** ``F = F_p (S + (1 - S) e)`` along ``u``, with ``F_p`` the push's strength
(log-normal, median ``peak_n``, spread ``peak_spread``, clipped to ``[peak_min_n,
peak_max_n]``, as for taps), ``S = HOLD_SHARE`` the light hold a person keeps on a handle, and
the deviation ``e = min(1, |V u - v| / V)`` of the base's velocity ``v`` from the velocity the
person wants, ``V = GUIDE_SPEED`` along ``u``: a base standing still or going the wrong way is
pushed with ``F_p``, one going the person's way at ``V`` with ``S F_p``. The force rises and
falls with raised-cosine ramps of ``RAMP_S``.

**When to let go.** Once the base heads the right way (speed at least ``V / 2`` within
``RIGHT_DEG`` of ``u``) without a break for the person's release reaction ``r = max(0.05,
reaction_s (1 + 0.25 z))`` and the push has lasted ``MIN_HOLD_S``, or at the push's longest
hold (log-normal, median ``hold_s``, spread ``duration_spread``, clipped to 0.5..10 s), the
person lets go (the ``RAMP_S`` ramp down).

The robot never reads any of this: it feels the handle's force through its sensor.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from ..episode.physics import HumanModel
from ..geometry.grid import ACTION_ANGLES
from .force_cue import CONTACT_N, HumanPush, PushProfile
from .pushing_human import PushingHuman

#: the speed at which the person wants the base to go their way (m/s; the default admittance
#: moves the base at 25 N / 80 N s/m = 0.31 m/s)
GUIDE_SPEED = 0.3
#: the share of a push's strength the person keeps while the base goes their way
HOLD_SHARE = 0.4
#: how far the base's heading may be off the person's aim for "the right way" (degrees)
RIGHT_DEG = 30.0
#: the shortest push (s): a grasp is felt even when the base already goes the right way
MIN_HOLD_S = 0.5
#: the raised-cosine ramps of the force at grasp and release (s)
RAMP_S = 0.2


class GuidingPush(HumanPush):
    """A push whose force the person sets at every physics step (:attr:`now`: the world-frame
    force, N) and whose end is known only at the release: until then ``profile.duration_s`` is
    the longest hold."""

    def __init__(self, angle: float, t0: float, profile: PushProfile, intended_heading: int):
        super().__init__(angle, t0, profile, intended_heading)
        self.now = np.zeros(3)
        self.released_at: float | None = None
        #: the force the person applied, step by step: ``[sum |F| dt, max |F|, contact s]``
        self.felt = np.zeros(3)

    def applied(self, t: float, dt: float) -> None:
        """The force :attr:`now` acts for the physics step at ``t`` (of ``dt``): counted into
        :attr:`felt` when the push acts then."""
        if self.active(t):
            f = math.hypot(float(self.now[0]), float(self.now[1]))
            self.felt[0] += f * dt
            self.felt[1] = max(self.felt[1], f)
            self.felt[2] += dt if f >= CONTACT_N else 0.0

    def effort(self, dt: float, t_end: float) -> tuple[float, float, float]:
        """The force the person set, as applied step by step (:attr:`felt`; ``dt`` and
        ``t_end`` are the steps' own)."""
        return float(self.felt[0]), float(self.felt[1]), float(self.felt[2])

    def force(self, t: float) -> np.ndarray:
        """The force the person applies now (set by :class:`GuidingHuman` before the step)."""
        return self.now.copy() if self.active(t) else np.zeros(3)

    def release(self, t: float) -> None:
        """The person lets go at ``t``: the push ends after the ramp down."""
        self.released_at = t
        self.profile = replace(self.profile, duration_s=max(t - self.t0 + RAMP_S, 1e-6))


def _ramp(s: float) -> float:
    """The raised-cosine ramp ``(1 - cos(pi s)) / 2`` for ``s`` in [0, 1]."""
    s = min(max(s, 0.0), 1.0)
    return 0.5 - 0.5 * math.cos(math.pi * s)


class GuidingHuman(PushingHuman):
    """The closed-loop person of the module docstring, a ``pre_substep`` hook on the base (the
    grasp times and the stream are :class:`~.pushing_human.PushingHuman`'s).

    ``heading_at(cell)`` draws the person's heading at a cell (their aim, the tapping
    person's draw); ``probs(cell)`` is the human model's heading distribution there."""

    def __init__(self, human: HumanModel, rng: np.random.Generator, delta_t: int,
                 heading_at: Callable[[int], int],
                 probs: Callable[[int], np.ndarray], step_s: float = 1.0, watch=None):
        super().__init__(human, rng, delta_t, heading_at, probs, step_s, watch)
        self.push: GuidingPush | None = None
        self._aim_cell = -1
        self._right_since: float | None = None

    def quiet_until(self) -> float:
        """No quiet stretch while the person holds the handle."""
        return -math.inf if self.push is not None else super().quiet_until()

    def _aim(self, cell: int) -> int:
        """The person's heading at ``cell``: drawn from the human model at its ``gamma_h``
        (module docstring)."""
        return int(self.heading_at(cell))

    def _grasp(self, base, t: float) -> None:
        """Take the handle now: the push's strength, longest hold, aim noise and release
        reaction drawn from the person's stream (module docstring)."""
        p, rng = self.model, self.rng
        peak = float(np.clip(p.peak_n * p.peak_spread ** rng.standard_normal(),
                             p.peak_min_n, p.peak_max_n))
        hold = float(np.clip(p.hold_s * p.duration_spread ** rng.standard_normal(), 0.5, 10.0))
        self._noise = math.radians(p.noise_deg) * float(rng.standard_normal())
        self._reaction = max(0.05, p.reaction_s * (1.0 + 0.25 * float(rng.standard_normal())))
        heading = self._aim(base.cell)
        push = GuidingPush(float(ACTION_ANGLES[heading]) + self._noise, t,
                           PushProfile(peak_n=peak, duration_s=hold, noise_deg=p.noise_deg,
                                       shape="plateau"), heading)
        self.push, self._aim_cell, self._right_since = push, base.cell, None
        base.pushes.append(push)
        self.given.append(push)
        self.next_t = None if self.corrective else t + self._gap()

    def __call__(self, base) -> None:
        """Before a physics step: grasp when due, then set the push's force for this step."""
        t = float(base.data.time)
        push = self.push
        if push is None:
            if self.next_t is None or t < self.next_t:
                return
            self._grasp(base, t)
            push = self.push
        if push.released_at is not None:  # ramping down
            left = push.t0 + push.profile.duration_s - t
            if left <= 0.0:
                push.now[:] = 0.0
                self.push = None
                return
            push.now[:2] = self._last_xy * _ramp(left / RAMP_S)
            push.applied(t, base.dt)
            return
        cell = base.cell
        if cell != self._aim_cell:  # re-aim at the new cell's best heading
            self._aim_cell = cell
            push.intended_heading = self._aim(cell)
            push.angle = float(ACTION_ANGLES[push.intended_heading]) + self._noise
        ux, uy = math.cos(push.angle), math.sin(push.angle)
        vx, vy = (float(x) for x in base.velocity)
        speed = math.hypot(vx, vy)
        right = speed >= 0.5 * GUIDE_SPEED and \
            (vx * ux + vy * uy) >= speed * math.cos(math.radians(RIGHT_DEG))
        held = t - push.t0
        if right:
            if self._right_since is None:
                self._right_since = t
        else:
            self._right_since = None
        if held >= push.profile.duration_s or (
                held >= MIN_HOLD_S and self._right_since is not None and
                t - self._right_since >= self._reaction):
            push.release(t)
        dev = min(1.0, math.hypot(GUIDE_SPEED * ux - vx, GUIDE_SPEED * uy - vy) / GUIDE_SPEED)
        f = push.profile.peak_n * (HOLD_SHARE + (1.0 - HOLD_SHARE) * dev) * _ramp(held / RAMP_S)
        self._last_xy = np.array([f * ux, f * uy])
        push.now[:2] = self._last_xy
        push.now[2] = 0.0
        push.applied(t, base.dt)
