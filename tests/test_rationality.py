"""The learned-gamma belief is the exact posterior over (gamma, goal, preference): brute force
over the grid x 10 goals x all 2^8 preferences of simple."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from pathpref.inference.belief import PreferenceBelief, entropy
from pathpref.inference.human import ObservationModel
from pathpref.inference.rationality import GAMMA_GRID, GammaBelief, grid_models

from .test_belief import brute_posterior, random_observations


def brute_gamma_posterior(models, observations, ruled_out=(), weights=None):
    """``(M, G, 256)`` posterior over (gamma, goal, theta) by enumeration: the product of the
    likelihoods (to the power ``weights[t]``) of every observation under each gamma, uniform
    prior over gamma, goals and preferences, ruled-out goals at 0."""
    logs = []
    for m in models:
        logp = np.zeros((len(m.goals), 2 ** m.world.n_polytopes))
        for t, (s, h) in enumerate(observations):
            thetas = brute_posterior(m, [])[1]
            v = m.world.cell_polytope[s]
            w = 1.0 if weights is None else weights[t]
            logp += w * np.log(m.likelihood[s, h][:, thetas[:, v]])
        logp[list(ruled_out)] = -np.inf
        logs.append(logp)
    logp = np.stack(logs)
    p = np.exp(logp - logp.max())
    return p / p.sum(), thetas


@pytest.mark.parametrize("normalize", [True, False])
@pytest.mark.parametrize("seed,true_gamma", [(0, 0.5), (1, 1.5), (2, 5.0)])
def test_mixture_equals_brute_force(simple, normalize, seed, true_gamma):
    rng = np.random.default_rng(seed)
    goals = rng.choice(simple.n_cells, size=10, replace=False)
    model = ObservationModel.build(simple, goals, normalize=normalize)
    models = grid_models(model)
    truth = models[GAMMA_GRID.index(true_gamma)]
    obs = random_observations(simple, truth, rng, 25)
    weights = rng.choice([1.0, 0.5, 2.0], size=len(obs))
    belief = GammaBelief.independent(model)
    for (s, h), w in zip(obs[:15], weights[:15], strict=True):
        belief.update(s, h, w)
    belief.rule_out(3)
    for (s, h), w in zip(obs[15:], weights[15:], strict=True):
        belief.update(s, h, w)
    belief.rule_out(7)
    post, thetas = brute_gamma_posterior(models, obs, ruled_out=(3, 7), weights=weights)
    assert np.allclose(belief.gamma_marginal(), post.sum(axis=(1, 2)), atol=1e-10)
    assert np.allclose(belief.joint_gamma_goal(), post.sum(axis=2), atol=1e-10)
    assert np.allclose(belief.goal_marginal(), post.sum(axis=(0, 2)), atol=1e-10)
    assert belief.goal_marginal()[[3, 7]].tolist() == [0.0, 0.0]
    for v in range(simple.n_polytopes):
        ref = np.stack([post[:, :, thetas[:, v] == k].sum(axis=(0, 2)) for k in range(2)],
                       axis=1)
        assert np.allclose(belief.joint(v), ref, atol=1e-10)
        assert np.allclose(belief.preference_marginal(v), ref.sum(axis=0), atol=1e-10)
        cond = belief.local_given_goal(v)
        live = ref.sum(axis=1) > 0
        assert np.allclose(cond[live], ref[live] / ref[live].sum(axis=1, keepdims=True),
                           atol=1e-10)
    v = simple.cell_polytope[obs[-1][0]]
    assert belief.joint_entropy(v) == pytest.approx(entropy(belief.joint(v)))


def test_evidence_is_the_log_normaliser(simple):
    """``logsumexp log_joint`` is ``log P(o_1:t)``: summed by hand over goals and the 2^8
    preferences (uniform priors), for a belief whose tables were rescaled many times."""
    rng = np.random.default_rng(4)
    goals = rng.choice(simple.n_cells, size=10, replace=False)
    model = ObservationModel.build(simple, goals, gamma=5.0)
    obs = random_observations(simple, model, rng, 40)
    b = PreferenceBelief(model)
    for s, h in obs:
        b.update(s, h)
    thetas = brute_posterior(model, [])[1]
    logp = np.zeros((10, len(thetas)))
    for s, h in obs:
        logp += np.log(model.likelihood[s, h][:, thetas[:, simple.cell_polytope[s]]])
    top = logp.max()
    want = top + np.log(np.exp(logp - top).sum() / (10 * len(thetas)))
    lj = b.log_joint()
    got = lj.max() + np.log(np.exp(lj - lj.max()).sum())
    assert b.log_top < -10  # the tables were rescaled: the offset matters
    assert got == pytest.approx(want, rel=1e-10)


@pytest.mark.parametrize("true_gamma", [0.5, 5.0])
def test_gamma_concentrates_on_the_humans(simple, true_gamma):
    """200 headings of a human with gamma 0.5 (or 5) put most of the weight on that value."""
    rng = np.random.default_rng(11)
    goals = rng.choice(simple.n_cells, size=10, replace=False)
    model = ObservationModel.build(simple, goals)
    truth = grid_models(model)[GAMMA_GRID.index(true_gamma)]
    belief = GammaBelief.independent(model)
    for s, h in random_observations(simple, truth, rng, 200):
        belief.update(s, h)
    assert int(np.argmax(belief.gamma_marginal())) == GAMMA_GRID.index(true_gamma)
    assert belief.gamma_marginal().max() > 0.9


def test_one_gamma_is_the_plain_belief(simple):
    """A grid of one value is the plain belief (same goal marginal and tables)."""
    rng = np.random.default_rng(6)
    goals = rng.choice(simple.n_cells, size=10, replace=False)
    model = ObservationModel.build(simple, goals)
    mix = GammaBelief.independent(model, coupling=True, gammas=(model.gamma,))
    plain = PreferenceBelief(model, coupling=True)
    assert mix.inner[0].model is model
    for s, h in random_observations(simple, model, rng, 30):
        for b in (mix, plain):
            b.update(s, h)
    for b in (mix, plain):
        b.enter(0, int(simple.graph.neighbors[0][0]))
    assert np.allclose(mix.goal_marginal(), plain.goal_marginal(), atol=1e-12)
    for v in range(simple.n_polytopes):
        assert np.allclose(mix.local_given_goal(v), plain.local_given_goal(v), atol=1e-12)
    assert mix.observed_polytopes() == plain.observed_polytopes()


def test_learned_gamma_is_a_prior_option_with_its_own_key():
    """``prior='learned-gamma'`` builds the mixture over the grid (the preset's coupling), is in
    the key (the default prior's keys are unchanged), and an episode of a human with gamma 0.5
    (5), pushing every step, ends with most weight on that value."""
    from pathpref.episode import EpisodeSpec
    from pathpref.episode.runner import EpisodeRunner

    plain = EpisodeSpec.single("simple", "path_preference", 1, preset="paper", queries=300)
    assert "prior" not in plain.key()
    for true_gamma, seed in ((0.5, 0), (5.0, 1)):
        spec = EpisodeSpec.single("simple", "path_preference", 1, seed=seed, preset="paper",
                                  queries=300, prior="learned-gamma",
                                  physics=f'{{"gamma_h": {true_gamma}}}')
        assert "|prior=learned-gamma|" in spec.key()
        runner = EpisodeRunner(spec)
        belief = runner.policy.belief
        assert isinstance(belief, GammaBelief)
        assert [b.model.gamma for b in belief.inner] == list(GAMMA_GRID)
        assert all(b.coupling for b in belief.inner)  # the paper preset's coupling
        assert belief.inner[1].model is runner.model  # the assumed gamma's tables reused
        for _ in range(spec.t_max):  # bounded: the episode ends by t_max
            if runner.done:
                break
            runner.step()
        assert runner.done
        assert belief.gamma_marginal()[GAMMA_GRID.index(true_gamma)] > 0.9


def test_route_belief_evidence_is_the_log_normaliser(simple):
    """``RouteBelief.log_joint`` is absolutely scaled too: its log-sum-exp over goals equals
    ``log P(o_1:t)`` under the route prior, enumerated (every tree toward each goal's polytope,
    uniform, uniform goals)."""
    from pathpref.inference.routes import RouteBelief

    from .test_routes import is_tree, observations

    rng = np.random.default_rng(2)
    goals = rng.choice(simple.n_cells, size=4, replace=False)
    model = ObservationModel.build(simple, goals, gamma=5.0)
    obs = observations(simple, model, rng, 30)
    b = RouteBelief(model)
    for s, h in obs:
        b.update(s, h)
    nbrs = simple.graph.neighbors
    thetas = np.array(list(itertools.product(*[range(len(n)) for n in nbrs])))
    loglik = np.zeros((4, len(thetas)))
    for s, h in obs:
        loglik += np.log(model.likelihood[s, h][:, thetas[:, simple.cell_polytope[s]]])
    top = loglik.max()
    total = 0.0
    for g, r in enumerate(simple.cell_polytope[goals]):
        keep = np.array([t[r] == 0 and is_tree(t, r, nbrs) for t in thetas])
        total += (np.exp(loglik[g] - top) * keep).sum() / keep.sum() / 4
    want = top + np.log(total)
    lj = b.log_joint()
    got = lj.max() + np.log(np.exp(lj - lj.max()).sum())
    assert want < -10  # far from 0: a missing scale would show
    assert got == pytest.approx(want, rel=1e-9)
