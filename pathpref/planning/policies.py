"""The four methods of the paper (Sec. V-A, SPEC 8) behind one small interface.

A :class:`Policy` is told what the robot observes and asked for an action:

* ``observe(cell, heading)``: the human gave heading ``heading`` (0..7) at ``cell``;
* ``rule_out(goal_index)``: the robot stood on that candidate and it was not the goal;
* ``enter(v_from, v_to)``: the robot crossed from one polytope into another;
* ``act(t, cell, heading)``: the action (0..7, or :data:`STAY`) at decision step ``t``
  (1-based), with this step's heading or None.

Every policy carries a belief (``policy.belief``) so that episodes can log ``P(true goal)`` and
the goal entropy whatever the method. Add a method with :func:`register_method`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..geometry.world import World
from ..inference.belief import GoalBelief, PreferenceBelief
from ..inference.human import ObservationModel
from .pomcp import POMCP
from .pomdp import Preset, Rewards

STAY = -1


@dataclass
class PolicyContext:
    """Everything a policy may use: the map, likelihood tables, parameters, randomness."""

    world: World
    model: ObservationModel
    preset: Preset
    t_max: int
    queries: int
    rng: np.random.Generator
    coupling: bool = False


class Policy(ABC):
    """Base class: holds a belief and forwards observations to it."""

    name = "policy"

    def __init__(self, ctx: PolicyContext, belief: PreferenceBelief | GoalBelief):
        self.ctx = ctx
        self.belief = belief

    def observe(self, cell: int, heading: int) -> None:
        self.belief.update(cell, heading)

    def rule_out(self, goal_index: int) -> None:
        self.belief.rule_out(goal_index)

    def enter(self, v_from: int, v_to: int) -> None:
        if isinstance(self.belief, PreferenceBelief):
            self.belief.enter(v_from, v_to)

    @abstractmethod
    def act(self, t: int, cell: int, heading: int | None) -> int:
        """The action at decision step ``t`` from ``cell``; ``heading`` is this step's input."""

    def _seed(self) -> int:
        return int(self.ctx.rng.integers(2**31))


class PlannerPolicy(Policy):
    """POMCP from the policy's belief with the given rewards, depth ``T_max - t + 1``."""

    def __init__(self, ctx: PolicyContext, belief: PreferenceBelief | GoalBelief,
                 rewards: Rewards):
        super().__init__(ctx, belief)
        self.planner = POMCP(ctx.world, ctx.model.goals, rewards, queries=ctx.queries,
                             c=ctx.preset.ucb_c)

    def act(self, t: int, cell: int, heading: int | None) -> int:
        depth = self.ctx.t_max - t + 1
        return self.planner.search(cell, self.belief, depth, self._seed()).action


class PathPreferencePolicy(PlannerPolicy):
    """The paper's method: POMCP over ``(g, theta)`` with the exact factored belief."""

    name = "path_preference"

    def __init__(self, ctx: PolicyContext):
        super().__init__(ctx, PreferenceBelief(ctx.model, coupling=ctx.coupling),
                         ctx.preset.path_preference)


class GoalOnlyPolicy(PlannerPolicy):
    """Goal-only baseline: POMCP over ``g`` alone, no preference reward, goal-only belief."""

    name = "goal_only"

    def __init__(self, ctx: PolicyContext):
        super().__init__(ctx, GoalBelief(ctx.model), ctx.preset.goal_only)


class CompliantPolicy(Policy):
    """Follows the human's heading; without input keeps it ``momentum`` more steps, then stays.

    It plans nothing; its (passive) path-preference belief is only logged.
    """

    name = "compliant"

    def __init__(self, ctx: PolicyContext):
        super().__init__(ctx, PreferenceBelief(ctx.model, coupling=ctx.coupling))
        self.last = STAY
        self.remaining = 0

    def act(self, t: int, cell: int, heading: int | None) -> int:
        if heading is not None:
            self.last, self.remaining = heading, self.ctx.preset.momentum
            return heading
        if self.remaining > 0 and self.last != STAY:
            self.remaining -= 1
            return self.last
        return STAY


class BlendedPolicy(PathPreferencePolicy):
    """Path preference + blend: on a step with input, follow the human when the robot is unsure
    (``H(g, p_v) > h``, nats), otherwise take the path-preference action."""

    name = "blended"

    def act(self, t: int, cell: int, heading: int | None) -> int:
        if heading is not None:
            v = int(self.ctx.world.cell_polytope[cell])
            if self.belief.joint_entropy(v) > self.ctx.preset.entropy_threshold:
                return heading
        return super().act(t, cell, heading)


METHODS: dict[str, Callable[[PolicyContext], Policy]] = {
    "compliant": CompliantPolicy,
    "goal_only": GoalOnlyPolicy,
    "path_preference": PathPreferencePolicy,
    "blended": BlendedPolicy,
}


def register_method(name: str, factory: Callable[[PolicyContext], Policy]) -> None:
    """Add a method (a class or function taking a :class:`PolicyContext`) under ``name``."""
    METHODS[name] = factory


def make_policy(name: str, ctx: PolicyContext) -> Policy:
    if name not in METHODS:
        raise ConfigError(f"unknown method '{name}'; choose from {', '.join(METHODS)} or 'all'")
    return METHODS[name](ctx)


def resolve_methods(names: list[str]) -> list[str]:
    """Expand 'all' and check every name."""
    out: list[str] = []
    for n in names:
        for m in (list(METHODS) if n == "all" else [n]):
            if m not in METHODS:
                raise ConfigError(
                    f"unknown method '{m}'; choose from {', '.join(METHODS)} or 'all'"
                )
            if m not in out:
                out.append(m)
    return out
