"""The task's shaped reward without loops (``reward="potential"``): the move cost, the goal and
the person's preference as a potential (Ng, Harada and Russell 1999, with ``gamma = 1``)::

    r(s, a, s') = -c(s, a, s')  +  Phi(s') - Phi(s)  +  R_g [s' = g]
    Phi(s)      = -D_{v(s), p_v(s)}(s, g)

``D`` is the constrained cost-to-go of :mod:`pathpref.inference.costs` (paper Eq. 5) to the true
goal ``g``, leaving ``v(s)`` through the person's preferred exit ``p_v(s)`` (the unconstrained grid
distance ``d(s, g)`` where the polytope has no preference); ``c`` is the grid move cost (1 or
sqrt(2), 1 for a blocked move), :data:`STAY_COST` (1 cell, a straight move's cost) for a
decision to stay, and for a cell change at control rate between cells that are not grid
neighbours the straight distance between their centres, in cells. Scale: one cell is 1, the
goal ``R_g = 50`` (the paper's goal reward), and ``|Phi|`` at most the longest constrained
route (a few tens of cells on the built-in maps).

Staying costs as much as a straight move, a time cost: every decision is paid for, so waiting
for the person is never free and an agent cannot earn more by standing still (return
``-T_max - D(s_0)`` over ``T_max`` decisions) than by driving toward the goal. At control rate
the reward comes at cell changes only (:mod:`.navigate_control`), so the stay cost never
applies there.

Because the shaping term is a difference of potentials, it sums to ``Phi(s_T) - Phi(s_0)`` over
any path and to 0 over any closed one: a loop earns exactly minus its move cost. An episode that
reaches the goal returns ``R_g - (C - D(s_0))`` with ``C`` its move cost, i.e. ``R_g`` minus the
length of its detour over the person's preferred route; one that does not returns
``-(C - D(s_0) + D(s_T))``.
"""

from __future__ import annotations

import numpy as np

from pathpref.geometry.grid import STAY
from pathpref.geometry.world import World
from pathpref.inference.costs import build_cost_tables

#: the reward rules a task accepts: the paper's (SPEC 6), the potential above and the person's
#: route (:mod:`.route_reward`, the ``-v1`` ids')
REWARDS = ("paper", "potential", "route")
#: ``c`` of a decision to stay (cells): the time cost of one decision, a straight move's cost
STAY_COST = 1.0


def preference_potential(world: World, goal_cell: int, pref: np.ndarray) -> np.ndarray:
    """``Phi`` per cell (module docstring): ``-D_{v(s), p_v(s)}(s, g)``, ``(n,)`` float64;
    ``pref[v]`` is the preferred neighbour polytope of ``v`` (-1: none). Cells that cannot
    reach the goal get the most negative finite value."""
    tables = build_cost_tables(world, np.array([goal_cell]))
    nbr = world.graph.neighbor_table()  # (P, K) neighbour ids, -1 padded
    pref = np.asarray(pref, dtype=int)
    slot = np.argmax(nbr == pref[:, None], axis=1)  # k with N(v)[k] = p_v
    has = (pref >= 0) & (nbr == pref[:, None]).any(axis=1)
    v = np.asarray(world.cell_polytope, dtype=int)
    n = world.n_cells
    d = np.where(has[v], tables.constrained[np.arange(n), slot[v], 0], tables.dist[0])
    finite = np.isfinite(d)
    d = np.where(finite, d, d[finite].max() if finite.any() else 0.0)
    return -d


def move_cost(world: World, s: int, s2: int, a: int) -> float:
    """``c(s, a, s')`` of the module docstring: the grid move's cost, :data:`STAY_COST` for
    staying in the cell (``a`` is STAY and ``s' = s``), the straight distance (cells) for a
    cell change between cells that are no grid neighbours (``a`` is STAY, ``s' != s``)."""
    if a != STAY:
        return float(world.motion.cost[s, a])
    if s2 == s:
        return STAY_COST
    return float(np.hypot(*(world.cells[s2] - world.cells[s]).astype(float)))


def potential_reward(world: World, phi: np.ndarray, s: int, s2: int, a: int, goal_cell: int,
                     goal_reward: float) -> float:
    """``r(s, a, s')`` of the module docstring."""
    r = -move_cost(world, s, s2, a) + float(phi[s2] - phi[s])
    return r + goal_reward if s2 == goal_cell else r
