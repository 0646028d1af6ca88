"""Time-aware waiting: a budget of waiting per crossing, so a robot never stalls
(:attr:`~.pomdp.Preset.budget_waits`, the ``robust-slack`` preset).

The robust search (:mod:`.guided`) and the crossing check (:mod:`.crossing`) may wait in a
polytope for the next pushes, but each judges one crossing at a time against the whole time
left, so the first uncertain crossing may spend the slack every later one needs; and where the
search's values are flat (nothing to gain by any move) its choice drifts, so the robot shuffles
inside a polytope. This rule runs after them on the move ``a`` they chose at cell ``s`` in
polytope ``v`` with ``D`` steps left, from the search's root particles ``(g_j, theta_j)``
(exact draws of the posterior) and their preferred routes from ``s``
(:func:`~.crossing.route_walks`: ``L_j`` steps, ``U_j`` the doubt summed over its crossings,
first move ``m_j``).

* **Moves that go somewhere pass.** ``a`` leaves ``v``, or it lowers the particles' mean
  cost-to-go ``h(s) = mean_j h_j(s)`` (``h_j``: the human model's cost to ``g_j`` through
  ``theta_j``'s exit of ``v``, :func:`.guided._heuristic`): ``h(s') < h(s)``.
* **Any other move is a wait**: standing still (:data:`~pathpref.geometry.grid.STAY`) or a
  move that gains nothing. A wait is kept, as a stand-still (no shuffling: the robot does not
  drift away from the faces while it waits), only while all of these hold:

  - something can be learnt: ``E_1 - E_0 >= MIN_GAIN``, the expected gain in the probability
    of the most probable exit of ``v`` from one more push at ``s``
    (:func:`~.crossing.best_exit_after_pushes`), and ``v`` is not the goal's polytope of
    every particle;
  - the slack pays for the next push and keeps a reserve for the crossings after this one:
    ``w + lambda T U' <= D - L``, with ``w`` the steps to the next expected push, ``T`` the
    interval between pushes, ``L`` the median of ``L_j`` over the particles whose route
    arrives in time, and ``U'`` the median over them of the doubt of the route's later
    crossings, ``U_j - u_v``: ``u_x`` (:func:`doubt`) is how much the particles disagree on
    the exit of ``x`` (for ``v`` itself, on entering it, ``1 - max_e P(p_v = e | o)``), so
    ``T U'`` is the waiting the later crossings would need if each uncertain one waited for a
    push, and ``lambda`` (:data:`RESERVE`) the share of it held back (pushes felt on the way
    settle some of them): waiting here does not take the time a later crossing needs;
  - the robot has waited for at most :data:`PUSHES_PER_CROSSING` pushes here:
    ``W_v + w <= K T``, ``W_v`` the steps waited in ``v`` so far.

* **Otherwise the robot commits** to the most probable route: the most frequent first move
  ``m_j`` among the particles whose exit of ``v`` is the most probable one
  (``argmax_e P(p_v = e | o)``; all particles when ``v`` is the goal's polytope of each).

The rule needs root particles (route-prior beliefs); without them the move passes unchanged.
Bounds: one route walk of at most ``D + 1`` steps per particle per decision, and ``8`` heading
rows for the gain.
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
        v = int(planner.cell_poly[cell])
        slots = [int(x) for x in planner.nbr[v] if x >= 0]
        u = doubt(pool_theta)
        if v != self.poly and slots:  # this crossing's doubt under the belief itself
            u[v] = 1.0 - float(belief.joint(v).sum(axis=0).max())
        steps, doubts, first = route_walks(cell, depth, pool_g, pool_theta, planner.goal_cells,
                                           planner.cell_poly, planner.next_cell, planner.moves,
                                           u)
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
