"""One rule for which moves exist: the robot's footprint sweeps a move only if it keeps its reach
from every obstacle and wall (pathpref/geometry/footprint.py), checked against shapely's exact
distances, by hand, on the paper's maps (no move removed) and on generated plans."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pathpref.errors import MapError
from pathpref.geometry.footprint import (
    DEFAULT_FOOTPRINT,
    POINT_ROBOT,
    Clearance,
    Footprint,
    segment_segment_distance,
)
from pathpref.geometry.generate import floor_plan, random_floor_plan
from pathpref.geometry.grid import MOVES
from pathpref.geometry.maps import load_map
from pathpref.geometry.world import load_world

shapely = pytest.importorskip("shapely")
from shapely.geometry import LineString, Point, Polygon  # noqa: E402

SETTINGS = settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
#: float tolerance of the comparisons with shapely (distances of order 1 cell)
TOL = 1e-9


def test_a_diamond_blocks_the_moves_that_pass_too_close():
    """A square turned 45 degrees, corners (2.95, 1.5), (3.5, 0.95), (4.05, 1.5), (3.5, 2.05).
    The E move from cell (2, 2) to (3, 2), centres (1.5, 1.5) to (2.5, 1.5), ends 0.45 from
    the left corner; the E move from (3, 3) to (4, 3), centres (2.5, 2.5) to (3.5, 2.5), ends
    0.45 above the top corner (the upper-left edge's nearest point is that corner: the
    projection of (3.5, 2.5) onto it falls past its end). Reach 0.4: both allowed; reach 0.5:
    both blocked. With the corners 0.15 farther out (half-diagonal 0.7) they pass at 0.3:
    blocked for the default robot, allowed for a point."""
    def diamond(h):
        return [[3.5 - h, 1.5], [3.5, 1.5 - h], [3.5 + h, 1.5], [3.5, 1.5 + h]]

    raw = {"name": "diamond", "width": 6, "height": 4,
           "obstacles": [{"vertices": diamond(0.55)}]}
    c = Clearance(load_map(raw))
    assert c.distance([1.5, 1.5], [2.5, 1.5])[0] == pytest.approx(0.45, abs=TOL)
    assert c.distance([2.5, 2.5], [3.5, 2.5])[0] == pytest.approx(0.45, abs=TOL)
    E = 2
    for fp, blocked in ((DEFAULT_FOOTPRINT, False), (Footprint(0.4, 0.1), True)):
        world = load_world(raw, footprint=fp)
        for cell in ((2, 2), (3, 3)):
            assert world.motion.blocked[world.cell(cell), E] == blocked, (fp, cell)
    near = {**raw, "obstacles": [{"vertices": diamond(0.7)}]}
    assert load_world(near).motion.blocked[load_world(near).cell((2, 2)), E]
    point = load_world(near, footprint=POINT_ROBOT)
    assert not point.motion.blocked[point.cell((2, 2)), E]


@SETTINGS
@given(st.lists(st.floats(-3, 3), min_size=8, max_size=8), st.integers(0, 2**31 - 1))
def test_segment_distance_matches_shapely(coords, seed):
    p, q, a, b = np.array(coords).reshape(4, 2)
    want = LineString([p, q]).distance(LineString([a, b])) if (p != q).any() and (a != b).any() \
        else None
    if want is not None:
        assert segment_segment_distance(p, q, a, b) == pytest.approx(want, abs=TOL)


@SETTINGS
@given(st.integers(6, 16), st.integers(6, 16), st.integers(1, 6), st.integers(0, 2),
       st.integers(0, 2**31 - 1), st.sampled_from([DEFAULT_FOOTPRINT, Footprint(0.45, 0.05)]))
def test_every_allowed_move_clears_and_every_removed_one_touches(W, H, n_rot, n_box, seed, fp):
    """Property: an allowed move's swept disc keeps the reach from every obstacle (shapely's
    polygon-to-segment distance) and stays inside the walls; a move the corner rule allows but
    the footprint removes comes closer than the reach (the rule is exact, not conservative)."""
    raw = random_floor_plan(W, H, n_rot, n_box, seed=seed, size_range=(0.6, 3.0))
    world = load_world(raw, footprint=fp)
    point = load_world(raw, footprint=POINT_ROBOT)
    polys = [Polygon(o.vertices) for o in world.spec.obstacles]
    box = Polygon([(0, 0), (W, 0), (W, H), (0, H)]).exterior
    centres = world.cells - 0.5
    for s, a in zip(*np.nonzero(~point.motion.blocked), strict=True):
        t = point.motion.next_cell[s, a]
        seg = LineString([centres[s], centres[t]])
        d = min([p.distance(seg) for p in polys] + [box.distance(seg)])
        if world.motion.blocked[s, a]:
            assert d < fp.reach + TOL, (s, a, d)
        else:
            assert d >= fp.reach - TOL, (s, a, d)
            assert world.motion.next_cell[s, a] == t


def test_the_paper_maps_keep_every_move_and_their_identity():
    """Cell rectangles: straight moves keep 0.5 cells, diagonal ones sqrt(2)/2, more than the
    reach 0.4 (footprint.py's docstring); so the motion, graph and map hash are the point
    robot's, and the paper preset's stored replays (tests marked cross_cpu) are unchanged."""
    for name in ("simple", "office", "classroom"):
        w, p = load_world(name), load_world(name, footprint=POINT_ROBOT)
        for field in ("next_cell", "cost", "blocked", "crossed_edge"):
            assert np.array_equal(getattr(w.motion, field), getattr(p.motion, field)), name
        assert np.array_equal(w.graph.edges, p.graph.edges)
        assert "footprint_reach" not in w.spec.canonical()
    assert "footprint_reach" in load_map(floor_plan(7)).canonical()


def test_the_graph_holds_only_transitions_the_robot_makes():
    """Every edge of the graph is crossed by an allowed move, and every allowed move that
    changes polytope crosses the edge between its two polytopes."""
    for seed in (3, 11):
        world = load_world(floor_plan(seed))
        m = world.motion
        crossed = np.unique(m.crossed_edge[m.crossed_edge >= 0])
        assert np.array_equal(crossed, np.arange(world.graph.n_edges))
        s, a = np.nonzero(~m.blocked)
        v, w = world.cell_polytope[s], world.cell_polytope[m.next_cell[s, a]]
        ch = v != w
        assert np.array_equal(world.graph.edges_between(v[ch], w[ch]), m.crossed_edge[s, a][ch])
        for u in range(world.n_polytopes):  # neighbour lists agree with the edges
            for k, nb in enumerate(world.graph.neighbors[u]):
                assert world.graph.edge_between(u, int(nb)) == world.graph.neighbor_edges[u][k]


def test_a_route_through_a_gap_too_narrow_is_refused_naming_it():
    """A wall at x in [3.15, 4] with a gap at y in (2, 2.6): the only free cell in it, (4, 3),
    has its centre (3.5, 2.5) 0.1 from the wall above. A point robot goes through; the
    default robot (reach 0.4) cannot, and the route that needs the gap is refused in one
    line naming the first passage it cannot make, (3, 3) to (4, 3), 0.10 cells from the wall."""
    raw = {"name": "gap", "width": 7, "height": 5, "obstacles": [
        {"vertices": [[3.15, 2.6], [4.0, 2.6], [4.0, 5.0], [3.15, 5.0]]},
        {"vertices": [[3.15, 0.0], [4.0, 0.0], [4.0, 2.0], [3.15, 2.0]]},
    ], "preference": {"route": [[1, 1], [6, 1]], "closed": False}}
    assert load_world(raw, footprint=POINT_ROBOT).preference is not None
    with pytest.raises(MapError) as err:
        load_world(raw)
    msg = str(err.value)
    assert "\n" not in msg and "waypoint 2 cannot be reached from 1" in msg
    assert "(3, 3) to (4, 3) is too narrow" in msg and "0.10 cells" in msg
    assert "clearance 0.1" in msg


def test_generated_plans_route_in_the_robots_free_area():
    """floor_plan draws waypoints from the robot's largest component, so every generated
    plan loads for the default robot and its route's waypoints are mutually reachable."""
    for seed in range(20, 32):
        for kind in ("open", "loop"):
            world = load_world(floor_plan(seed, kind))
            pts = [world.cell(tuple(c)) for c in world.spec.preference["route"]]
            d = world.motion.distances_from(np.array(pts[:1]))[0]
            assert np.isfinite(d[pts]).all()


def test_point_checks_agree_with_shapely():
    raw = random_floor_plan(12, 9, 3, seed=5, size_range=(1.0, 3.0))
    spec = load_map(raw)
    c = Clearance(spec)
    rng = np.random.default_rng(0)
    polys = [Polygon(o.vertices) for o in spec.obstacles]
    box = Polygon([(0, 0), (12, 0), (12, 9), (0, 9)])
    for xy in rng.uniform([0, 0], [12, 9], size=(200, 2)):
        want = min(p.distance(Point(xy)) for p in polys) >= 0.4 and \
            box.exterior.distance(Point(xy)) >= 0.4 and box.contains(Point(xy))
        assert c.clear_at(xy, 0.4) == want


def test_moves_are_symmetric():
    world = load_world(floor_plan(5))
    m = world.motion
    for s, a in zip(*np.nonzero(~m.blocked), strict=True):
        t = m.next_cell[s, a]
        assert not m.blocked[t, (a + 4) % 8] and m.next_cell[t, (a + 4) % 8] == s
        assert np.array_equal(world.cells[t] - world.cells[s], MOVES[a])
