"""The circulation prior: one-way flows round a centre, and a push that informs the far side.

The flows are checked on a ring whose answer is known by hand; the posterior's exactness is
checked against the brute force with the homotopy prior's (``tests/test_homotopy_prior.py``,
parametrised over both mixtures)."""

from __future__ import annotations

import numpy as np
import pytest

from pathpref.geometry.circulation import circulations
from pathpref.geometry.maps import load_map
from pathpref.geometry.world import World
from pathpref.inference.circulation_prior import CirculationBelief
from pathpref.inference.human import ObservationModel
from pathpref.inference.routes import RouteBelief


def ring() -> World:
    """A 9 x 9 room round a 3 x 3 block: eight polytopes, each touching two others."""
    return World.from_spec(load_map({"name": "ring", "width": 9, "height": 9, "obstacles": [
        {"cells": {"lower_left": [4, 4], "size": [3, 3]}}]}))


def poly(w: World, x: int, y: int) -> int:
    return int(w.cell_polytope[w.cell((x, y))])


def test_a_ring_has_exactly_its_two_circulations():
    """Round one block every centre of the lattice gives one of two flows: the ring clockwise
    (up the west side, east along the top, down the east side, west along the bottom; y up)
    and its reverse. Each is a single directed cycle through all eight polytopes."""
    w = ring()
    assert w.n_polytopes == 8
    flows = circulations(w)
    assert flows.shape == (2, 8)
    sw, w_mid, nw = poly(w, 2, 2), poly(w, 2, 5), poly(w, 2, 8)
    n_mid, ne, e_mid = poly(w, 5, 8), poly(w, 8, 8), poly(w, 8, 5)
    se, s_mid = poly(w, 8, 2), poly(w, 5, 2)
    clockwise = {sw: w_mid, w_mid: nw, nw: n_mid, n_mid: ne, ne: e_mid, e_mid: se, se: s_mid,
                 s_mid: sw}
    want_cw = np.array([clockwise[v] for v in range(8)])
    want_ccw = np.empty(8, dtype=np.int64)
    want_ccw[want_cw] = np.arange(8)
    assert sorted(map(tuple, flows.tolist())) == sorted([tuple(want_cw), tuple(want_ccw)])
    # a single cycle: eight steps from any polytope come back to it, visiting all
    for f in flows:
        seen, v = set(), 0
        for _ in range(8):
            seen.add(v)
            v = int(f[v])
        assert v == 0 and len(seen) == 8
    with pytest.raises(ValueError):
        circulations(w, centres=0)


def test_one_push_informs_the_far_side_of_the_ring():
    """The goal in the middle of the top side. A push north in the south-west corner says the
    person goes up the west side; under the circulation prior that shifts the exit of the
    south-east corner (the opposite corner, never observed) toward the west, the clockwise
    flow, by more than under the route prior, where the two corners share only the
    arborescence constraint."""
    w = ring()
    goal = w.cell((5, 8))
    model = ObservationModel.build(w, np.array([goal]), normalize=True)
    se = poly(w, 8, 2)
    west = int(np.flatnonzero(w.graph.neighbors[se] == poly(w, 5, 2))[0])
    gains = {}
    for name, belief in (("circulation", CirculationBelief(model, -1)),
                         ("routes", RouteBelief(model))):
        before = belief.preference_given_goal(se)[0, west]
        belief.update(w.cell((2, 2)), 0)  # heading N
        after = belief.preference_given_goal(se)[0, west]
        gains[name] = after - before
    assert gains["circulation"] > 0
    assert gains["circulation"] > gains["routes"]


def test_the_circulation_prior_needs_no_start():
    w = ring()
    model = ObservationModel.build(w, np.array([w.cell((5, 8))]), normalize=True)
    b = CirculationBelief(model, -1)
    assert b.n_ways.tolist() == [2]  # the two flows complete into two distinct trees
    assert np.isclose(b.goal_marginal().sum(), 1.0)


def test_a_circulation_episode_runs_and_replays():
    """One robust episode under the circulation prior runs end to end and gives the same
    steps when run again (the particles are seeded by the episode)."""
    from pathpref.episode.runner import run_episode
    from pathpref.episode.spec import EpisodeSpec

    spec = EpisodeSpec(map="office", method="path_preference", delta_t=5, instance=0, run=0,
                       preset="robust", prior="circulation", human="consistent",
                       instance_seed=3, run_seed=4)
    a, b = run_episode(spec), run_episode(spec)
    assert a.steps == b.steps and a.success == b.success
    assert a.steps > 0
