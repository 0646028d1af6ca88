"""The four methods of the paper (Sec. V-A, SPEC 8) and two reference methods (``oracle``,
``goal_known``: they know what the others infer) behind one small interface.

A :class:`Policy` is told what the robot observes and asked for an action:

* ``observe(cell, heading)``: the human gave heading ``heading`` (0..7) at ``cell``;
* ``rule_out(goal_index)``: the robot stood on that candidate and it was not the goal;
* ``enter(v_from, v_to)``: the robot crossed from one polytope into another;
* ``act(t, cell, heading)``: the action (0..7, or :data:`STAY`) at decision step ``t``
  (1-based), with this step's heading or None.

Every policy carries a belief (``policy.belief``) so that episodes can log ``P(true goal)`` and
the goal entropy whatever the method. Add a method with :func:`register_method`.

Every setting a policy reads comes from ``ctx.preset``: the named preset with the episode's
overrides (queries, UCB constant, coupling, time budget) applied once, by
:meth:`pathpref.episode.EpisodeSpec.planner`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .. import plugins
from ..errors import ConfigError
from ..geometry.following import preference_following_distance, preferred_move
from ..geometry.grid import STAY
from ..geometry.world import World
from ..inference.belief import Belief, GoalBelief
from ..inference.human import ObservationModel
from ..inference.priors import PriorInputs, make_belief
from ..kernels import load_cached
from .crossing import check_crossing
from .hindsight import hindsight_action
from .pomcp import POMCP
from .pomdp import Preset, Rewards
from .slack import WaitBudget


@dataclass
class PolicyContext:
    """Everything a policy may use: the map, likelihood tables, settings, randomness.

    ``preset`` holds every planner setting (rewards, queries, ``ucb_c``, coupling, time
    budget), already resolved for the episode. ``true_goal`` (index into the goal candidates)
    and ``true_preference`` (the human's, per polytope, -1 = none) are given to every policy
    but read only by the reference methods ``oracle`` and ``goal_known``, which exist to show
    what is possible."""

    world: World
    model: ObservationModel
    preset: Preset
    t_max: int
    rng: np.random.Generator
    true_goal: int = -1
    true_preference: np.ndarray | None = None
    #: the robot's start cell (-1: unknown; the homotopy prior needs it)
    start: int = -1


def preference_belief(ctx: PolicyContext, prior: np.ndarray | None = None) -> Belief:
    """The path-preference belief of the preset's prior (a name of
    :mod:`pathpref.inference.priors`: built from the model, ``ctx.start`` and the preset's
    coupling), with goal prior ``prior`` (uniform when None)."""
    return make_belief(ctx.preset.prior, PriorInputs(ctx.model, ctx.start, prior,
                                                     ctx.preset.coupling))


class Policy(ABC):
    """Base class: holds a belief and forwards observations to it."""

    name = "policy"

    def __init__(self, ctx: PolicyContext, belief: Belief):
        self.ctx = ctx
        self.belief = belief
        #: how many events (inputs, directions, ruled-out goals, polytope changes) this policy
        #: has fed its belief: the belief's state changes only when it does, so readers of the
        #: belief may keep what they computed from it until this count moves
        self.evidence = 0

    def observe(self, cell: int, heading: int, weight: float = 1.0) -> None:
        """The human gave ``heading`` at ``cell``: condition the belief on it (``weight``:
        how confident the observation is, :meth:`Belief.update`)."""
        self.evidence += 1
        if weight == 1.0:
            self.belief.update(cell, heading)
        else:
            self.belief.update(cell, heading, weight)

    def observe_direction(self, cell: int, angle: float, kappa: float, weight: float) -> None:
        """A force direction ``angle`` felt at ``cell`` (a sample of a sustained push):
        :meth:`Belief.update_direction`."""
        self.evidence += 1
        self.belief.update_direction(cell, angle, kappa, weight)

    def rule_out(self, goal_index: int) -> None:
        """The robot stood on candidate ``goal_index`` and it was not the goal."""
        self.evidence += 1
        self.belief.rule_out(goal_index)

    def enter(self, v_from: int, v_to: int) -> None:
        """The robot crossed from polytope ``v_from`` into ``v_to``."""
        self.evidence += 1
        self.belief.enter(v_from, v_to)

    @abstractmethod
    def act(self, t: int, cell: int, heading: int | None) -> int:
        """The action at decision step ``t`` from ``cell``; ``heading`` is this step's input."""

    def _seed(self) -> int:
        return int(self.ctx.rng.integers(2**31))


