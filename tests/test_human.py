"""The Boltzmann human model (SPEC 4): cost-excess rules, normalisation, sampling."""

from __future__ import annotations

import numpy as np
import pytest

from pathpref.geometry.grid import ACTION_NAMES
from pathpref.inference.human import BLOCK_PENALTY, GAMMA_H, ObservationModel, SimulatedHuman


def act(name):
    return ACTION_NAMES.index(name)


@pytest.fixture(scope="module")
def fig4(simple):
    """The Fig. 4 instance: goals (1..10, 8), true goal (1, 8)."""
    goals = np.array([simple.cell((x, 8)) for x in range(1, 11)])
    return ObservationModel.build(simple, goals)


def slot(world, v, w):
    return world.graph.neighbor_index(v, w)


def test_normalised_and_unnormalised(simple, fig4):
    L = fig4.likelihood
    assert np.allclose(L.sum(axis=1), 1.0)
    raw = ObservationModel(simple, fig4.tables, normalize=False).likelihood
    assert raw.max() <= 1.0 + 1e-12
    # away from the goal the best heading has excess 0: un-normalised likelihood exactly 1
    best = raw.max(axis=1)  # (n, G, K)
    at_goal = np.arange(simple.n_cells)[:, None] == fig4.goals[None, :]
    assert np.allclose(best[~at_goal], 1.0)
    assert (best[at_goal] < 1.0).all()  # on the goal every heading moves away
    # normalisation only rescales per (s, g, k)
    ratio = L / raw
    assert np.allclose(ratio, ratio[:, :1])


def test_blocked_heading_penalty(simple, fig4):
    s = simple.cell((1, 1))
    raw = ObservationModel(simple, fig4.tables, normalize=False).likelihood
    assert raw[s, act("S"), 3, 0] == pytest.approx(np.exp(-GAMMA_H * BLOCK_PENALTY))


def test_non_preferred_exit_costs_back_and_forth(simple, fig4):
    """At (4,2) the exit east (to the polytope below the table) is non-preferred when the
    preference points north: excess 2 d(s, o)."""
    s = simple.cell((4, 2))
    v = simple.cell_polytope[s]
    east = simple.cell_polytope[simple.cell((5, 2))]
    north = simple.cell_polytope[simple.cell((1, 5))]
    delta, _ = fig4._delta
    g = 3  # goal (4, 8): outside v
    assert delta[s, act("E"), g, slot(simple, v, north)] == pytest.approx(2.0)
    assert delta[s, act("E"), g, slot(simple, v, east)] < 2.0


def test_goal_inside_polytope_is_unconstrained(simple, fig4):
    delta, delta_u = fig4._delta
    s = simple.cell((2, 9))  # same polytope as goal (1, 8)
    for k in range(2):
        assert np.allclose(delta[s, :, 0, k], delta_u[s, :, 0])


def test_best_heading_follows_preference(simple, fig4):
    """From (1,1) to goal (1,8): with preference 'east' the human goes E/NE, with 'north' N/NE."""
    s = simple.cell((1, 1))
    v = simple.cell_polytope[s]
    east = slot(simple, v, simple.cell_polytope[simple.cell((5, 1))])
    north = slot(simple, v, simple.cell_polytope[simple.cell((1, 5))])
    L = fig4.likelihood
    assert L[s, act("E"), 0, east] > L[s, act("N"), 0, east]
    assert L[s, act("N"), 0, north] > L[s, act("E"), 0, north]


def test_simulated_human_frequencies(simple, fig4):
    human = SimulatedHuman(fig4, 0, simple.preference)
    s = simple.cell((3, 2))
    rng = np.random.default_rng(0)
    n = 20000
    counts = np.bincount([human.sample(s, rng) for _ in range(n)], minlength=8)
    p = human.probs(s)
    assert np.abs(counts / n - p).max() < 4 * np.sqrt(0.25 / n)


@pytest.mark.parametrize("first", ["likelihood", "goal_likelihood"])
@pytest.mark.parametrize("chunk", [7, 2048])
def test_normalised_model_keeps_one_full_table(simple, first, chunk, monkeypatch):
    """A normalised model does not keep the ``(n, 8, G, K)`` excess once its likelihood is
    built (whichever table is asked for first), and its tables, built a block of 7 cells or
    all cells at a time, equal the Boltzmann model of the whole :func:`cost_excess` exactly
    (same arithmetic)."""
    from pathpref.inference import human
    from pathpref.inference.human import boltzmann, cost_excess

    goals = np.random.default_rng(0).choice(simple.n_cells, size=6, replace=False)
    model = ObservationModel.build(simple, goals)
    monkeypatch.setattr(human, "EXCESS_CHUNK", chunk)
    lik = getattr(model, first)
    other = model.goal_likelihood if first == "likelihood" else model.likelihood
    delta, delta_u = cost_excess(simple, model.tables, chunk=10**6)
    if first == "likelihood":
        assert "_delta" not in model.__dict__
        lik, glik = lik, other
    else:
        lik, glik = other, lik
    assert np.array_equal(lik, boltzmann(delta, GAMMA_H, True))
    assert np.array_equal(glik, boltzmann(delta_u, GAMMA_H, True))
    assert model.heading_probs is model.likelihood
