"""The crossing check (:mod:`pathpref.planning.crossing`, the ``robust-check`` preset): the
exact value of information of a crossing, the particles' route times, and the decision."""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest

from pathpref.episode import EpisodeSpec, run_episode
from pathpref.geometry.following import preference_following_distance
from pathpref.geometry.grid import STAY
from pathpref.inference.belief import PreferenceBelief
from pathpref.inference.human import ObservationModel
from pathpref.inference.routes import RouteBelief
from pathpref.planning import crossing, policies
from pathpref.planning.crossing import (
    LOOKAHEAD_PUSHES,
    ExitMemo,
    best_exit_after_pushes,
    check_crossing,
    route_steps,
    wait_value,
)
from pathpref.planning.pomcp import POMCP, SearchResult
from pathpref.planning.pomdp import get_preset


def _vote_likelihood(p: float = 0.9) -> np.ndarray:
    """``(8, 1, 2)``: heading 0 with probability ``p`` under exit 0 (``1 - p`` under exit 1),
    heading 1 the other way round, no other heading."""
    lik = np.zeros((8, 1, 2))
    lik[0, 0] = [p, 1 - p]
    lik[1, 0] = [1 - p, p]
    return lik


def test_best_exit_after_pushes_is_a_majority_vote():
    """Two exits equally likely, each push pointing at the preferred one with probability 0.9:
    the best exit after ``k`` pushes is the majority's, right with probability 0.9 after one or
    two pushes (a tie is a coin), ``0.9^3 + 3 0.9^2 0.1 = 0.972`` after three or four."""
    got = best_exit_after_pushes(np.array([[0.5, 0.5]]), _vote_likelihood(), 4)
    np.testing.assert_allclose(got, [0.5, 0.9, 0.9, 0.972, 0.972], atol=1e-12)


def _brute_force(joint: np.ndarray, lik: np.ndarray, k: int) -> float:
    """``E_k`` by Bayes' rule on every heading sequence, one at a time."""
    lik = lik / lik.sum(axis=0, keepdims=True)
    total = 0.0
    for seq in itertools.product(range(8), repeat=k):
        post = joint.copy()
        for h in seq:
            post = post * lik[h]
        p_seq = post.sum()
        if p_seq > 0:
            total += p_seq * (post.sum(axis=0) / p_seq).max()
    return total


def test_best_exit_after_pushes_matches_bayes_on_every_sequence():
    """Three goals, three exits, random joint and likelihood (some headings impossible):
    ``E_0..E_3`` equal the brute force's, start at the best marginal and never fall."""
    rng = np.random.default_rng(4)
    joint = rng.dirichlet(np.ones(9)).reshape(3, 3)
    lik = rng.random((8, 3, 3)) * (rng.random((8, 1, 1)) > 0.25)
    got = best_exit_after_pushes(joint, lik, 3)
    want = [joint.sum(axis=0).max()] + [_brute_force(joint, lik, k) for k in (1, 2, 3)]
    np.testing.assert_allclose(got, want, rtol=1e-10)
    assert np.all(np.diff(got) >= -1e-12)


def test_pushes_that_say_nothing_about_the_exit_are_worth_nothing():
    """A heading likelihood that does not depend on the exit leaves ``E_k = E_0``."""
    rng = np.random.default_rng(1)
    joint = rng.dirichlet(np.ones(6)).reshape(2, 3)
    lik = np.repeat(rng.random((8, 2, 1)), 3, axis=2)
    np.testing.assert_allclose(best_exit_after_pushes(joint, lik, 4),
                               joint.sum(axis=0).max(), rtol=1e-12)


def test_one_exit_many_goals_sums_like_numpy():
    """A polytope with one exit and 8 or more goals takes the pairwise sum over the goals
    (:func:`crossing._pairwise`, NumPy's order for a contiguous run): ``E_k`` is then the
    total probability, 1, for every ``k``, and the pairwise sum of runs of every length up
    to 300 and of 20 000 terms is NumPy's within 1e-12 (relative)."""
    rng = np.random.default_rng(4)
    joint = rng.random((12, 1))
    joint /= joint.sum()
    got = best_exit_after_pushes(joint, rng.random((8, 12, 1)) + 0.01, 3)
    np.testing.assert_allclose(got, np.ones(4), rtol=1e-12)
    for n in [*range(1, 301), 20_000]:
        a = rng.random(n)
        np.testing.assert_allclose(crossing._pairwise(a, 0, n), a.sum(), rtol=1e-12)


