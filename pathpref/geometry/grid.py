"""Grid motion (paper Sec. V "Transition model", SPEC 3, extended to any convex obstacles).

Eight compass actions, in this order (index = heading index everywhere in pathpref)::

    0 N (0, +1)   1 NE (+1, +1)   2 E (+1, 0)   3 SE (+1, -1)
    4 S (0, -1)   5 SW (-1, -1)   6 W (-1, 0)   7 NW (-1, +1)

Straight moves cost 1, diagonal moves sqrt(2). A move is *blocked* (the robot stays, cost 1) when
the target is outside the map or not free, and, for a diagonal move only, when it changes polytope
across more than one line (the paper's corner rule: a diagonal through an arrangement vertex,
past an obstacle corner, or through a polytope that holds no cell). A straight move between two
free cells is not blocked by this rule: it crosses the lines on which the sign vectors of its
two polytopes differ, in one step, and records the polytope it left and the one it entered (a
facet edge when that is one line, a move edge of :mod:`pathpref.geometry.graph` otherwise). On
the paper's axis-aligned maps a straight move crosses at most one line, so the rule is the
paper's. ``crossed_edge[s, a]`` is the graph edge a move crosses (-1: none). See
``docs/motion_rule.md`` for a picture.

**The robot's footprint.** A move is blocked, too, when the robot's footprint cannot sweep it:
:func:`apply_footprint` with the mask of :func:`swept_clear` (the exact rule of
:mod:`.footprint`: the segment between the two cell centres keeps the footprint's reach from
every obstacle and wall). This is the one rule for which moves exist, for the grid world and
the physical bodies alike. It removes no move on maps of cell rectangles (the paper's); on
rotated obstacles it removes the moves that cut a corner or pass through an obstacle thinner
than a cell. :func:`restrict_graph` then keeps only the graph edges some allowed move crosses,
so the planner and the human model see the transitions the body can perform.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components, dijkstra

from .arrangement import Arrangement
from .footprint import Clearance, Footprint
from .graph import PolytopeGraph, build_graph
from .maps import MapSpec

#: the action that keeps the robot in its cell (not one of the eight moves; the compliant
#: baseline's "stop" and a blocked plan's fallback)
STAY = -1

ACTION_NAMES = ("N", "NE", "E", "SE", "S", "SW", "W", "NW")
MOVES = np.array([[0, 1], [1, 1], [1, 0], [1, -1], [0, -1], [-1, -1], [-1, 0], [-1, 1]])
MOVE_COST = np.linalg.norm(MOVES, axis=1)
#: heading angle (radians, from +x counter-clockwise) of each action
ACTION_ANGLES = np.arctan2(MOVES[:, 1], MOVES[:, 0])
BLOCKED_COST = 1.0


def heading_to_action(angle: float) -> int:
    """Bin a heading angle (radians, 0 = east, counter-clockwise) into one of 8 sectors."""
    k = int(np.round(np.mod(angle, 2 * np.pi) / (np.pi / 4))) % 8  # 0 = E, 1 = NE, ...
    return (2 - k) % 8


@dataclass(frozen=True)
class GridMotion:
    """Deterministic grid transitions over free cells.

    Attributes:
        next_cell: ``(n, 8)`` index of the cell reached (the same cell when blocked).
        cost: ``(n, 8)`` action cost (1, sqrt(2), or 1 when blocked).
        blocked: ``(n, 8)`` bool.
        crossed_edge: ``(n, 8)`` graph edge crossed, -1 for none.
    """

    next_cell: np.ndarray
    cost: np.ndarray
    blocked: np.ndarray
    crossed_edge: np.ndarray

    @property
    def n_cells(self) -> int:
        """Number of free cells."""
        return len(self.next_cell)

    def adjacency(self) -> csr_matrix:
        """Sparse matrix of move costs between distinct cells (symmetric)."""
        n = self.n_cells
        src = np.repeat(np.arange(n), 8)
        dst = self.next_cell.ravel()
        w = self.cost.ravel()
        ok = ~self.blocked.ravel()
        return csr_matrix((w[ok], (src[ok], dst[ok])), shape=(n, n))

    def components(self) -> np.ndarray:
        """``(n,)`` label of each cell's connected component under the motion rule (0-based,
        numbered by first cell). Moves are symmetric, so weak and strong components agree."""
        _, labels = connected_components(self.adjacency(), directed=False)
        return labels

    def distances_from(self, sources: np.ndarray) -> np.ndarray:
        """Shortest grid distance from each source cell to every cell (inf: unreachable)."""
        return dijkstra(self.adjacency(), directed=True, indices=np.asarray(sources))


def move_targets(arr: Arrangement) -> tuple[np.ndarray, np.ndarray]:
    """``(n, 8)`` target cell of each move (-1: off the map or not free) and the ``(n, 8, 2)``
    target grid coordinates (1-based)."""
    tgt = arr.cells[:, None, :] + MOVES[None, :, :]
    inside = (tgt[..., 0] >= 1) & (tgt[..., 0] <= arr.width) & (tgt[..., 1] >= 1) & (
        tgt[..., 1] <= arr.height
    )
    tx = np.clip(tgt[..., 0] - 1, 0, arr.width - 1)
    ty = np.clip(tgt[..., 1] - 1, 0, arr.height - 1)
    return np.where(inside, arr.cell_index[tx, ty], -1), tgt


def swept_clear(spec: MapSpec, arr: Arrangement, footprint: Footprint) -> np.ndarray:
    """``(n, 8)`` whether the footprint sweeps each move between free cells without touching
    an obstacle or wall (:class:`~.footprint.Clearance`; False for moves off the free cells).
    Each unordered move is computed once (N, NE, E, SE; the others are their reverses)."""
    t_idx, _ = move_targets(arr)
    ok = np.zeros(t_idx.shape, dtype=bool)
    clearance = Clearance(spec)
    centres = arr.cells - 0.5
    for a in range(4):
        src = np.flatnonzero(t_idx[:, a] >= 0)
        dst = t_idx[src, a]
        clear = clearance.clear(centres[src], centres[dst], footprint.reach)
        ok[src, a] = clear
        ok[dst, (a + 4) % 8] = clear
    return ok


def build_motion(arr: Arrangement, graph: PolytopeGraph) -> GridMotion:
    """Tabulate every move from every free cell by the corner rule (see module docstring);
    :func:`apply_footprint` then removes the moves the robot cannot sweep."""
    n = arr.n_cells
    t_idx, _ = move_targets(arr)
    free = t_idx >= 0
    src = np.repeat(np.arange(n)[:, None], 8, axis=1)
    v_src = arr.cell_polytope[src]
    v_tgt = np.where(free, arr.cell_polytope[np.maximum(t_idx, 0)], -1)
    change = free & (v_src != v_tgt)
    edge = -np.ones((n, 8), dtype=int)
    edge[change] = graph.edges_between(v_src[change], v_tgt[change])
    diagonal = (MOVES[:, 0] != 0) & (MOVES[:, 1] != 0)
    lines = np.zeros((n, 8), dtype=int)
    lines[change] = arr.lines_between(v_src[change], v_tgt[change])
    ok = free & ((v_src == v_tgt) | ((edge >= 0) & ~(diagonal[None, :] & (lines > 1))))
    next_cell = np.where(ok, t_idx, src)
    cost = np.where(ok, MOVE_COST[None, :], BLOCKED_COST)
    crossed = np.where(ok & (v_src != v_tgt), edge, -1)
    return GridMotion(next_cell=next_cell, cost=cost, blocked=~ok, crossed_edge=crossed)


def apply_footprint(motion: GridMotion, swept: np.ndarray) -> GridMotion:
    """``motion`` with the moves outside ``swept`` (:func:`swept_clear`) blocked: the robot
    stays, at the cost of a blocked move, and crosses nothing."""
    ok = ~motion.blocked & swept
    src = np.repeat(np.arange(motion.n_cells)[:, None], 8, axis=1)
    return GridMotion(next_cell=np.where(ok, motion.next_cell, src),
                      cost=np.where(ok, motion.cost, BLOCKED_COST), blocked=~ok,
                      crossed_edge=np.where(ok, motion.crossed_edge, -1))


def restrict_graph(graph: PolytopeGraph, motion: GridMotion) -> tuple[PolytopeGraph, GridMotion]:
    """The graph's edges that some allowed move crosses, and the motion renumbered to them
    (module docstring). Edges keep their relative order (facet edges, then move edges) and
    each vertex its neighbours' order; when every edge is crossed, both are returned as they
    are."""
    used = np.zeros(graph.n_edges, dtype=bool)
    used[motion.crossed_edge[motion.crossed_edge >= 0]] = True
    if used.all():
        return graph, motion
    keep = np.flatnonzero(used)
    new_id = -np.ones(graph.n_edges, dtype=int)
    new_id[keep] = np.arange(len(keep))
    E = graph.edges[keep]
    P = len(graph.neighbors)
    mask = [used[e] for e in graph.neighbor_edges]
    eid = np.arange(len(E), dtype=np.int64)
    keys = np.concatenate([E[:, 0] * P + E[:, 1], E[:, 1] * P + E[:, 0]]).astype(np.int64)
    order = np.argsort(keys, kind="stable")
    pruned = PolytopeGraph(
        edges=E,
        edge_hyperplane=graph.edge_hyperplane[keep],
        neighbors=tuple(nb[m] for nb, m in zip(graph.neighbors, mask, strict=True)),
        neighbor_edges=tuple(new_id[ne[m]] for ne, m in zip(graph.neighbor_edges, mask,
                                                             strict=True)),
        pair_keys=keys[order],
        pair_edge=np.concatenate([eid, eid])[order],
    )
    crossed = np.where(motion.crossed_edge >= 0, new_id[np.maximum(motion.crossed_edge, 0)], -1)
    return pruned, GridMotion(next_cell=motion.next_cell, cost=motion.cost,
                              blocked=motion.blocked, crossed_edge=crossed)


def blocked_passage(spec: MapSpec, arr: Arrangement, footprint: Footprint, a: int, b: int) -> str:
    """Why cell ``b`` cannot be reached from cell ``a`` by a robot of ``footprint``: one
    sentence naming the first move the footprint blocks on a shortest path between them
    without the footprint (the passage too narrow for it, and how close it passes to an
    obstacle or wall), or saying that no path exists even for a point robot."""
    motion = build_motion(arr, build_graph(arr))
    dist, pred = dijkstra(motion.adjacency(), indices=int(a), return_predecessors=True)
    cell = lambda i: tuple(int(c) for c in arr.cells[i])  # noqa: E731
    if not np.isfinite(dist[b]):
        return f"no path joins {cell(a)} and {cell(b)} even for a point robot"
    path = [int(b)]
    for _ in range(arr.n_cells):  # a shortest path visits each cell at most once
        if path[-1] == a:
            break
        path.append(int(pred[path[-1]]))
    path.reverse()
    swept = swept_clear(spec, arr, footprint)
    clearance = Clearance(spec)
    centres = arr.cells - 0.5
    for u, w in zip(path[:-1], path[1:], strict=False):
        k = int(np.flatnonzero(motion.next_cell[u] == w)[0])
        if not swept[u, k]:
            d = min(float(clearance.distance(centres[u], centres[w])[0]),
                    float(clearance.wall_distance(centres[u], centres[w])[0]))
            return (f"the passage from {cell(u)} to {cell(w)} is too narrow for the robot: the "
                    f"move passes {max(d, 0.0):.2f} cells from an obstacle or wall, and the "
                    f"robot needs {footprint.reach:g} ({footprint.describe()})")
    return f"{cell(b)} cannot be reached from {cell(a)} by the robot ({footprint.describe()})"
