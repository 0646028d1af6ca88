"""The coarse decomposition (obstacle edges extended until they hit an obstacle or the wall)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pathpref.errors import MapError
from pathpref.geometry.generate import random_floor_plan
from pathpref.geometry.maps import builtin_map_path
from pathpref.geometry.world import load_world


def paper_map(name: str, **extra) -> dict:
    raw = json.loads(builtin_map_path(name).read_text())
    raw.pop("preference")  # tables name the arrangement's polytopes
    return {**raw, **extra}


def test_one_table_in_a_room_is_the_papers_arrangement():
    """On `simple` every extended edge reaches the wall: coarse = arrangement."""
    a = load_world(paper_map("simple"))
    c = load_world(paper_map("simple", decomposition="coarse"))
    assert (c.n_polytopes, c.graph.n_edges) == (8, 8)
    assert (c.cell_polytope == a.cell_polytope).all()
    assert (c.motion.crossed_edge >= 0).sum() == (a.motion.crossed_edge >= 0).sum()


def test_hand_drawn_blocked_extensions():
    """6 x 5 map, box B1 = cell (2, 2) and a tall box B2 = cells (4, 1..3) from the floor.

    Lines: x = 1, 2, 3, 4 and y = 1, 2, 3: 5 columns x 4 rows = 20 regions, 4 inside boxes ->
    16 polytopes. B1's bottom and top edges (y = 1, y = 2) extended to the right stop at B2
    (x = 3), so right of B2 they cut nothing: the three regions of the strip x in [4, 6],
    y in [0, 3] merge into one -> 14 regions. B2's top edge (y = 3) passes above B1 to the
    wall and still cuts; between the boxes (x in [2, 3]) y = 1 and y = 2 still cut."""
    raw = {"name": "two", "width": 6, "height": 5, "obstacles": [
        {"cells": {"lower_left": [2, 2], "size": [1, 1]}},
        {"cells": {"lower_left": [4, 1], "size": [1, 3]}}]}
    a = load_world(raw)
    c = load_world({**raw, "decomposition": "coarse"})
    assert (a.n_polytopes, c.n_polytopes) == (16, 14)
    region = {xy: int(c.cell_polytope[c.cell(xy)]) for xy in
              [(5, 1), (6, 2), (5, 3), (5, 4), (3, 1), (3, 2)]}
    assert region[(5, 1)] == region[(6, 2)] == region[(5, 3)] != region[(5, 4)]
    assert region[(3, 1)] != region[(3, 2)]


@pytest.mark.parametrize("name, regions, edges", [("office", 49, 62), ("classroom", 52, 68)])
def test_paper_maps_coarse_counts(name, regions, edges):
    w = load_world(paper_map(name, decomposition="coarse"))
    assert (w.n_polytopes, w.graph.n_edges) == (regions, edges)


@pytest.mark.parametrize("seed", range(12))
def test_regions_are_convex_and_obstacle_free(seed):
    """Each region's hull holds no cell of another region and no obstacle vertex, and the
    region count never exceeds the arrangement's."""
    raw = random_floor_plan(18, 14, 6, n_boxes=1, seed=seed, size_range=(0.8, 4.0))
    a = load_world(raw)
    c = load_world({**raw, "decomposition": "coarse"})
    assert c.n_polytopes <= a.n_polytopes
    centres = c.cells - 0.5
    for r in range(c.n_polytopes):
        A, b = c.arrangement.A[r], c.arrangement.b[r]
        if len(A) == 0:
            continue
        inside = (centres @ A.T - b < -1e-6).all(axis=1)
        assert not (inside & (c.cell_polytope != r)).any()
        for o in c.spec.obstacles:
            assert not (o.vertices @ A.T - b < -1e-6).all(axis=1).any()
    # every region change is a recorded crossing of one edge between the two regions
    m = c.motion
    src = np.repeat(np.arange(c.n_cells)[:, None], 8, axis=1)
    change = c.cell_polytope[src] != c.cell_polytope[m.next_cell]
    assert (m.crossed_edge[change] >= 0).all() and (m.crossed_edge[~change] == -1).all()


def test_fewer_regions_on_a_cluttered_floor():
    raw = random_floor_plan(40, 40, 32, seed=1)
    a = load_world(raw)
    c = load_world({**raw, "decomposition": "coarse"})
    assert c.n_polytopes < 0.6 * a.n_polytopes


def test_bad_decomposition_and_stale_table():
    with pytest.raises(MapError, match="'decomposition' must be one of"):
        load_world(paper_map("simple", decomposition="voronoi"))
    raw = json.loads(builtin_map_path("office").read_text())
    with pytest.raises(MapError, match="lie in the same polytope"):
        load_world({**raw, "decomposition": "coarse"})
