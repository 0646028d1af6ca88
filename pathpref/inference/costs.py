"""Constrained cost-to-go tables (paper Eq. 5, SPEC 4), precomputed once per map and goal set.

For a goal ``g`` and a polytope ``v`` with preferred neighbour ``p = N(v)[k]``, the constrained
cost-to-go from a cell ``o`` in ``v`` is the length of the shortest grid path to ``g`` that stays in
``v`` until it leaves through the face toward ``p``, and is unconstrained afterwards::

    D_{v,k}(o, g) = min_{a in v, a -> b crosses edge (v, p)}  d_v(o, a) + c(a, b) + d(b, g)

with ``d_v`` the grid distance using only cells of ``v`` and ``d`` the unconstrained grid
distance. When ``g`` lies in ``v`` nothing is constrained: ``D_{v,k}(o, g) = d(o, g)``. If the
constraint cannot be met (the cells of a thin slanted polytope need not be grid-connected),
``D`` falls back to ``d`` for that cell, so the human model stays defined.

Everything is array work: one Dijkstra over the whole grid per goal set, one inside each
polytope, then a min-plus product per (polytope, neighbour) vectorised over goals.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse.csgraph import dijkstra

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


def build_cost_tables(world: World, goals: np.ndarray) -> CostTables:
    """Compute :class:`CostTables` for the goal cells ``goals`` (see module docstring)."""
    goals = np.asarray(goals, dtype=int)
    motion, graph = world.motion, world.graph
    n, G, K = world.n_cells, len(goals), max(graph.max_degree, 1)
    dist = motion.distances_from(goals)  # (G, n); moves are symmetric so d(o,g) = d(g,o)
    goal_poly = world.cell_polytope[goals]
    D = np.full((n, K, G), np.inf)
    feasible = np.zeros((n, K, G), dtype=bool)
    adj = motion.adjacency()
    for v in range(world.n_polytopes):
        cells = world.arrangement.polytope_cells(v)
        dv = dijkstra(adj[cells][:, cells], directed=True)  # (m, m)
        crossed = motion.crossed_edge[cells]  # (m, 8)
        step = motion.cost[cells]
        nxt = motion.next_cell[cells]
        for k, e in enumerate(graph.neighbor_edges[v]):
            a_loc, act = np.nonzero(crossed == e)
            if len(a_loc) == 0:
                continue
            # exit cost from each exit cell a: c(a, b) + d(b, g), minimised over its exit moves
            via = step[a_loc, act][:, None] + dist[:, nxt[a_loc, act]].T  # (moves, G)
            exit_cost = np.full((len(cells), G), np.inf)
            np.minimum.at(exit_cost, a_loc, via)
            has_exit = np.unique(a_loc)
            D[cells, k, :] = np.min(
                dv[:, has_exit, None] + exit_cost[None, has_exit, :], axis=1
            )
        deg = len(graph.neighbors[v])
        inside = goal_poly == v
        unconstrained = dist[:, cells].T  # (m, G)
        # goal inside v: nothing constrained; unmet constraint: fall back to d
        block = D[cells, :deg, :]
        block[:, :, inside] = unconstrained[:, None, inside]
        feasible[cells, :deg, :] = np.isfinite(block)
        bad = ~np.isfinite(block) & np.isfinite(unconstrained)[:, None, :]
        block[bad] = np.broadcast_to(unconstrained[:, None, :], block.shape)[bad]
        D[cells, :deg, :] = block
    return CostTables(
        goals=goals, dist=dist, constrained=D, goal_polytope=goal_poly, feasible=feasible
    )
