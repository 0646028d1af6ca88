"""The route prior's posterior is exact: brute force over every preference vector, keeping the
in-arborescences toward the goal's polytope, on the paper's ring and on two small random floor
plans with degrees up to 5; Wilson's sampler against the exact marginals."""

from __future__ import annotations

import itertools
import time

import numpy as np
import pytest

from pathpref.geometry.footprint import DEFAULT_FOOTPRINT, POINT_ROBOT
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


def every_theta(model, observations):
    """``(thetas, loglik)``: every preference vector (a slot per polytope) and, per goal, the
    log-likelihood of the observations under it, straight from the model's table."""
    w = model.world
    thetas = np.array(list(itertools.product(*[range(len(n)) for n in w.graph.neighbors])))
    loglik = np.zeros((len(model.goals), len(thetas)))
    for s, h in observations:
        v = w.cell_polytope[s]
        loglik += np.log(model.likelihood[s, h][:, thetas[:, v]])
    return thetas, loglik


def brute(model, observations):
    """``(P(g | o), {v: (G, deg v) P(p_v | g, o)})`` by enumerating every theta."""
    w = model.world
    nbrs = w.graph.neighbors
    P = w.n_polytopes
    G = len(model.goals)
    roots = w.cell_polytope[model.goals]
    thetas, loglik = every_theta(model, observations)
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


def random_world(seed: int, footprint=POINT_ROBOT):
    """A 7 x 6 plan with a rotated rectangle and a box; for a point robot by default (the
    graphs these cases were written for)."""
    return load_world(random_floor_plan(7, 6, 1, 1, seed=seed, size_range=(1.0, 2.5)),
                      footprint=footprint)


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


@pytest.mark.parametrize("factor", ["dense", "sparse", "lean"])
@pytest.mark.parametrize("name,seed", CASES)
def test_route_posterior_equals_brute_force(simple, name, seed, factor, monkeypatch):
    """Both factorisations of the minor (dense LAPACK, SuperLU for big maps) give the brute
    force's posterior, and so do lean splits (first-entry rows held at the heads only, as on
    maps of more than :data:`routes.LEAN_ROWS` polytopes)."""
    if factor == "sparse":
        monkeypatch.setattr(routes, "DENSE_MAX", 0)
    if factor == "lean":
        monkeypatch.setattr(routes, "LEAN_ROWS", 0)
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


@pytest.mark.parametrize("factor", ["dense", "sparse"])
def test_route_posterior_next_to_a_dead_end_pocket(factor, monkeypatch):
    """Found when the robot's footprint removed the move edge (1, 5) of ``random30``'s graph
    (16 edges left): polytope 1 became a leaf behind 2, a pocket the walk from 2 leaves only
    back to 5. Before :func:`routes._support`, the first-entry rows that a rank-one update
    (:meth:`_Split.extend`) gave the pocket kept about 3e-16 of rounding in the wrong
    columns, which the chain read as an exit beside a true escape probability of about 8e-9:
    queried after every heading, the goal marginal left the enumeration from the 12th heading
    on (1e-8) and was off by 1e-3 after 21. Now it agrees to 1e-9 throughout."""
    if factor == "sparse":
        monkeypatch.setattr(routes, "DENSE_MAX", 0)
    world = random_world(30, footprint=DEFAULT_FOOTPRINT)
    rng = np.random.default_rng(1)
    goals = rng.choice(world.n_cells, size=4, replace=False)
    model = ObservationModel.build(world, goals, normalize=True)
    obs = observations(world, model, rng, 20)
    obs += obs[-3:]
    belief = RouteBelief(model)
    worst = 0.0
    for k, (s, h) in enumerate(obs):
        belief.update(s, h)
        goal, _ = brute(model, obs[: k + 1])
        worst = max(worst, float(np.abs(belief.goal_marginal() - goal).max()))
    assert worst < 1e-9


