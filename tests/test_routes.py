"""The route prior's posterior is exact: brute force over every preference vector, keeping the
in-arborescences toward the goal's polytope, on the paper's ring and on two small random floor
plans with degrees up to 5; Wilson's sampler against the exact marginals."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from pathpref.geometry.generate import random_floor_plan
from pathpref.geometry.world import load_world
from pathpref.inference import routes
from pathpref.inference.human import ObservationModel, SimulatedHuman
from pathpref.inference.routes import RouteBelief, components


def is_tree(theta, root, neighbors):
    """True when following theta from every polytope reaches ``root`` (no cycle)."""
    P = len(theta)
    for v in range(P):
        u, steps = v, 0
        while u != root:
            u = neighbors[u][theta[u]]
            steps += 1
            if steps > P:
                return False
    return True


def brute(model, observations):
    """``(P(g | o), {v: (G, deg v) P(p_v | g, o)})`` by enumerating every theta."""
    w = model.world
    nbrs = w.graph.neighbors
    P = w.n_polytopes
    G = len(model.goals)
    roots = w.cell_polytope[model.goals]
    thetas = np.array(list(itertools.product(*[range(len(n)) for n in nbrs])))
    loglik = np.zeros((G, len(thetas)))
    for s, h in observations:
        v = w.cell_polytope[s]
        loglik += np.log(model.likelihood[s, h][:, thetas[:, v]])
    goal = np.zeros(G)
    cond = {v: np.zeros((G, len(nbrs[v]))) for v in range(P)}
    for g in range(G):
        r = roots[g]
        # the root has no exit: fix its slot to 0 so each tree is counted once
        keep = np.array([t[r] == 0 and is_tree(t, r, nbrs) for t in thetas])
        n_trees = keep.sum()
        wts = np.exp(loglik[g] - loglik.max()) * keep
        goal[g] = wts.sum() / n_trees
        for v in range(P):
            for k in range(len(nbrs[v])):
                cond[v][g, k] = wts[thetas[:, v] == k].sum()
            if v == r:
                cond[v][g] = 1.0
            cond[v][g] /= cond[v][g].sum()
    return goal / goal.sum(), cond


def random_world(seed: int):
    return load_world(random_floor_plan(7, 6, 1, 1, seed=seed, size_range=(1.0, 2.5)))


def observations(world, model, rng, n, goal=0):
    """``n`` headings of a Boltzmann human (the map's preference where it has one, else a random
    one), at cells along its own path with random jumps."""
    pref = world.preference
    if pref is None:
        pref = np.array([rng.choice(nb) for nb in world.graph.neighbors])
    human = SimulatedHuman(model, goal, pref)
    s = int(rng.integers(world.n_cells))
    out = []
    for _ in range(n):
        h = human.sample(s, rng)
        out.append((s, h))
        s = (int(rng.integers(world.n_cells)) if rng.random() < 0.3
             else int(world.motion.next_cell[s, h]))
    return out


CASES = [("simple", 0), ("simple", 1), ("random11", 0), ("random30", 1)]


@pytest.mark.parametrize("factor", ["dense", "sparse"])
@pytest.mark.parametrize("name,seed", CASES)
def test_route_posterior_equals_brute_force(simple, name, seed, factor, monkeypatch):
    """Both factorisations of the minor (dense LAPACK, SuperLU for big maps) give the brute
    force's posterior."""
    if factor == "sparse":
        monkeypatch.setattr(routes, "DENSE_MAX", 0)
    world = simple if name == "simple" else random_world(int(name[6:]))
    rng = np.random.default_rng(seed)
    goals = rng.choice(world.n_cells, size=4, replace=False)
    model = ObservationModel.build(world, goals, normalize=True)
    obs = observations(world, model, rng, 20)
    # cross one face back and forth: the same observations twice in a row must compound exactly
    obs += obs[-3:]
    belief = RouteBelief(model)
    for s, h in obs:
        belief.update(s, h)
    goal, cond = brute(model, obs)
    assert np.allclose(belief.goal_marginal(), goal, atol=1e-9)
    for v in range(world.n_polytopes):
        deg = len(world.graph.neighbors[v])
        assert np.allclose(belief.preference_given_goal(v)[:, :deg], cond[v], atol=1e-9), v


def test_route_prior_forbids_cycles(simple):
    """Every particle the search draws is a tree toward the goal's polytope: no mutual
    preference, no cycle, no exit at the root; an untouched 8-ring has exactly 8 trees."""
    from pathpref.planning.guided import tree_pool
    from pathpref.planning.pomcp import POMCP
    from pathpref.planning.pomdp import get_preset

    rng = np.random.default_rng(3)
    goals = rng.choice(simple.n_cells, size=4, replace=False)
    model = ObservationModel.build(simple, goals, normalize=True)
    belief = RouteBelief(model)
    assert np.isclose(np.exp(belief._log_trees[0]), simple.n_polytopes)
    planner = POMCP(simple, goals, get_preset("robust").path_preference, tables=model.tables)
    g, slots = tree_pool(planner.nbr, planner.preference_cdf(belief),
                         np.cumsum(belief.goal_marginal()), planner.goal_poly,
                         components(simple.graph.neighbors), 400, 1)
    nbrs = simple.graph.neighbors
    for gi, row in zip(g, slots, strict=True):
        r = belief.goal_polytope[gi]
        assert row[r] == -1
        theta = [0 if v == r else k for v, k in enumerate(row)]
        assert is_tree(theta, r, nbrs)


