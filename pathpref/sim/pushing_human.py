"""A simulated human who pushes like a person: strength, duration and shape drawn from
distributions, timing not locked to the robot's decisions, and an option to intervene when the
robot heads the wrong way (:class:`~pathpref.episode.physics.HumanModel` holds the settings,
``docs/physics.md`` their sources).

* **Strength and duration** (:func:`sample_profile`): log-normal, ``F = F_med s_F^z`` and
  ``T = T_med s_T^z'`` with ``z, z' ~ N(0, 1)``, clipped to their ranges; the angle noise is
  ``N(0, sigma)`` as before.
* **Timing** (:class:`PushingHuman`, a ``pre_substep`` hook on the base, so a push may begin
  at any physics step, while the base drives, brakes or stands):
  ``interval``: the next push ``I (1 + j u)`` seconds after the last began, ``u ~ U[-1, 1]``;
  ``rate``: exponential gaps of mean ``I`` (a Poisson process); in both the first push comes
  ``reaction_s`` after the start (the paper's protocol also gives an input before the first
  move; without it the robot drove its first seconds uninformed: success 0.28 against 0.53 at
  input steps in the study, ``docs/physics.md``);
  ``corrective``: when the robot starts a move the human finds wrong (its heading has less
  than half the probability of the human's most likely heading, SPEC 4), a push follows
  after a reaction time ``~ reaction_s (1 + 0.25 z)`` with probability ``p_correct``; after a
  right move a needless push with ``p_needless``. Both are scaled by what the human has seen
  (Wang et al. 2025, arXiv 2501.03515: people withhold corrections from a robot that seems
  to fail and add needless ones to one that seems to work): with ``r`` the share of right
  moves among the last 5, ``p_correct r`` and ``p_needless r``.
  The heading is drawn from the Boltzmann model at the cell where the push begins.
  **A guided episode's corrective person** (``--timing guidance`` with the episode's
  ``--push-rule corrective delay=D miss=M``, :mod:`pathpref.episode.corrective`: ``watch``):
  when the robot starts a move the rule finds wrong (the move would leave the person's route
  or head away from the goal along it: ``CorrectiveHuman.needs_push`` on the move's start and
  target cells), the person takes the handle after the reaction delay ``reaction_s (1 + 0.25
  z)`` (at least 0.05 s; 0.4 s median: a visual reaction of 0.2-0.25 s and the force's
  build-up, ``PHRI_NOTES`` section 5) plus ``D`` decision steps, unless the need is missed
  (probability ``M``, drawn from the rule's stream); no need is noticed while a grasp is due.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable

import numpy as np

from ..episode.physics import HumanModel
from ..geometry.grid import STAY
from .force_cue import HumanPush, PushProfile


def sample_profile(human: HumanModel, rng: np.random.Generator,
                   confidence: float = 1.0) -> PushProfile:
    """One push's profile: log-normal strength and duration (module docstring); with
    ``strength_confidence`` ``c > 0`` the median strength is ``F_med exp(c (q - 1/2))`` for a
    heading the human gives with confidence ``q`` (its probability over the most likely
    heading's): a firm push is a confident one."""
    p = human
    median = p.peak_n if p.strength_confidence == 0 else \
        p.peak_n * float(np.exp(p.strength_confidence * (confidence - 0.5)))
    peak = median * p.peak_spread ** rng.standard_normal()
    dur = p.duration_s * p.duration_spread ** rng.standard_normal()
    if p.timing == "guidance":  # a sustained push: held for a log-normal time, median hold_s
        hold = p.hold_s * p.duration_spread ** rng.standard_normal()
        return PushProfile(peak_n=float(np.clip(peak, p.peak_min_n, p.peak_max_n)),
                           duration_s=float(np.clip(hold, 0.5, 10.0)), noise_deg=p.noise_deg,
                           shape="plateau")
    return PushProfile(peak_n=float(np.clip(peak, p.peak_min_n, p.peak_max_n)),
                       duration_s=float(np.clip(dur, 0.1, p.duration_max_s)),
                       noise_deg=p.noise_deg, shape=p.shape)


class PushingHuman:
    """Starts pushes on a base at times of its own (module docstring).

    ``heading_at(cell)`` draws the human's heading at a cell; ``probs(cell)`` gives the
    human's heading distribution there (for ``corrective``); ``delta_t`` sets the default
    interval (``delta_t`` decision steps of ``step_s`` seconds: the one rule,
    :meth:`~pathpref.episode.physics.Physics.step_s`). Attach with :meth:`attach`; tell it of
    each move with :meth:`robot_moves`."""

    def __init__(self, human: HumanModel, rng: np.random.Generator, delta_t: int,
                 heading_at: Callable[[int], int],
                 probs: Callable[[int], np.ndarray] | None = None, step_s: float = 1.0,
                 watch=None):
        self.model, self.rng = human, rng
        self.heading_at, self.probs = heading_at, probs
        self.interval = human.interval_s if human.interval_s > 0 else delta_t * step_s
        self.step_s = step_s
        #: the episode's corrective rule (guided episodes; module docstring), or None
        self.watch = watch
        self.next_t: float | None = None
        self.given: list[HumanPush] = []
        self.recent: deque[bool] = deque(maxlen=5)
        #: the person intervenes when the robot errs (``corrective`` taps, or a guided
        #: episode's corrective rule), not on a clock
        self.corrective = human.timing == "corrective" or watch is not None

    def attach(self, base) -> None:
        """Push ``base`` from now on (a ``pre_substep`` hook)."""
        self.base = base
        base.pre_substep.append(self)
        t = float(base.data.time)
        if self.model.timing in ("interval", "rate", "guidance") and not self.corrective:
            # the first push when the mission starts (after a reaction time), as the paper's
            # protocol gives an input before the first move; then at the human's own times
            self.next_t = t + self.model.reaction_s

    def _gap(self) -> float:
        p = self.model
        if p.timing == "rate":
            return float(self.rng.exponential(self.interval))
        return float(self.interval * (1.0 + p.jitter * self.rng.uniform(-1.0, 1.0)))

    def robot_moves(self, cell: int, heading: int | None) -> None:
        """The robot starts a move from ``cell`` toward ``heading`` (None: it stays). In
        ``corrective`` timing the human may react (module docstring)."""
        p = self.model
        if self.watch is not None:
            self._watch_move(cell, heading)
            return
        if not self.corrective or heading is None or self.probs is None:
            return
        q = self.probs(cell)
        right = bool(q[heading] >= 0.5 * q.max())
        seen = float(np.mean(self.recent)) if self.recent else 1.0
        self.recent.append(right)
        chance = (p.p_needless if right else p.p_correct) * seen
        if self.rng.random() < chance and self.next_t is None:
            delay = max(0.05, p.reaction_s * (1.0 + 0.25 * self.rng.standard_normal()))
            self.next_t = float(self.base.data.time) + delay

    def _watch_move(self, cell: int, action: int | None) -> None:
        """A guided episode's corrective person sees the robot start ``action`` from ``cell``
        (module docstring)."""
        w = self.watch
        move = STAY if action is None else int(action)
        m = w.world.motion
        target = cell if move == STAY or m.blocked[cell, move] else int(m.next_cell[cell, move])
        if self.next_t is not None or not w.needs_push(cell, move, target) or \
                w.rng.random() < w.rule.miss:
            return
        delay = max(0.05, self.model.reaction_s * (1.0 + 0.25 * self.rng.standard_normal()))
        self.next_t = float(self.base.data.time) + delay + w.rule.delay * self.step_s

    def quiet_until(self) -> float:
        """The simulated time before which :meth:`__call__` does nothing (the next push's
        start; infinity while none is due): the compiled steps of :mod:`.coasting` run to it."""
        return math.inf if self.next_t is None else self.next_t

    def __call__(self, base) -> None:
        """Before a physics step: begin a push when one is due."""
        t = float(base.data.time)
        if self.next_t is None or t < self.next_t:
            return
        heading = self.heading_at(base.cell)
        q = 1.0 if self.probs is None else float(self.probs(base.cell)[heading] /
                                                   self.probs(base.cell).max())
        push = HumanPush.sample(heading, t, sample_profile(self.model, self.rng, q),
                                self.rng)
        base.pushes.append(push)
        self.given.append(push)
        self.next_t = None if self.corrective else t + self._gap()
