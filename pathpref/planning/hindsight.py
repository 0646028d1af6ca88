"""Hindsight optimisation (``--methods hindsight``): the standard answer of shared autonomy,
on the same exact belief and the same value as the default preset.

Javdani, Admoni, Pellegrinelli, Srinivasa and Bagnell, "Shared autonomy via hindsight
optimization for teleoperation and teaming", IJRR 2018 (RSS 2015): act as if the hidden
parameter became known right after this step,

    a* = argmax_a  Q_HOP(b, s, a),    Q_HOP(b, s, a) = sum_theta b(theta) Q_theta(s, a),

``Q_theta`` the value of the best plan when ``theta`` is known. Here ``theta = (g, p)``, the
goal and the person's preferred exits, and ``b`` is the path-preference belief of the preset
(the route prior's exact posterior). The sum is estimated on the ``m`` exact draws ``(g_j,
p_j)`` the robust search starts from (:meth:`~.pomcp.POMCP.particles`; the same pool rule and
the same reuse between pushes), so ``Q_HOP = (1/m) sum_j Q_j``.

**The value** is the default preset's (:attr:`~.pomdp.Rewards.arrival` ``alpha``,
:attr:`~.pomdp.Rewards.goal_after_violation` ``rho``, the discount ``gamma`` resolved for the
mission): reaching ``g`` at step ``L`` after ``n`` crossings against ``p`` pays
``gamma^(L-1) (alpha + (1 - alpha) rho^n)``; a time-out pays 0. With ``(g_j, p_j)`` known, after
move ``a`` from ``s`` to ``s'`` with ``D`` steps left, two plans are valued from the cost
tables (the human model's, :attr:`~pathpref.inference.human.ObservationModel.tables`, walked
as the robust search's rollouts walk them, :func:`~.guided.rollout_moves`):

* the person's route: from each polytope through ``p_j``'s exit (the walk of
  :func:`~.crossing.route_walks`), ``L_P`` steps, ``n_P`` crossings against ``p_j`` on it;
* arriving alone: the shortest way to ``g_j`` (``d(., g_j)``), ``L_A`` steps, ``n_A``
  crossings against ``p_j`` on it,

and ``Q_j(a) = max over the plans that arrive within D - 1 steps of
gamma^L (alpha + (1 - alpha) rho^(h_j + v_j(a) + n))`` with ``L`` the plan's steps after the
move, ``h_j`` the episode's crossings so far against ``p_j`` and ``v_j(a)`` 1 when ``a``
itself leaves ``v(s)`` by another face than ``p_j(v(s))`` (never in the goal's polytope).
A move onto ``g_j`` is worth ``alpha + (1 - alpha) rho^(h_j + v_j(a))``. Blocked moves are not
candidates; ties go to the lowest move index; when no plan of any particle arrives in time
(every ``Q_HOP`` is 0) the robot takes the move that minimises ``c(s, a) + mean_j d(s', g_j)``.

What hindsight optimisation leaves out, by construction: the value of information. It never
waits for a push (with ``theta`` known there is nothing to learn), and it plans toward the
belief-weighted mix of hypotheses, which is why it is the baseline a path-preference planner
has to beat.

Bounds: per decision, two walks of at most ``D`` steps per particle per move: ``16 m D``
steps.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from ..errors import ConfigError
from ..geometry.grid import STAY
from .guided import FIRST_FROM


@nb.njit(cache=True, inline="always")
def _walk(s, left, g, theta, follow, goal_cells, goal_poly, cell_poly, next_cell, cross_slot,
          moves):
    """``(steps, against)``: the walk from ``s`` to goal ``g`` (``follow``: through
    ``theta``'s exit of each polytope; else the shortest way), at most ``left`` steps;
    ``steps = left + 1`` when it does not arrive (or is stuck); ``against``: its crossings
    that leave a polytope by another face than ``theta``'s (the goal's polytope excepted)."""
    steps = 0
    against = 0
    gc = goal_cells[g]
    while s != gc and steps <= left:
        v = cell_poly[s]
        kv = theta[v] if follow else -1
        a = FIRST_FROM[moves[s, kv + 1, g], 0]
        s2 = next_cell[s, a]
        if s2 == s:
            return left + 1, against
        k = cross_slot[s, a]
        if k >= 0 and v != goal_poly[g] and theta[v] != k:
            against += 1
        s = s2
        steps += 1
    if s != gc:
        return left + 1, against
    return steps, against


@nb.njit(cache=True)
def hindsight_values(cell, depth, pool_g, pool_theta, past_against, goal_cells, goal_poly,
                     cell_poly, next_cell, cross_slot, moves, discount, arrival, rho):
    """``(8,)`` ``Q_HOP(b, s, a)`` of the module docstring for each move ``a`` from ``cell``
    with ``depth`` steps left (-1 for a blocked move). ``pool_g``, ``pool_theta``: the ``m``
    particles' goal indices and preferred slots; ``past_against``: ``h_j``, each particle's
    count of the episode's crossings against its preference."""
    q = -np.ones(8)
    m = pool_g.shape[0]
    v = cell_poly[cell]
    for a in range(8):
        s2 = next_cell[cell, a]
        if s2 == cell:
            continue
        k = cross_slot[cell, a]
        total = 0.0
        for j in range(m):
            g = pool_g[j]
            theta = pool_theta[j]
            n0 = past_against[j]
            if k >= 0 and v != goal_poly[g] and theta[v] != k:
                n0 += 1
            if s2 == goal_cells[g]:
                total += arrival + (1.0 - arrival) * rho ** n0
                continue
            best = 0.0
            left = depth - 1
            for follow in (True, False):
                steps, against = _walk(s2, left, g, theta, follow, goal_cells, goal_poly,
                                       cell_poly, next_cell, cross_slot, moves)
                if steps <= left:
                    val = discount ** steps * (arrival + (1.0 - arrival) * rho ** (n0 + against))
                    if val > best:
                        best = val
            total += best
        q[a] = total / m
    return q


