"""Map loading: built-in maps, file round trip, and every kind of bad input (MapError)."""

from __future__ import annotations

import json

import pytest

from pathpref.errors import MapError
from pathpref.geometry.maps import load_map
from pathpref.geometry.world import load_world


def base(**kw):
    d = {"name": "t", "width": 6, "height": 5, "obstacles": []}
    d.update(kw)
    return d


def test_builtin_maps_load():
    for name in ("simple", "office", "classroom"):
        spec = load_map(name)
        assert spec.name == name and spec.obstacles


def test_file_round_trip(tmp_path):
    spec = load_map("office")
    path = tmp_path / "office_copy.json"
    path.write_text(json.dumps(spec.to_dict()))
    a, b = load_world(path), load_world("office")
    assert (a.cell_polytope == b.cell_polytope).all()
    assert (a.preference == b.preference).all()


def test_clockwise_and_counter_clockwise_are_the_same():
    ccw = [[1, 1], [3, 1], [3, 3], [1, 3]]
    a = load_world(base(obstacles=[{"vertices": ccw}]))
    b = load_world(base(obstacles=[{"vertices": ccw[::-1]}]))
    assert (a.cell_polytope == b.cell_polytope).all()


def test_overlapping_obstacles_are_valid():
    w = load_world(base(obstacles=[{"cells": {"lower_left": [2, 2], "size": [2, 2]}},
                                   {"cells": {"lower_left": [3, 3], "size": [2, 2]}}]))
    assert w.n_cells == 30 - 7


BAD = [
    ("not a dict", [], "JSON object"),
    ("missing width", {"height": 3}, "'width' is missing"),
    ("width float", base(width=2.5), "whole number"),
    ("width zero", base(width=0), "between 1"),
    ("unknown field", base(colour="red"), "unknown map field"),
    ("obstacles not list", base(obstacles={}), "must be a list"),
    ("two vertices", base(obstacles=[{"vertices": [[1, 1], [2, 2]]}]), "at least 3"),
    ("nan vertex", base(obstacles=[{"vertices": [[1, 1], [2, float("nan")], [1, 2]]}]), "finite"),
    ("inf vertex", base(obstacles=[{"vertices": [[1, 1], [2, float("inf")], [1, 2]]}]), "finite"),
    ("string vertex", base(obstacles=[{"vertices": [[1, 1], ["a", 2], [1, 2]]}]), "number"),
    ("non-convex", base(obstacles=[{"vertices": [[1, 1], [4, 1], [2, 2], [4, 3], [1, 3]]}]),
     "not convex"),
    ("bow-tie", base(obstacles=[{"vertices": [[1, 1], [3, 3], [3, 1], [1, 3]]}]),
     "self-intersecting"),
    ("self-crossing", base(obstacles=[{"vertices": [[1, 1], [4, 3], [4, 1], [1, 2]]}]),
     "not convex|self-intersecting"),
    ("pentagram", base(width=20, height=20, obstacles=[{"vertices": [
        [10, 18], [14.7, 3.5], [2.4, 12.5], [17.6, 12.5], [5.3, 3.5]]}]), "self-intersecting"),
    ("collinear", base(obstacles=[{"vertices": [[1, 1], [2, 2], [3, 3]]}]), "zero area"),
    ("outside", base(obstacles=[{"vertices": [[5, 1], [7, 1], [7, 2]]}]), "outside the map"),
    ("no form", base(obstacles=[{"centre": [1, 1]}]), "needs 'vertices'"),
    ("both forms", base(obstacles=[{"vertices": [[1, 1], [2, 1], [2, 2]],
                                    "cells": {"lower_left": [1, 1], "size": [1, 1]}}]), "both"),
    ("cells size 0", base(obstacles=[{"cells": {"lower_left": [1, 1], "size": [0, 1]}}]),
     "positive"),
    ("cells malformed", base(obstacles=[{"cells": [1, 1]}]), "lower_left"),
    ("no free cell", base(obstacles=[{"cells": {"lower_left": [1, 1], "size": [6, 5]}}]),
     "no free cell"),
    ("goal band bad", base(goal_band={"x": [3, 1]}), "goal_band.x"),
    ("pref not object", base(preference=[1]), "preference"),
]


@pytest.mark.parametrize("case,raw,msg", BAD, ids=[b[0] for b in BAD])
def test_bad_maps(case, raw, msg):
    with pytest.raises(MapError, match=msg):
        load_world(raw)


BAD_PREF = [
    ("unknown vertex cell", {"table": [{"from": [9, 9], "to": [1, 1]}]}, "outside"),
    ("on obstacle", {"table": [{"from": [3, 3], "to": [1, 1]}]}, "obstacle"),
    ("not neighbours", {"table": [{"from": [1, 1], "to": [6, 5]}]}, "not neighbours"),
    ("conflict", {"table": [{"from": [1, 1], "to": [3, 1]}, {"from": [1, 1], "to": [1, 3]}]},
     "conflicts"),
    ("bad form", {"list": []}, "must be"),
    ("route too short", {"route": [[1, 1]]}, "at least 2"),
]


@pytest.mark.parametrize("case,pref,msg", BAD_PREF, ids=[b[0] for b in BAD_PREF])
def test_bad_preferences(case, pref, msg):
    raw = base(obstacles=[{"cells": {"lower_left": [3, 3], "size": [1, 1]}}], preference=pref)
    with pytest.raises(MapError, match=msg):
        load_world(raw)


def test_bad_files(tmp_path):
    p = tmp_path / "broken.json"
    p.write_text("{not json")
    with pytest.raises(MapError, match="not valid JSON"):
        load_map(p)
    with pytest.raises(MapError, match="no map named"):
        load_map(tmp_path / "missing.json")
    w = load_world("simple")
    with pytest.raises(MapError, match="obstacle"):
        w.cell((5, 5), "goal")
    with pytest.raises(MapError, match="outside"):
        w.cell((0, 5), "start")
