"""The homotopy prior: the ways round the obstacles, and an exact mixture posterior.

The ways are checked on maps whose classes can be counted by hand; the posterior against a
brute force over every preference vector (the route prior's trees and each way's independent
exits, summed term by term), and the search's particles against the exact marginals."""

from __future__ import annotations

import numpy as np
import pytest

from pathpref.errors import ConfigError
from pathpref.geometry.maps import load_map
from pathpref.geometry.ways import find_ways, sketch, way_potential
from pathpref.geometry.world import World
from pathpref.inference.circulation_prior import CirculationBelief
from pathpref.inference.homotopy_prior import HomotopyBelief
from pathpref.inference.human import ObservationModel
from tests.test_routes import every_theta, is_tree, observations, random_world


def box_world(obstacles):
    return World.from_spec(load_map({"name": "t", "width": 9, "height": 7,
                                     "obstacles": obstacles}))


def test_one_obstacle_has_two_ways_and_none_has_one():
    """A block in the middle of a room: a route passes it above or below, two classes whose
    signatures differ by one crossing of its ray; an empty room has one class."""
    w = box_world([{"cells": {"lower_left": [4, 3], "size": [2, 2]}}])
    sk = sketch(w)
    west = int(w.cell_polytope[w.cell((1, 4))])
    east = int(w.cell_polytope[w.cell((9, 4))])
    ways = find_ways(sk, west, east)
    assert len(ways) == 2
    assert sorted(ways.signatures[:, 0].tolist()) in ([-1, 0], [0, 1])
    for route in ways.routes:
        assert route[0] == west and route[-1] == east
        assert all(int(b) in w.graph.neighbors[int(a)] for a, b in zip(route[:-1], route[1:],
                                                                       strict=True))
    # the two ways pass on opposite sides: their cell y's straddle the block
    ys = [np.mean([w.cells[w.cell_polytope == v][:, 1].mean() for v in r[1:-1]])
          for r in ways.routes]
    assert min(ys) < 3.5 < 4.5 < max(ys)
    empty = box_world([])
    sk0 = sketch(empty)
    assert len(find_ways(sk0, 0, empty.n_polytopes - 1)) == 1
    # the potential is 0 at the goal and the route's length at the start
    phi = way_potential(sk, ways.routes[0])
    assert phi[east] == pytest.approx(0.0, abs=1e-12)
    assert phi[west] == pytest.approx(ways.lengths[0], rel=1e-9)


def test_two_obstacles_in_a_row_give_the_via_route_classes():
    """Two blocks side by side: a via route (two shortest paths joined at one polytope)
    passes above both or below both; weaving between them (above one, below the other) is
    a concatenation of three shortest paths and is not a way (module docstring). The two
    ways differ by one crossing of each block's ray; a stretch of 1 keeps the shortest."""
    w = box_world([{"cells": {"lower_left": [3, 3], "size": [1, 2]}},
                   {"cells": {"lower_left": [6, 3], "size": [1, 2]}}])
    sk = sketch(w)
    a = int(w.cell_polytope[w.cell((1, 4))])
    b = int(w.cell_polytope[w.cell((9, 4))])
    many = find_ways(sk, a, b, k=50, stretch=50.0)
    assert len(many) == 2
    assert np.abs(many.signatures[0] - many.signatures[1]).tolist() == [1, 1]
    assert np.all(np.diff(many.lengths) >= 0)
    assert len(find_ways(sk, a, b, stretch=1.0)) == 1


def brute(belief: HomotopyBelief, model, obs):
    """``(P(g | o), {v: (G, deg) P(p_v | g, o)})`` by enumerating every theta under the
    mixture: the route prior's trees (uniform) and each way's product of exit rows."""
    w = model.world
    nbrs = w.graph.neighbors
    P, G = w.n_polytopes, len(model.goals)
    roots = w.cell_polytope[model.goals]
    thetas, loglik = every_theta(model, obs)
    a = belief.tree_share
    goal = np.zeros(G)
    cond = {v: np.zeros((G, len(nbrs[v]))) for v in range(P)}
    top = loglik.max()
    for g in range(G):
        r = roots[g]
        at_root = thetas[:, r] == 0  # the root's exit does not matter: count it once
        keep = np.array([t[r] == 0 and is_tree(t, r, nbrs) for t in thetas])
        lik = np.exp(loglik[g] - top)
        prior = np.where(keep, a / keep.sum(), 0.0)
        ways = belief.ways[g]
        for pi in ways:
            pw = np.ones(len(thetas))
            for v in range(P):
                if v != r:
                    pw *= pi[v, thetas[:, v]]
            prior = prior + (1 - a) / len(ways) * pw * at_root
        wts = prior * lik
        goal[g] = wts.sum()
        for v in range(P):
            for k in range(len(nbrs[v])):
                cond[v][g, k] = wts[thetas[:, v] == k].sum()
            cond[v][g] = 1.0 if v == r else cond[v][g]
            cond[v][g] /= cond[v][g].sum()
    return goal / goal.sum(), cond


