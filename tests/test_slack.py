"""Time-aware waiting (:mod:`pathpref.planning.slack`, the ``robust-slack`` preset): the route
walks it reads, when a wait is kept, when the robot commits, and that no episode stalls."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pathpref.episode import EpisodeSpec, run_episode
from pathpref.geometry.grid import STAY
from pathpref.inference.human import ObservationModel
from pathpref.inference.routes import RouteBelief
from pathpref.planning.crossing import effective_rho, route_steps, route_walks
from pathpref.planning.hindsight import shortest_walks
from pathpref.planning.pomcp import POMCP
from pathpref.planning.pomdp import get_preset
from pathpref.planning.slack import CONFIDENT, ON_TIME, PUSHES_PER_CROSSING, WaitBudget, doubt


def _searched(world, goals, cell, depth=60):
    """A robust planner that has searched from ``cell`` under a route-prior belief with nothing
    observed (so it holds root particles), its belief and model."""
    model = ObservationModel.build(world, goals)
    belief = RouteBelief(model)
    planner = POMCP(world, goals, get_preset("robust-slack").path_preference.for_mission(depth),
                    queries=1000, tables=model.tables, likelihood=model.cell_likelihood)
    planner.search(cell, belief, depth, 5, [], (1, 1))
    return planner, belief, model


def _hops(nbr, theta, v, goal_poly):
    """The polytopes a particle's exits lead through from ``v`` to ``goal_poly``."""
    out = []
    while v != goal_poly:
        out.append(v)
        v = int(nbr[v, theta[v]])
    return out


@pytest.fixture
def searched(simple):
    goals = np.array([simple.cell((9, 9)), simple.cell((9, 1)), simple.cell((1, 8))])
    s = simple.cell((4, 2))
    return (s, *_searched(simple, goals, s))


def test_route_walks_follow_the_exits(searched):
    """Each particle's walk crosses exactly the polytopes its exits lead through (the polytope
    chain from ``v(s)`` to its goal's, followed by hand), its first move starts a walk one step
    shorter, and the weighted count is the weight summed over that chain."""
    s, planner, _, _ = searched
    pool_g, pool_theta = planner.root_particles()
    P = len(planner.nbr)
    steps, crossings, first = route_walks(s, 200, pool_g, pool_theta, planner.goal_cells,
                                          planner.cell_poly, planner.next_cell, planner.moves,
                                          np.ones(P))
    np.testing.assert_array_equal(steps, route_steps(s, 200, pool_g, pool_theta,
                                                     planner.goal_cells, planner.cell_poly,
                                                     planner.next_cell, planner.moves))
    weight = np.arange(1.0, P + 1)
    weighted = route_walks(s, 200, pool_g, pool_theta, planner.goal_cells, planner.cell_poly,
                           planner.next_cell, planner.moves, weight)[1]
    v = int(planner.cell_poly[s])
    for j in range(len(pool_g)):
        chain = _hops(planner.nbr, pool_theta[j], v, int(planner.goal_poly[pool_g[j]]))
        assert crossings[j] == len(chain), j
        assert weighted[j] == pytest.approx(sum(weight[x] for x in chain)), j
        s2 = int(planner.next_cell[s, first[j]])
        again = route_walks(s2, 200, pool_g[j:j + 1], pool_theta[j:j + 1], planner.goal_cells,
                            planner.cell_poly, planner.next_cell, planner.moves, np.ones(P))[0]
        assert again[0] == steps[j] - 1, j


def test_doubt_by_hand():
    """Four particles, three polytopes: all agree on polytope 0 (doubt 0), split 3:1 on
    polytope 1 (0.25), 2:1:1 on polytope 2 (0.5)."""
    theta = np.array([[0, 1, -1], [0, 1, 0], [0, 1, 1], [0, 2, -1]])
    np.testing.assert_allclose(doubt(theta), [0.0, 0.25, 0.5])


def _inside_moves(world, cell):
    m, cp = world.motion, world.cell_polytope
    return [a for a in range(8) if not m.blocked[cell, a]
            and cp[m.next_cell[cell, a]] == cp[cell]]


def _crossing(world, cell):
    m, cp = world.motion, world.cell_polytope
    return next(a for a in range(8) if not m.blocked[cell, a]
                and cp[m.next_cell[cell, a]] != cp[cell])


def _wait_move(budget, planner, cell):
    """A move inside the polytope that brings the particles no nearer their goals."""
    v = int(planner.cell_poly[cell])
    g, th = planner.root_particles()
    here = budget._togo(planner, cell, v, g, th)
    return next(a for a in _inside_moves(planner.world, cell)
                if budget._togo(planner, int(planner.next_cell[cell, a]), v, g, th) >= here)


