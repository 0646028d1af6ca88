"""Time-aware waiting: a budget of waiting over the route, and arriving before the route when
time runs out, so a robot never stalls (:attr:`~.pomdp.Preset.budget_waits`, the
``robust-slack`` preset).

The robust search (:mod:`.guided`) and the crossing check (:mod:`.crossing`) may wait in a
polytope for the next pushes, but each judges one crossing at a time against the whole time
left, so the first uncertain crossing may spend the slack every later one needs; and where the
search's values are flat (nothing to gain by any move) its choice drifts, so the robot shuffles
inside a polytope. This rule runs with them at cell ``s`` in polytope ``v`` with ``D`` steps
left, from the search's root particles ``(g_j, theta_j)`` (exact draws of the posterior) and
their preferred routes from ``s`` (:func:`~.crossing.route_walks`: ``L_j`` steps, ``U_j`` the
doubt summed over its crossings, first move ``m_j``).

0. **Arrive first when the routes no longer fit** (:meth:`WaitBudget.plan`, right after the
   search): when fewer than :data:`ON_TIME` of the particles' preferred routes arrive within
   ``D`` steps (``mean_j [L_j <= D] < ON_TIME``), the policy takes its move from a search for
   the goal alone (the preset's goal-only rewards on the same goal marginal): reaching the
   goal by another route is then worth more than a preferred route that times out.

Otherwise, on the move ``a`` the search and the check chose (:meth:`WaitBudget.decide`):

1. **Moves that go somewhere pass.** ``a`` leaves ``v``, or it lowers the particles' mean
   cost-to-go ``h(s) = mean_j h_j(s)`` (``h_j``: the human model's cost to ``g_j`` through
   ``theta_j``'s exit of ``v``, :func:`.guided._heuristic`): ``h(s') < h(s)``.
2. **Any other move is a wait**: standing still (:data:`~pathpref.geometry.grid.STAY`) or a
   move that gains nothing. It is allowed only while

   - the slack pays for the next push and keeps a reserve for the crossings after this one:
     ``w + lambda T U' <= D - L``, with ``w`` the steps to the next expected push, ``T`` the
     interval between pushes, ``L`` the median of ``L_j`` over the particles whose route
     arrives in time, and ``U'`` the median over them of the doubt of the route's later
     crossings, ``U_j - u_v``: ``u_x`` (:func:`doubt`) is how much the particles disagree on
     the exit of ``x`` (for ``v`` itself, on entering it, ``1 - max_e P(p_v = e | o)``), so
     ``T U'`` is the waiting the later crossings would need if each uncertain one waited for
     a push, and ``lambda`` (:data:`RESERVE`) the share of it held back (pushes felt on the
     way settle some of them): waiting here does not take the time a later crossing needs;
   - the robot has waited at most :data:`PUSHES_PER_CROSSING` push intervals here:
     ``W_v + w <= K T``, ``W_v`` the steps waited in ``v`` so far;
   - ``v`` is not the goal's polytope of every particle.

   An allowed wait is a **stand-still** when one more push at ``s`` is expected to raise the
   probability of the best exit of ``v`` by at least :data:`MIN_GAIN` (``E_1 - E_0``,
   :func:`~.crossing.best_exit_after_pushes`): no shuffling, the robot does not drift from
   the faces while a push here would tell it something. Where a push here would tell little
   and the exit is not settled (``E_0 <`` :data:`SETTLED`), the search's own move is kept
   (it may seek a cell where a push says more); it counts toward ``W_v``.
3. **Otherwise the robot commits** to the most probable route: the most frequent first move
   ``m_j`` among the particles whose exit of ``v`` is the most probable one
   (``argmax_e P(p_v = e | o)``; all particles when ``v`` is the goal's polytope of each).

The rule needs root particles (route-prior beliefs); without them the move passes unchanged.
Bounds: one route walk of at most ``D + 1`` steps per particle per decision, ``8`` heading
rows for the gain, and at most ``K T`` steps of waiting in a polytope per visit.
"""

from __future__ import annotations

import numpy as np

from ..geometry.grid import STAY
from .crossing import LOOKAHEAD_PUSHES, best_exit_after_pushes, route_walks

#: the least expected gain in the probability of the best exit that one more push must offer
#: for a wait to be kept
MIN_GAIN = 0.01
#: the share of the later crossings' expected waiting held back (``lambda``)
RESERVE = 0.5
#: a polytope's exit counts as settled once its most probable exit has this probability
SETTLED = 0.95
#: below this share of the root particles whose preferred route still arrives in time, the
#: robot plans for arriving alone
ON_TIME = 0.75
#: the most pushes a robot waits for at one crossing (the crossing check's lookahead)
PUSHES_PER_CROSSING = LOOKAHEAD_PUSHES