@pytest.mark.parametrize("kind", [HomotopyBelief, CirculationBelief])
@pytest.mark.parametrize("name,seed", [("random11", 0), ("random30", 1), ("random5", 2)])
def test_homotopy_posterior_equals_brute_force(name, seed, kind):
    world = random_world(int(name[6:]))
    rng = np.random.default_rng(seed)
    goals = rng.choice(world.n_cells, size=3, replace=False)
    model = ObservationModel.build(world, goals, normalize=True)
    start = int(rng.integers(world.n_cells))
    belief = kind(model, start)
    assert belief.n_ways.min() >= 1
    obs = observations(world, model, rng, 12)
    obs += obs[-2:]
    for s, h in obs:
        belief.update(s, h)
    belief.rule_out(2) if rng.random() < 0.5 else None
    goal, cond = brute(belief, model, obs)
    if belief.ruled_out[2]:
        goal[2] = 0.0
        goal /= goal.sum()
    assert np.allclose(belief.goal_marginal(), goal, atol=1e-9)
    for v in range(world.n_polytopes):
        deg = len(world.graph.neighbors[v])
        for g in range(3):
            if belief.ruled_out[g]:
                continue
            assert np.allclose(belief.preference_given_goal(v)[g, :deg], cond[v][g],
                               atol=1e-9), (v, g)


@pytest.mark.parametrize("kind", [HomotopyBelief, CirculationBelief])
def test_particles_match_the_exact_marginals(kind):
    """The way particles (the search's root states) are draws of the posterior: their goal and
    exit frequencies match the exact marginals within 5 standard errors (plus 3 draws, for
    the rarest exits); the tree share is
    the route prior's posterior weight; the goal's polytope has no exit (-1)."""
    world = random_world(11)
    rng = np.random.default_rng(4)
    goals = rng.choice(world.n_cells, size=3, replace=False)
    model = ObservationModel.build(world, goals, normalize=True)
    belief = kind(model, int(rng.integers(world.n_cells)))
    for s, h in observations(world, model, rng, 6):
        belief.update(s, h)
    n = 4000
    m_tree, tree_cdf, g, slots = belief.particles(n, np.random.default_rng(1))
    post = belief.component_posterior()
    p_tree = post[:, 0].sum()
    se = np.sqrt(p_tree * (1 - p_tree) / n)
    assert abs(m_tree / n - p_tree) <= 5 * se + 1e-12
    assert np.allclose(np.diff(np.r_[0, tree_cdf]), post[:, 0] / post[:, 0].sum())
    ways = post[:, 1:].sum(axis=1) / post[:, 1:].sum()
    freq = np.bincount(g, minlength=3) / len(g)
    assert np.all(np.abs(freq - ways) <= 5 * np.sqrt(ways * (1 - ways) / len(g)) + 1e-12)
    for gi in range(3):
        mine = slots[g == gi]
        if len(mine) < 200:
            continue
        r = int(belief.goal_polytope[gi])
        assert np.all(mine[:, r] == -1)
        w_post = post[gi, 1:] / post[gi, 1:].sum()
        for v in range(world.n_polytopes):
            deg = len(world.graph.neighbors[v])
            if v == r or deg == 0:
                continue
            exact = sum(w_post[c] * belief.way_given(gi, c, v)
                        for c in range(int(belief.n_ways[gi])))
            got = np.bincount(mine[:, v], minlength=deg) / len(mine)
            tol = 5 * np.sqrt(np.maximum(exact * (1 - exact), 0.0) / len(mine)) + 3.0 / len(mine)
            assert np.all(np.abs(got - exact) <= tol), (gi, v)


def test_the_homotopy_prior_needs_a_start(simple):
    model = ObservationModel.build(simple, np.array([0, 5]), normalize=True)
    with pytest.raises(ConfigError, match="start"):
        HomotopyBelief(model, -1)


def test_a_homotopy_episode_runs_and_replays():
    """One robust episode under the homotopy prior runs end to end and gives the same steps
    when run again (the particles are seeded by the episode)."""
    from pathpref.episode.runner import run_episode
    from pathpref.episode.spec import EpisodeSpec

    spec = EpisodeSpec(map="office", method="path_preference", delta_t=5, instance=0, run=0,
                       preset="robust",
                       prior="homotopy", human="consistent", instance_seed=3, run_seed=4)
    a, b = run_episode(spec), run_episode(spec)
    assert a.steps == b.steps and a.success == b.success
    assert a.steps > 0