def test_exit_memo_gives_best_exit_after_pushes_exactly(monkeypatch):
    """:class:`ExitMemo` returns :func:`best_exit_after_pushes`' values bit for bit: asked
    again with equal inputs and at most as many pushes it computes nothing (``E_0..E_k`` is a
    prefix of the longer answer), and any other cell, joint or a longer lookahead is
    computed afresh."""
    rng = np.random.default_rng(2)
    lik = rng.random((3, 8, 4, 3)) + 0.01  # (cells, headings, goals, exits)
    joint = rng.random((4, 3))
    joint /= joint.sum()
    calls = []
    real = crossing.best_exit_after_pushes

    def spy(j, lk, k):
        calls.append(k)
        return real(j, lk, k)

    monkeypatch.setattr(crossing, "best_exit_after_pushes", spy)
    memo = ExitMemo()
    asks = [(joint, 1, 3, 1), (joint.copy(), 1, 1, 1), (joint, 1, 3, 1), (joint, 2, 1, 2),
            (joint, 2, 2, 3), (joint[::-1].copy(), 2, 1, 4), (joint, 1, 3, 5)]
    for j, cell, k, n_calls in asks:
        got = memo(j, lik, cell, k)
        assert np.array_equal(got, real(j, lik[cell], k))
        assert len(calls) == n_calls


def test_wait_value_by_hand():
    """``P = 0.5``, ``E = 0.5, 0.9, 0.9, 0.972, 0.972``, waits of 1..4 steps, ``rho = 0.1``,
    ``gamma = 0.98``: crossing now is worth ``0.1 + 0.9 * 0.5 = 0.55``; waiting three pushes
    ``0.98^3 (0.1 + 0.9 * 0.972) = 0.917474``, the best, a ratio of 1.668135. No particle's
    route fits after a wait: 0. None fits now: 0."""
    E = np.array([0.5, 0.9, 0.9, 0.972, 0.972])
    waits = np.arange(5)
    gain, k = wait_value(0.5, E, np.ones(5), waits, 0.1, 0.98)
    assert k == 3
    assert gain == pytest.approx(0.98 ** 3 * (0.1 + 0.9 * 0.972) / 0.55, rel=1e-12)
    assert gain == pytest.approx(1.668135, abs=1e-6)
    assert wait_value(0.5, E, np.array([1.0, 0, 0, 0, 0]), waits, 0.1, 0.98)[0] == 0.0
    assert wait_value(0.5, E, np.zeros(5), waits, 0.1, 0.98) == (0.0, 0)


def _searched(world, goals, cell, pushes=(1, 1)):
    """A robust planner that has searched from ``cell`` under a route-prior belief (so it
    holds root particles), its belief and model."""
    model = ObservationModel.build(world, goals)
    belief = RouteBelief(model)
    planner = POMCP(world, goals, get_preset("robust").path_preference.for_mission(60),
                    queries=1000, tables=model.tables, likelihood=model.cell_likelihood)
    planner.search(cell, belief, 60, 5, [], pushes)
    return planner, belief, model


def test_route_steps_follow_each_particles_preference(simple):
    """Each particle's walk arrives within the time and takes at least as many steps as the
    fewest that leave every polytope only toward the particle's preferred neighbour (a walk
    that cut across another face could be shorter); with one step fewer than a particle's
    walk, that particle is out of time (``depth + 1``)."""
    goals = np.array([simple.cell((9, 9)), simple.cell((9, 1)), simple.cell((1, 8))])
    s = simple.cell((1, 1))
    planner, _, _ = _searched(simple, goals, s)
    pool_g, pool_theta = planner.root_particles()
    steps = route_steps(s, 200, pool_g, pool_theta, planner.goal_cells, planner.cell_poly,
                        planner.next_cell, planner.moves)
    assert np.all(steps <= 200)
    nbr = planner.nbr
    for j in range(len(pool_g)):
        pref = np.where(pool_theta[j] >= 0, nbr[np.arange(len(nbr)), pool_theta[j]], -1)
        fewest = preference_following_distance(simple, pref, goals[pool_g[j]], steps=True)
        assert steps[j] >= fewest[s] - 1e-9, j
    short = route_steps(s, int(steps.min()) - 1, pool_g, pool_theta, planner.goal_cells,
                        planner.cell_poly, planner.next_cell, planner.moves)
    assert np.all(short == steps.min())  # depth + 1 for every particle


def _crossing_move(world, cell):
    """A free move from ``cell`` into another polytope and the free moves that stay."""
    m, cp = world.motion, world.cell_polytope
    free = [a for a in range(8) if not m.blocked[cell, a]]
    out = [a for a in free if cp[m.next_cell[cell, a]] != cp[cell]]
    return out[0], [a for a in free if cp[m.next_cell[cell, a]] == cp[cell]]


