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

0. **Arrive first when the routes no longer fit** (:meth:`WaitBudget.plan`, on the search's
   root particles, drawn before the search: :meth:`~.pomcp.POMCP.particles`): when fewer
   than :data:`ON_TIME` of the particles' preferred routes arrive within ``D`` steps
   (``mean_j [L_j <= D] < ON_TIME``), the policy takes its move from a search for the goal
   alone (the preset's goal-only rewards on the same goal marginal), and the
   path-preference search, whose move would not be used, is not run: reaching the goal by
   another route is then worth more than a preferred route that times out.

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

**One objective, per goal** (:attr:`WaitBudget.per_goal`, the ``robust-value`` preset). Three
rules change, so that the value the robot acts on is the one its rewards state, arriving first
and the person's route second (``gamma^(L-1) (alpha + (1 - alpha) rho^n)``,
:attr:`~.pomdp.Rewards.arrival`), judged goal by goal:

0'. *Arrive first, per goal, inside the one search* (:meth:`WaitBudget.plan` before the search,
   :meth:`WaitBudget.late_goals`): a goal ``g`` is *late* when fewer than :data:`ON_TIME` of its
   own particles' routes arrive in the ``D`` steps left (``mean_{j: g_j = g} [L_j <= D] <
   ON_TIME``); the search's simulations from a late goal's particles roll out by the shortest
   way, following the particle's exit only in polytopes the belief has observed
   (:class:`~.search_inputs.BeliefRows` ``pool_late``). So the search values, for each goal,
   arriving by another route (``alpha + (1 - alpha) rho^n``) where its routes no longer fit,
   and the person's route where they do; there is no switch to a separate search, and goal
   uncertainty alone changes nothing (rule 0 switched the whole decision to the goal-only
   search when fewer than ``ON_TIME`` of all the particles' routes fitted, so a far goal's
   particles switched it while the near goal's route still fitted).
2'. *Waits budgeted against every particle's route*: ``L`` and ``U'`` are medians over all the
   particles of the route each is planned to take: its route (``L_j``, ``U_j``), or for a late
   goal's particle the shortest way (:func:`~.hindsight.shortest_walks`, doubt 0: it does not
   wait); rule 2 took them over the routes that arrive, so the particles that did not fit did
   not shorten the slack.
4. *Crossings committed at a stated confidence*: a move that leaves ``v`` into ``u`` with
   ``P(p_v = u | o) <`` :data:`CONFIDENT`, after fewer than two pushes felt in ``v`` on this
   visit, is a wait (a stand-still) while rule 2's budget pays for the next push and a push
   at ``s`` is expected to raise the best exit's probability by :data:`MIN_GAIN`.

