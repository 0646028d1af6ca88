"""Constrained cost tables against a brute-force search on a layered graph."""

from __future__ import annotations

import heapq

import numpy as np
import pytest

from pathpref.inference.costs import build_cost_tables


def brute_constrained(world, o: int, k: int, g: int) -> float:
    """Shortest path o -> g that leaves v(o) only toward N(v)[k] (then unconstrained)."""
    m, cp = world.motion, world.cell_polytope
    v = cp[o]
    if cp[g] == v:
        return float(world.motion.distances_from(np.array([o]))[0, g])
    p = world.graph.neighbors[v][k]
    dist = {(o, 0): 0.0}
    heap = [(0.0, o, 0)]
    while heap:
        d, x, left = heapq.heappop(heap)
        if d > dist.get((x, left), np.inf):
            continue
        if left and x == g:
            return d
        for a in range(8):
            if m.blocked[x, a]:
                continue
            t = m.next_cell[x, a]
            if left:
                nl = 1
            elif cp[t] == v:
                nl = 0
            elif cp[t] == p:
                nl = 1
            else:
                continue
            nd = d + m.cost[x, a]
            if nd < dist.get((t, nl), np.inf):
                dist[(t, nl)] = nd
                heapq.heappush(heap, (nd, t, nl))
    return np.inf


@pytest.fixture(scope="module")
def rotated_world():
    """A floor plan with rotated obstacles: thin polytopes, move edges, multi-line moves."""
    from pathpref.geometry.generate import random_floor_plan
    from pathpref.geometry.world import load_world

    w = load_world(random_floor_plan(14, 12, 6, n_boxes=1, seed=4))
    assert w.graph.n_move_edges > 0
    return w


@pytest.mark.parametrize("name", ["simple", "office", "classroom", "rotated"])
def test_constrained_costs_match_brute_force(worlds, rotated_world, name):
    w = rotated_world if name == "rotated" else worlds[name]
    rng = np.random.default_rng(3)
    goals = rng.choice(w.n_cells, size=6, replace=False)
    t = build_cost_tables(w, goals)
    cells = rng.choice(w.n_cells, size=min(40, w.n_cells), replace=False)
    for o in cells:
        v = w.cell_polytope[o]
        for k in range(len(w.graph.neighbors[v])):
            for gi, g in enumerate(goals):
                ref = brute_constrained(w, int(o), k, int(g))
                if np.isfinite(ref):
                    assert t.constrained[o, k, gi] == pytest.approx(ref)
                    assert t.feasible[o, k, gi]
                else:  # constraint cannot be met: the table falls back to the plain distance
                    assert not t.feasible[o, k, gi]
                    assert t.constrained[o, k, gi] == t.dist[gi, o]


def test_unconstrained_distance_is_octile_on_empty_map():
    from pathpref.geometry.world import load_world

    w = load_world({"name": "empty", "width": 5, "height": 4, "obstacles": []})
    t = build_cost_tables(w, np.array([w.cell((5, 4))]))
    s = w.cell((1, 1))
    assert t.dist[0, s] == pytest.approx(3 * np.sqrt(2) + 1)
