"""The polytope graph ``G = (V, E)`` (paper Sec. IV-A/B).

Vertices are the free polytopes of the arrangement. Two polytopes are joined when their sign
vectors differ in exactly one line ``h`` and ``h`` carries a facet of positive length of both
(equivalently, ``h`` is an essential row of one of them: the region across that facet is the
other). Each edge records the line it crosses. The neighbour order of a vertex follows its
essential rows, so "neighbour k of v" is stable for a given map.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .arrangement import Arrangement


@dataclass(frozen=True)
class PolytopeGraph:
    """Adjacency of free polytopes.

    Attributes:
        edges: ``(E, 2)`` vertex pairs ``(u, w)`` with ``u < w``.
        edge_hyperplane: ``(E,)`` index of the line each edge crosses.
        neighbors: per vertex, the array of neighbour vertex ids.
        neighbor_edges: per vertex, the edge id toward each neighbour.
        edge_id: ``(P, P)`` matrix, edge id or -1.
    """

    edges: np.ndarray
    edge_hyperplane: np.ndarray
    neighbors: tuple[np.ndarray, ...]
    neighbor_edges: tuple[np.ndarray, ...]
    edge_id: np.ndarray

    @property
    def n_vertices(self) -> int:
        return len(self.neighbors)

    @property
    def n_edges(self) -> int:
        return len(self.edges)

    @property
    def max_degree(self) -> int:
        return max((len(n) for n in self.neighbors), default=0)

    def edge_between(self, v: int, w: int) -> int:
        """Id of the edge joining polytopes ``v`` and ``w`` (-1 when not adjacent)."""
        return int(self.edge_id[v, w])

    def edges_between(self, v: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Vectorised :meth:`edge_between` over arrays of polytope ids (-1: not adjacent)."""
        return self.edge_id[np.asarray(v), np.asarray(w)]

    def neighbor_index(self, v: int, w: int) -> int:
        """Position of ``w`` in ``neighbors[v]`` (-1 when not adjacent)."""
        hit = np.flatnonzero(self.neighbors[v] == w)
        return int(hit[0]) if len(hit) else -1


def build_graph(arr: Arrangement) -> PolytopeGraph:
    """Join polytopes that share a facet (see module docstring)."""
    P = arr.n_polytopes
    key = {arr.signs[v].tobytes(): v for v in range(P)}
    edge_id = -np.ones((P, P), dtype=int)
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
            if edge_id[v, w] < 0:
                edge_id[v, w] = edge_id[w, v] = len(edges)
                edges.append((min(v, w), max(v, w)))
                hyper.append(int(h))
    neighbors = tuple(np.array(n, dtype=int) for n in nbrs)
    neighbor_edges = tuple(edge_id[v, neighbors[v]] for v in range(P))
    return PolytopeGraph(
        edges=np.array(edges, dtype=int).reshape(-1, 2),
        edge_hyperplane=np.array(hyper, dtype=int),
        neighbors=neighbors,
        neighbor_edges=neighbor_edges,
        edge_id=edge_id,
    )
