"""Convert the authors' map data (shared/data/paper_maps.json) into pathpref's map format.

    python scripts/convert_paper_maps.py ../shared/data/paper_maps.json pathpref/maps

Obstacles are copied as cell rectangles. The authors' preference ``M_pref`` (polytope id ->
preferred neighbour id, in their numbering) is written in a numbering-free form: each entry
becomes ``{"from": cell, "to": cell}`` with a representative cell of each polytope. ``classroom``
has no preference in the authors' data; it gets a route (see pathpref/geometry/preference.py).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

NAMES = {"Map 1": "simple", "Map 2": "office", "Map 3": "classroom"}
DESCRIPTIONS = {
    "simple": "Paper Map 1: 10x10 grid, one 2x2 table; the human goes around it counter-clockwise.",
    "office": "Paper Map 2: 10x10 office, 12 desks and walls; 56 polytopes.",
    "classroom": "Paper Map 3: 20x20 classroom, 8 desk rows; the human goes around the desks "
    "clockwise (a route; the authors' data has no preference for this map).",
}
# A clockwise loop around the desks of the classroom along the outer corridors: up the west
# side, east along the north wall, down the east side, west along the south wall.
CLASSROOM_ROUTE = [[1, 1], [1, 20], [20, 20], [20, 1]]


def convert(m: dict) -> dict:
    name = NAMES[m["paper_name"]]
    out = {
        "name": name,
        "description": DESCRIPTIONS[name],
        "width": m["grid"][0],
        "height": m["grid"][1],
        "obstacles": [
            {"cells": {"lower_left": o["lower_left_cell"], "size": o["size_cells"]}}
            for o in m["obstacles"]
        ],
    }
    pref = m["preference"].get("M_pref")
    if pref:
        rep = {p["id"]: p["representative_cell"] for p in m["polytopes"]}
        out["preference"] = {
            "table": [
                {"from": rep[int(v)], "to": rep[int(w)]}
                for v, w in sorted(pref.items(), key=lambda kv: int(kv[0]))
                if int(w) > 0
            ]
        }
    else:
        out["preference"] = {"route": CLASSROOM_ROUTE, "closed": True}
    if name == "office":
        out["goal_band"] = {"x": [2, 10], "y": [8, 9]}
    out["t_max"] = 60 if name == "classroom" else 30  # paper Sec. V-B (SPEC 6)
    return out


def main(src: str, dst: str) -> None:
    data = json.loads(Path(src).read_text())
    for m in data["maps"]:
        out = convert(m)
        path = Path(dst) / f"{out['name']}.json"
        path.write_text(json.dumps(out, indent=1) + "\n")
        print("wrote", path)


if __name__ == "__main__":
    main(*sys.argv[1:3])