def past_against(planner, history, pool_g: np.ndarray, pool_theta: np.ndarray) -> np.ndarray:
    """``(m,)`` ``h_j``: the episode's polytope transitions ``(v, w)`` that left ``v`` by
    another face than particle ``j``'s exit (``v`` not its goal's polytope)."""
    out = np.zeros(len(pool_g), np.int64)
    goal_poly = planner.goal_poly[pool_g]
    for v, w in history:
        k = int(np.flatnonzero(planner.nbr[v] == w)[0])
        out += (pool_theta[:, v] != k) & (goal_poly != v)
    return out


def hindsight_action(planner, belief, cell: int, depth: int, seed: int, history) -> int:
    """The move of hindsight optimisation (module docstring) from ``cell`` with ``depth``
    steps left. ``planner``: a robust :class:`~.pomcp.POMCP` with the path-preference rewards
    (its particles, tables and value); ``history``: the episode's transitions ``(v, w)``."""
    drawn = planner.particles(belief, seed)
    if drawn is None:
        raise ConfigError("hindsight needs a route-prior belief (a robust preset: "
                          "--preset robust-slack, robust-check, robust-wait or robust)")
    pool_g, pool_theta = drawn
    r = planner.rewards
    q = hindsight_values(int(cell), int(max(depth, 1)), pool_g, pool_theta,
                         past_against(planner, history, pool_g, pool_theta),
                         planner.goal_cells, planner.goal_poly, planner.cell_poly,
                         planner.next_cell, planner.cross_slot, planner.moves,
                         float(r.discount), float(r.arrival), float(r.goal_after_violation))
    if q.max() > 0.0:
        return int(np.argmax(q))
    free = q >= 0.0
    if not free.any():
        return STAY
    d = planner.dist[pool_g][:, planner.next_cell[cell]].mean(axis=0)
    return int(np.argmin(np.where(free, planner.cost[cell] + d, np.inf)))


@nb.njit(cache=True)
def shortest_walks(cell, depth, pool_g, pool_theta, goal_cells, goal_poly, cell_poly, next_cell,
                   cross_slot, moves):
    """``(steps, against)``, each ``(m,)``: each particle's walk from ``cell`` to its goal by
    the shortest way (the arrival plan of the module docstring; ``depth + 1`` steps where it
    does not arrive within ``depth``) and its crossings against the particle's exits. At most
    ``depth + 1`` steps per particle."""
    m = pool_g.shape[0]
    steps = np.empty(m, np.int64)
    against = np.empty(m, np.int64)
    for j in range(m):
        steps[j], against[j] = _walk(cell, depth, pool_g[j], pool_theta[j], False, goal_cells,
                                     goal_poly, cell_poly, next_cell, cross_slot, moves)
    return steps, against