def test_components_label_islands():
    nbrs = [np.array([1]), np.array([0]), np.array([], dtype=int), np.array([4]), np.array([3])]
    lab = components(nbrs)
    assert lab[0] == lab[1] != lab[2] and lab[3] == lab[4] != lab[0] and lab[2] != lab[3]


def test_search_particles_match_exact_posterior(simple):
    """The robust search's root particles (compiled Wilson, :func:`tree_pool`) are draws from
    the exact route posterior: goal frequencies and every ``p_v`` frequency within 5 standard
    errors of :class:`RouteBelief`'s closed form."""
    from pathpref.planning.guided import tree_pool
    from pathpref.planning.pomcp import POMCP
    from pathpref.planning.pomdp import get_preset

    world = random_world(11)
    rng = np.random.default_rng(2)
    goals = rng.choice(world.n_cells, size=3, replace=False)
    model = ObservationModel.build(world, goals, normalize=True)
    belief = RouteBelief(model)
    for s, h in observations(world, model, rng, 4):  # a few: every goal keeps some weight
        belief.update(s, h)
    planner = POMCP(world, goals, get_preset("robust").path_preference, tables=model.tables)
    cdf = planner.preference_cdf(belief)
    n = 20000
    g, slots = tree_pool(planner.nbr, cdf, np.cumsum(belief.goal_marginal()), planner.goal_poly,
                         components(world.graph.neighbors), n, 7)
    pg = belief.goal_marginal()
    assert np.all(np.abs(np.bincount(g, minlength=len(goals)) / n - pg)
                  <= 5 * np.sqrt(pg * (1 - pg) / n) + 1e-9)
    tested = 0
    for gi in range(len(goals)):
        rows = slots[g == gi]
        if len(rows) < 1000:  # too few draws of this goal for a sharp test
            continue
        tested += 1
        for v in range(world.n_polytopes):
            if v == belief.goal_polytope[gi]:
                assert np.all(rows[:, v] == -1)
                continue
            deg = len(world.graph.neighbors[v])
            freq = np.bincount(rows[:, v], minlength=deg) / len(rows)
            exact = belief.preference_given_goal(v)[gi, :deg]
            se = np.sqrt(exact * (1 - exact) / len(rows))
            assert np.all(np.abs(freq - exact) <= 5 * se + 1e-9), (gi, v)
    assert tested >= 2


def test_prior_in_the_episode_key_and_rows(tmp_path):
    """robust episodes run with the route prior and say so in their key; paper keys are as
    they were; a row stored before the field existed replays with the independent prior,
    also after 'db upgrade'."""
    import shutil
    import sqlite3

    from pathpref.apps.cli import main
    from pathpref.episode import EpisodeSpec
    from pathpref.experiments.store import row_spec

    robust = EpisodeSpec.single("simple", "path_preference", 5, preset="robust")
    paper = EpisodeSpec.single("simple", "path_preference", 5, preset="paper")
    assert robust.prior == "routes" and "prior=routes" in robust.key()
    assert paper.prior == "independent" and "prior" not in paper.key()
    assert robust.planner().prior == "routes"
    old = EpisodeSpec.single("simple", "path_preference", 5, preset="robust", prior="independent")
    assert "prior" not in old.key()
    db = tmp_path / "old.sqlite"
    shutil.copy("tests/data/saved_sweep.sqlite", db)  # schema 3: no prior column
    assert main(["db", "upgrade", str(db)]) == 0
    conn = sqlite3.connect(db)
    conn.row_factory = sqlite3.Row
    rows = [dict(r) for r in conn.execute("SELECT * FROM episodes WHERE preset = 'robust'")]
    conn.close()
    assert rows and all(r["prior"] is None for r in rows)  # added in place, empty
    assert all(row_spec(r).prior == "independent" and row_spec(r).key() == r["key"]
               for r in rows)
    assert row_spec({**rows[0], "prior": None}).prior == "independent"


def test_get_preset_takes_and_checks_the_prior():
    """``prior`` overrides the preset's (None keeps it); an unknown one is a one-line error."""
    from pathpref.errors import ConfigError
    from pathpref.planning.pomdp import get_preset

    assert get_preset("robust").prior == "routes"
    assert get_preset("paper").prior == "independent"
    assert get_preset("robust", prior=None).prior == "routes"
    assert get_preset("paper", prior="routes").prior == "routes"
    assert get_preset("robust", prior="independent").prior == "independent"
    with pytest.raises(ConfigError) as e:
        get_preset("paper", prior="tree")
    assert str(e.value) == "unknown prior 'tree'; choose independent or routes"