class PlannerPolicy(Policy):
    """POMCP from the policy's belief with the given rewards, depth ``T_max - t + 1``.

    Under the ``robust`` preset the search is :mod:`pathpref.planning.guided` (given the cost
    tables, the time budget and the episode's transitions so far)."""

    def __init__(self, ctx: PolicyContext, belief: Belief, rewards: Rewards):
        super().__init__(ctx, belief)
        p = ctx.preset
        robust = p.search == "robust"
        self.planner = POMCP(ctx.world, ctx.model.goals, rewards.for_mission(ctx.t_max),
                             queries=p.queries, c=p.ucb_c,
                             tables=ctx.model.tables if robust else None,
                             budget_ms=p.time_budget_ms if robust else 0.0,
                             likelihood=ctx.model.cell_likelihood
                             if robust and p.wait_for_pushes else None)
        self.history: list[tuple[int, int]] = []
        self.input_steps: list[int] = []
        self.waits = WaitBudget(p.value_per_goal) if robust and p.budget_waits else None
        self._arrival: POMCP | None = None

    def enter(self, v_from: int, v_to: int) -> None:
        """Record the transition (the robust search scores the episode's history)."""
        super().enter(v_from, v_to)
        self.history.append((v_from, v_to))

    def act(self, t: int, cell: int, heading: int | None) -> int:
        """POMCP's action from ``cell`` with depth ``T_max - t + 1``."""
        depth = self.ctx.t_max - t + 1
        if heading is not None:
            self.input_steps.append(t)
        pushes = self.expected_pushes(t)
        seed = self._seed()
        late = None
        if self.waits is not None and self.planner.rewards.use_preference \
                and self.planner.particles(self.belief, seed) is not None:
            # the search's own root pool (the same seed; the search reuses it), read before
            # the search: rule 0 needs nothing else, so a search whose move it would
            # discard is not run
            if self.waits.plan(self.planner, self.belief, cell, depth):  # rule 0
                return self.arrival().search(cell, self.belief, depth, self._seed(),
                                             self.history, pushes).action
            if self.waits.per_goal:
                late = self.waits.late_goals(len(self.ctx.model.goals))
        res = self.planner.search(cell, self.belief, depth, seed, self.history, pushes, late)
        a = res.action
        if self.ctx.preset.check_crossings and self.planner.tables is not None \
                and len(self.input_steps) >= 2:  # the pushes' interval is known (crossing)
            a = check_crossing(self.planner, self.belief, self.ctx.model.cell_likelihood,
                               res, cell, depth, pushes,
                               exits=None if self.waits is None else self.waits.exits)
        if self.waits is not None:
            a = self.waits.decide(self.planner, self.belief, self.ctx.model.cell_likelihood,
                                  a, cell, depth, pushes, heading is not None)
        return a

    def arrival(self) -> POMCP:
        """The search for arriving alone (the preset's goal-only rewards on this belief's goal
        marginal), used when the preferred routes no longer fit (:mod:`.slack`, 0); built on
        first use."""
        if self._arrival is None:
            p = self.ctx.preset
            self._arrival = POMCP(self.ctx.world, self.ctx.model.goals,
                                  p.goal_only.for_mission(self.ctx.t_max), queries=p.queries,
                                  c=p.ucb_c, tables=self.ctx.model.tables,
                                  budget_ms=p.time_budget_ms)
        return self._arrival

    def expected_pushes(self, t: int) -> tuple[int, int]:
        """``(next, every)``: in how many steps the human is expected to push next, and how
        often after that, from the inputs seen so far (the last interval between two of
        them; every step until two were seen)."""
        s = self.input_steps
        if len(s) < 2:
            return 1, 1
        every = max(s[-1] - s[-2], 1)
        return every - (t - s[-1]) % every, every


class PathPreferencePolicy(PlannerPolicy):
    """The paper's method: POMCP over ``(g, theta)`` with the exact factored belief."""

    name = "path_preference"

    def __init__(self, ctx: PolicyContext):
        super().__init__(ctx, preference_belief(ctx),
                         ctx.preset.path_preference)


class GoalKnownPolicy(PlannerPolicy):
    """Reference: knows the true goal (a one-hot goal prior), infers the preference, plans with
    the preset's path-preference search."""

    name = "goal_known"

    def __init__(self, ctx: PolicyContext):
        if ctx.true_goal < 0:
            raise ConfigError("goal_known needs the episode's true goal")
        prior = np.zeros(len(ctx.model.goals))
        prior[ctx.true_goal] = 1.0
        belief = preference_belief(ctx, prior)
        super().__init__(ctx, belief, ctx.preset.path_preference)


