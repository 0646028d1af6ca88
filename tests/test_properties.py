"""Property tests on random maps with random convex obstacles (rotated, overlapping, touching
the border): arrangement invariants, grid moves, the belief as a distribution and equal to the
brute-force posterior."""

from __future__ import annotations

import itertools

import numpy as np
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from scipy.spatial import ConvexHull

from pathpref.errors import MapError
from pathpref.geometry.world import load_world
from pathpref.inference.belief import PreferenceBelief
from pathpref.inference.human import ObservationModel

SETTINGS = settings(max_examples=40, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])


@st.composite
def random_maps(draw, max_side: int = 10):
    W = draw(st.integers(3, max_side))
    H = draw(st.integers(3, max_side))
    obstacles = []
    for _ in range(draw(st.integers(0, 4))):
        n = draw(st.integers(3, 6))
        pts = np.array([[draw(st.floats(0, W)), draw(st.floats(0, H))] for _ in range(n)])
        # snap some points onto the border (obstacles touching the walls)
        pts[:, 0] = np.where(pts[:, 0] < 0.4, 0.0, np.where(pts[:, 0] > W - 0.4, W, pts[:, 0]))
        pts[:, 1] = np.where(pts[:, 1] < 0.4, 0.0, np.where(pts[:, 1] > H - 0.4, H, pts[:, 1]))
        try:
            hull = ConvexHull(pts)
        except Exception:  # noqa: BLE001 - degenerate point sets are skipped
            continue
        if hull.volume < 0.3:
            continue
        obstacles.append({"vertices": pts[hull.vertices].tolist()})
    raw = {"name": "random", "width": W, "height": H, "obstacles": obstacles}
    try:
        world = load_world(raw)
    except MapError:
        assume(False)
    return world


@SETTINGS
@given(random_maps())
def test_arrangement_invariants(world):
    arr, graph = world.arrangement, world.graph
    assert len(world.cell_polytope) == world.n_cells and (world.cell_polytope >= 0).all()
    for v in range(world.n_polytopes):
        centres = world.cells[arr.polytope_cells(v)] - 0.5
        assert len(centres) > 0
        assert (centres @ arr.A[v].T - arr.b[v] <= 1e-9).all()
        # a cell is in exactly one polytope: no other polytope's sign vector matches its centre
    side = (world.cells - 0.5) @ arr.normals.T - arr.offsets > 1e-9
    matches = (side[:, None, :] == arr.signs[None, :, :]).all(axis=2)
    assert (matches.sum(axis=1) == 1).all()
    for v, nb in enumerate(graph.neighbors):
        for w in nb:
            assert v in graph.neighbors[w]
            assert graph.edge_between(v, w) == graph.edge_between(w, v) >= 0
    for (u, w), h in zip(graph.edges, graph.edge_hyperplane):
        diff = np.flatnonzero(arr.signs[u] != arr.signs[w]).tolist()
        assert diff == [h] if h >= 0 else len(diff) >= 2  # facet edge / move edge


@SETTINGS
@given(random_maps())
def test_moves_cross_exactly_one_edge(world):
    """A move that changes polytope records the one graph edge between the two polytopes."""
    m = world.motion
    for s in range(world.n_cells):
        for a in range(8):
            t = m.next_cell[s, a]
            u, v = world.cell_polytope[s], world.cell_polytope[t]
            if m.blocked[s, a]:
                assert t == s and m.crossed_edge[s, a] == -1
            elif u != v:
                e = m.crossed_edge[s, a]
                assert e >= 0 and set(world.graph.edges[e]) == {u, v}
            else:
                assert m.crossed_edge[s, a] == -1


@SETTINGS
@given(random_maps(max_side=7), st.integers(0, 2**32 - 1))
def test_belief_is_a_distribution_and_exact(world, seed):
    rng = np.random.default_rng(seed)
    G = min(4, world.n_cells)
    goals = rng.choice(world.n_cells, size=G, replace=False)
    model = ObservationModel.build(world, goals, normalize=bool(seed % 2))
    belief = PreferenceBelief(model)
    obs = [(int(rng.integers(world.n_cells)), int(rng.integers(8))) for _ in range(12)]
    for s, h in obs:
        belief.update(s, h)
        p = belief.goal_marginal()
        assert np.isfinite(p).all() and (p >= 0).all() and abs(p.sum() - 1) < 1e-9
    degs = [len(n) for n in world.graph.neighbors]
    if not 0 < np.prod([max(d, 1) for d in degs], dtype=float) <= 512:
        return
    # brute force over every preference vector
    choices = [range(d) if d else [0] for d in degs]
    thetas = np.array(list(itertools.product(*choices)), dtype=int).reshape(-1, len(degs))
    logp = np.zeros((G, len(thetas)))
    for s, h in obs:
        v = world.cell_polytope[s]
        if degs[v]:
            logp += np.log(model.likelihood[s, h][:, thetas[:, v]])
        else:
            logp += np.log(model.likelihood[s, h][:, :1])
    post = np.exp(logp - logp.max())
    post /= post.sum()
    assert np.allclose(belief.goal_marginal(), post.sum(axis=1), atol=1e-9)
