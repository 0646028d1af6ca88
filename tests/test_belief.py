"""The factored belief is the exact posterior: brute force over all 2^8 preferences of simple."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from pathpref.inference.belief import GoalBelief, PreferenceBelief, entropy
from pathpref.inference.human import ObservationModel, SimulatedHuman


def brute_posterior(model, observations):
    """(G, 256) posterior over (goal, theta) by enumeration; theta[v] in {0, 1}."""
    w = model.world
    P = w.n_polytopes
    assert all(len(n) == 2 for n in w.graph.neighbors)
    thetas = np.array(list(itertools.product([0, 1], repeat=P)))
    G = len(model.goals)
    logp = np.zeros((G, len(thetas)))
    for s, h in observations:
        v = w.cell_polytope[s]
        lik = model.likelihood[s, h]  # (G, K)
        logp += np.log(lik[:, thetas[:, v]])
    p = np.exp(logp - logp.max())
    return p / p.sum(), thetas


def random_observations(world, model, rng, n):
    human = SimulatedHuman(model, 0, world.preference)
    obs = []
    s = world.cell((1, 1))
    for _ in range(n):
        h = human.sample(s, rng)
        obs.append((s, h))
        jump = rng.random() >= 0.8
        s = int(rng.integers(world.n_cells)) if jump else int(world.motion.next_cell[s, h])
    return obs


@pytest.mark.parametrize("normalize", [True, False])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_factored_equals_brute_force(simple, normalize, seed):
    rng = np.random.default_rng(seed)
    goals = rng.choice(simple.n_cells, size=10, replace=False)
    model = ObservationModel.build(simple, goals, normalize=normalize)
    obs = random_observations(simple, model, rng, 25)
    belief = PreferenceBelief(model)
    for s, h in obs:
        belief.update(s, h)
    post, thetas = brute_posterior(model, obs)
    assert np.allclose(belief.goal_marginal(), post.sum(axis=1), atol=1e-10)
    for v in range(simple.n_polytopes):
        ref = np.stack([post[:, thetas[:, v] == k].sum(axis=1) for k in range(2)], axis=1)
        assert np.allclose(belief.joint(v), ref, atol=1e-10)
        assert np.allclose(belief.preference_marginal(v), ref.sum(axis=0), atol=1e-10)
    v = simple.cell_polytope[obs[-1][0]]
    assert belief.joint_entropy(v) == pytest.approx(entropy(belief.joint(v)))


def test_goal_only_equals_brute_force(simple):
    rng = np.random.default_rng(5)
    goals = rng.choice(simple.n_cells, size=10, replace=False)
    model = ObservationModel.build(simple, goals)
    obs = random_observations(simple, model, rng, 30)
    gb = GoalBelief(model)
    logp = np.zeros(10)
    for s, h in obs:
        gb.update(s, h)
        logp += np.log(model.goal_likelihood[s, h])
    ref = np.exp(logp - logp.max())
    assert np.allclose(gb.goal_marginal(), ref / ref.sum())


def test_rule_out_and_distribution(simple):
    goals = np.array([simple.cell((x, 8)) for x in range(1, 11)])
    model = ObservationModel.build(simple, goals)
    for b in (PreferenceBelief(model), GoalBelief(model)):
        b.update(simple.cell((1, 1)), 2)
        b.rule_out(4)
        p = b.goal_marginal()
        assert p[4] == 0.0 and p.sum() == pytest.approx(1.0) and (p >= 0).all()
        assert b.goal_entropy() < np.log(10)


def test_evidence_concentrates_on_truth(simple):
    """Many headings at several cells from the true (goal, preference) make both likely."""
    goals = np.array([simple.cell((x, 8)) for x in range(1, 11)])
    model = ObservationModel.build(simple, goals)
    human = SimulatedHuman(model, 0, simple.preference)
    rng = np.random.default_rng(0)
    b = PreferenceBelief(model)
    cells = [simple.cell(c) for c in [(1, 1), (3, 2), (6, 2), (8, 3)]]
    for _ in range(40):
        for s in cells:
            b.update(s, human.sample(s, rng))
    v0 = simple.cell_polytope[cells[0]]
    k = simple.graph.neighbor_index(v0, simple.preference[v0])
    assert b.preference_marginal(v0)[k] > 0.95


def test_coupling_lowers_going_back(simple):
    goals = np.array([simple.cell((x, 8)) for x in range(1, 11)])
    model = ObservationModel.build(simple, goals)
    s = simple.cell((3, 2))
    v = simple.cell_polytope[s]
    east = simple.cell_polytope[simple.cell((5, 2))]
    off, on = PreferenceBelief(model), PreferenceBelief(model, coupling=True)
    for b in (off, on):
        for _ in range(5):
            b.update(s, 2)  # east, repeatedly
        b.enter(v, east)
    back = simple.graph.neighbor_index(east, v)
    # without coupling the unobserved polytope stays uniform: 0.5 up to rounding (a matrix
    # product whose last bit depends on the CPU's kernels, docs/experiments.md "Replays exactly")
    assert off.preference_marginal(east)[back] == pytest.approx(0.5, rel=1e-12)
    assert on.preference_marginal(east)[back] < 0.5 - 1e-3


def test_entropy_of_nothing_is_zero_and_of_uniform_is_log_n():
    from pathpref.inference.belief import entropy

    assert entropy(np.zeros(4)) == 0.0
    assert entropy(np.ones(5)) == pytest.approx(np.log(5))
    assert entropy(np.array([3, 1])) == pytest.approx(-(0.75 * np.log(0.75) + 0.25 * np.log(0.25)))


def test_goal_belief_stays_finite_over_thousands_of_updates(simple):
    goals = np.array([simple.cell((x, 8)) for x in range(1, 11)])
    b = GoalBelief(ObservationModel.build(simple, goals))
    for _ in range(3000):
        b.update(simple.cell((5, 1)), 2)
    p = b.goal_marginal()
    assert np.isfinite(p).all() and p.sum() == pytest.approx(1.0)
    assert np.isfinite(b.log_w).all()


def test_goal_belief_prior_multiplies_the_likelihood(simple):
    goals = np.array([simple.cell((x, 8)) for x in range(1, 5)])
    model = ObservationModel.build(simple, goals)
    prior = np.array([0.7, 0.1, 0.2, 0.0])
    b = GoalBelief(model, prior=prior)
    assert b.goal_marginal() == pytest.approx(prior)
    b.update(simple.cell((3, 2)), 0)
    want = prior * model.goal_likelihood[simple.cell((3, 2)), 0]
    assert b.goal_marginal() == pytest.approx(want / want.sum())


def test_a_goal_row_far_below_the_others_keeps_its_shape(simple):
    """Evidence that makes one goal 1e-150 as likely per observation as the others (1e-1050
    after seven): its row of the table is rescaled on its own instead of underflowing to 0/0,
    so its exits keep their exact odds (2^7 : 1 here) and its log weight stays finite, for the
    independent and the route belief."""
    from pathpref.inference.routes import RouteBelief

    goals = np.array([simple.cell((x, 8)) for x in range(1, 5)])
    model = ObservationModel.build(simple, goals)
    v = 0
    deg = len(simple.graph.neighbors[v])
    f = np.ones((len(goals), deg))
    f[0] = 1e-150
    f[0, 0] = 2e-150  # goal 0: exit 0 twice as likely as each other exit
    for b in (PreferenceBelief(model), RouteBelief(model)):
        for _ in range(7):
            b._multiply(v, f)
        row = b.local_given_goal(v)[0]
        assert np.isfinite(row).all() and row[0] == pytest.approx(128 * row[1], rel=1e-12)
        w = b.goal_log_weights()
        assert np.isfinite(w).all() and w[1] - w[0] > 1000 * np.log(10)
    # independent prior: log mean of goal 0's row, worked out by hand
    ind = PreferenceBelief(model)
    for _ in range(7):
        ind._multiply(v, f)
    w = ind.goal_log_weights()
    want = 1050 * np.log(10) - np.log((128 + deg - 1) / deg)
    assert w[1] - w[0] == pytest.approx(want, rel=1e-9)


def brute_direction_posterior(model, observations, kappa):
    """(G, 256) posterior by enumeration for force directions: each observation ``(s, theta,
    w)`` multiplies by ``(sum_h exp(kappa (cos(theta - mu_h) - 1)) P(h | s, g, theta_v))^w``."""
    from pathpref.geometry.grid import ACTION_ANGLES

    w = model.world
    thetas = np.array(list(itertools.product([0, 1], repeat=w.n_polytopes)))
    logp = np.zeros((len(model.goals), len(thetas)))
    for s, angle, weight in observations:
        v = w.cell_polytope[s]
        a = np.exp(kappa * (np.cos(angle - ACTION_ANGLES) - 1.0))
        mix = sum(a[h] * model.likelihood[s, h] for h in range(8))  # (G, K)
        logp += weight * np.log(mix[:, thetas[:, v]])
    p = np.exp(logp - logp.max())
    return p / p.sum(), thetas


@pytest.mark.parametrize("seed", [0, 1])
def test_force_direction_updates_equal_brute_force(simple, seed):
    """Online updates from sampled force directions (a sustained push: tempered von Mises
    mixtures) give the posterior that enumeration over every preference gives."""
    rng = np.random.default_rng(seed)
    goals = rng.choice(simple.n_cells, size=10, replace=False)
    model = ObservationModel.build(simple, goals)
    obs = [(s, float(rng.uniform(-np.pi, np.pi)), float(rng.uniform(0.05, 1.0)))
           for s, _ in random_observations(simple, model, rng, 20)]
    belief, goal_only = PreferenceBelief(model), GoalBelief(model)
    for s, angle, w in obs:
        belief.update_direction(s, angle, 3.0, w)
        goal_only.update_direction(s, angle, 3.0, w)
    post, thetas = brute_direction_posterior(model, obs, 3.0)
    assert np.allclose(belief.goal_marginal(), post.sum(axis=1), atol=1e-10)
    for v in range(simple.n_polytopes):
        ref = np.stack([post[:, thetas[:, v] == k].sum(axis=1) for k in range(2)], axis=1)
        assert np.allclose(belief.joint(v), ref, atol=1e-10)
    # the goal-only belief: the same mixture of the unconstrained likelihood
    from pathpref.geometry.grid import ACTION_ANGLES

    lw = np.zeros(len(goals))
    for s, angle, w in obs:
        a = np.exp(3.0 * (np.cos(angle - ACTION_ANGLES) - 1.0))
        lw += w * np.log(a @ model.goal_likelihood[s])
    ref = np.exp(lw - lw.max())
    assert np.allclose(goal_only.goal_marginal(), ref / ref.sum(), atol=1e-10)


def test_force_direction_limits(simple):
    """A direction with a sharp spread along a heading's axis is that heading's update; no
    spread (kappa 0) is no evidence (the model's headings sum to one)."""
    from pathpref.geometry.grid import ACTION_ANGLES

    rng = np.random.default_rng(3)
    model = ObservationModel.build(simple, rng.choice(simple.n_cells, size=10, replace=False))
    obs = random_observations(simple, model, rng, 12)
    sharp, plain, none = (PreferenceBelief(model) for _ in range(3))
    for s, h in obs:
        sharp.update_direction(s, float(ACTION_ANGLES[h]), 5000.0)
        plain.update(s, h)
        none.update_direction(s, float(ACTION_ANGLES[h]), 0.0)
    assert np.allclose(sharp.goal_marginal(), plain.goal_marginal(), rtol=1e-9, atol=1e-12)
    assert np.allclose(none.goal_marginal(), 0.1, atol=1e-12)


def test_route_belief_takes_force_directions(simple):
    """The route prior's belief takes force directions through the same tables: a sharp
    direction along a heading is that heading's update, goal and preference marginals alike."""
    from pathpref.geometry.grid import ACTION_ANGLES
    from pathpref.inference.routes import RouteBelief

    rng = np.random.default_rng(5)
    model = ObservationModel.build(simple, rng.choice(simple.n_cells, size=10, replace=False))
    sharp, plain = RouteBelief(model), RouteBelief(model)
    for s, h in random_observations(simple, model, rng, 10):
        sharp.update_direction(s, float(ACTION_ANGLES[h]), 5000.0)
        plain.update(s, h)
        assert np.allclose(sharp.goal_marginal(), plain.goal_marginal(), rtol=1e-9, atol=1e-12)
    for v in range(simple.n_polytopes):
        assert np.allclose(sharp.preference_marginal(v), plain.preference_marginal(v),
                           rtol=1e-9, atol=1e-12)
