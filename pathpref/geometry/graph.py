"""The polytope graph ``G = (V, E)`` (paper Sec. IV-A/B, extended to any convex obstacles).

Vertices are the free polytopes of the arrangement (those holding a free cell). Two kinds of edge
join them:

* a *facet edge* (the paper's): the sign vectors of ``v`` and ``w`` differ in exactly one line
  ``h`` and ``h`` carries a facet of positive length of both (equivalently, ``h`` is an essential
  row of ``v`` and flipping it gives ``w``). The edge records ``h``.
* a *move edge*: a straight (N, E, S, W) grid move from a cell of ``v`` to a cell of ``w`` crosses
  two or more lines at once, through thin polytopes that hold no cell (or through an obstacle
  thinner than a cell, which the grid of cell centres cannot resolve). Such a move is a
  transition from ``v`` to ``w``; without this edge rotated obstacles cut free space into
  islands. The edge records ``-1`` for its line.

On maps whose obstacles are cell rectangles (the paper's), every straight move crosses at most
one line, so there are no move edges and the graph is the paper's. Facet edges are numbered
first, in the order of the vertices' essential rows; move edges follow, in order of their vertex
pairs. The neighbour order of a vertex is its facet neighbours (essential-row order), then its
move neighbours (ascending id), so "neighbour k of v" is stable for a given map.

Memory is ``O(P + E)``: edges are found through sorted pair keys, never a ``P x P`` table.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .arrangement import Arrangement

#: the straight moves that define move edges (E and N; W and S are their reverses)
_STRAIGHT = np.array([[1, 0], [0, 1]])


@dataclass(frozen=True)
class PolytopeGraph:
    """Adjacency of free polytopes.

    Attributes:
        edges: ``(E, 2)`` vertex pairs ``(u, w)`` with ``u < w``.
        edge_hyperplane: ``(E,)`` index of the line a facet edge crosses; -1 for a move edge.
        neighbors: per vertex, the array of neighbour vertex ids.
        neighbor_edges: per vertex, the edge id toward each neighbour.
        pair_keys: sorted ``u * P + w`` over both orientations of every edge.
        pair_edge: the edge id of each entry of ``pair_keys``.
    """

    edges: np.ndarray
    edge_hyperplane: np.ndarray
    neighbors: tuple[np.ndarray, ...]
    neighbor_edges: tuple[np.ndarray, ...]
    pair_keys: np.ndarray
    pair_edge: np.ndarray

    @property
    def n_edges(self) -> int:
        """Number of edges (facet and move edges)."""
        return len(self.edges)

    @property
    def n_move_edges(self) -> int:
        """Edges that join polytopes through a multi-line move (no shared facet)."""
        return int((self.edge_hyperplane < 0).sum())

    @property
    def max_degree(self) -> int:
        """Largest number of neighbours of a polytope."""
        return max((len(n) for n in self.neighbors), default=0)

    def neighbor_table(self) -> np.ndarray:
        """``(P, K)`` neighbour ids per polytope, padded with -1 (``K = max(max_degree, 1)``).

        Slot ``k`` of row ``v`` is the ``k``-th neighbour ``N(v)[k]``: the index a preference
        ``p_v`` is sampled and stored by in the belief and the planners."""
        table = -np.ones((len(self.neighbors), max(self.max_degree, 1)), dtype=int)
        for v, nb in enumerate(self.neighbors):
            table[v, : len(nb)] = nb
        return table

    def edges_between(self, v: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Edge id joining each pair ``(v[i], w[i])`` of polytope ids (-1 where not adjacent)."""
        v, w = np.broadcast_arrays(np.asarray(v, dtype=np.int64), np.asarray(w, dtype=np.int64))
        key = v * len(self.neighbors) + w
        pos = np.clip(np.searchsorted(self.pair_keys, key), 0, max(len(self.pair_keys) - 1, 0))
        if len(self.pair_keys) == 0:
            return np.full(key.shape, -1, dtype=np.int64)
        return np.where(self.pair_keys[pos] == key, self.pair_edge[pos], -1)

    def edge_between(self, v: int, w: int) -> int:
        """Id of the edge joining polytopes ``v`` and ``w`` (-1 when not adjacent)."""
        return int(self.edges_between(np.array(v), np.array(w)))

    def neighbor_index(self, v: int, w: int) -> int:
        """Position of ``w`` in ``neighbors[v]`` (-1 when not adjacent)."""
        hit = np.flatnonzero(self.neighbors[v] == w)
        return int(hit[0]) if len(hit) else -1


