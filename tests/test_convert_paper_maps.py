"""scripts/convert_paper_maps.py turns the authors' map data (``shared/data/paper_maps.json``)
into pathpref's map format: a small map in the authors' schema converted as worked out by hand,
and, where the authors' file is at hand, the three shipped maps reproduced exactly."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))

from convert_paper_maps import CLASSROOM_ROUTE, convert, main  # noqa: E402

#: the authors' data, beside the checkout (``../shared/data``) when it is there
PAPER_MAPS = ROOT.parent / "shared" / "data" / "paper_maps.json"


def _authors(paper_name: str, m_pref: dict | None) -> dict:
    """A map in the authors' schema: 10 x 10, one 2 x 2 table at (5, 5), three polytopes."""
    return {"paper_name": paper_name, "grid": [10, 10],
            "obstacles": [{"lower_left_cell": [5, 5], "size_cells": [2, 2]}],
            "polytopes": [{"id": 1, "representative_cell": [1, 1]},
                          {"id": 2, "representative_cell": [5, 1]},
                          {"id": 3, "representative_cell": [1, 5]}],
            "preference": {} if m_pref is None else {"M_pref": m_pref}}


def test_a_preference_becomes_cell_pairs():
    """Map 1: ``M_pref`` {1: 2, 2: 3, 3: -1} in the authors' polytope ids becomes two
    representative-cell pairs (a non-positive entry, no preference, is dropped), sorted by
    polytope; the table a cell rectangle; ``t_max`` 30."""
    out = convert(_authors("Map 1", {"2": 3, "1": 2, "3": -1}))
    assert out["name"] == "simple" and (out["width"], out["height"]) == (10, 10)
    assert out["obstacles"] == [{"cells": {"lower_left": [5, 5], "size": [2, 2]}}]
    assert out["preference"] == {"table": [{"from": [1, 1], "to": [5, 1]},
                                           {"from": [5, 1], "to": [1, 5]}]}
    assert out["t_max"] == 30 and "goal_band" not in out


def test_office_has_its_goal_band_and_classroom_its_route():
    """Map 2 gets the office's goal band; Map 3, with no ``M_pref``, the clockwise route
    around the desks, closed, and ``t_max`` 60."""
    office = convert(_authors("Map 2", {"1": 2}))
    assert office["name"] == "office" and office["goal_band"] == {"x": [2, 10], "y": [8, 9]}
    classroom = convert(_authors("Map 3", None))
    assert classroom["preference"] == {"route": CLASSROOM_ROUTE, "closed": True}
    assert classroom["t_max"] == 60


@pytest.mark.skipif(not PAPER_MAPS.exists(), reason=f"{PAPER_MAPS} is not at hand")
def test_the_authors_data_gives_the_shipped_maps(tmp_path, capsys):
    """Converting the authors' file writes simple, office and classroom exactly as shipped."""
    main(str(PAPER_MAPS), str(tmp_path))
    for name in ("simple", "office", "classroom"):
        got = json.loads((tmp_path / f"{name}.json").read_text())
        assert got == json.loads((ROOT / "pathpref" / "maps" / f"{name}.json").read_text())
