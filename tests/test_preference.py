"""Preferences: the authors' tables survive conversion; routes give a documented table."""

from __future__ import annotations

import numpy as np

from pathpref.geometry.preference import preference_to_table
from pathpref.geometry.world import load_world

from .test_arrangement import bijection


def test_paper_preferences_survive_conversion(worlds, paper_maps):
    for name in ("simple", "office"):
        w, ref = worlds[name], paper_maps[name]
        mapping = bijection(w, ref)
        theirs = {int(k): int(v) for k, v in ref["preference"]["M_pref"].items() if int(v) > 0}
        ours = {mapping[v]: mapping[int(p)] for v, p in enumerate(w.preference) if p >= 0}
        assert ours == theirs


def test_simple_preference_is_counter_clockwise(simple):
    """Around the table: lower-left -> east, lower-right -> north, ... (paper Fig. 2)."""
    cp = simple.cell_polytope
    at = lambda xy: cp[simple.cell(xy)]  # noqa: E731
    assert simple.preference[at((1, 1))] == at((5, 1))
    assert simple.preference[at((9, 1))] == at((9, 5))
    assert simple.preference[at((9, 9))] == at((5, 9))
    assert simple.preference[at((1, 9))] == at((1, 5))


def test_classroom_route_is_clockwise(worlds):
    w = worlds["classroom"]
    cp = w.cell_polytope
    at = lambda xy: cp[w.cell(xy)]  # noqa: E731
    assert w.preference[at((1, 2))] == at((1, 4))  # west side: north
    assert w.preference[at((19, 19))] == at((19, 17))  # north-east corner: south
    assert w.preference[at((10, 1))] == at((7, 1))  # south side: west
    assert (w.preference >= 0).all()
    # every preference points to a neighbour
    for v, p in enumerate(w.preference):
        assert p in w.graph.neighbors[v]


def test_table_round_trip(worlds):
    w = worlds["office"]
    table = preference_to_table(w.arrangement, w.preference)
    raw = w.spec.to_dict()
    raw["preference"] = {"table": table}
    assert np.array_equal(load_world(raw).preference, w.preference)


def test_open_route_leaves_the_end_without_preference():
    w = load_world({"name": "r", "width": 6, "height": 6,
                    "obstacles": [{"cells": {"lower_left": [3, 3], "size": [2, 2]}}],
                    "preference": {"route": [[1, 1], [6, 1], [6, 6]], "closed": False}})
    end = w.cell_polytope[w.cell((6, 6))]
    assert w.preference[end] == -1
    assert (np.delete(w.preference, end) >= 0).all()