def straight_move_pairs(arr: Arrangement) -> np.ndarray:
    """``(M, 2)`` polytope pairs ``(v, w)``, ``v != w``, joined by a straight move between free
    cells that crosses two or more lines (see module docstring), each unordered pair once."""
    pairs = []
    for dx, dy in _STRAIGHT:
        tgt = arr.cells + [dx, dy]
        ok = (tgt[:, 0] <= arr.width) & (tgt[:, 1] <= arr.height)
        src = np.flatnonzero(ok)
        j = arr.cell_index[tgt[src, 0] - 1, tgt[src, 1] - 1]
        src, j = src[j >= 0], j[j >= 0]
        v, w = arr.cell_polytope[src], arr.cell_polytope[j]
        diff = v != w
        v, w = v[diff], w[diff]
        many = arr.lines_between(v, w) >= 2
        pairs.append(np.stack([np.minimum(v, w)[many], np.maximum(v, w)[many]], axis=1))
    allp = np.concatenate(pairs) if pairs else np.zeros((0, 2), dtype=int)
    return np.unique(allp, axis=0) if len(allp) else allp.reshape(0, 2).astype(int)


def build_graph(arr: Arrangement) -> PolytopeGraph:
    """Join polytopes by facet edges and move edges (see module docstring)."""
    P = arr.n_polytopes
    key = {arr.signs[v].tobytes(): v for v in range(P)}
    found: dict[tuple[int, int], int] = {}
    edges: list[tuple[int, int]] = []
    hyper: list[int] = []
    nbrs: list[list[int]] = [[] for _ in range(P)]
    for v in range(P):
        for h in arr.rows[v]:
            s = arr.signs[v].copy()
            s[h] = ~s[h]
            w = key.get(s.tobytes(), -1)
            if w < 0:
                continue
            nbrs[v].append(w)
            pair = (min(v, w), max(v, w))
            if pair not in found:
                found[pair] = len(edges)
                edges.append(pair)
                hyper.append(int(h))
    move_nbrs: list[list[int]] = [[] for _ in range(P)]
    for v, w in straight_move_pairs(arr).tolist():
        found[(v, w)] = len(edges)
        edges.append((v, w))
        hyper.append(-1)
        move_nbrs[v].append(w)
        move_nbrs[w].append(v)
    for v in range(P):
        nbrs[v].extend(sorted(move_nbrs[v]))
    E = np.array(edges, dtype=np.int64).reshape(-1, 2)
    eid = np.arange(len(E), dtype=np.int64)
    keys = np.concatenate([E[:, 0] * P + E[:, 1], E[:, 1] * P + E[:, 0]])
    order = np.argsort(keys, kind="stable")
    neighbors = tuple(np.array(n, dtype=int) for n in nbrs)
    neighbor_edges = tuple(
        np.array([found[(min(v, w), max(v, w))] for w in neighbors[v]], dtype=int)
        for v in range(P)
    )
    return PolytopeGraph(
        edges=E.astype(int),
        edge_hyperplane=np.array(hyper, dtype=int),
        neighbors=neighbors,
        neighbor_edges=neighbor_edges,
        pair_keys=keys[order],
        pair_edge=np.concatenate([eid, eid])[order],
    )
