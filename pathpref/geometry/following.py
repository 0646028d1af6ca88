"""Paths that follow a preference: the shortest route to a goal that leaves each polytope ``v``
only toward its preferred neighbour ``p_v`` (any way out of a polytope without one).

Used by the ``oracle`` reference method (it follows this path) and by the ``consistent`` human
of the instance sampler (a goal the preference can lead to).
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from .world import World


def preference_following_distance(world: World, pref: np.ndarray, goal: int) -> np.ndarray:
    """``(n,)`` length of the shortest path from each cell to ``goal`` that leaves each polytope
    ``v`` only toward ``pref[v]`` (any way when ``pref[v] < 0``); inf where none exists."""
    m = world.motion
    n = world.n_cells
    src = np.repeat(np.arange(n), 8)
    dst = m.next_cell.ravel()
    v, w = world.cell_polytope[src], world.cell_polytope[dst]
    ok = ~m.blocked.ravel() & ((v == w) | (pref[v] < 0) | (pref[v] == w))
    # reversed graph: an edge t -> s for every allowed move s -> t, so one search from the goal
    rev = csr_matrix((m.cost.ravel()[ok], (dst[ok], src[ok])), shape=(n, n))
    return dijkstra(rev, directed=True, indices=goal)
