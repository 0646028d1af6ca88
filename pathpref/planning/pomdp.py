"""The POMDP of the paper (Sec. III-B and V, SPEC 6): rewards, presets and the generative step.

State ``(s, g, theta)``: the robot's cell ``s`` (observed), the goal ``g`` and the preference
``theta`` (hidden). Transitions are the deterministic grid motion of SPEC 3. The reward of a
move from ``s`` with action ``a`` is::

    r = -c(s, a)                                      (1 straight, sqrt 2 diagonal, 1 blocked)
        + R_p  if the move crosses the edge toward p_{v(s)} and g is not in v(s)
        + R_n  if it crosses any other edge (every exit is non-preferred when g is in v(s))
        + R_g  if it reaches g (terminal)

discounted by ``gamma``. The goal-only planner has no ``R_p``/``R_n`` terms.

The ``robust`` preset replaces this additive reward by the *success reward* of
:mod:`.guided`: ``R_g gamma^L`` at the goal, times ``rho`` if a transition on the way was not
the preferred one, nothing else.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from ..errors import ConfigError
from ..geometry.grid import STAY
from ..inference.priors import check_prior


@dataclass(frozen=True)
class Rewards:
    """Reward and discount of one planner."""

    goal: float
    preferred: float
    non_preferred: float
    discount: float
    use_preference: bool = True
    #: when True, ``discount`` is replaced by ``1 - 1 / T_max`` (a horizon that matches the
    #: mission time, so a goal at the far end of a large map still outweighs one crossing)
    horizon_discount: bool = False
    #: ``additive`` (the paper's reward above) or ``success`` (:mod:`.guided`)
    model: str = "additive"
    #: success reward only: what reaching the goal is worth after a non-preferred transition,
    #: as a fraction ``rho`` of ``goal``
    goal_after_violation: float = 0.1
    #: success reward only: the share ``a`` of ``goal`` that reaching the goal earns whatever
    #: the route; the goal then pays ``goal (a + (1 - a) rho^n)`` after ``n`` violations, so
    #: the expected return is ``a P(goal) + (1 - a) E[rho^n; goal]``: with ``a = 1/2`` it is
    #: ``(P(goal) + w P(strict)) / 2`` with ``w = 1`` up to the ``rho`` terms (a time-out
    #: is never preferred to arriving by another route). 0: the strict reward ``rho^n``.
    arrival: float = 0.0

    def for_mission(self, t_max: int) -> Rewards:
        """These rewards with the discount resolved for a mission of ``t_max`` steps."""
        if not self.horizon_discount:
            return self
        return replace(self, discount=1.0 - 1.0 / max(int(t_max), 2), horizon_discount=False)


@dataclass(frozen=True)
class Preset:
    """Named parameter set: the paper's values or the authors' code (SPEC 6 and 8).

    Attributes:
        path_preference: rewards of the path-preference planner.
        goal_only: rewards of the goal-only planner.
        momentum: compliant baseline keeps the last heading this many steps without input.
        entropy_threshold: blended baseline follows the human when ``H(g, p_v)`` exceeds it.
        search: ``paper`` (PO-UCT with uniform rollouts, :mod:`.pomcp`) or ``robust``
            (guided rollouts, scaled exploration, preferred crossings paid once per episode,
            anytime budget: :mod:`.guided`).
        coupling: the back-edge coupling of the belief (a heuristic; ``robust`` uses the route
            prior instead).
        prior: the preference prior of the path-preference belief: ``independent`` (the
            paper's: each ``p_v`` uniform and independent) or ``routes`` (preferences form a
            tree toward the goal, :mod:`pathpref.inference.routes`; exact posterior) or
            ``learned-gamma`` (the independent prior, with the human's rationality ``gamma``
            inferred too: uniform over :data:`pathpref.inference.rationality.GAMMA_GRID`,
            exact posterior, :mod:`pathpref.inference.rationality`) or ``homotopy`` (a
            mixture over the ways round the obstacles from the start to each goal and the
            route prior; exact posterior, :mod:`pathpref.inference.homotopy_prior`) or
            ``circulation`` (a mixture over one-way flows round the map, each completed for
            the goal, and the route prior; exact posterior,
            :mod:`pathpref.inference.circulation_prior`).
        queries: POMCP simulations per decision (the cap under a time budget).
        ucb_c: UCB exploration constant.
        time_budget_ms: robust search's wall-time budget per decision (0: ``queries`` only).
        wait_for_pushes: the robust search under a route-prior belief also branches on the
            headings of the pushes it expects and may stand still for one (a move into a
            wall), so a plan can wait for what the next push says (:mod:`.guided`, 7);
            the ``robust-wait`` preset.
        check_crossings: where the robust search's move leaves the robot's polytope, check it
            exactly against waiting for the next pushes (value of information of the
            crossing against the time it costs, :mod:`.crossing`; route-prior beliefs); the
            ``robust-check`` preset.
        budget_waits: wait for pushes only within a budget of the time slack per crossing,
            standing still while waiting, and commit to the most probable route otherwise
            (:mod:`.slack`; route-prior beliefs); the ``robust-slack`` preset.
        value_per_goal: with ``budget_waits``, one objective judged per goal: the search's
            particles whose goal's own routes no longer fit arrive by the shortest way in its
            rollouts (keeping the preference where it was observed), so one search weighs
            arriving against the route goal by goal, instead of switching to the goal-only
            search; waits budgeted against every particle's planned route; no crossing below
            :data:`~.slack.CONFIDENT` on fewer than two pushes while the slack pays for
            another (:mod:`.slack`, rules 0', 2', 4); the ``robust-value`` preset.

    This is the one home of every planner setting: an episode resolves its preset with its
    overrides once (:func:`get_preset`) and policies read nothing else.
    """

    name: str
    path_preference: Rewards
    goal_only: Rewards
    momentum: int
    entropy_threshold: float = 1.6
    queries: int = 5000
    ucb_c: float = 1.0
    search: str = "paper"
    coupling: bool = True
    time_budget_ms: float = 0.0
    prior: str = "independent"
    wait_for_pushes: bool = False
    check_crossings: bool = False
    budget_waits: bool = False
    value_per_goal: bool = False



PRESETS: dict[str, Preset] = {
    "paper": Preset(
        name="paper",
        path_preference=Rewards(goal=50.0, preferred=15.5, non_preferred=-18.0, discount=0.95),
        goal_only=Rewards(goal=50.0, preferred=0.0, non_preferred=0.0, discount=0.95,
                          use_preference=False),
        momentum=5,
    ),
    "original": Preset(
        name="original",
        path_preference=Rewards(goal=60.0, preferred=15.5, non_preferred=-18.0, discount=0.92),
        goal_only=Rewards(goal=1000.0, preferred=0.0, non_preferred=0.0, discount=0.96,
                          use_preference=False),
        momentum=2,
    ),
    "robust": Preset(
        name="robust",
        path_preference=Rewards(goal=1.0, preferred=0.0, non_preferred=0.0, discount=0.95,
                                horizon_discount=True, model="success",
                                goal_after_violation=0.1),
        goal_only=Rewards(goal=1.0, preferred=0.0, non_preferred=0.0, discount=0.95,
                          use_preference=False, horizon_discount=True, model="success"),
        momentum=5,
        search="robust",
        coupling=False,
        prior="routes",
    ),
}
#: the robust preset whose search waits for the pushes it expects (Preset.wait_for_pushes):
#: more strict successes at both input rates, on the maps it was made on and on twelve
#: held-out plans (docs/robust.md, "Waiting for a push")
PRESETS["robust-wait"] = replace(PRESETS["robust"], name="robust-wait", wait_for_pushes=True)
#: robust-wait whose crossings are checked against waiting for the next pushes
#: (Preset.check_crossings; docs/robust.md, "Look before crossing")
PRESETS["robust-check"] = replace(PRESETS["robust-wait"], name="robust-check",
                                  check_crossings=True)

#: robust-check whose goal is worth reaching by any route (Rewards.arrival = 0.2: value
#: 0.2 (P(goal) + 4 P(strict)) up to the rho terms) and whose waits are budgeted over the
#: route's crossings
#: (Preset.budget_waits; docs/robust.md, "Never stall")
PRESETS["robust-slack"] = replace(
    PRESETS["robust-check"], name="robust-slack", budget_waits=True,
    path_preference=replace(PRESETS["robust-check"].path_preference, arrival=0.2))

#: robust-slack with one objective judged per goal (Preset.value_per_goal; docs/robust.md,
#: "One objective, per goal")
PRESETS["robust-value"] = replace(PRESETS["robust-slack"], name="robust-value",
                                  value_per_goal=True)

#: the preset of applications (render, demo, interact, tasks, studies, evaluate without
#: --preset); the tables of docs/robust.md name the preset they were made with
DEFAULT_PRESET = "robust-slack"


def get_preset(name: str, **overrides) -> Preset:
    """A preset of :data:`PRESETS` by name, with optional field overrides."""
    if name not in PRESETS:
        raise ConfigError(f"unknown preset '{name}'; choose one of {sorted(PRESETS)}")
    if overrides.get("prior") is not None:
        check_prior(overrides["prior"])
    return replace(PRESETS[name], **{k: v for k, v in overrides.items() if v is not None})


def transition_reward(world, s: int, s2: int, a: int, goal_cell: int, pref_neighbor: int,
                      rewards: Rewards) -> float:
    """The reward of SPEC 6 for the transition ``s -> s2`` under action ``a`` (the one
    definition: :func:`step_reward`, the dm_control task and, as the compiled copy it is tested
    against, the ``_step`` of :mod:`.pomcp`)::

        -c(s, a)                 (0 for STAY: the task's "stop" action)
        + R_p if v(s2) != v(s) = v, v(s2) = p_v and the goal is not in v
        + R_n if v(s2) != v(s) otherwise                (only when ``rewards.use_preference``)
        + R_g if s2 is the goal

    ``s2`` is the cell actually reached (the grid's ``next_cell[s, a]``, or where a physical
    base ended); ``pref_neighbor`` is ``p_{v(s)}`` (-1: none, every exit non-preferred).
    """
    r = 0.0 if a == STAY else -float(world.motion.cost[s, a])
    v, w = int(world.cell_polytope[s]), int(world.cell_polytope[s2])
    if v != w and rewards.use_preference:
        goal_in_v = int(world.cell_polytope[goal_cell]) == v
        r += rewards.preferred if (w == pref_neighbor and not goal_in_v) else rewards.non_preferred
    if s2 == goal_cell:
        r += rewards.goal
    return r


def step_reward(
    world, s: int, a: int, goal_cell: int, pref_neighbor: int, rewards: Rewards
) -> tuple[int, float, bool, int]:
    """One generative step in plain Python (reference for the compiled search).

    Returns ``(next_cell, reward, reached_goal, crossed_edge)``; ``pref_neighbor`` is the
    preferred neighbour polytope id of ``v(s)`` (or -1 for none).
    """
    s2 = int(world.motion.next_cell[s, a])
    r = transition_reward(world, s, s2, a, goal_cell, pref_neighbor, rewards)
    return s2, r, s2 == goal_cell, int(world.motion.crossed_edge[s, a])
