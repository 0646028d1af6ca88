"""Large-map memory (issue 28 item 3): the blocked computations give the arrays of one block,
and the per-cell likelihood tables hold each cell's own slots of the padded table, exactly."""

from __future__ import annotations

import numpy as np
import pytest

from pathpref.geometry import arrangement
from pathpref.geometry.generate import random_floor_plan, with_loop_preference
from pathpref.geometry.maps import load_map
from pathpref.geometry.world import World
from pathpref.inference import human
from pathpref.inference.human import GAMMA_H, ObservationModel, boltzmann, cost_excess


def _world_arrays(w: World) -> dict[str, np.ndarray]:
    a, g, m = w.arrangement, w.graph, w.motion
    return {"cell_polytope": a.cell_polytope, "signs": a.signs, "edges": g.edges,
            "edge_hyperplane": g.edge_hyperplane,
            "neighbors": np.concatenate([np.r_[len(n), n] for n in g.neighbors]),
            "next_cell": m.next_cell, "blocked": m.blocked, "crossed_edge": m.crossed_edge,
            "cost": m.cost, "preference": w.preference}


def test_120_map_chunked_equals_one_block(monkeypatch):
    """A 120 x 120 floor plan (the 500 x 500 bench map's obstacle density: 7 rotated, 14 boxes)
    built with sign blocks of 13 cells and pair blocks of 7 pairs gives exactly the arrays of
    one block over everything: cell polytopes, sign vectors, graph edges and neighbours, grid
    motion and preference."""
    spec = load_map(with_loop_preference(random_floor_plan(
        120, 120, 7, n_boxes=14, seed=0, size_range=(2.0, 12.0), name="floor_120")))
    monkeypatch.setattr(arrangement, "SIGN_CHUNK", 10**9)
    monkeypatch.setattr(arrangement, "PAIR_CHUNK", 10**9)
    whole = _world_arrays(World.from_spec(spec))
    monkeypatch.setattr(arrangement, "SIGN_CHUNK", 13)
    monkeypatch.setattr(arrangement, "PAIR_CHUNK", 7)
    world = World.from_spec(spec)
    part = _world_arrays(world)
    assert world.n_polytopes > 100 and world.motion.crossed_edge.max() > 100
    for k, v in whole.items():
        assert part[k].dtype == v.dtype and np.array_equal(part[k], v), k


@pytest.mark.parametrize("chunk", [1, 3, None])
def test_lines_between_is_the_count_of_differing_signs(chunk):
    """``lines_between`` against a loop over each pair's sign vectors (repeated pairs, a
    pair with itself, both orders) on a rotated 40 x 40 map."""
    arr = World.from_spec(load_map(random_floor_plan(40, 40, 16, seed=2))).arrangement
    rng = np.random.default_rng(0)
    v = rng.integers(0, arr.n_polytopes, size=300)
    w = rng.integers(0, arr.n_polytopes, size=300)
    v, w = np.r_[v, w, v[:5], 4], np.r_[w, v, w[:5], 4]
    want = [sum(int(a != b) for a, b in zip(arr.signs[i], arr.signs[j], strict=True))
            for i, j in zip(v.tolist(), w.tolist(), strict=True)]
    got = arr.lines_between(v, w, chunk)
    assert got.tolist() == want and got[-1] == 0 and max(want) >= 3


@pytest.fixture(scope="module")
def rotated():
    """A rotated 40 x 40 plan whose polytope degrees range from 0 or 1 to well above 4."""
    return World.from_spec(load_map(with_loop_preference(random_floor_plan(
        40, 40, 24, n_boxes=6, seed=3, size_range=(2.0, 8.0), name="rot40"))))


@pytest.mark.parametrize("normalize", [True, False])
def test_cell_tables_are_the_padded_tables_own_slots(rotated, normalize, monkeypatch):
    """Each cell's block of the per-cell tables is the padded Boltzmann table of the whole
    excess at that cell, slots ``0..k_s-1`` with ``k_s = max(deg(v(s)), 1)`` (degrees counted
    from the neighbour lists), exactly; the padded tables rebuilt from them equal the old
    padded ones exactly (pad slots ``exp(0)``, 1/8 normalised); built 7 cells at a time."""
    monkeypatch.setattr(human, "EXCESS_CHUNK", 7)
    goals = np.random.default_rng(1).choice(rotated.n_cells, size=5, replace=False)
    model = ObservationModel.build(rotated, goals, normalize=normalize)
    lik, probs = model.cell_likelihood, model.cell_heading_probs
    delta, delta_u = cost_excess(rotated, model.tables, chunk=10**6)
    want_lik = boltzmann(delta, GAMMA_H, normalize)
    want_probs = boltzmann(delta, GAMMA_H, True)
    deg = [len(rotated.graph.neighbors[v]) for v in rotated.cell_polytope.tolist()]
    assert min(deg) <= 1 and max(deg) >= 8
    for s in range(rotated.n_cells):
        k = max(deg[s], 1)
        assert lik[s].shape == (8, 5, k)
        assert np.array_equal(lik[s], want_lik[s, :, :, :k])
        assert np.array_equal(probs[s], want_probs[s, :, :, :k])
    assert lik.flat.size == 8 * 5 * sum(max(d, 1) for d in deg) < want_lik.size * 0.6
    assert np.array_equal(model.likelihood, want_lik)
    assert np.array_equal(model.heading_probs, want_probs)
    assert np.array_equal(model.goal_likelihood, boltzmann(delta_u, GAMMA_H, normalize))
    assert np.array_equal(model.goal_heading_probs, boltzmann(delta_u, GAMMA_H, True))
    assert (probs is lik) == normalize
