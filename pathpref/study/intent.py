"""The robot's intended path, drawn for the study's observers: the cells it means to visit.

The planner (POMCP) returns only its next action, so the path beyond it is the belief's most
likely intention, read off the belief the planner samples its root states from:

* the goal ``g* = argmax_g P(g | o_1:t)`` (the lowest index among equals);
* in every polytope ``v`` whose preference table given ``g*`` is not uniform
  (``max_k P(p_v = N(v)[k] | g*, o_1:t) - min_k ... > 1e-9``), the most likely exit
  ``p_v = N(v)[argmax_k]``; elsewhere (no evidence, or a goal-only belief) any exit;
* the path: the decided move (when one is under way: the robot's cell, then the cell it drives
  to), then the shortest path from there to ``g*``'s cell that leaves each polytope only toward
  its ``p_v`` (:func:`~pathpref.geometry.following.preference_route`); when that preference does
  not lead to ``g*``, the plain shortest path; when ``g*`` cannot be reached, no more cells.

A policy that plans nothing (``compliant``: it follows the last heading) intends only its
decided move. The path has at most ``n_cells + 2`` cells (the route walk is bounded by
``n_cells`` moves), each a free cell of the map, and starts at the robot's cell.
"""

from __future__ import annotations

import numpy as np

from ..geometry.following import preference_route
from ..geometry.grid import STAY
from ..geometry.world import World
from ..inference.belief import Belief, GoalBelief
from ..planning.policies import PlannerPolicy, Policy

#: a preference table row whose spread is at most this is uniform (no exit favoured)
UNIFORM_TOL = 1e-9


def likely_preference(world: World, belief: Belief, goal_index: int) -> np.ndarray:
    """``(n_polytopes,)`` the most likely exit of each polytope given goal ``goal_index``
    (module docstring), -1 where the belief favours none."""
    pref = np.full(world.n_polytopes, -1, dtype=np.int64)
    if isinstance(belief, GoalBelief):
        return pref
    neighbors = world.graph.neighbors
    for v in range(world.n_polytopes):
        if len(neighbors[v]) < 2:
            continue
        row = np.asarray(belief.preference_given_goal(v), float)[goal_index, :len(neighbors[v])]
        if row.max() - row.min() > UNIFORM_TOL:
            pref[v] = int(neighbors[v][int(np.argmax(row))])
    return pref


def intended_path(world: World, goals: np.ndarray, belief: Belief, cell: int,
                  action: int | None = None, plans: bool = True) -> list[int]:
    """The cells (indices) the robot intends to visit from ``cell`` (module docstring):
    ``action`` is the move under way (None or STAY: none), ``goals`` the candidates' cells,
    ``plans`` False for a policy that plans nothing (only the decided move)."""
    path = [int(cell)]
    if action is not None and action != STAY:
        nxt = int(world.motion.next_cell[cell, action])
        if nxt != path[-1]:
            path.append(nxt)
    if not plans:
        return path
    g = int(np.argmax(belief.goal_marginal()))
    goal = int(goals[g])
    route = preference_route(world, likely_preference(world, belief, g), path[-1], goal)
    if not route:
        route = preference_route(world, np.full(world.n_polytopes, -1, np.int64), path[-1],
                                 goal)
    return path + route[1:]


def policy_path(world: World, goals: np.ndarray, policy: Policy, cell: int,
                action: int | None = None) -> list[int]:
    """:func:`intended_path` of ``policy`` (its belief; a planner's or only its move)."""
    return intended_path(world, goals, policy.belief, cell, action,
                         plans=isinstance(policy, PlannerPolicy))