The rule needs root particles (route-prior beliefs); without them the move passes unchanged.
Bounds: one route walk of at most ``D + 1`` steps per particle per decision, ``8`` heading
rows for the gain, and at most ``K T`` steps of waiting in a polytope per visit.
"""

from __future__ import annotations

import numpy as np

from ..geometry.grid import STAY
from .crossing import LOOKAHEAD_PUSHES, ExitMemo, route_walks
from .hindsight import shortest_walks

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
#: rule 4: the least probability that a crossing is the preferred one for the robot to make it
#: after fewer than two pushes felt in the polytope, while the slack pays for another push
CONFIDENT = 0.97


def doubt(pool_theta: np.ndarray) -> np.ndarray:
    """``(P,)`` ``u_x = 1 - max_e share_x(e)``: how much the particles disagree on the exit
    of each polytope ``x`` (``share_x(e)``: the share of the rows of ``pool_theta`` whose
    exit of ``x`` is ``e``); 0 where they all agree."""
    m, P = pool_theta.shape
    k = int(pool_theta.max()) + 2
    counts = np.bincount((pool_theta + 1 + k * np.arange(P)).ravel(),
                         minlength=P * k).reshape(P, k)
    return 1.0 - counts.max(axis=1) / m


class WaitBudget:
    """The rule of the module docstring, with the state it keeps over an episode: the polytope
    the robot is in, the steps ``W_v`` it has waited there and the pushes felt there.
    ``per_goal``: rules 0', 2' and 4 (one objective, per goal) in place of 0 and 2."""

    def __init__(self, per_goal: bool = False) -> None:
        self.per_goal = bool(per_goal)
        self.poly = -1
        self.waited = 0
        self.felt = 0
        self._walks = None
        #: :func:`~.crossing.best_exit_after_pushes` kept between calls (shared with the
        #: crossing check: :class:`~.crossing.ExitMemo`)
        self.exits = ExitMemo()

    def plan(self, planner, belief, cell: int, depth: int) -> bool:
        """Read the root particles' routes from ``cell`` with ``depth`` steps left (the pool
        the search starts from, :meth:`~.pomcp.POMCP.particles`: before the search, and
        before :meth:`decide`); True when the robot is out of time for the preferred
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
        planned, planned_doubt = steps, doubts
        if self.per_goal:  # rule 2': each particle's planned route, the shortest for late goals
            late = self.late_goals(len(planner.goal_cells), pool_g, steps, depth)[pool_g]
            short = shortest_walks(cell, depth, pool_g, pool_theta, planner.goal_cells,
                                   planner.goal_poly, planner.cell_poly, planner.next_cell,
                                   planner.cross_slot, planner.moves)[0]
            planned = np.where(late, short, steps)
            planned_doubt = np.where(late, 0.0, doubts)
        self._walks = (cell, depth, u, steps, doubts, first, planned, planned_doubt, pool_g)
        return bool(np.mean(steps <= depth) < ON_TIME) and not self.per_goal

    def late_goals(self, n_goals: int, pool_g=None, steps=None, depth=None) -> np.ndarray:
        """``(G,)`` rule 0': the goals fewer than :data:`ON_TIME` of whose particles' routes
        arrive in the steps left (from the walks of the last :meth:`plan`, or the arrays
        given); False for a goal without particles."""
        if pool_g is None:
            depth, steps, pool_g = self._walks[1], self._walks[3], self._walks[8]
        n = np.bincount(pool_g, minlength=n_goals)
        fit = np.bincount(pool_g, weights=(steps <= depth).astype(float), minlength=n_goals)
        return (n > 0) & (fit < ON_TIME * n)

    def decide(self, planner, belief, likelihood, a: int, cell: int, depth: int,
               pushes: tuple[int, int], pushed: bool = False) -> int:
        """The move to make instead of ``a`` (module docstring). ``planner``: the robust
        :class:`~.pomcp.POMCP` whose last search ran from ``cell`` with ``depth`` steps left;
        ``likelihood``: :attr:`~pathpref.inference.human.ObservationModel.cell_likelihood`;
        ``pushes``: ``(next, every)`` as the search was given them; ``pushed``: a push was
        felt at this step (rule 4 counts them per visit of a polytope)."""
        particles = planner.root_particles()
        if particles is None:
            return a
        pool_g, pool_theta = particles
        cell, depth = int(cell), int(depth)
        if self._walks is None or self._walks[:2] != (cell, depth):
            self.plan(planner, belief, cell, depth)
        _, _, u, steps, doubts, first, planned, planned_doubt, _ = self._walks
        v = int(planner.cell_poly[cell])
        slots = [int(x) for x in planner.nbr[v] if x >= 0]
        if self.per_goal:
            steps, doubts = planned, planned_doubt
        ok = np.ones(len(steps), bool) if self.per_goal else steps <= depth
        route = float(np.median(steps[ok])) if ok.any() else float(depth)
        later = float(np.median(doubts[ok])) - u[v] if ok.any() else 0.0
        every = max(int(pushes[1]), 1)
        reserve = RESERVE * every * max(later, 0.0)
        if v != self.poly:
            self.poly, self.waited, self.felt = v, 0, 0
        self.felt += bool(pushed)
        w = max(int(pushes[0]), 1)
        at_goal = bool(np.all(planner.goal_poly[pool_g] == v))
        can_wait = not at_goal and bool(slots) and w + reserve <= depth - route \
            and self.waited + w <= PUSHES_PER_CROSSING * every
        gain = None
        if a != STAY:
            s2 = int(planner.next_cell[cell, a])
            u2 = int(planner.cell_poly[s2])
            if s2 != cell and u2 != v:
                if self.per_goal and can_wait and self.felt < 2 and u2 in slots and float(
                        belief.joint(v)[:, slots.index(u2)].sum()) < CONFIDENT:
                    gain = self.exits(belief.joint(v), likelihood, cell, 1)
                    if gain[1] - gain[0] >= MIN_GAIN:
                        self.waited += 1
                        return STAY
                return a
            if s2 != cell and self._togo(planner, s2, v, pool_g, pool_theta) \
                    < self._togo(planner, cell, v, pool_g, pool_theta):
                return a
        if can_wait:
            if gain is None:
                gain = self.exits(belief.joint(v), likelihood, cell, 1)
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