def test_waits_stand_still_then_commit_within_the_bound(searched):
    """Nothing observed, ample time, a push every step: a move that gains nothing becomes a
    stand-still where a push would tell something (else the move itself, while the exit is
    unsettled), at most PUSHES_PER_CROSSING times in a row with at least one stand-still;
    then the robot commits to the first move of the most probable route (a move that goes
    somewhere). A crossing and a move toward the particles' goals pass unchanged."""
    s, planner, belief, model = searched
    budget = WaitBudget()
    lik = model.cell_likelihood
    a = _wait_move(budget, planner, s)
    got = [budget.decide(planner, belief, lik, a, s, 60 - t, (1, 1)) for t in range(10)]
    n_wait = next(i for i, b in enumerate(got) if b not in (STAY, a))
    assert 1 <= n_wait <= PUSHES_PER_CROSSING and STAY in got[:n_wait]
    committed = got[n_wait]
    assert committed != STAY and not planner.world.motion.blocked[s, committed]
    assert all(b == committed for b in got[n_wait:])  # the budget is spent: no more waits
    cross = _crossing(planner.world, s)
    assert WaitBudget().decide(planner, belief, lik, cross, s, 60, (1, 1)) == cross
    assert WaitBudget().decide(planner, belief, lik, committed, s, 60, (1, 1)) == committed


def test_out_of_time_plans_for_arriving(searched):
    """``plan`` says out of time exactly when fewer than ON_TIME of the particles' routes
    fit: never with ample time, always with one step fewer than the quickest route."""
    s, planner, belief, _ = searched
    g, th = planner.root_particles()
    steps = route_steps(s, 200, g, th, planner.goal_cells, planner.cell_poly,
                        planner.next_cell, planner.moves)
    budget = WaitBudget()
    assert not budget.plan(planner, belief, s, int(steps.max()))
    assert budget.plan(planner, belief, s, int(steps.min()) - 1)
    depth = int(np.sort(steps)[int(np.ceil(ON_TIME * len(steps))) - 1])
    assert budget.plan(planner, belief, s, depth) == (np.mean(steps <= depth) < ON_TIME)


def test_no_slack_no_wait(searched):
    """With exactly the time the quickest particle's route needs (the particles that arrive in
    time then need all of it), a move that gains nothing is replaced by the most probable
    route's first move at once; so is a stand-still."""
    s, planner, belief, model = searched
    g, th = planner.root_particles()
    steps = route_steps(s, 60, g, th, planner.goal_cells, planner.cell_poly, planner.next_cell,
                        planner.moves)
    tight = int(steps.min())
    budget = WaitBudget()
    a = _wait_move(budget, planner, s)
    for b in (a, STAY):
        got = WaitBudget().decide(planner, belief, model.cell_likelihood, b, s, tight, (1, 1))
        assert got != STAY and got != b


def test_waits_for_sparse_pushes_are_bounded_too(searched):
    """Pushes every 5 steps: at most PUSHES_PER_CROSSING intervals are waited in one polytope
    (``W + w <= K T`` steps), whatever the belief says; then the robot commits."""
    s, planner, belief, model = searched
    budget = WaitBudget()
    a = _wait_move(budget, planner, s)
    n = 0
    for t in range(60):
        if budget.decide(planner, belief, model.cell_likelihood, a, s, 200 - t,
                         (5 - t % 5, 5)) not in (STAY, a):
            break
        n += 1
    assert 1 <= n <= PUSHES_PER_CROSSING * 5


def test_an_episode_with_almost_no_pushes_does_not_stall():
    """One push in the whole mission (ΔT = 30 on ``simple``): the robot never stands still
    more than PUSHES_PER_CROSSING steps in a row, reaches the goal, and replays identically."""
    spec = EpisodeSpec(map="simple", method="path_preference", delta_t=30, instance=0, run=1,
                       instance_seed=11, run_seed=12, preset="robust-slack", queries=800,
                       human="consistent")
    res = run_episode(spec)
    cells = [(r.x, r.y) for r in res.log]
    longest = run = 0
    for a, b in zip(cells, cells[1:], strict=False):
        run = run + 1 if a == b else 0
        longest = max(longest, run)
    assert longest <= PUSHES_PER_CROSSING
    assert res.goal_reached
    again = run_episode(spec)
    assert [(r.x, r.y) for r in again.log] == cells


