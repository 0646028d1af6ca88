"""Free space stays connected whatever the obstacles' rotation (for a point robot: the grid's
corner rule alone; the robot's footprint then removes the moves it cannot sweep,
tests/test_footprint.py), and the polytope sequence of a route still tells its homotopy class
(paper Sec. IV-B), on random floor plans."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.sparse.csgraph import dijkstra

from pathpref.geometry.footprint import POINT_ROBOT, Clearance
from pathpref.geometry.generate import (
    four_connected_components,
    random_floor_plan,
    rotated_rectangle,
)
from pathpref.geometry.maps import free_cell_mask
from pathpref.geometry.world import load_world

SETTINGS = settings(max_examples=25, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow])


def four_labels(world):
    lab, _ = four_connected_components(free_cell_mask(world.spec))
    x, y = world.cells[:, 0] - 1, world.cells[:, 1] - 1
    return lab[x, y]


@SETTINGS
@given(st.integers(8, 24), st.integers(8, 24), st.integers(1, 14), st.integers(0, 3),
       st.integers(0, 2**31 - 1), st.sampled_from(["arrangement", "coarse"]))
def test_motion_keeps_every_four_connected_component(W, H, n_rot, n_box, seed, decomposition):
    """Two free cells connected on the 4-connected grid are connected under the corner rule
    (a point robot)."""
    raw = random_floor_plan(W, H, n_rot, n_box, seed=seed, size_range=(0.6, 4.0))
    world = load_world({**raw, "decomposition": decomposition}, footprint=POINT_ROBOT)
    four = four_labels(world)
    motion = world.motion.components()
    for label in np.unique(four):
        # every 4-connected component lies inside one motion component
        assert len(np.unique(motion[four == label])) == 1


def test_rotated_40x40_reachable_fraction_is_one():
    """40x40 maps with 32 and 64 rotated rectangles: a point robot reaches all of the largest
    4-connected free area (the corner rule alone once reached 9% and 1%)."""
    for n in (32, 64):
        world = load_world(random_floor_plan(40, 40, n, seed=1), footprint=POINT_ROBOT)
        four = np.bincount(four_labels(world))[1:]
        motion = np.bincount(world.motion.components())
        assert motion.max() / four.max() >= 1.0
        assert world.graph.n_move_edges > 0


def test_warehouse_corridor_is_reachable():
    """Two racks and two rotated crates: the bottom corridor used to be cut off."""
    crates = [rotated_rectangle(np.array([6.3, 3.1]), np.array([1.6, 1.1]), 0.6),
              rotated_rectangle(np.array([10.2, 8.4]), np.array([1.8, 1.2]), 2.2)]
    world = load_world({"name": "warehouse", "width": 16, "height": 12, "obstacles": [
        {"cells": {"lower_left": [3, 5], "size": [10, 1]}},
        {"cells": {"lower_left": [3, 9], "size": [10, 1]}},
        *({"vertices": c.tolist()} for c in crates)]})
    d = world.motion.distances_from(np.array([world.cell((1, 1))]))[0]
    # every cell the robot's disc fits in is reached; the 5 others (centres 0.004 to 0.29
    # cells from a crate, under the reach 0.4) are cells it cannot stand in
    clearance = Clearance(world.spec)
    fits = np.array([clearance.clear_at(c - 0.5, world.footprint.reach) for c in world.cells])
    assert np.isfinite(d[fits]).all() and fits.sum() == world.n_cells - 5
    assert not np.isfinite(d[~fits]).any()
    for corridor in ((8, 3), (8, 7), (8, 11)):  # below, between and above the racks
        assert np.isfinite(d[world.cell(corridor)])


# --- homotopy ---------------------------------------------------------------------------------
def winding_number(loop: np.ndarray, p: np.ndarray) -> int:
    """Winding number of the closed polyline ``loop`` (points, last joins first) around ``p``."""
    d = loop - p
    ang = np.arctan2(d[:, 1], d[:, 0])
    turn = np.diff(np.concatenate([ang, ang[:1]]))
    turn = (turn + np.pi) % (2 * np.pi) - np.pi
    return int(np.round(turn.sum() / (2 * np.pi)))


def route(world, pred_from, a: int, b: int) -> list[int]:
    out = [b]
    while out[-1] != a:
        out.append(int(pred_from[out[-1]]))
    return out[::-1]


def polytope_sequence(world, cells: list[int]) -> list[int]:
    seq = [int(world.cell_polytope[cells[0]])]
    for c in cells[1:]:
        v = int(world.cell_polytope[c])
        if v != seq[-1]:
            seq.append(v)
    return seq


def touches_obstacle(world, cells: list[int]) -> bool:
    pts = world.cells[cells] - 0.5
    for p0, p1 in zip(pts[:-1], pts[1:]):
        seg = p0 + np.linspace(0, 1, 11)[:, None] * (p1 - p0)
        for o in world.spec.obstacles:
            if (seg @ o.A.T - o.b < -1e-9).all(axis=1).any():
                return True
    return False


def homotopy_pairs_checked(seed: int, decomposition: str = "arrangement") -> int:
    """Paper Sec. IV-B: same ends, different homotopy class -> different vertex sequence;
    returns how many non-homotopic pairs were compared on one random map.

    Two routes from s to t (the shortest, and the shortest through a random waypoint) are in
    different classes when the loop they make winds around some obstacle; routes that pass
    through an obstacle thinner than a cell have no class and are skipped."""
    rng = np.random.default_rng(seed)
    raw = random_floor_plan(16, 14, 5, n_boxes=1, seed=seed, size_range=(1.5, 4.0))
    world = load_world({**raw, "decomposition": decomposition})
    adj = world.motion.adjacency()
    comp = world.motion.components()
    big = np.flatnonzero(comp == np.bincount(comp).argmax())
    checked = 0
    for _ in range(20):
        s, t, w = (int(c) for c in rng.choice(big, size=3, replace=False))
        _, pred = dijkstra(adj, indices=[s, w], return_predecessors=True)
        r1 = route(world, pred[0], s, t)
        r2 = route(world, pred[0], s, w) + route(world, pred[1], w, t)[1:]
        if touches_obstacle(world, r1) or touches_obstacle(world, r2):
            continue
        loop = world.cells[r1 + r2[::-1][1:-1]] - 0.5
        centres = [o.vertices.mean(axis=0) for o in world.spec.obstacles]
        if any(winding_number(loop, c) != 0 for c in centres):
            checked += 1
            assert polytope_sequence(world, r1) != polytope_sequence(world, r2), (seed, r1, r2)
    return checked


@pytest.mark.parametrize("decomposition", ["arrangement", "coarse"])
def test_routes_in_different_homotopy_classes_cross_different_polytope_sequences(decomposition):
    checked = sum(homotopy_pairs_checked(seed, decomposition) for seed in range(30))
    assert checked >= 30  # enough non-homotopic pairs were actually compared
