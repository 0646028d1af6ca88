"""The per-participant fit of the human's rationality gamma_h (pathpref/study/rationality.py):
recovered from pushes simulated with a known gamma, the likelihood checked against models built
at each gamma, the estimate and interval against a case solved by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from pathpref.inference.human import ObservationModel, SimulatedHuman
from pathpref.study.plan import parse_study
from pathpref.study.rationality import (
    CHI2_1_95,
    GRID,
    fit_gamma,
    heading_log_probs,
    log_likelihood,
)

STEP = GRID[1] / GRID[0]  # the grid's ratio between neighbours


@pytest.fixture(scope="module")
def trial():
    t = {"name": "a", "map": "simple", "start": [5, 2], "goal": [5, 9],
         "candidates": [[2, 9], [5, 9], [9, 9]], "route": [[5, 2], [2, 2], [2, 9], [5, 9]],
         "time_limit_s": 10}
    return parse_study({"trials": [t]}).trials[0]


def simulated_pushes(trial, gamma: float, n: int, seed: int):
    """``n`` headings drawn from the Boltzmann human with ``gamma`` (its own model, built at
    that gamma) at cells drawn uniformly among the free cells but the goal."""
    world = trial.world
    goals = np.array([world.cell(c) for c in trial.candidates])
    human = SimulatedHuman(ObservationModel.build(world, goals, gamma=gamma),
                           trial.goal_index, trial.route_preference())
    rng = np.random.default_rng(seed)
    free = [c for c in range(world.n_cells) if c != world.cell(trial.goal)]
    cells = rng.choice(free, size=n)
    heads = np.array([human.sample(int(c), rng) for c in cells])
    return [tuple(int(v) for v in world.cells[c]) for c in cells], heads


def test_recovers_a_known_gamma_within_its_interval(trial):
    """Pushes drawn with gamma 2: the estimate's interval holds 2 and is bounded; over 20
    independent participants of 60 pushes the 95% interval holds the truth at least 17 times
    (expected 19; P(at most 16 of 20) = 1.6% for a true 95% interval)."""
    cells, heads = simulated_pushes(trial, 2.0, 300, seed=1)
    fit = fit_gamma(heading_log_probs(trial, cells), heads)
    assert fit.n == 300 and not fit.low_open and not fit.high_open
    assert fit.low <= 2.0 <= fit.high and fit.high / fit.low < 2.0
    covered = 0
    for seed in range(100, 120):
        cells, heads = simulated_pushes(trial, 2.0, 60, seed)
        f = fit_gamma(heading_log_probs(trial, cells), heads)
        covered += f.low <= 2.0 <= f.high
    assert covered >= 17
    # a human twice as rational is told apart
    cells, heads = simulated_pushes(trial, 6.0, 300, seed=2)
    sharp = fit_gamma(heading_log_probs(trial, cells), heads)
    assert sharp.low <= 6.0 <= sharp.high and sharp.low > fit.high


def test_likelihood_is_the_models_own_at_every_gamma(trial):
    """l(gamma) from the gamma = 1 table equals the sum of log P(h | s) of models built at
    gamma itself (no power identity used), to 1e-9 relative."""
    cells, heads = simulated_pushes(trial, 1.5, 40, seed=3)
    logp = heading_log_probs(trial, cells)
    world = trial.world
    goals = np.array([world.cell(c) for c in trial.candidates])
    for g in (0.3, 1.0, 2.5, 7.0):
        human = SimulatedHuman(ObservationModel.build(world, goals, gamma=g),
                               trial.goal_index, trial.route_preference())
        want = sum(math.log(human.probs(world.cell(c))[h]) for c, h in zip(cells, heads))
        got = log_likelihood(logp, heads, np.array([g]))[0]
        assert got == pytest.approx(want, rel=1e-9)


def test_two_headings_solved_by_hand():
    """Two possible headings with log P_1 = 0 and -1 (the others impossible), seen 30 and 10
    times: l(gamma) = -10 gamma - 40 log(1 + e^-gamma), maximal at gamma = log 3; the interval
    ends solve 2 (l(log 3) - l(gamma)) = 3.841 (found here by bisection)."""
    logp = np.full((40, 8), -np.inf)
    logp[:, 0], logp[:, 1] = 0.0, -1.0
    heads = np.array([0] * 30 + [1] * 10)
    fit = fit_gamma(logp, heads)

    def ll(g):
        return -10 * g - 40 * math.log1p(math.exp(-g))

    best = math.log(3.0)
    lo = brentq(lambda g: 2 * (ll(best) - ll(g)) - CHI2_1_95, 0.1, best)
    hi = brentq(lambda g: 2 * (ll(best) - ll(g)) - CHI2_1_95, best, 10.0)
    assert best / STEP <= fit.gamma <= best * STEP  # the nearest grid point
    assert lo <= fit.low <= lo * STEP and hi / STEP <= fit.high <= hi  # grid points inside
    assert not fit.low_open and not fit.high_open


def test_unbounded_directions_are_open(trial):
    """Every push along the most likely heading: l grows with gamma for ever, the estimate is
    the grid's top and its upper bound is open; every push along the least likely: the
    bottom, open below. No cue: no fit."""
    world = trial.world
    free = [tuple(int(v) for v in world.cells[c]) for c in range(world.n_cells)
            if c != world.cell(trial.goal)]
    logp = heading_log_probs(trial, free)
    rows = [i for i, r in enumerate(logp) if np.sum(r == r.max()) == 1
            and np.sum(r == r.min()) == 1]
    assert len(rows) > 10
    best = fit_gamma(logp[rows], logp[rows].argmax(axis=1))
    assert best.gamma == GRID[-1] and best.high_open and ">= 10]" in best.text()
    worst = fit_gamma(logp[rows], logp[rows].argmin(axis=1))
    assert worst.gamma == GRID[0] and worst.low_open and worst.text().startswith("0.10 [<= 0.1,")
    none = fit_gamma(np.zeros((0, 8)), np.zeros(0, int))
    assert none.n == 0 and none.text() == "-"