class HindsightPolicy(PlannerPolicy):
    """Hindsight optimisation (Javdani et al., IJRR 2018), the standard answer of shared
    autonomy: the move that maximises the belief-weighted value of each hypothesis ``(g, p)``
    as if it became known after this step (:mod:`.hindsight`), on the path-preference belief
    and with the path-preference value of the preset (a robust, route-prior preset)."""

    name = "hindsight"

    def __init__(self, ctx: PolicyContext):
        if ctx.preset.search != "robust" or ctx.preset.prior != "routes":
            raise ConfigError(f"hindsight needs a robust preset with the route prior, not "
                              f"'{ctx.preset.name}' (prior {ctx.preset.prior}); use --preset "
                              "robust-slack (the default), robust-check, robust-wait or robust")
        super().__init__(ctx, preference_belief(ctx), ctx.preset.path_preference)
        self.waits = None

    def act(self, t: int, cell: int, heading: int | None) -> int:
        """Hindsight optimisation's move from ``cell`` with ``T_max - t + 1`` steps left."""
        return hindsight_action(self.planner, self.belief, cell, self.ctx.t_max - t + 1,
                                self._seed(), self.history)


class OraclePolicy(Policy):
    """Reference ceiling: knows goal and preference and follows the shortest path that obeys
    the preference (leave ``v`` only toward ``p_v``; anywhere from a polytope without one).

    ``togo[s]`` is that path's length from ``s`` (one Dijkstra from the goal over the allowed
    moves, reversed); the oracle takes the move minimising ``c(s, a) + togo[s']``. Where no
    such path exists (the preference never leads to the goal) it takes the unconstrained
    shortest path: it then reaches the goal but cannot succeed."""

    name = "oracle"

    def __init__(self, ctx: PolicyContext):
        if ctx.true_goal < 0 or ctx.true_preference is None:
            raise ConfigError("oracle needs the episode's true goal and the map's preference")
        super().__init__(ctx, preference_belief(ctx))
        goal = int(ctx.model.goals[ctx.true_goal])
        self.togo = preference_following_distance(ctx.world, ctx.true_preference, goal)
        self.dist = ctx.model.tables.dist[ctx.true_goal]

    def act(self, t: int, cell: int, heading: int | None) -> int:
        """Follow the preference-respecting shortest path (see class docstring)."""
        if np.isfinite(self.togo[cell]):  # follow the preference: leave v only toward p_v
            return preferred_move(self.ctx.world, self.ctx.true_preference, self.togo, cell)
        m = self.ctx.world.motion
        score = np.where(~m.blocked[cell], m.cost[cell] + self.dist[m.next_cell[cell]], np.inf)
        if not np.isfinite(score).any():
            return STAY
        return int(np.argmin(score))


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
        super().__init__(ctx, preference_belief(ctx))
        self.last = STAY
        self.remaining = 0

    def act(self, t: int, cell: int, heading: int | None) -> int:
        """The heading when there is one; else the last one for ``momentum`` steps; else STAY."""
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
        """The human's heading when the robot is unsure, else the path-preference action."""
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
    "goal_known": GoalKnownPolicy,
    "oracle": OraclePolicy,
    "hindsight": HindsightPolicy,
}
#: the reference methods (they know what the others infer); 'all' leaves them out
REFERENCE_METHODS = ("goal_known", "oracle")
#: methods from outside the paper ('baselines'); 'all' (the paper's four) leaves them out
OUTSIDE_METHODS = ("hindsight",)


def register_method(name: str, factory: Callable[[PolicyContext], Policy]) -> None:
    """Add a method (a class or function taking a :class:`PolicyContext`) under ``name``."""
    METHODS[name] = factory


def _known(name: str) -> bool:
    """Whether method ``name`` exists: built in, registered, or declared by another package
    in the entry-point group ``pathpref.methods`` (loaded and registered then)."""
    if name in METHODS:
        return True
    found = plugins.load_callable(
        plugins.METHODS, name, "a method (a class or function taking a PolicyContext)"
    ) if isinstance(name, str) else None
    if found is None:
        return False
    register_method(name, found)
    return True


def make_policy(name: str, ctx: PolicyContext) -> Policy:
    """The method ``name`` (a key of :data:`METHODS`, or another package's) built on
    ``ctx``, with the kernels of the modules imported so far loaded from numba's cache
    (:func:`pathpref.kernels.load_cached`: its first decision loads none)."""
    if not _known(name):
        raise ConfigError(f"unknown method '{name}'; choose from {', '.join(METHODS)}")
    policy = METHODS[name](ctx)
    load_cached()  # the kernels its decisions call, from numba's cache (pathpref.kernels)
    return policy


def resolve_methods(names: list[str]) -> list[str]:
    """Expand 'all' and check every name."""
    out: list[str] = []
    everyday = [m for m in METHODS if m not in REFERENCE_METHODS + OUTSIDE_METHODS]
    groups = {"all": everyday, "reference": list(REFERENCE_METHODS),
              "baselines": list(OUTSIDE_METHODS)}
    for n in names:
        for m in groups.get(n, [n]):
            if not _known(m):
                raise ConfigError(
                    f"unknown method '{m}'; choose from {', '.join(METHODS)}, 'all' (the four "
                    "methods of the paper), 'reference' (oracle, goal_known) or 'baselines' "
                    "(hindsight)"
                )
            if m not in out:
                out.append(m)
    return out