def doubt(pool_theta: np.ndarray) -> np.ndarray:
    """``(P,)`` ``u_x = 1 - max_e share_x(e)``: how much the particles disagree on the exit
    of each polytope ``x`` (``share_x(e)``: the share of the rows of ``pool_theta`` whose
    exit of ``x`` is ``e``); 0 where they all agree."""
    m, P = pool_theta.shape
    k = int(pool_theta.max()) + 2
    counts = np.zeros((P, k), np.int64)
    np.add.at(counts, (np.broadcast_to(np.arange(P), (m, P)), pool_theta + 1), 1)
    return 1.0 - counts.max(axis=1) / m


class WaitBudget:
    """The rule of the module docstring, with the state it keeps over an episode: the polytope
    the robot is in and the steps ``W_v`` it has waited there."""

    def __init__(self) -> None:
        self.poly = -1
        self.waited = 0
        self._walks = None

    def plan(self, planner, belief, cell: int, depth: int) -> bool:
        """Read the root particles' routes from ``cell`` with ``depth`` steps left (after the
        search, before :meth:`decide`); True when the robot is out of time for the preferred
        routes: fewer than :data:`ON_TIME` of the particles' routes arrive in time (the
        policy then plans for arriving alone, module docstring)."""
        particles = planner.root_particles()
        self._walks = None
        if particles is None:
            return False
        pool_g, pool_theta = particles
        cell, depth = int(cell), int(depth)
        v = int(planner.cell_poly[cell])
        u = doubt(pool_theta)
        if v != self.poly and any(x >= 0 for x in planner.nbr[v]):
            u[v] = 1.0 - float(belief.joint(v).sum(axis=0).max())
        steps, doubts, first = route_walks(cell, depth, pool_g, pool_theta, planner.goal_cells,
                                           planner.cell_poly, planner.next_cell, planner.moves,
                                           u)
        self._walks = (cell, depth, u, steps, doubts, first)
        return bool(np.mean(steps <= depth) < ON_TIME)

    def decide(self, planner, belief, likelihood, a: int, cell: int, depth: int,
               pushes: tuple[int, int]) -> int:
        """The move to make instead of ``a`` (module docstring). ``planner``: the robust
        :class:`~.pomcp.POMCP` whose last search ran from ``cell`` with ``depth`` steps left;
        ``likelihood``: :attr:`~pathpref.inference.human.ObservationModel.cell_likelihood`;
        ``pushes``: ``(next, every)`` as the search was given them."""
        particles = planner.root_particles()
        if particles is None:
            return a
        pool_g, pool_theta = particles
        cell, depth = int(cell), int(depth)
        if self._walks is None or self._walks[:2] != (cell, depth):
            self.plan(planner, belief, cell, depth)
        _, _, u, steps, doubts, first = self._walks
        v = int(planner.cell_poly[cell])
        slots = [int(x) for x in planner.nbr[v] if x >= 0]
        ok = steps <= depth
        route = float(np.median(steps[ok])) if ok.any() else float(depth)
        later = float(np.median(doubts[ok])) - u[v] if ok.any() else 0.0
        every = max(int(pushes[1]), 1)
        reserve = RESERVE * every * max(later, 0.0)
        if v != self.poly:
            self.poly, self.waited = v, 0
        if a != STAY:
            s2 = int(planner.next_cell[cell, a])
            if s2 != cell and (int(planner.cell_poly[s2]) != v
                               or self._togo(planner, s2, v, pool_g, pool_theta)
                               < self._togo(planner, cell, v, pool_g, pool_theta)):
                return a
        w = max(int(pushes[0]), 1)
        at_goal = bool(np.all(planner.goal_poly[pool_g] == v))
        if not at_goal and slots and w + reserve <= depth - route \
                and self.waited + w <= PUSHES_PER_CROSSING * every:
            gain = best_exit_after_pushes(belief.joint(v), likelihood[cell], 1)
            if gain[1] - gain[0] >= MIN_GAIN:
                self.waited += 1
                return STAY
            if gain[0] < SETTLED:
                self.waited += 1
                return a
        return self._commit(belief, v, slots, at_goal, pool_theta, first, a)

    @staticmethod
    def _togo(planner, s: int, v: int, pool_g, pool_theta) -> float:
        """``h(s)``: the particles' mean cost-to-go from ``s`` in ``v`` through their exits of
        ``v`` (the goal's distance where ``v`` is the goal's polytope)."""
        kv = pool_theta[:, v]
        here = kv >= 0
        h = np.where(here, planner.ctg[s, np.maximum(kv, 0), pool_g],
                     planner.dist[pool_g, s])
        return float(np.mean(h))

    @staticmethod
    def _commit(belief, v: int, slots: list[int], at_goal: bool, pool_theta, first,
                a: int) -> int:
        """The first move of the most probable route (module docstring); ``a`` if no
        particle's route moves."""
        pick = np.ones(len(first), bool)
        if slots and not at_goal:
            k = int(np.argmax(belief.joint(v).sum(axis=0)))
            pick = pool_theta[:, v] == k
            if not pick.any():
                pick[:] = True
        moves = first[pick]
        moves = moves[moves >= 0]
        if moves.size == 0:
            return a
        return int(np.bincount(moves, minlength=8).argmax())
