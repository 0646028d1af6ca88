"""The consistent human holds the goal's polytope (pathpref/geometry/following.py, "The goal's
polytope is held"): its route, the oracle's path and its pushes never leave the goal's polytope
``r`` from a cell that can reach the goal inside ``r``.

Before the rule, on ``examples/maps/hall.json`` (instance seeds 1000 and 1007, consistent human)
the route left ``r`` and came back on a path of the same length: cells (8, 3) in r = 12, (8, 4)
in 10, (9, 5) in 12; and (1, 11) in r = 2, (2, 10) in 4, (2, 9) in 2 (the oracle made 2 and 1
back-crossings there). Those cases are kept as they were found: the hall with its route's
second waypoint at (16, 2), for a point robot (the example map now has it at (17, 2), since
the default robot's footprint cannot reach (16, 2)). Of 330 instances (10 on each of the
example maps, the 24 held-out plans and the paper's three), 3 routes left ``r``; with the rule
none does.
"""

from __future__ import annotations

import glob
import json
from pathlib import Path

import numpy as np
import pytest

from pathpref.episode import EpisodeSpec, run_episode
from pathpref.episode.instances import sample_instance
from pathpref.geometry.following import (
    consistent_preference,
    goal_polytope_distance,
    goal_polytope_hold,
    human_route,
)
from pathpref.geometry.footprint import POINT_ROBOT
from pathpref.geometry.world import load_world
from pathpref.inference.human import ObservationModel, SimulatedHuman

HALL = "examples/maps/hall.json"


def _hall_as_found():
    """The hall of the cases above (module docstring): its route through (16, 2), for a point
    robot."""
    raw = json.loads(Path(HALL).read_text())
    raw["preference"]["route"][1] = [16, 2]
    return load_world(raw, footprint=POINT_ROBOT)


def _route(world, seed):
    inst = sample_instance(world, seed, 10, consistent=True, t_max=world.spec.t_max)
    r = int(world.cell_polytope[inst.goal_cell])
    q = consistent_preference(world, world.require_preference(), r)[0]
    return inst, r, q, human_route(world, q, inst.start, inst.goal_cell)


@pytest.mark.parametrize("seed, r, cells", [
    (1000, 12, [(4, 5), (5, 4), (5, 3), (6, 2), (7, 2), (8, 3), (9, 4), (9, 5)]),
    (1007, 2, [(1, 11), (1, 10), (2, 9), (2, 8)]),
])
def test_the_routes_that_left_the_goals_polytope_stay_in_it(seed, r, cells):
    world = _hall_as_found()
    inst, goal_poly, q, route = _route(world, seed)
    assert goal_poly == r and q[r] == -1
    assert [tuple(int(c) for c in world.cells[k]) for k in route] == cells
    polys = world.cell_polytope[route]
    first = int(np.argmax(polys == r))
    assert (polys[first:] == r).all()  # once in r, never out
    # the oracle walks it: no back-crossing, T_max - slack steps
    spec = EpisodeSpec(map=HALL, method="oracle", delta_t=5, instance=0, run=0,
                       instance_seed=seed, run_seed=1, human="consistent")
    res = run_episode(spec, world=world)
    assert res.success and res.back_crossings == 0 and res.violations == 0
    assert [(s.x, s.y) for s in res.log] == cells
    assert res.steps == len(cells) - 1 == spec.t_max - res.slack


def _plans():
    return sorted(glob.glob("examples/maps/*.json")) + [
        "docs/results/heldout_plans/heldout_check-loop_9306.json",
        "docs/results/heldout_plans/heldout_9001.json",
        "docs/results/heldout_plans/heldout_loop_9101.json"]


def test_the_human_route_never_leaves_a_polytope_by_a_face_its_preference_forbids():
    """Property over plans and instances: every polytope change of the human's route leaves
    ``v`` toward ``q_v`` where ``q_v >= 0``, and leaves the goal's polytope only from a cell
    that is not held (none, on these plans); every polytope of the goal's component but ``r``
    has a preference, and following it reaches ``r``."""
    checked = 0
    for path in _plans():
        world = load_world(path)
        if world.preference is None:
            continue
        for seed in range(1000, 1010):
            inst, r, q, route = _route(world, seed)
            held = goal_polytope_hold(world, q, inst.goal_cell)
            assert route and route[-1] == inst.goal_cell
            for a, b in zip(route, route[1:], strict=False):
                v, w = int(world.cell_polytope[a]), int(world.cell_polytope[b])
                if v == w:
                    continue
                assert q[v] < 0 or q[v] == w, (path, seed)
                assert not (v == r and held[a]), (path, seed)
            # wherever the robot may be pushed (r's component), a preference leads to r
            P = world.n_polytopes
            reach = np.isfinite(consistent_preference(world, world.require_preference(), r)[1])
            for v in np.flatnonzero(reach):
                u, hops = int(v), 0
                while u != r and hops <= P:
                    assert q[u] >= 0, (path, seed, v)
                    u, hops = int(q[u]), hops + 1
                assert u == r, (path, seed, v)
            checked += 1
    assert checked >= 60


def test_the_consistent_humans_pushes_stay_in_the_goals_polytope():
    world = _hall_as_found()
    inst, r, q, _ = _route(world, 1000)
    model = ObservationModel.build(world, np.array(inst.goals))
    free = SimulatedHuman(model, inst.true_goal, q)  # the paper's protocol: at the goal
    held = SimulatedHuman(model, inst.true_goal, q, hold=True)
    cell = world.cell((8, 3))
    assert world.cell_polytope[cell] == r
    m = world.motion
    # straight at the goal: N and NE tie (0.377 each) and N leaves r for polytope 10
    assert int(np.argmax(free.probs(cell))) == 0
    assert world.cell_polytope[m.next_cell[cell, 0]] != r
    p = held.probs(cell)
    assert p.sum() == pytest.approx(1.0, abs=1e-12)
    assert int(np.argmax(p)) == 1 and world.cell_polytope[m.next_cell[cell, 1]] == r
    # the excess by hand: NE stays in r on the shortest path inside r (0), N leaves r (2 c)
    d = goal_polytope_distance(world, inst.goal_cell)
    delta = np.where(m.blocked[cell], 4.0,
                     np.where(world.cell_polytope[m.next_cell[cell]] == r,
                              m.cost[cell] + d[m.next_cell[cell]] - d[cell], 2 * m.cost[cell]))
    want = np.exp(-model.gamma * delta)
    assert p == pytest.approx(want / want.sum(), rel=1e-9)
    # outside r, and without hold, the human is the one it was
    out = world.cell((5, 3))
    assert world.cell_polytope[out] != r
    assert np.array_equal(held.probs(out), free.probs(out))
    np.testing.assert_array_equal(free.probs(cell),
                                  model.goal_heading_probs[cell, :, inst.true_goal])


def test_no_hold_where_the_goals_polytope_has_a_preference():
    world = load_world("simple")
    pref = world.require_preference()
    goal = world.cell((1, 8))
    assert pref[world.cell_polytope[goal]] >= 0
    assert not goal_polytope_hold(world, pref, goal).any()
