"""Arrangement and polytope graph against the authors' saved graphs and hand-drawn maps."""

from __future__ import annotations

import numpy as np
import pytest

from pathpref.geometry.polygon import essential_rows, essential_rows_lp
from pathpref.geometry.world import load_world

COUNTS = {"simple": (8, 8, 96), "office": (56, 73, 75), "classroom": (73, 89, 276)}


def bijection(world, ref) -> dict[int, int]:
    """Our polytope id -> authors' id, asserting the two partitions of cells are the same."""
    theirs = {tuple(c): p["id"] for p in ref["polytopes"] for c in p["cells"]}
    ours = {tuple(c): int(v) for c, v in zip(world.cells.tolist(), world.cell_polytope)}
    assert set(ours) == set(theirs), "different free cells"
    mapping: dict[int, int] = {}
    for c, v in ours.items():
        assert mapping.setdefault(v, theirs[c]) == theirs[c], f"cell {c} splits polytope {v}"
    assert len(set(mapping.values())) == len(mapping), "two of our polytopes merge in theirs"
    return mapping


@pytest.mark.parametrize("name", list(COUNTS))
def test_counts(worlds, name):
    w = worlds[name]
    assert (w.n_polytopes, w.graph.n_edges, w.n_cells) == COUNTS[name]


@pytest.mark.parametrize("name", list(COUNTS))
def test_same_partition_and_edges_as_authors(worlds, paper_maps, name):
    w, ref = worlds[name], paper_maps[name]
    mapping = bijection(w, ref)
    theirs = {
        frozenset((p["id"], nb["neighbor"])) for p in ref["polytopes"] for nb in p["neighbors"]
    }
    ours = {frozenset((mapping[int(u)], mapping[int(v)])) for u, v in w.graph.edges}
    assert ours == theirs


@pytest.mark.parametrize("name", list(COUNTS))
def test_reduced_rows_match_authors_on_bounded_polytopes(worlds, paper_maps, name):
    """Our essential rows equal the authors' reduced H-rep (minus map-border rows)."""
    w, ref = worlds[name], paper_maps[name]
    mapping = bijection(w, ref)
    by_id = {p["id"]: p for p in ref["polytopes"]}
    arr = w.arrangement
    for v in range(w.n_polytopes):
        p = by_id[mapping[v]]
        theirs = {
            (tuple(np.round(np.array(a, float) / np.linalg.norm(a), 9)),
             round(b / np.linalg.norm(a), 9))
            for k, (a, b) in enumerate(zip(p["A"], p["b"]))
            if (k + 1) not in p["contour_rows"]
        }
        ours = {(tuple(np.round(a, 9)), round(float(b), 9)) for a, b in zip(arr.A[v], arr.b[v])}
        assert ours == theirs, f"polytope {v} (authors' {p['id']})"


@pytest.mark.parametrize("name", list(COUNTS))
def test_clip_and_lp_redundancy_agree(worlds, name):
    """The fast clipping method finds the same essential rows as SPEC's HiGHS LP method."""
    w = worlds[name]
    arr = w.arrangement
    for v in range(w.n_polytopes):
        A, b = arr.constraint_rows(v)
        fast = essential_rows(A, b, arr.width, arr.height)
        ref = essential_rows_lp(A, b, arr.width, arr.height)
        assert fast.tolist() == ref.tolist(), f"polytope {v}"


@pytest.mark.parametrize("name", list(COUNTS))
def test_invariants(worlds, name):
    w = worlds[name]
    # every free cell in exactly one polytope, and the polytope's polygon contains its centre
    assert (w.cell_polytope >= 0).all()
    for v in range(w.n_polytopes):
        A, b = w.arrangement.A[v], w.arrangement.b[v]
        centres = w.cells[w.arrangement.polytope_cells(v)] - 0.5
        assert (centres @ A.T - b <= 1e-9).all()
    # adjacency symmetric, edges cross exactly one line (no move edges on the paper's maps)
    assert w.graph.n_move_edges == 0
    for (u, v), e in zip(w.graph.edges, range(w.graph.n_edges)):
        assert w.graph.edge_between(u, v) == w.graph.edge_between(v, u) == e
    for (u, v), h in zip(w.graph.edges, w.graph.edge_hyperplane):
        diff = np.flatnonzero(w.arrangement.signs[u] != w.arrangement.signs[v])
        assert diff.tolist() == [h]


