"""The reward rule of SPEC 6, pinned with hand-computed values (paper preset: R_p = 15.5,
R_n = -18, R_g = 50), and the dm_control task's rewards checked step by step against it."""

from __future__ import annotations

import math
import os

import numpy as np
import pytest

from pathpref.geometry.grid import STAY
from pathpref.planning.pomdp import get_preset, step_reward, transition_reward

R = get_preset("paper").path_preference
GO = get_preset("paper").goal_only


def _moves(world):
    """Every (s, a, s2, v, w) of the map's grid motion."""
    m, poly = world.motion, world.cell_polytope
    for s in range(world.n_cells):
        for a in range(8):
            s2 = int(m.next_cell[s, a])
            yield s, a, s2, int(poly[s]), int(poly[s2])


def _first(world, cond):
    return next(x for x in _moves(world) if cond(*x))


def _far_goal(world, *polys):
    """A cell in none of ``polys`` (so 'the goal is in v' is false)."""
    return int(np.flatnonzero(~np.isin(world.cell_polytope, polys))[0])


def test_hand_computed_rewards(simple):
    w, pref = simple, simple.preference
    blocked = simple.motion.blocked
    s, a, s2, v, _ = _first(w, lambda s, a, s2, v, u: a == 0 and v == u and not blocked[s, a])
    g = _far_goal(w, v)
    assert transition_reward(w, s, s2, a, g, int(pref[v]), R) == -1.0
    s, a, s2, v, _ = _first(w, lambda s, a, s2, v, u: a == 1 and v == u and not blocked[s, a])
    assert transition_reward(w, s, s2, a, _far_goal(w, v), int(pref[v]), R) == -math.sqrt(2)
    # straight into the preferred neighbour, goal elsewhere: -1 + 15.5
    s, a, s2, v, u = _first(w, lambda s, a, s2, v, u: a % 2 == 0 and u == pref[v] and v != u)
    assert transition_reward(w, s, s2, a, _far_goal(w, v, u), int(pref[v]), R) == 14.5
    # the same move when the goal lies in v: every exit is non-preferred, -1 - 18
    g_in_v = int(np.flatnonzero(w.cell_polytope == v)[0])
    assert transition_reward(w, s, s2, a, g_in_v, int(pref[v]), R) == -19.0
    # the goal-only planner has no preference terms
    assert transition_reward(w, s, s2, a, _far_goal(w, v, u), int(pref[v]), GO) == -1.0
    # straight into a non-preferred neighbour: -1 - 18; with no preference (-1) as well
    s, a, s2, v, u = _first(w, lambda s, a, s2, v, u: a % 2 == 0 and v != u and u != pref[v])
    assert transition_reward(w, s, s2, a, _far_goal(w, v, u), int(pref[v]), R) == -19.0
    assert transition_reward(w, s, s2, a, _far_goal(w, v, u), -1, R) == -19.0
    # STAY costs nothing; a blocked move costs 1 and stays
    assert transition_reward(w, s, s, STAY, _far_goal(w, v), int(pref[v]), R) == 0.0
    s, a, s2, v, _ = _first(w, lambda s, a, s2, v, u: blocked[s, a])
    assert s2 == s and transition_reward(w, s, s2, a, _far_goal(w, v), int(pref[v]), R) == -1.0
    # reaching the goal inside its polytope: -1 + 50
    s, a, s2, v, _ = _first(w, lambda s, a, s2, v, u: a == 2 and v == u and s2 != s)
    assert transition_reward(w, s, s2, a, s2, int(pref[v]), R) == 49.0
    # step_reward is the same rule on the grid's own transition
    assert step_reward(w, s, a, s2, int(pref[v]), R) == (s2, 49.0, True, -1)


def _independent_reward(world, s, s2, a, goal, pref_v):
    """SPEC 6 written out again, as the oracle for the task."""
    r = 0.0 if a == 8 else -(1.0 if world.motion.blocked[s, a] else (1.0, math.sqrt(2))[a % 2])
    v, u = world.cell_polytope[s], world.cell_polytope[s2]
    if v != u:
        good = pref_v == u and world.cell_polytope[goal] != v
        r += 15.5 if good else -18.0
    return r + (50.0 if s2 == goal else 0.0)


@pytest.mark.parametrize("seed", [0, 1])
def test_task_rewards_follow_the_rule_step_by_step(seed):
    os.environ.setdefault("MUJOCO_GL", "egl")
    from pathpref_tasks import load

    env = load("navigate", map="simple", method="compliant", delta_t=2, seed=seed,
               queries=50, t_max=25)
    rng = np.random.default_rng(seed)
    ts = env.reset()
    crossings = 0
    while not ts.last():
        r = env.task.runner
        before = r.cell
        a = int(rng.integers(9))
        ts = env.step(a)
        w = r.world
        want = _independent_reward(w, before, r.cell, a, r.instance.goal_cell,
                                   int(r.pref[w.cell_polytope[before]]))
        assert ts.reward == pytest.approx(want, abs=1e-12), (before, r.cell, a)
        crossings += w.cell_polytope[before] != w.cell_polytope[r.cell]
    assert crossings > 0  # the episode exercised the preference terms


def test_horizon_discount_resolves_to_one_minus_one_over_t_max():
    rb = get_preset("robust").path_preference
    assert rb.horizon_discount
    for t_max, want in ((30, 1 - 1 / 30), (60, 1 - 1 / 60), (2, 0.5), (1, 0.5)):
        r = rb.for_mission(t_max)
        assert r.discount == pytest.approx(want) and r.horizon_discount is False
        assert r.for_mission(999).discount == r.discount  # resolved once, not again
    assert R.for_mission(60) is R  # the paper's fixed discount is kept