def test_unobserved_components_partition_as_scipys():
    """:func:`routes._u_components` (union-find; SciPy's graph was most of a decision's
    :func:`routes._support` on a 40 x 40 plan) splits the polytopes exactly as SciPy's
    ``connected_components`` of the slots with both ends in the set, on 200 random graphs and
    sets, a polytope outside the set alone."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    rng = np.random.default_rng(5)
    for _ in range(200):
        n = int(rng.integers(1, 60))
        e = int(rng.integers(0, 3 * n))
        a, b = rng.integers(0, n, e), rng.integers(0, n, e)
        src, dst = np.concatenate([a, b]), np.concatenate([b, a])  # slots both ways
        in_u = rng.random(n) < rng.random()
        both = in_u[src] & in_u[dst]
        g = sp.csr_matrix((np.ones(int(both.sum())), (src[both], dst[both])), shape=(n, n))
        want = connected_components(g, directed=False)[1]
        got = routes._u_components(src.astype(np.int64), dst.astype(np.int64), in_u)
        # the same partition: labels map one to one
        pairs = set(zip(got.tolist(), want.tolist()))
        assert len(pairs) == len(set(got.tolist())) == len(set(want.tolist()))


def test_first_entry_support_by_hand():
    """:func:`routes._entry_allowed`: a head may first enter state ``c`` exactly when some
    slot leads from its component of the unobserved set into a polytope of state ``c``
    (components by SciPy's ``connected_components``, the pairs by a set), on 200 random
    graphs, sets and states."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    rng = np.random.default_rng(7)
    for _ in range(200):
        n = int(rng.integers(2, 50))
        e = int(rng.integers(1, 3 * n))
        a, b = rng.integers(0, n, e), rng.integers(0, n, e)
        src, dst = np.concatenate([a, b]), np.concatenate([b, a])
        m = int(rng.integers(1, 6))
        state = np.where(rng.random(n) < 0.3, rng.integers(0, m, n), -1)
        in_u = (state < 0) & (rng.random(n) < 0.9)
        both = in_u[src] & in_u[dst]
        g = sp.csr_matrix((np.ones(int(both.sum())), (src[both], dst[both])), shape=(n, n))
        comp = connected_components(g, directed=False)[1]
        pairs = {(comp[x], state[y]) for x, y in zip(src.tolist(), dst.tolist())
                 if in_u[x] and state[y] >= 0}
        heads = rng.integers(0, n, int(rng.integers(1, 8)))
        want = np.array([[(comp[h], c) in pairs and bool(in_u[h]) for c in range(m)]
                         for h in heads.tolist()])
        got = routes._entry_allowed(src.astype(np.int64), dst.astype(np.int64), in_u,
                                    state.astype(np.int64), heads.astype(np.int64), m)
        assert np.array_equal(got, want)


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
                         components(simple.graph.neighbors), 400, 1, 10**9)[:2]
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
                         components(world.graph.neighbors), n, 7, 10**9)[:2]
    assert _assert_draws_match(world, belief, g, slots) >= 2


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
    assert str(e.value) == ("unknown prior 'tree'; choose independent, routes, learned-gamma, "
                            "homotopy or circulation")


def _draw_all_observed_first(planner, belief, n, seed, budget=10**6):
    """``n`` trees all drawn by the fallback (observed exits first, then Wilson, its walk
    stage given ``budget`` steps at first): budget 0 in the first sampler."""
    from pathpref.planning.guided import tree_pool

    cdf = planner.preference_cdf(belief)
    g, slots, over = tree_pool(planner.nbr, cdf, np.cumsum(belief.goal_marginal()),
                               planner.goal_poly, planner.component, n, seed, 0)
    assert over.all()  # budget 0: every tree goes to the fallback
    slots[over] = planner._observed_first(belief, g[over], cdf, seed, budget)
    return g, slots


def _assert_draws_match(world, belief, g, slots, min_draws=1000):
    n = len(g)
    pg = belief.goal_marginal()
    assert np.all(np.abs(np.bincount(g, minlength=len(pg)) / n - pg)
                  <= 5 * np.sqrt(pg * (1 - pg) / n) + 1e-9)
    tested = 0
    for gi in range(len(pg)):
        rows = slots[g == gi]
        if len(rows) < min_draws:
            continue
        tested += 1
        nbrs = world.graph.neighbors
        r = belief.goal_polytope[gi]
        for row in rows[:200]:  # every draw is a tree toward r
            assert row[r] == -1 and is_tree([0 if v == r else k for v, k in enumerate(row)],
                                            r, nbrs)
        for v in range(world.n_polytopes):
            if v == r:
                continue
            deg = len(nbrs[v])
            freq = np.bincount(rows[:, v], minlength=deg) / len(rows)
            exact = belief.preference_given_goal(v)[gi, :deg]
            se = np.sqrt(exact * (1 - exact) / len(rows))
            assert np.all(np.abs(freq - exact) <= 5 * se + 1e-9), (gi, v)
    return tested


def _observed_plan():
    """A random floor plan (seed 11), 3 goal candidates and a route belief after 12 pushes,
    with a robust planner on it: the fallback sampler's test case."""
    from pathpref.planning.pomcp import POMCP
    from pathpref.planning.pomdp import get_preset

    world = random_world(11)
    rng = np.random.default_rng(5)
    goals = rng.choice(world.n_cells, size=3, replace=False)
    model = ObservationModel.build(world, goals, normalize=True)
    belief = RouteBelief(model)
    for s, h in observations(world, model, rng, 12):
        belief.update(s, h)
    planner = POMCP(world, goals, get_preset("robust").path_preference, tables=model.tables)
    return world, belief, planner


def test_observed_first_trees_match_exact_posterior():
    """The fallback sampler (the observed polytopes' exits drawn jointly from their exact
    conditionals, then Wilson's walk over the rest) draws from the exact route posterior, on a
    random floor plan with many observed polytopes (every tree forced through it)."""
    world, belief, planner = _observed_plan()
    assert len(belief.observed_polytopes()) >= 4
    g, slots = _draw_all_observed_first(planner, belief, 20000, 3)
    assert _assert_draws_match(world, belief, g, slots) >= 1