def test_hand_drawn_three_by_three():
    """A 3x3 map with the centre cell blocked: 4 lines -> 8 polytopes around it, a ring."""
    w = load_world({"name": "ring", "width": 3, "height": 3,
                    "obstacles": [{"cells": {"lower_left": [2, 2], "size": [1, 1]}}]})
    assert w.n_cells == 8 and w.n_polytopes == 8 and w.graph.n_edges == 8
    assert sorted(len(n) for n in w.graph.neighbors) == [2] * 8
    # corner cell (1,1): N and E are crossings, NE is blocked (obstacle), diagonal to (2,3)? no.
    s = w.cell((1, 1))
    assert not w.motion.blocked[s, 0] and not w.motion.blocked[s, 2]
    assert w.motion.blocked[s, 1]  # NE is the obstacle
    assert w.motion.crossed_edge[s, 0] >= 0


def test_rotated_obstacles():
    """A rotated square and a triangle: polytopes cover the free cells, graph is consistent."""
    c, s = np.cos(0.5), np.sin(0.5)
    square = (np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * 1.3) @ np.array([[c, -s], [s, c]]).T
    square = (square + [4.0, 4.0]).tolist()
    tri = [[6.2, 1.0], [8.7, 2.1], [7.1, 3.9]]
    w = load_world({"name": "rot", "width": 10, "height": 8,
                    "obstacles": [{"vertices": square}, {"vertices": tri[::-1]}]})
    assert w.n_polytopes > 8
    signs = w.arrangement.signs
    for (u, v), h in zip(w.graph.edges, w.graph.edge_hyperplane):
        diff = np.flatnonzero(signs[u] != signs[v])
        if h >= 0:  # facet edge: one line
            assert diff.tolist() == [h]
        else:  # move edge: a straight move across several lines
            assert len(diff) >= 2
    # every non-blocked move that changes polytope crosses the edge between them; a diagonal
    # move never crosses more than one line (the corner rule)
    m = w.motion
    for i in range(w.n_cells):
        for a in range(8):
            j = m.next_cell[i, a]
            u, v = w.cell_polytope[i], w.cell_polytope[j]
            if u != v:
                assert m.crossed_edge[i, a] == w.graph.edge_between(u, v) >= 0
                if a % 2 == 1:
                    assert (signs[u] != signs[v]).sum() == 1
            else:
                assert m.crossed_edge[i, a] == -1
    # no move inside a polytope or across a facet passes through an obstacle (a straight move
    # across several lines may clip an obstacle thinner than a cell, as on the 4-connected grid)
    obs = w.spec.obstacles
    for i in range(w.n_cells):
        for a in range(8):
            e = m.crossed_edge[i, a]
            if m.blocked[i, a] or (e >= 0 and w.graph.edge_hyperplane[e] < 0):
                continue
            p0, p1 = w.cells[i] - 0.5, w.cells[m.next_cell[i, a]] - 0.5
            pts = p0 + np.linspace(0, 1, 21)[:, None] * (p1 - p0)
            for o in obs:
                assert not (pts @ o.A.T - o.b < -1e-9).all(axis=1).any()


@pytest.mark.parametrize("chunk", [1, 7, 100])
def test_sign_vectors_chunked_equal_one_block(chunk, monkeypatch):
    """The cells' sign vectors computed ``SIGN_CHUNK`` cells at a time (chunks of 1, 7 and 100
    cells on a 40 x 40 map with 32 rotated obstacles, 1045 polytopes) give the same
    arrangement as one block over all cells: the same polytope of every cell, the same sign
    vectors and facet rows."""
    from pathpref.geometry import arrangement
    from pathpref.geometry.generate import random_floor_plan
    from pathpref.geometry.maps import load_map

    spec = load_map(random_floor_plan(40, 40, 32, seed=1))
    monkeypatch.setattr(arrangement, "SIGN_CHUNK", 10**9)
    whole = arrangement.build_arrangement(spec)
    monkeypatch.setattr(arrangement, "SIGN_CHUNK", chunk)
    part = arrangement.build_arrangement(spec)
    assert len(whole.signs) == 1045
    assert np.array_equal(part.cell_polytope, whole.cell_polytope)
    assert np.array_equal(part.signs, whole.signs) and part.signs.dtype == bool
    assert all(np.array_equal(a, b) for a, b in zip(part.rows, whole.rows, strict=True))