def test_a_decision_runs_one_search(monkeypatch):
    """Every decision of a ``robust-slack`` episode runs exactly one search: the arrival
    search alone when the routes no longer fit (rule 0 reads the root pool before the search,
    so the path-preference search whose move it would discard is not run), the
    path-preference search otherwise; both kinds occur in this short mission, and the episode
    replays identically."""
    from pathpref.planning.pomcp import POMCP

    kinds = []
    real = POMCP.search

    def spy(self, *args, **kw):
        kinds.append(self.rewards.use_preference)
        return real(self, *args, **kw)

    monkeypatch.setattr(POMCP, "search", spy)
    spec = EpisodeSpec(map="simple", method="path_preference", delta_t=3, instance=1, run=1,
                       instance_seed=12, run_seed=12, preset="robust-slack", queries=400,
                       human="consistent", t_max=12)
    res = run_episode(spec)
    assert len(kinds) == res.steps
    assert 0 < sum(kinds) < len(kinds)  # some decisions of each kind
    kinds.clear()
    again = run_episode(spec)
    assert [(r.x, r.y, r.action) for r in again.log] == [(r.x, r.y, r.action) for r in res.log]


def test_slack_preset_is_robust_check_plus_budget_and_arrival():
    """``robust-slack`` differs from ``robust-check`` in the wait budget and the arrival share
    only; the older presets keep the strict reward (arrival 0, their decisions unchanged)."""
    slack, check = get_preset("robust-slack"), get_preset("robust-check")
    assert slack.budget_waits and not check.budget_waits
    assert slack.path_preference.arrival == 0.2
    assert replace(slack, name="robust-check", budget_waits=False,
                   path_preference=replace(slack.path_preference, arrival=0.0)) == check
    for name in ("paper", "original", "robust", "robust-wait", "robust-check"):
        assert get_preset(name).path_preference.arrival == 0.0


def test_effective_rho_by_hand():
    """A success after one wrong crossing is worth ``a + (1 - a) rho``: 0.1 for ``a = 0``,
    ``0.2 + 0.8 * 0.1 = 0.28`` for ``a = 0.2``, 1 for ``a = 1``."""
    r = get_preset("robust").path_preference
    assert effective_rho(r) == 0.1
    assert effective_rho(replace(r, arrival=0.2)) == pytest.approx(0.28)
    assert effective_rho(replace(r, arrival=1.0)) == pytest.approx(1.0)


