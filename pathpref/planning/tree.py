"""Pieces shared by the paper's search (:mod:`.pomcp`) and the robust one (:mod:`.guided`),
compiled with numba and inlined into both kernels.

The tree is stored in flat arrays indexed by node: visit counts ``n_node``, per-action counts
``n_sa`` and mean returns ``q_sa``, and ``child[node, a]`` (-1 until expanded). One node is
expanded per simulation, so ``queries + 2`` rows always suffice. Rows are allocated
uninitialised and set when their node is created (:func:`init_node`), so a large ``queries``
(an anytime search capped by its time budget) costs no up-front zeroing.
"""

from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True, inline="always")
def new_tree(queries):
    """``(n_node, n_sa, q_sa, child)`` for a search of ``queries`` simulations, the root
    (row 0) initialised."""
    M = queries + 2
    tree = (np.empty(M, np.int64), np.empty((M, 8), np.int64), np.empty((M, 8)),
            np.empty((M, 8), np.int32))
    init_node(tree[0], tree[1], tree[2], tree[3], 0)
    return tree


@nb.njit(cache=True, inline="always")
def init_node(n_node, n_sa, q_sa, child, i):
    """Node ``i`` unvisited, no action tried, no child."""
    n_node[i] = 0
    n_sa[i, :] = 0
    q_sa[i, :] = 0.0
    child[i, :] = -1


@nb.njit(cache=True, inline="always")
def sample_index(cdf):
    """An index drawn from the cumulative distribution ``cdf`` (one uniform draw)."""
    u = np.random.random()
    i = 0
    while i < cdf.shape[0] - 1 and u > cdf[i]:
        i += 1
    return i


@nb.njit(cache=True, inline="always")
def sample_slot(v, gi, nbr, pref_cdf):
    """Slot ``k`` of ``p_v = N(v)[k]`` drawn from ``P(p_v | g)`` (cumulative ``pref_cdf[gi,
    v]``, over ``v``'s neighbours only)."""
    u = np.random.random()
    k = 0
    K = nbr.shape[1]
    while k < K - 1 and nbr[v, k + 1] >= 0 and u > pref_cdf[gi, v, k]:
        k += 1
    return k


@nb.njit(cache=True, inline="always")
def best_root_action(n_sa, q_sa):
    """The visited root action with the highest mean return (0 if none was visited)."""
    best_a = 0
    best_q = -1e300
    for b in range(8):
        if n_sa[0, b] > 0 and q_sa[0, b] > best_q:
            best_q = q_sa[0, b]
            best_a = b
    return best_a
