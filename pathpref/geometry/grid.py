"""Grid motion (paper Sec. V "Transition model", SPEC 3, extended to any convex obstacles).

Eight compass actions, in this order (index = heading index everywhere in pathpref)::

    0 N (0, +1)   1 NE (+1, +1)   2 E (+1, 0)   3 SE (+1, -1)
    4 S (0, -1)   5 SW (-1, -1)   6 W (-1, 0)   7 NW (-1, +1)

Straight moves cost 1, diagonal moves sqrt(2). A move is *blocked* (the robot stays, cost 1) when
the target is outside the map or not free, and, for a diagonal move only, when it changes polytope
across more than one line (the paper's corner rule: a diagonal through an arrangement vertex,
past an obstacle corner, or through a polytope that holds no cell). A straight move between two
free cells is never blocked: it crosses the lines on which the sign vectors of its two polytopes
differ, in one step, and records the polytope it left and the one it entered (a facet edge when
that is one line, a move edge of :mod:`pathpref.geometry.graph` otherwise). Hence two free cells
connected on the 4-connected grid of free cells are connected under this rule, whatever the
obstacles' rotation. On the paper's axis-aligned maps a straight move crosses at most one line,
so the rule is the paper's. ``crossed_edge[s, a]`` is the graph edge a move crosses (-1: none).
See ``docs/motion_rule.md`` for a picture.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components, dijkstra

from .arrangement import Arrangement
from .graph import PolytopeGraph

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


def build_motion(arr: Arrangement, graph: PolytopeGraph) -> GridMotion:
    """Tabulate every move from every free cell (see module docstring)."""
    n = arr.n_cells
    tgt = arr.cells[:, None, :] + MOVES[None, :, :]  # (n, 8, 2) 1-based
    inside = (tgt[..., 0] >= 1) & (tgt[..., 0] <= arr.width) & (tgt[..., 1] >= 1) & (
        tgt[..., 1] <= arr.height
    )
    tx = np.clip(tgt[..., 0] - 1, 0, arr.width - 1)
    ty = np.clip(tgt[..., 1] - 1, 0, arr.height - 1)
    t_idx = np.where(inside, arr.cell_index[tx, ty], -1)
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
