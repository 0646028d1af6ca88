"""When the simulated human pushes: every ``Delta_T`` steps (the paper's periodic human), or only
when needed (the *corrective* human).

A push rule is the text of :attr:`EpisodeSpec.push_rule`: ``""`` (the periodic human, the
default) or ``corrective delay=D miss=M`` (:meth:`PushRule.text`, the one spelling stored).

The corrective human watches the robot after every decision step ``t`` (``Delta_T`` must be 1):
the robot moved from ``b`` to ``s`` by action ``a``. With ``F`` the length of the shortest path
to the true goal that leaves each polytope ``v`` only toward ``p_v``
(:func:`~pathpref.geometry.following.preference_following_distance`, the human's route) and
``d`` the unconstrained grid distance to the goal, the robot *needs a push* after step ``t``
when any of::

    left:      b -> s left v(b) toward w != p_{v(b)} (p_{v(b)} >= 0): it left the route
    leaving:   s' = next(s, a) (its move again, not blocked) would leave v(s) toward
               w != p_{v(s)} (p_{v(s)} >= 0): it is about to leave the route
    no gain:   F(s) >= F(b) when F(b) < inf, else d(s) >= d(b): it stood still or headed
               away from the goal (along the route while it can still follow it)

holds. A need noticed when no push is pending is missed with probability ``M`` (one draw from
the episode's fourth seed stream, :func:`miss_stream`; the periodic human draws nothing from it)
and otherwise scheduled ``D`` steps later: the human pushes after step ``t + D``, at the cell
the robot is in then (a heading drawn as the periodic human draws it), whether or not the need
still holds. While a push is pending no new need is noticed. Before step 1 the robot has not
moved, so the human does not push: a robot that stands still is pushed after step ``1 + D``.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..geometry.following import preference_following_distance
from ..geometry.grid import STAY
from ..geometry.world import World

#: the periodic human's push rule (the default: left out of the episode's key)
PERIODIC = ""
#: the longest reaction delay accepted (decision steps)
MAX_DELAY = 1000
_PATTERN = re.compile(r"corrective(?: delay=(\S+))?(?: miss=(\S+))?")


@dataclass(frozen=True)
class PushRule:
    """The corrective human's reaction ``delay`` (decision steps, 0..:data:`MAX_DELAY`) and
    ``miss`` probability (0..1) (module docstring)."""

    delay: int = 0
    miss: float = 0.0

    def __post_init__(self) -> None:
        d = self.delay
        if isinstance(d, bool) or not isinstance(d, int | np.integer) or not 0 <= d <= MAX_DELAY:
            raise ConfigError(f"push rule delay must be an integer in 0..{MAX_DELAY}, got "
                              f"{d!r}")
        m = self.miss
        if isinstance(m, bool) or not isinstance(m, int | float) or not (
                math.isfinite(m) and 0 <= m <= 1):
            raise ConfigError(f"push rule miss must be a probability in 0..1, got {m!r}")

    @property
    def text(self) -> str:
        """The stored spelling, e.g. ``corrective delay=1 miss=0.1``."""
        return f"corrective delay={int(self.delay)} miss={float(self.miss)!r}"


def parse_push_rule(text: str) -> PushRule | None:
    """The push rule of ``text``: None for the periodic human (``""``), a :class:`PushRule`
    for ``corrective`` with optional ``delay=D`` and ``miss=M`` (defaults 0 and 0); a
    ConfigError line for anything else."""
    if text == PERIODIC:
        return None
    m = _PATTERN.fullmatch(text) if isinstance(text, str) else None
    if m is None:
        raise ConfigError(f"unknown push rule {text!r}; use '' (periodic, every Delta_T) or "
                          "'corrective delay=D miss=M'")
    delay, miss = m.groups()
    try:
        numbers = (int(delay) if delay is not None else 0,
                   float(miss) if miss is not None else 0.0)
    except ValueError:
        raise ConfigError(f"push rule {text!r}: delay must be an integer and miss a number"
                          ) from None
    return PushRule(*numbers)


def miss_stream(run_seed: int) -> np.random.Generator:
    """The corrective human's miss draws: the fourth stream of ``run_seed`` (the first three
    are the human's headings, the policy's and the body's, unchanged by this one)."""
    return np.random.default_rng(np.random.SeedSequence(run_seed).spawn(4)[3])


class CorrectiveHuman:
    """When the corrective human pushes (module docstring) for one episode: the route field
    ``F`` and the distance ``d`` to ``goal``, the pending push and the miss stream."""

    def __init__(self, rule: PushRule, world: World, pref: np.ndarray, goal: int,
                 rng: np.random.Generator):
        self.rule, self.world, self.pref, self.rng = rule, world, np.asarray(pref), rng
        self.route = preference_following_distance(world, self.pref, goal)
        self.dist = world.motion.distances_from(np.array([goal]))[0]  # moves are symmetric
        #: the step after which the scheduled push is given (None: none pending)
        self.due: int | None = None

    def _leaves(self, cell: int, to: int) -> bool:
        """``cell -> to`` leaves ``v(cell)`` by a face other than its preferred one."""
        poly = self.world.cell_polytope
        v, w = int(poly[cell]), int(poly[to])
        return v != w and self.pref[v] >= 0 and self.pref[v] != w

    def needs_push(self, before: int, action: int, after: int) -> bool:
        """Whether the move ``before -> after`` by ``action`` calls for a push (``left``,
        ``leaving`` or ``no gain`` of the module docstring)."""
        if self._leaves(before, after):
            return True
        m = self.world.motion
        if action != STAY and not m.blocked[after, action] and \
                self._leaves(after, int(m.next_cell[after, action])):
            return True
        field = self.route if math.isfinite(self.route[before]) else self.dist
        return bool(field[after] >= field[before])

    def pushes_after(self, t: int, before: int, action: int, after: int) -> bool:
        """Whether the human pushes after step ``t`` (the move ``before -> after`` by
        ``action``): a need is noticed (unless one is pending, and unless missed) and the
        push falls due ``delay`` steps later."""
        if self.due is None and self.needs_push(before, action, after) and \
                not self.rng.random() < self.rule.miss:
            self.due = t + self.rule.delay
        if self.due is not None and t >= self.due:
            self.due = None
            return True
        return False