def test_arrival_one_values_any_route(simple):
    """With ``a = 1`` the goal pays ``gamma^(L-1)`` whatever the route: with the goal known,
    no root value exceeds ``gamma^(d-1)``, ``d`` the fewest steps to it, and the best is
    within 20 % of it (the search finds a way, right or wrong); with ``a = 0`` and no push
    expected (every crossing judged by the particle's exits, none known), the same search
    values the best move less."""
    goals = np.array([simple.cell((9, 9)), simple.cell((1, 8))])
    s = simple.cell((1, 1))
    model = ObservationModel.build(simple, goals)
    prior = np.array([1.0, 0.0])
    d = int(model.tables.dist[0, s] // 1)
    best = {}
    for a in (0.0, 1.0):
        r = replace(get_preset("robust").path_preference, arrival=a).for_mission(30)
        planner = POMCP(simple, goals, r, queries=3000, tables=model.tables)
        res = planner.search(s, RouteBelief(model, prior=prior), 30, 3, [], (1000, 1000))
        best[a] = float(res.values[res.visits > 0].max())
        bound = r.discount ** (model.tables.dist[0, s] - 1)
        assert best[a] <= bound + 1e-9
    assert best[1.0] >= 0.8 * r.discount ** (d - 1)
    assert best[0.0] < best[1.0]


def _shortest_walk(planner, s, g, theta, depth):
    """Plain-Python reference: the shortest-way walk of the rollouts (``moves[s, 0, g]``, first
    of tied moves) from ``s`` to goal ``g``, its steps (``depth + 1``: no arrival) and its
    crossings against ``theta`` (the goal's polytope excepted)."""
    steps, against, gc = 0, 0, planner.goal_cells[g]
    while s != gc and steps <= depth:
        bits = int(planner.moves[s, 0, g])
        a = next((b for b in range(8) if bits >> b & 1), 0)
        s2 = int(planner.next_cell[s, a])
        if s2 == s:
            return depth + 1, against
        v, k = int(planner.cell_poly[s]), int(planner.cross_slot[s, a])
        against += k >= 0 and v != planner.goal_poly[g] and theta[v] != k
        s, steps = s2, steps + 1
    return (steps if s == gc else depth + 1), against


def test_shortest_walks_by_hand(searched):
    """The arrival plan's walks (:func:`shortest_walks`) against a plain walk of the shortest
    way: the same steps and the same count of crossings against each particle's exits."""
    s, planner, _, _ = searched
    g, th = planner.root_particles()
    steps = route_steps(s, 200, g, th, planner.goal_cells, planner.cell_poly, planner.next_cell,
                        planner.moves)
    some_against = False
    for depth in (int(steps.max()), int(np.median(steps)), 3):
        got, against = shortest_walks(s, depth, g, th, planner.goal_cells, planner.goal_poly,
                                      planner.cell_poly, planner.next_cell, planner.cross_slot,
                                      planner.moves)
        for j in range(len(g)):
            la, n = _shortest_walk(planner, s, int(g[j]), th[j], depth)
            some_against |= n > 0 and la <= depth
            assert (got[j], against[j]) == (la, n), j
    assert some_against  # the case exercises the crossings' count


def test_late_goals_by_hand(searched):
    """Rule 0' (robust-value): a goal is late when fewer than ON_TIME of its own particles'
    routes fit, counted here particle by particle; robust-value never switches the whole
    decision (``plan`` is False), where rule 0 switches once fewer than ON_TIME of all the
    particles fit, whatever goal they hold."""
    s, planner, belief, _ = searched
    g, th = planner.root_particles()
    G = len(planner.goal_cells)
    steps = route_steps(s, 200, g, th, planner.goal_cells, planner.cell_poly, planner.next_cell,
                        planner.moves)
    mixed = 0
    for depth in range(int(steps.min()) - 1, int(steps.max()) + 1):
        budget = WaitBudget(per_goal=True)
        assert budget.plan(planner, belief, s, depth) is False
        want = np.zeros(G, bool)
        for k in range(G):
            mine = [steps[j] <= depth for j in range(len(g)) if g[j] == k]
            want[k] = bool(mine) and sum(mine) < ON_TIME * len(mine)
        np.testing.assert_array_equal(budget.late_goals(G), want)
        mixed += 0 < want.sum() < len(set(g.tolist()))
        assert WaitBudget().plan(planner, belief, s, depth) == (np.mean(steps <= depth) < ON_TIME)
    assert mixed  # some depth makes one goal late and not another


def test_late_particles_roll_out_by_the_shortest_way(simple):
    """No late goal: the search is bit for bit the one without the argument. Every goal late,
    with enough steps left for every particle's shortest way but not for every route (some
    of those particles' rollouts timed out): the rollouts that arrive raise the root's best
    value."""
    goals = np.array([simple.cell((9, 9)), simple.cell((9, 1)), simple.cell((1, 8))])
    s = simple.cell((4, 2))
    planner, belief, _ = _searched(simple, goals, s)
    g, th = planner.root_particles()
    steps = route_steps(s, 200, g, th, planner.goal_cells, planner.cell_poly, planner.next_cell,
                        planner.moves)
    short = shortest_walks(s, 200, g, th, planner.goal_cells, planner.goal_poly,
                           planner.cell_poly, planner.next_cell, planner.cross_slot,
                           planner.moves)[0]
    depth = int(short.max())
    assert (steps > depth).mean() > 0.25
    base = planner.search(s, belief, depth, 7, [], (1, 1))
    same = planner.search(s, belief, depth, 7, [], (1, 1), np.zeros(len(goals), bool))
    np.testing.assert_array_equal(base.visits, same.visits)
    np.testing.assert_array_equal(base.values, same.values)
    late = planner.search(s, belief, depth, 7, [], (1, 1), np.ones(len(goals), bool))
    assert late.values.max() > base.values.max()


def test_one_push_crossing_waits_below_confidence(searched):
    """Rule 4 (robust-value): nothing observed (the crossing's probability is the prior's, below
    CONFIDENT), ample time: a crossing is a stand-still until two pushes were felt in the
    polytope, then it passes; without slack it passes at once; robust-slack lets it pass."""
    s, planner, belief, model = searched
    lik = model.cell_likelihood
    cross = _crossing(planner.world, s)
    v = int(planner.cell_poly[s])
    slots = [int(x) for x in planner.nbr[v] if x >= 0]
    u = int(planner.cell_poly[planner.next_cell[s, cross]])
    assert float(belief.joint(v)[:, slots.index(u)].sum()) < CONFIDENT
    budget = WaitBudget(per_goal=True)
    assert budget.decide(planner, belief, lik, cross, s, 60, (1, 1), pushed=False) == STAY
    assert budget.decide(planner, belief, lik, cross, s, 59, (1, 1), pushed=True) == STAY
    assert budget.decide(planner, belief, lik, cross, s, 58, (1, 1), pushed=True) == cross
    assert WaitBudget().decide(planner, belief, lik, cross, s, 60, (1, 1)) == cross
    g, th = planner.root_particles()
    tight = int(route_steps(s, 60, g, th, planner.goal_cells, planner.cell_poly,
                            planner.next_cell, planner.moves).min())
    assert WaitBudget(per_goal=True).decide(planner, belief, lik, cross, s, tight,
                                            (1, 1)) == cross
