"""Constrained cost-to-go tables (paper Eq. 5, SPEC 4), precomputed once per map and goal set.

For a goal ``g`` and a polytope ``v`` with preferred neighbour ``p = N(v)[k]``, the constrained
cost-to-go from a cell ``o`` in ``v`` is the length of the shortest grid path to ``g`` that stays in
``v`` until it leaves through the face toward ``p``, and is unconstrained afterwards::

    D_{v,k}(o, g) = min_{a in v, a -> b crosses edge (v, p)}  d_v(o, a) + c(a, b) + d(b, g)

with ``d_v`` the grid distance using only cells of ``v`` and ``d`` the unconstrained grid
distance. When ``g`` lies in ``v`` nothing is constrained: ``D_{v,k}(o, g) = d(o, g)``. If the
constraint cannot be met (the cells of a thin slanted polytope need not be grid-connected),
``D`` falls back to ``d`` for that cell, so the human model stays defined.

Exact and without an all-pairs search: ``d_v(o, a)`` is symmetric (moves inside ``v`` are), so for
each (polytope, exit, goal) one multi-source Dijkstra inside ``v``, started from every exit cell
``a`` with the initial cost ``min_b c(a, b) + d(b, g)``, gives ``D_{v,k}(., g)`` for every cell of
``v`` at once (compiled; ``O(|Omega_g| sum_v deg(v) |v| log |v|)`` time, ``O(n)`` extra memory).
The unconstrained ``d`` is one Dijkstra over the whole grid per goal.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

from ..geometry.world import World


@dataclass(frozen=True)
class CostTables:
    """Cost-to-go for a goal set.

    Attributes:
        goals: ``(G,)`` goal cell indices.
        dist: ``(G, n)`` unconstrained grid distance ``d(o, g)`` (inf: unreachable).
        constrained: ``(n, K, G)`` ``D_{v(o),k}(o, g)``; ``K`` = the graph's maximum degree,
            entries with ``k >= deg(v(o))`` are ``inf``.
        goal_polytope: ``(G,)`` polytope of each goal.
        feasible: ``(n, K, G)`` True where the constraint can be met (or the goal lies in the
            cell's polytope); elsewhere ``constrained`` holds the unconstrained ``d``.
    """

    goals: np.ndarray
    dist: np.ndarray
    constrained: np.ndarray
    goal_polytope: np.ndarray
    feasible: np.ndarray


@nb.njit(cache=True)
def _exit_dijkstra(next_cell, cost, blocked, crossed, cell_poly, poly_ptr, poly_cells, nbr_ptr,
                   nbr_edges, dist, D):
    """Fill ``D[o, k, g]`` for every cell ``o`` and neighbour slot ``k`` of its polytope: the
    multi-source Dijkstra of the module docstring. Unreachable entries stay ``inf``."""
    n = next_cell.shape[0]
    G = dist.shape[0]
    best = np.full(n, np.inf)
    heap_d = np.empty(9 * n + 8)
    heap_c = np.empty(9 * n + 8, np.int64)
    for v in range(len(poly_ptr) - 1):
        c0, c1 = poly_ptr[v], poly_ptr[v + 1]
        for k in range(nbr_ptr[v + 1] - nbr_ptr[v]):
            e = nbr_edges[nbr_ptr[v] + k]
            for g in range(G):
                h = 0
                for ci in range(c0, c1):
                    c = poly_cells[ci]
                    best[c] = np.inf
                    for a in range(8):
                        if crossed[c, a] == e:
                            val = cost[c, a] + dist[g, next_cell[c, a]]
                            if val < best[c]:
                                best[c] = val
                    if best[c] < np.inf:
                        # push (best[c], c)
                        i = h
                        h += 1
                        while i > 0 and heap_d[(i - 1) // 2] > best[c]:
                            heap_d[i] = heap_d[(i - 1) // 2]
                            heap_c[i] = heap_c[(i - 1) // 2]
                            i = (i - 1) // 2
                        heap_d[i] = best[c]
                        heap_c[i] = c
                while h > 0:
                    d, c = heap_d[0], heap_c[0]
                    # pop the root: move the last element down
                    h -= 1
                    ld, lc = heap_d[h], heap_c[h]
                    i = 0
                    while True:
                        j = 2 * i + 1
                        if j >= h:
                            break
                        if j + 1 < h and heap_d[j + 1] < heap_d[j]:
                            j += 1
                        if heap_d[j] >= ld:
                            break
                        heap_d[i] = heap_d[j]
                        heap_c[i] = heap_c[j]
                        i = j
                    heap_d[i] = ld
                    heap_c[i] = lc
                    if d > best[c]:
                        continue
                    for a in range(8):
                        t = next_cell[c, a]
                        if blocked[c, a] or t == c or cell_poly[t] != v:
                            continue
                        nd = d + cost[c, a]
                        if nd < best[t]:
                            best[t] = nd
                            i = h
                            h += 1
                            while i > 0 and heap_d[(i - 1) // 2] > nd:
                                heap_d[i] = heap_d[(i - 1) // 2]
                                heap_c[i] = heap_c[(i - 1) // 2]
                                i = (i - 1) // 2
                            heap_d[i] = nd
                            heap_c[i] = t
                for ci in range(c0, c1):
                    c = poly_cells[ci]
                    D[c, k, g] = best[c]


def build_cost_tables(world: World, goals: np.ndarray) -> CostTables:
    """Compute :class:`CostTables` for the goal cells ``goals`` (see module docstring)."""
    goals = np.asarray(goals, dtype=int)
    motion, graph = world.motion, world.graph
    n, G, K = world.n_cells, len(goals), max(graph.max_degree, 1)
    dist = motion.distances_from(goals)  # (G, n); moves are symmetric so d(o,g) = d(g,o)
    cell_poly = world.cell_polytope
    goal_poly = cell_poly[goals]
    order = np.argsort(cell_poly, kind="stable")
    poly_ptr = np.searchsorted(cell_poly[order], np.arange(world.n_polytopes + 1))
    deg = np.array([len(nb) for nb in graph.neighbors], dtype=np.int64)
    nbr_ptr = np.concatenate([[0], np.cumsum(deg)]).astype(np.int64)
    nbr_edges = np.concatenate([*graph.neighbor_edges, np.zeros(0, int)]).astype(np.int64)
    D = np.full((n, K, G), np.inf)
    _exit_dijkstra(np.asarray(motion.next_cell, dtype=np.int64),
                   np.asarray(motion.cost, dtype=np.float64), motion.blocked,
                   np.asarray(motion.crossed_edge, dtype=np.int64),
                   np.asarray(cell_poly, dtype=np.int64), poly_ptr.astype(np.int64),
                   order.astype(np.int64), nbr_ptr, nbr_edges,
                   np.ascontiguousarray(dist, dtype=np.float64), D)
    # goal inside v(o): nothing constrained; unmet constraint: fall back to d (in place: the
    # temporaries are (n, K, G) masks, not tables)
    slot = np.arange(K)[None, :] < deg[cell_poly][:, None]  # (n, K) real neighbour slots
    unconstrained = np.broadcast_to(dist.T[:, None, :], D.shape)
    inside = (goal_poly[None, :] == cell_poly[:, None])[:, None, :] & slot[:, :, None]
    np.copyto(D, unconstrained, where=inside)
    del inside
    feasible = np.isfinite(D)
    feasible &= slot[:, :, None]
    bad = ~np.isfinite(D)
    bad &= slot[:, :, None]
    bad &= np.isfinite(unconstrained)
    np.copyto(D, unconstrained, where=bad)
    del bad
    return CostTables(
        goals=goals, dist=dist, constrained=D, goal_polytope=goal_poly, feasible=feasible
    )