def test_an_unsure_crossing_waits_when_time_allows_and_not_otherwise(simple):
    """Nothing observed, a push expected every step, ample time: the crossing's exit is a
    guess that pushes would settle, so the check takes the best-valued move that stays in the
    polytope. With exactly the time the quickest particle needs, any wait makes every route
    too long, and the robot crosses. A move that stays, and a belief without root particles
    (the independent prior), pass unchanged."""
    goals = np.array([simple.cell((9, 9)), simple.cell((9, 1)), simple.cell((1, 8))])
    s = simple.cell((4, 2))
    planner, belief, model = _searched(simple, goals, s)
    a, stay_moves = _crossing_move(simple, s)
    assert stay_moves
    values = np.full(8, 0.2)
    values[a] = 0.5
    values[stay_moves[-1]] = 0.3
    result = SearchResult(a, np.full(8, 10), values, 100, 1000)
    lik = model.cell_likelihood
    assert check_crossing(planner, belief, lik, result, s, 60, (1, 1)) == stay_moves[-1]
    pool = planner.root_particles()
    quickest = int(route_steps(s, 60, *pool, planner.goal_cells, planner.cell_poly,
                               planner.next_cell, planner.moves).min())
    assert check_crossing(planner, belief, lik, result, s, quickest, (1, 1)) == a
    inside = SearchResult(stay_moves[0], np.full(8, 10), values, 100, 1000)
    assert check_crossing(planner, belief, lik, inside, s, 60, (1, 1)) == stay_moves[0]
    indep = POMCP(simple, goals, get_preset("robust").path_preference.for_mission(60),
                  queries=200, tables=model.tables)
    indep.search(s, PreferenceBelief(model, coupling=False), 60, 5, [], (1, 1))
    assert indep.root_particles() is None
    assert check_crossing(indep, PreferenceBelief(model, coupling=False), lik, result, s, 60,
                          (1, 1)) == a


def test_a_wait_with_no_tried_move_inside_stands_still(simple):
    """If the search tried no move that stays in the polytope, waiting is standing still."""
    goals = np.array([simple.cell((9, 9)), simple.cell((9, 1)), simple.cell((1, 8))])
    s = simple.cell((4, 2))
    planner, belief, model = _searched(simple, goals, s)
    a, stay_moves = _crossing_move(simple, s)
    visits = np.full(8, 10)
    visits[stay_moves] = 0
    result = SearchResult(a, visits, np.full(8, 0.5), 100, 1000)
    assert check_crossing(planner, belief, model.cell_likelihood, result, s, 60,
                          (1, 1)) == STAY


def test_check_preset_is_robust_wait_plus_the_check():
    """``robust-check`` differs from ``robust-wait`` in ``check_crossings`` only."""
    check, wait = get_preset("robust-check"), get_preset("robust-wait")
    assert check.check_crossings and not wait.check_crossings
    assert replace(check, name="robust-wait", check_crossings=False) == wait
    assert LOOKAHEAD_PUSHES >= 1


def test_the_check_waits_for_the_push_interval_and_replays(monkeypatch):
    """An episode under ``robust-check`` runs to its end and replays identically; the check is
    consulted only once two pushes have been felt (their interval known)."""
    calls = []
    real = policies.check_crossing

    def spy(planner, belief, lik, res, cell, depth, pushes, **kw):
        calls.append(pushes)
        return real(planner, belief, lik, res, cell, depth, pushes, **kw)

    monkeypatch.setattr(policies, "check_crossing", spy)
    spec = EpisodeSpec(map="simple", method="path_preference", delta_t=3, instance=0, run=1,
                       instance_seed=11, run_seed=12, preset="robust-check", queries=800,
                       human="consistent")
    first = run_episode(spec)
    n_first = len(calls)
    again = run_episode(spec)
    assert (first.goal_reached, first.success, first.steps) == \
        (again.goal_reached, again.success, again.steps)
    assert first.steps > 0 and len(calls) == 2 * n_first
    assert all(p[1] == 3 for p in calls)  # the interval ΔT = 3, never the first guess (1, 1)


def test_the_check_is_bounded_in_its_worst_cases():
    """A walk that circles without reaching its goal, or is stuck, stops after ``depth + 1``
    steps whatever ``depth``; the heading sum at its largest (every heading possible, so no
    sequence is pruned; 10 goals, 12 exits) still gives probabilities in ``[E_0, 1]``."""
    n = 50
    ring = np.repeat(((np.arange(n) + 1) % n)[:, None], 8, axis=1)  # every move: one cell on
    stuck = np.repeat(np.arange(n)[:, None], 8, axis=1)  # every move: stay
    moves = np.zeros((n, 2, 1), np.uint8)
    goal_cells, cell_poly = np.array([n + 7]), np.zeros(n, np.int64)  # a goal never reached
    pool_g, pool_theta = np.zeros(3, np.int64), -np.ones((3, 1), np.int64)
    for nxt in (ring, stuck):
        for depth in (5, 10**6):
            got = route_steps(0, depth, pool_g, pool_theta, goal_cells, cell_poly, nxt, moves)
            assert np.all(got == depth + 1)
    rng = np.random.default_rng(2)
    joint = rng.dirichlet(np.ones(120)).reshape(10, 12)
    e = best_exit_after_pushes(joint, rng.random((8, 10, 12)) + 0.01, LOOKAHEAD_PUSHES)
    assert e[0] == pytest.approx(joint.sum(axis=0).max()) and np.all(e <= 1 + 1e-12)
    assert np.all(np.diff(e) >= -1e-12)
