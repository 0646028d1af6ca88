"""The reward of the ``-v1`` Gymnasium ids (``reward="route"``): its optimum is the person's
route. ``reward="potential"`` (:mod:`.reward`, the ``-v0`` ids) shapes the move cost with the
person's preference, but shaping never changes which policy is optimal (Ng, Harada and Russell
1999): under it the shortest path to the goal, which crosses faces the person does not want
crossed whenever their route is longer, earns more than their route. The preference has to be
in the reward itself; here a violation of it (leaving a polytope ``v`` toward anything but the
person's preferred neighbour ``p_v``, the success rule's violation) ends the episode with a
penalty, and the potential guides toward the goal along the person's whole route.

Per decision (at control rate: per cell change, the only steps with a reward)::

    r(s, a, s') = -c(s, a, s')  +  gamma Phi(s') - Phi(s)  +  R_g [s' = g, V = 0]  -  P V
    Phi(s)      = -F(s),        V = [the move s -> s' violates the person's preference]

The episode ends (terminated, discount 0) at the goal and at the first violation (no success
is possible after one: success is the goal reached without a violation), and is truncated
after ``T_max`` decisions. ``c`` is the move cost of :func:`.reward.move_cost` (1 straight,
sqrt 2 diagonal, 1 for a blocked move or a stay), ``R_g = 50`` the goal reward (not paid for
a move that reaches the goal by a violation: no success), ``gamma`` the
discount the agent trains with (the ``gamma`` task argument, :data:`DISCOUNT` by default:
``examples/train_ppo.py``'s).

``F(s)`` is the cost-to-go along the person's preferred route under their true preference
``p``: the length of the shortest grid path from ``s`` to the goal ``g`` that leaves *every*
polytope ``v`` on its way only toward ``p_v`` (any way where ``p_v = -1``; the goal's polytope
is held; :func:`pathpref.geometry.following.preference_following_distance`, the path the
``oracle`` method and the route-follower below drive). ``F(g) = 0``. Cells from which no such
path exists get ``F_max``, the largest finite ``F`` of the instance, so ``0 <= F <= F_max``.

**The person's route earns R_g and more.** Along it ``F(s_t) = c_t + F(s_{t+1})`` (each move
is the one minimising ``c + F``), so each step earns
``-c_t + F(s_t) - gamma F(s_{t+1}) = (1 - gamma) F(s_{t+1}) >= 0`` and the last one ``R_g``
besides: its return is ``U_route = R_g + (1 - gamma) sum_{t=1}^{T-1} F(s_t) >= R_g``, and
discounted ``G_route >= gamma^(T-1) R_g > 0``.

**An episode with a violation earns less than 0.** Ending at its ``k``-th step
(``k <= T_max``), its undiscounted shaping sums to
``F(s_0) - gamma F(s_k) + (1 - gamma) sum_{t=1}^{k-1} F(s_t) <= F_max (1 + (1 - gamma)(T_max - 1))``
and its discounted shaping to ``gamma^k Phi(s_k) - Phi(s_0) <= F_max``, while its penalty,
paid at step ``k``, is discounted to at least ``gamma^(T_max - 1) P``. With::

    P = F_max * max(1 + (1 - gamma)(T_max - 1),  gamma^-(T_max - 1))

both its return and its discounted return are at most minus its move cost, ``< 0``. So on
every instance where the person's route reaches the goal in time and another policy violates
the preference (the shortest path does whenever the route is longer and leaves a polytope by
a face the person does not want), the route earns more, in return and in discounted return:
the reward's optimum and the success rule agree. (``P`` is per instance; over 60 instances
each at ``gamma = 0.99`` it is at most 23 on simple, 37 on office, 138 on classroom and 97 on
a generated 24 x 16 plan. With ``gamma = 1`` the shaping telescopes exactly and ``P = F_max``.)

**An episode that neither violates nor arrives** (truncated at ``T_max``, every decision
costing at least 1) returns at most ``F(s_0) - T_max + (1 - gamma)(T_max - 1) F_max``, which
is below ``R_g`` whenever ``F(s_0) + (1 - gamma) T_max F_max < T_max + R_g``. For every
instance whose route fits in ``T_max`` decisions (``F(s_0) <= sqrt 2 T_max``) that holds when
``(1 - gamma) T_max F_max < R_g - (sqrt 2 - 1) T_max``: on simple and office at
``gamma = 0.99`` (5.2 and 8.3 against 37.6 over those instances), not by this bound on
classroom and the generated plans (``T_max`` 60 and 72), where the route earns more than such
an episode only as far as the tests measured it.

Undiscounted per step, ``(1 - gamma) F <= 0.01 F_max`` is below every move's cost wherever
``F_max < 100`` (every map but some classroom instances at ``gamma = 0.99``), so a loop
there still costs.
"""

from __future__ import annotations

import numpy as np

from pathpref.geometry.following import preference_following_distance
from pathpref.geometry.world import World

from .reward import move_cost

#: the discount the ``-v1`` ids shape with by default: ``examples/train_ppo.py`` trains with it
DISCOUNT = 0.99


def violation_penalty(f_max: float, gamma: float, t_max: int) -> float:
    """``P`` of the module docstring: ``F_max max(1 + (1 - gamma)(T_max - 1),
    gamma^-(T_max - 1))``."""
    n = max(int(t_max) - 1, 0)
    return float(f_max) * max(1.0 + (1.0 - gamma) * n, gamma ** -n)


class RouteReward:
    """The reward of the module docstring for one episode: the person's preference ``pref``
    (per polytope, -1: none), the goal cell, ``gamma``, ``T_max`` and ``R_g``."""

    def __init__(self, world: World, goal_cell: int, pref: np.ndarray, gamma: float,
                 t_max: int, goal_reward: float):
        togo = preference_following_distance(world, np.asarray(pref, dtype=int), goal_cell)
        finite = np.isfinite(togo)
        #: ``F_max``: the longest finite cost-to-go along the route (cells)
        self.f_max = float(togo[finite].max())  # the goal's own 0 is always finite
        #: ``F`` per cell, ``F_max`` where the route does not reach the goal
        self.togo = np.where(finite, togo, self.f_max)
        self.world, self.goal_cell = world, int(goal_cell)
        self.gamma, self.goal_reward = float(gamma), float(goal_reward)
        #: ``P``, the penalty of a violation
        self.penalty = violation_penalty(self.f_max, self.gamma, t_max)

    def __call__(self, s: int, s2: int, a: int, violated: bool) -> float:
        """``r(s, a, s')``; ``violated``: the move broke the person's preference."""
        r = -move_cost(self.world, s, s2, a) - self.gamma * self.togo[s2] + self.togo[s]
        if violated:
            return float(r - self.penalty)
        return float(r + self.goal_reward if s2 == self.goal_cell else r)