def test_doubled_walk_budgets_keep_the_draws_exact():
    """A walk stage that passes its budget is drawn again with twice the budget. Started at a
    quarter of the polytopes (fewer steps than a tree has edges: the first stages always
    fail), every tree is still drawn and the draws still follow the exact route posterior:
    which stage is kept depends only on its number of steps, independent of its tree."""
    world, belief, planner = _observed_plan()
    unobserved = world.n_polytopes - len(belief.observed_polytopes())
    g, slots = _draw_all_observed_first(planner, belief, 20000, 7,
                                        budget=max(1, world.n_polytopes // 4))
    assert world.n_polytopes // 4 < unobserved - 1  # the first stage cannot finish a tree
    assert _assert_draws_match(world, belief, g, slots) >= 1


def _mutual(world, goals, n_rounds, ratio=0.05):
    """A route belief holding ``n_rounds`` rounds of evidence that polytopes ``a = 0`` and its
    first neighbour ``b`` point at each other (each round multiplies every other exit's weight
    by ``ratio``), with the factors it applied."""
    nbrs = world.graph.neighbors
    a, b = 0, int(nbrs[0][0])
    model = ObservationModel.build(world, goals, normalize=True)
    belief = RouteBelief(model)
    G = len(goals)
    step, log_factors = {}, {}
    for v, u in ((a, b), (b, a)):
        f = np.full((G, len(nbrs[v])), ratio)
        f[:, int(np.flatnonzero(nbrs[v] == u)[0])] = 1.0
        step[v] = f
        log_factors[v] = n_rounds * np.log(f)
    for _ in range(n_rounds):
        for v in (a, b):
            belief._multiply(v, step[v])
    return model, belief, log_factors, (a, b)


def _brute_tables(world, goals, log_factors):
    """``(P(g | o), {v: P(p_v | g, o)})`` by enumeration from per-polytope log weight tables
    (the evidence is far below the smallest double)."""
    nbrs = world.graph.neighbors
    thetas = np.array(list(itertools.product(*[range(len(n)) for n in nbrs])))
    roots = world.cell_polytope[goals]
    G = len(goals)
    logw = np.zeros((G, len(thetas)))
    for v, lf in log_factors.items():
        logw += lf[:, thetas[:, v]]
    goal = np.full(G, -np.inf)
    cond = {}
    for g in range(G):
        keep = np.array([t[roots[g]] == 0 and is_tree(t, roots[g], nbrs) for t in thetas])
        lw = np.where(keep, logw[g], -np.inf)
        goal[g] = np.logaddexp.reduce(lw) - np.log(keep.sum())
        w = np.exp(lw - lw.max())
        for v in range(len(nbrs)):
            c = np.array([w[thetas[:, v] == k].sum() for k in range(len(nbrs[v]))])
            if v == roots[g]:  # no exit at the goal: shown as uniform
                c[:] = 1.0
            cond.setdefault(v, np.zeros((G, len(nbrs[v]))))[g] = c / c.sum()
    return np.exp(goal - np.logaddexp.reduce(goal)), cond


@pytest.mark.parametrize("rounds", [1, 8, 40, 400])
def test_mutual_evidence_stays_exact(simple, rounds):
    """Two neighbouring polytopes pointing at each other, up to ``0.05^400`` (far below the
    smallest double): the goal marginal and every preference marginal equal a log-space
    brute force (the LU of the minor returned 0/0 there), and stay finite."""
    a, b = 0, int(simple.graph.neighbors[0][0])
    free = np.flatnonzero(~np.isin(simple.cell_polytope, [a, b]))
    goals = np.random.default_rng(1).choice(free, size=4, replace=False)
    _, belief, factors, _ = _mutual(simple, goals, rounds)
    goal, cond = _brute_tables(simple, goals, factors)
    assert np.allclose(belief.goal_marginal(), goal, atol=1e-9)
    for v in range(simple.n_polytopes):
        deg = len(simple.graph.neighbors[v])
        got = belief.preference_given_goal(v)[:, :deg]
        assert np.isfinite(got).all() and np.allclose(got, cond[v], atol=1e-9), v
        assert np.isfinite(belief.joint_entropy(v))


def test_mutual_evidence_decision_is_bounded(simple):
    """The state that made Wilson's walk run for 1e14+ steps: a decision of the robust search
    finishes (every tree's walk passes its budget and is drawn observed exits first), in a
    CPU time far below the 30 minutes it took (generous bound: compilation included), and its
    particles still follow the exact posterior."""
    import time

    from pathpref.planning.guided import tree_pool
    from pathpref.planning.pomcp import POMCP, WALK_STEPS_MIN, WALK_STEPS_PER_POLYTOPE
    from pathpref.planning.pomdp import get_preset

    a, b = 0, int(simple.graph.neighbors[0][0])
    free = np.flatnonzero(~np.isin(simple.cell_polytope, [a, b]))
    goals = np.random.default_rng(2).choice(free, size=9, replace=False)
    model, belief, _, _ = _mutual(simple, goals, 60)
    planner = POMCP(simple, goals, get_preset("robust").path_preference, tables=model.tables)
    cdf = planner.preference_cdf(belief)
    budget = WALK_STEPS_PER_POLYTOPE * simple.n_polytopes + WALK_STEPS_MIN
    _, _, over = tree_pool(planner.nbr, cdf, np.cumsum(belief.goal_marginal()),
                           planner.goal_poly, planner.component, 64, 1, budget)
    assert over.all()  # the trap is real: no walk escapes within its budget
    t0 = time.process_time()
    cell = int(np.flatnonzero(simple.cell_polytope == a)[0])
    for seed in range(3):
        res = planner.search(cell, belief, 30, seed)
        assert 0 <= res.action < 8
    assert time.process_time() - t0 < 60.0
    g, slots = _draw_all_observed_first(planner, belief, 8000, 4)
    assert _assert_draws_match(simple, belief, g, slots, min_draws=600) >= 2


def test_ping_pong_pushes_keep_decisions_bounded(simple):
    """Pushes back and forth across one face (8 each way, as a person correcting a robot that
    keeps crossing), through the human model's own likelihoods: the marginals stay finite and
    normalised, and each decision's pool and search finish."""
    import time

    from pathpref.planning.pomcp import POMCP
    from pathpref.planning.pomdp import get_preset

    nbrs = simple.graph.neighbors
    a, b = 0, int(nbrs[0][0])
    free = np.flatnonzero(~np.isin(simple.cell_polytope, [a, b]))
    goals = np.random.default_rng(3).choice(free, size=9, replace=False)
    model = ObservationModel.build(simple, goals, normalize=True)
    belief = RouteBelief(model)
    planner = POMCP(simple, goals, get_preset("robust").path_preference, tables=model.tables)
    moves = simple.motion.next_cell
    # a cell of a with a move into b (and back): the headings that cross the face
    pairs = [(s, h) for s in np.flatnonzero(simple.cell_polytope == a) for h in range(8)
             if simple.cell_polytope[moves[s, h]] == b]
    s_a, h_ab = pairs[0]
    s_b = int(moves[s_a, h_ab])
    h_ba = next(h for h in range(8) if moves[s_b, h] == s_a)
    t0 = time.process_time()
    for i in range(8):
        belief.update(int(s_a), int(h_ab))
        belief.update(s_b, h_ba)
        pg = belief.goal_marginal()
        assert np.isfinite(pg).all() and np.isclose(pg.sum(), 1.0)
        for v in (a, b):
            p = belief.preference_given_goal(v)
            assert np.isfinite(p).all() and np.allclose(p.sum(axis=1), 1.0)
        planner.search(s_b, belief, 30, i)
    assert time.process_time() - t0 < 60.0


def _leads_to_root(nbr, row, root):
    """Every polytope of ``root``'s component reaches ``root`` by following ``row``'s exits."""
    from pathpref.inference.routes import components
    comp = components([n[n >= 0] for n in nbr])
    for v in np.flatnonzero(comp == comp[root]):
        u, hops = int(v), 0
        while u != root:
            assert row[u] >= 0 and hops <= len(nbr), (v, u)
            u, hops = int(nbr[u, row[u]]), hops + 1
    return True


def test_observed_first_walk_stage_never_errors(simple):
    """The fallback's walk over the unobserved polytopes is bounded, and where it cannot finish
    the decision still has its trees: with no step allowed (a budget of 0 doubles to 0, the
    worst case) every tree is completed (:func:`~pathpref.planning.guided.complete_tree`): the
    observed exits as drawn, every polytope of the goal's component leading to its polytope,
    counted in ``completed_trees``; no error, no loop."""
    from pathpref.planning.pomcp import POMCP
    from pathpref.planning.pomdp import get_preset

    goals = np.array([simple.cell((9, 9)), simple.cell((1, 8))])
    model = ObservationModel.build(simple, goals, normalize=True)
    belief = RouteBelief(model)
    for xy, h in (((4, 2), 0), ((2, 7), 1), ((8, 2), 1)):
        belief.update(simple.cell(xy), h)
    planner = POMCP(simple, goals, get_preset("robust").path_preference, tables=model.tables)
    g = np.array([0, 1, 0, 1])
    slots = planner._observed_first(belief, g, planner.preference_cdf(belief), 0, 0)
    assert planner.completed_trees == 4
    for j in range(4):
        assert _leads_to_root(planner.nbr, slots[j], int(planner.goal_poly[g[j]]))


def test_completed_tree_keeps_set_exits_on_a_large_plan():
    """On a 40 x 40 plan (1046 polytopes) a completion keeps every exit set before it (those
    that leave room for a tree) and leads every polytope to the root, in well under a second."""
    from pathpref.geometry.generate import floor_plan
    from pathpref.geometry.world import load_world
    from pathpref.planning.guided import complete_tree

    w = load_world(floor_plan(5001, "open", width=40, height=40, rotated=32))
    nbr = w.graph.neighbor_table().astype(np.int64)
    P = len(nbr)
    assert P > 1000
    rng = np.random.default_rng(0)
    root = int(rng.integers(P))
    base = complete_tree(nbr, np.full(P, -2), root)  # a tree: its exits may all be set
    assert _leads_to_root(nbr, base, root)
    row = np.full(P, -2)
    keep = rng.choice(np.flatnonzero(base >= 0), P // 3, replace=False)
    row[keep] = base[keep]
    t0 = time.process_time()
    out = complete_tree(nbr, row, root)
    assert time.process_time() - t0 < 1.0
    np.testing.assert_array_equal(out[keep], base[keep])
    assert _leads_to_root(nbr, out, root)


def _fresh(model, pushes):
    """A belief holding ``pushes`` whose unobserved blocks are all factorised afresh."""
    belief = RouteBelief(model)
    for s, h in pushes:
        belief.update(s, h)
    belief._last_split.clear()  # no split to extend from: every (r, S) is factorised
    return belief


@pytest.mark.parametrize("factor,limit", [("dense", "count"), ("sparse", "count"),
                                          ("sparse", "bytes")])
def test_updated_posterior_equals_fresh_factorisation(factor, limit, monkeypatch):
    """80 pushes, one at a time, on a 104-polytope floor plan: the posterior reached by
    rank-one updates of the unobserved block (:meth:`routes._Split.extend`, refactorised
    every 7 removals here to cross several factors, or every 5 by the byte bound
    :data:`routes.BLOCK_BYTES` of a large map's blocks) equals a fresh factorisation of every
    block, goal marginal and every preference marginal (observed and unobserved polytopes)
    within 1e-9 absolute (probabilities; measured differences <= 2e-14), and so do the chain's
    first-entry distributions and ``log det L_UU``. The belief holds one split per goal
    polytope, and no block more removals than its bound (:func:`routes._refactor_after`)."""
    if factor == "sparse":
        monkeypatch.setattr(routes, "DENSE_MAX", 0)
    bound = 5  # columns of the largest block (103 rows) under the byte bound
    if limit == "count":
        monkeypatch.setattr(routes, "REFACTOR_AFTER", 7)
    else:
        monkeypatch.setattr(routes, "BLOCK_BYTES", 8 * 103 * bound + 7)
    world = load_world(random_floor_plan(20, 16, 3, 6, seed=4, size_range=(1.5, 4.0)))
    assert world.n_polytopes == 104
    rng = np.random.default_rng(5)
    goals = rng.choice(world.n_cells, size=4, replace=False)
    model = ObservationModel.build(world, goals, normalize=True)
    belief = RouteBelief(model)
    pushes = []
    for i in range(80):
        s, h = int(rng.integers(world.n_cells)), int(rng.integers(8))
        pushes.append((s, h))
        belief.update(s, h)
        belief.goal_marginal()  # one polytope more per split (when the push is in a new one)
        if i % 20 != 19:
            continue
        fresh = _fresh(model, pushes)
        assert np.allclose(belief.goal_marginal(), fresh.goal_marginal(), rtol=0, atol=1e-9)
        for g in range(len(goals)):
            a, b = belief.observed_chain(g), fresh.observed_chain(g)
            assert a.states == b.states
            assert np.allclose(a.heads, b.heads, rtol=0, atol=1e-9)
            assert np.isclose(a.split.logdet_u, b.split.logdet_u, rtol=1e-10)
        for v in range(world.n_polytopes):
            assert np.allclose(belief.preference_given_goal(v), fresh.preference_given_goal(v),
                               rtol=0, atol=1e-9), (i, v)
        assert len(belief._splits) == len(belief._minors)
        assert all(len(sp_.block.removed) <= routes._refactor_after(sp_.block.n0)
                   for sp_ in belief._splits.values())
    # the updates did run: 30+ polytopes observed, blocks from several factors
    assert len(belief.observed_polytopes()) >= 30
    assert any(len(sp_.block.removed) for sp_ in belief._last_split.values())
    if limit == "bytes":  # fewer than 64 observed: only the byte bound refactorised
        assert len(belief.observed_polytopes()) < 64
        assert max(sp_.block.n0 for sp_ in belief._last_split.values()) <= 103 - bound


@pytest.mark.parametrize("factor", ["dense", "sparse"])
def test_lean_splits_equal_dense_ones(factor, monkeypatch):
    """A lean split (:data:`routes.LEAN_ROWS` 0 here: every split) holds ``H`` only at the
    unobserved heads of its observed polytopes' slots, computing a head's row it did not
    hold from one more solve (``H(u, .) = (L_UU^-1 e_u)^T B``). Over 60 pushes on a
    104-polytope floor plan (refactorised every 7 removals, so lean rows come both from
    factorisations and from rank-one updates) its goal marginal, chain heads, ``log det
    L_UU`` and every preference marginal (observed and unobserved polytopes) equal the dense
    splits' within 1e-9 absolute, and it holds no row that no head reads."""
    if factor == "sparse":
        monkeypatch.setattr(routes, "DENSE_MAX", 0)
    monkeypatch.setattr(routes, "REFACTOR_AFTER", 7)
    world = load_world(random_floor_plan(20, 16, 3, 6, seed=4, size_range=(1.5, 4.0)))
    rng = np.random.default_rng(8)
    goals = rng.choice(world.n_cells, size=4, replace=False)
    model = ObservationModel.build(world, goals, normalize=True)
    beliefs = {"lean": RouteBelief(model), "dense": RouteBelief(model)}
    rows = {"lean": 0, "dense": 10**9}

    def each(fn):
        out = {}
        for name, b in beliefs.items():
            monkeypatch.setattr(routes, "LEAN_ROWS", rows[name])
            out[name] = fn(b)
        return out["lean"], out["dense"]

    nbrs = world.graph.neighbors
    for i in range(60):
        s, h = int(rng.integers(world.n_cells)), int(rng.integers(8))
        each(lambda b, s=s, h=h: b.update(s, h))
        lean, dense = each(lambda b: b.goal_marginal())
        assert np.allclose(lean, dense, rtol=0, atol=1e-9)
        if i % 15 != 14:
            continue
        for g in range(len(goals)):
            a, b = each(lambda bel, g=g: bel.observed_chain(g))
            assert a.states == b.states
            assert np.allclose(a.heads, b.heads, rtol=0, atol=1e-9)
            assert np.isclose(a.split.logdet_u, b.split.logdet_u, rtol=1e-10)
            assert a.split.lean and not b.split.lean
            held = np.flatnonzero(a.split.hcol >= 0)
            assert np.array_equal(held, routes._Split._kept(a.states, nbrs, a.split.u_index))
            assert a.split.Ht.shape == (len(a.states) + 1, len(held))
        for v in range(world.n_polytopes):
            a, b = each(lambda bel, v=v: bel.preference_given_goal(v))
            assert np.allclose(a, b, rtol=0, atol=1e-9), (i, v)
    assert any(len(sp_.block.removed) for sp_ in beliefs["lean"]._last_split.values())


def test_refactor_bound_by_count_and_bytes(monkeypatch):
    """:func:`routes._refactor_after`: ``REFACTOR_AFTER`` (64) removals up to 32,768 rows at
    the default 16 MiB, then as many columns of ``8 n0`` bytes as fit (14 at the 500 x 500
    map's 144,700 rows), never fewer than 4."""
    assert [routes._refactor_after(n) for n in (1, 8452, 32768, 32769, 144700, 10**7)] == \
        [64, 64, 64, 63, 14, 4]
    monkeypatch.setattr(routes, "REFACTOR_AFTER", 7)
    assert routes._refactor_after(100) == 7


def test_block_without_rows_inverts_the_principal_submatrix():
    """:class:`routes._Block`: after removing rows one at a time, and from a block that is not
    the last of its shared buffer (a fork), a column of the block's inverse equals the column
    of the inverted principal submatrix (numpy's inverse, 1e-12 relative)."""
    rng = np.random.default_rng(0)
    n = 12
    adj = np.triu(rng.random((n, n)) < 0.4, 1)
    adj = (adj | adj.T).astype(float)
    A = np.diag(adj.sum(axis=1) + 1.0) - adj  # a symmetric M-matrix (one exit per row)
    blk = routes._Block(routes._DenseLU(A), n)

    def check(b, keep):
        inv = np.linalg.inv(A[np.ix_(keep, keep)])
        for j, i in enumerate(keep):
            col, _ = b.column(i)
            assert np.allclose(col[keep], inv[:, j], rtol=1e-12, atol=1e-14)

    b1 = blk.without(3, blk.column(3)[1])
    b2 = b1.without(7, b1.column(7)[1])
    fork = b1.without(0, b1.column(0)[1])  # b1 is no longer its buffer's last: a copy
    check(b2, [i for i in range(n) if i not in (3, 7)])
    check(fork, [i for i in range(n) if i not in (3, 0)])
    check(b1, [i for i in range(n) if i != 3])


def test_block_buffer_grows_and_keeps_earlier_blocks_exact():
    """:class:`routes._Block`'s removal buffer starts at 4 columns and doubles: a chain of 9
    removals crosses two copies (capacity 4 -> 8 -> 16), and every block of the chain, the
    early ones included (their columns live in the older buffers), still inverts its principal
    submatrix (numpy, 1e-12 relative); the capacity is the doubling's, not REFACTOR_AFTER."""
    rng = np.random.default_rng(1)
    n = 20
    adj = np.triu(rng.random((n, n)) < 0.3, 1)
    adj = (adj | adj.T).astype(float)
    A = np.diag(adj.sum(axis=1) + 1.0) - adj
    chain = [routes._Block(routes._DenseLU(A), n)]
    order = rng.permutation(n)[:9].tolist()
    for i in order:
        chain.append(chain[-1].without(i, chain[-1].column(i)[1]))
    assert [b.cols[0].shape[1] for b in chain[1:]] == [4] * 4 + [8] * 4 + [16]
    for m, b in enumerate(chain):
        keep = [i for i in range(n) if i not in order[:m]]
        inv = np.linalg.inv(A[np.ix_(keep, keep)])
        for j, i in enumerate(keep):
            assert np.allclose(b.column(i)[0][keep], inv[:, j], rtol=1e-12, atol=1e-14)


def test_goal_minors_share_their_components_slots():
    """The goals' minors of one component hold one copy of its slot arrays (the root's own
    slots included), and each minor still numbers the component without its root: on a map
    with islands, one ``src`` per component among the goal polytopes."""
    world = random_world(30)
    label = components(world.graph.neighbors)
    goals = np.arange(world.n_cells)[:: max(1, world.n_cells // 12)]
    belief = RouteBelief(ObservationModel.build(world, goals, normalize=True))
    roots = {int(r) for r in belief.goal_polytope}
    assert len(roots) >= 3
    assert len({id(m.src) for m in belief._minors.values()}) == len({int(label[r]) for r in roots})
    for r, m in belief._minors.items():
        members = np.flatnonzero(label == label[r])
        assert m.n == len(members) - 1 and m.index[r] == -1
        assert sorted(set(m.src.tolist())) == members.tolist()


def _laplacian_minor(rng, side: int):
    """A grid graph's Laplacian (unit weights, 4-neighbours, random extra diagonals) without
    node 0's row and column: a symmetric M-matrix, as :class:`routes._Split` factorises."""
    import scipy.sparse as sp

    idx = np.arange(side * side).reshape(side, side)
    e = np.concatenate([np.c_[idx[:, :-1].ravel(), idx[:, 1:].ravel()],
                        np.c_[idx[:-1].ravel(), idx[1:].ravel()]])
    diag_e = np.c_[idx[:-1, :-1].ravel(), idx[1:, 1:].ravel()]
    e = np.concatenate([e, diag_e[rng.random(len(diag_e)) < 0.3]])
    N = side * side
    W = sp.coo_matrix((np.ones(2 * len(e)), (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])),
                      shape=(N, N)).tocsr()
    L = (sp.diags(np.asarray(W.sum(axis=1)).ravel()) - W).tocsr()
    return L[1:, 1:].tocoo()


def test_sparse_factor_is_l_and_pivots_and_solves_exactly():
    """The sparse factor of a minor (:func:`routes._factor` above DENSE_MAX) keeps only the
    unit lower triangle ``L`` (as many values as SuperLU's ``L``) and the pivots: ``log det``
    equals numpy's ``slogdet`` (1e-12 relative), and solves with one and with several
    right-hand sides equal numpy's dense solve (1e-10 relative to the solution's largest
    entry; a 900-row grid minor)."""
    from scipy.sparse.linalg import splu

    rng = np.random.default_rng(2)
    A = _laplacian_minor(rng, 30)
    n = A.shape[0]
    assert n > routes.DENSE_MAX
    logdet, f = routes._factor(n, A.row, A.col, A.data)
    assert isinstance(f, routes._SparseLDL)
    slu = splu(A.tocsc(), permc_spec="MMD_AT_PLUS_A",
               options={"SymmetricMode": True, "DiagPivotThresh": 0.0})
    assert len(f.val) == slu.L.nnz and f.perm.tolist() == slu.perm_c.tolist()
    dense = A.toarray()
    sign, want = np.linalg.slogdet(dense)
    assert sign == 1 and np.isclose(logdet, want, rtol=1e-12, atol=0)
    b1 = np.zeros(n)
    b1[rng.integers(n)] = 1.0
    B = rng.random((n, 3))
    for b in (b1, B):
        x, ref = f.solve(b), np.linalg.solve(dense, b)
        assert x.shape == b.shape
        assert np.allclose(x, ref, rtol=0, atol=1e-10 * np.abs(ref).max())


def test_sparse_factor_keeps_superlu_when_it_pivots_off_the_diagonal():
    """A zero on the diagonal makes SuperLU pivot off it (``perm_r != perm_c``): the factor is
    then SuperLU's own, and it solves the system (1e-12)."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import splu

    A = np.array([[0.0, 2.0, 0.0], [2.0, 1.0, 1.0], [0.0, 1.0, 3.0]])
    slu = splu(sp.csc_matrix(A), permc_spec="MMD_AT_PLUS_A",
               options={"SymmetricMode": True, "DiagPivotThresh": 0.0})
    f, d = routes._SparseLDL.of(slu)
    assert f is slu and not np.array_equal(slu.perm_r, slu.perm_c)
    assert np.isclose(abs(np.prod(d)), abs(np.linalg.det(A)), rtol=1e-12)
    b = np.array([1.0, -2.0, 0.5])
    assert np.allclose(f.solve(b), np.linalg.solve(A, b), rtol=1e-12, atol=1e-12)


def test_kept_pool_rows_compare_as_the_whole_walk_table(simple):
    """The root pool is kept with the walk rows of the polytopes observed when it was drawn
    only (:meth:`POMCP._same_rows`); the comparison agrees with ``np.array_equal`` of the
    whole ``(G, P, K)`` table in every case (every row of a polytope not observed is the
    uniform one, :meth:`POMCP.preference_cdf`): unchanged; an observed row changed; a polytope
    observed then and not now; a newly observed polytope whose rows are still uniform (equal
    tables: reuse) or not."""
    from pathpref.planning.pomcp import POMCP
    from pathpref.planning.pomdp import get_preset

    goals = np.random.default_rng(4).choice(simple.n_cells, size=5, replace=False)
    model = ObservationModel.build(simple, goals, normalize=True)
    belief = RouteBelief(model)
    planner = POMCP(simple, goals, get_preset("robust").path_preference, queries=100,
                    tables=model.tables)
    for s, h in ((0, 2), (17, 5)):
        belief.update(s, h)
    observed = np.asarray(belief.observed_polytopes(), dtype=np.int64)
    cdf = planner.preference_cdf(belief)
    kept_rows = cdf[:, observed].copy()
    others = [v for v in range(simple.n_polytopes) if v not in observed.tolist()]
    cases = [(cdf.copy(), observed)]
    changed = cdf.copy()
    changed[1, observed[0], 0] *= 0.5
    cases.append((changed, observed))
    changed = cdf.copy()  # observed then, not now: its rows back to uniform
    changed[:, observed[0]] = planner._uniform_cdf[observed[0]]
    cases.append((changed, observed[1:]))
    cases.append((cdf.copy(), np.sort(np.r_[observed, others[1]])))  # uniform rows: equal
    changed = cdf.copy()
    changed[2, others[1], 0] *= 0.5
    cases.append((changed, np.sort(np.r_[observed, others[1]])))
    got = [planner._same_rows(observed, kept_rows, obs, c) for c, obs in cases]
    assert got == [np.array_equal(cdf, c) for c, _ in cases] == [True, False, False, True,
                                                                  False]


def test_root_pool_is_reused_while_the_belief_is_unchanged(simple):
    """The robust search draws its root particles again only when the goal marginal or a walk
    row has changed: two decisions with no push in between share one pool; a push, or a
    candidate ruled out, draws a new one. Pool size ``ceil(queries / 32)`` up to 128."""
    from pathpref.planning.pomcp import POMCP
    from pathpref.planning.pomdp import get_preset

    goals = np.random.default_rng(4).choice(simple.n_cells, size=5, replace=False)
    model = ObservationModel.build(simple, goals, normalize=True)
    belief = RouteBelief(model)
    robust = get_preset("robust").path_preference
    assert [POMCP(simple, goals, robust, queries=q, tables=model.tables).pool_size()
            for q in (5000, 4096, 4095, 1000, 33, 1)] == [128, 128, 128, 32, 2, 1]
    planner = POMCP(simple, goals, robust, queries=500, tables=model.tables)
    start = int(np.flatnonzero(~np.isin(np.arange(simple.n_cells), goals))[0])
    pool = []
    real = planner._pool

    def spy(*a):
        out = real(*a)
        pool.append(out)
        return out

    planner._pool = spy
    planner.search(start, belief, 30, 0)
    planner.search(start, belief, 30, 1)
    assert planner.pools_drawn == 1 and pool[1][1] is pool[0][1] and len(pool[0][0]) == 16
    belief.update(start, 2)
    planner.search(start, belief, 30, 2)
    assert planner.pools_drawn == 2
    planner.search(start, belief, 30, 3)
    assert planner.pools_drawn == 2
    belief.rule_out(1)
    planner.search(start, belief, 30, 4)
    assert planner.pools_drawn == 3 and not np.any(pool[-1][0] == 1)


def test_root_pool_shrinks_on_large_plans_only():
    """``min(128, ceil(queries / 32), max(32, ceil(33440 / P)))`` on a plan of ``P``
    polytopes: the paper's maps keep 128 at 5000 queries; a 40 x 40 plan with 32 rotated
    obstacles (1045 polytopes) gets 32; 469 polytopes get ceil(33440 / 469) = 72."""
    from pathpref.geometry.generate import with_loop_preference
    from pathpref.geometry.maps import load_map
    from pathpref.geometry.world import World
    from pathpref.planning.pomcp import POMCP
    from pathpref.planning.pomdp import get_preset

    robust = get_preset("robust").path_preference
    sizes = {}
    for name, spec in (("classroom", "classroom"),
                       ("r32", with_loop_preference(random_floor_plan(32, 32, 16, seed=1))),
                       ("r40", with_loop_preference(random_floor_plan(40, 40, 32, seed=1)))):
        world = World.from_spec(load_map(spec))
        goals = np.arange(0, world.n_cells, max(1, world.n_cells // 5))[:5]
        tables = ObservationModel.build(world, goals, normalize=True).tables
        sizes[name] = (world.n_polytopes, [
            POMCP(world, goals, robust, queries=q, tables=tables).pool_size()
            for q in (5000, 1000)])
    assert sizes == {"classroom": (73, [128, 32]), "r32": (469, [72, 32]),
                     "r40": (1045, [32, 32])}
