"""Absorbing Markov chains on the observed polytopes, computed with high relative accuracy
(compiled with numba): the route prior's determinant, its exact preference marginals, and the
exact joint draw of the observed polytopes' exits (:mod:`.routes`).

**The chain.** ``k`` transient states (the observed polytopes ``S`` of the goal polytope's
component, the goal's polytope excluded) and one absorbing state (the goal's polytope ``r``),
given as a ``(k, k + 1)`` array of non-negative weights ``w[i, j]`` (column ``k``: toward
``r``); the diagonal is ignored (a self-loop changes no absorption probability and no
arborescence). Its Laplacian minor is ``L = diag(w 1) - w[:, :k]`` with the diagonal taken as
the *sum of the off-diagonal weights* (to other states and to ``r``).

**Why not an LU.** Evidence that two neighbouring polytopes point at each other makes ``L``
nearly singular (the walk between them escapes with probability ``eps``); an LU with pivoting
then computes ``det L ~ eps`` and the marginals ``W (M_vv - M_uv)`` (``M = L^-1`` of size
``1/eps``) by cancellation, and both turn to noise, 0/0 or NaN once ``eps`` nears the
machine's. Grassmann, Taksar and Heyman's elimination (GTH, 1985) avoids every subtraction:
eliminating state ``i`` folds its weights into the others,
``w[a, b] += w[a, i] w[i, b] / d_i``, and its pivot is ``d_i = sum_{b remaining, b != i}
w[i, b]`` (absorbing columns included), a sum of non-negative terms. Every quantity is then
computed to a few ulps *relative* accuracy whatever ``eps``:

* ``det L = prod_i d_i`` (Gaussian elimination without pivoting of an M-matrix, whose pivots
  are exactly these sums): :func:`gth_logdet`;
* absorption probabilities ``q_z = P_z(reach r before x)``, by the same elimination with ``x``
  made absorbing and a back-substitution of non-negative terms: :func:`reach_root_before`.

**Marginals.** Under the route prior ``P(p_x = y | g, o) = W(x, y) q_y / sum_u W(x, u) q_u``
with ``q_y = P_y(reach r before x)`` (the loop-erased walk's first step, equivalently
``W (M_xx - M_yx) / ...`` of :mod:`.routes`, without the cancellation). A slot's head ``y`` is
either a state, ``r``, or an unobserved polytope, which the caller describes by its first-entry
distribution ``h`` over ``S`` and ``r`` (a harmonic measure): then ``q_y = h[:k] q + h[k]``.
:func:`exit_probabilities`.

**Exact joint draw of the observed exits** (:func:`draw_observed_exits`): the exits of the
observed polytopes are drawn one after the other from their exact conditional given those
drawn before (the marginal above in the chain in which each drawn polytope moves to its drawn
head deterministically: its row becomes the head's first-entry distribution). The cost is
``O(k^4)`` whatever the evidence; Wilson's walk (:func:`pathpref.planning.guided.tree_pool`)
then completes the tree over the unobserved polytopes, whose rows are uniform.
"""

from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True)
def gth_logdet(w):
    """``log det L`` of the chain ``w`` (``(k, k + 1)``, module docstring) by GTH elimination;
    ``-inf`` when some state cannot reach the absorbing one (a zero pivot)."""
    k = w.shape[0]
    a = w.copy()
    total = 0.0
    for i in range(k):
        d = a[i, k]
        for j in range(i + 1, k):
            d += a[i, j]
        if not d > 0.0:
            return -np.inf
        total += np.log(d)
        for r in range(i + 1, k):
            f = a[r, i]
            if f > 0.0:
                f /= d
                for j in range(i + 1, k + 1):
                    if j != r:
                        a[r, j] += f * a[i, j]
    return total


@nb.njit(cache=True)
def reach_root_before(w, x):
    """``(k,)`` ``q_z = P_z(reach r before x)`` in the chain ``w`` (module docstring) with state
    ``x`` made absorbing (``q_x = 0``); 0 for a state that can reach neither."""
    k = w.shape[0]
    a = w.copy()
    d = np.zeros(k)
    for i in range(k):
        if i == x:
            continue
        s = a[i, k] + a[i, x]
        for j in range(i + 1, k):
            if j != x:
                s += a[i, j]
        d[i] = s
        if not s > 0.0:
            continue
        for r in range(i + 1, k):
            if r == x:
                continue
            f = a[r, i]
            if f > 0.0:
                f /= s
                for j in range(i + 1, k):
                    if j != r and j != x:
                        a[r, j] += f * a[i, j]
                a[r, k] += f * a[i, k]
                a[r, x] += f * a[i, x]
    q = np.zeros(k)
    for i in range(k - 1, -1, -1):
        if i == x or not d[i] > 0.0:
            continue
        s = a[i, k]
        for j in range(i + 1, k):
            if j != x:
                s += a[i, j] * q[j]
        q[i] = min(s / d[i], 1.0)
    return q


@nb.njit(cache=True)
def exit_probabilities(w, i, slot_w, heads, n_slots):
    """``(n_slots,)`` ``P(p_x = slot)`` of state ``i`` in the chain ``w`` (module docstring):
    ``slot_w[s] q(heads[s])`` normalised, ``heads[s]`` the head's first-entry distribution
    over the states and ``r`` (``(K, k + 1)``). Uniform over the slots with weight when every
    product underflows to 0 (only for a goal whose weight is 0)."""
    k = w.shape[0]
    q = reach_root_before(w, i)
    p = np.zeros(n_slots)
    tot = 0.0
    for s in range(n_slots):
        h = heads[s, k]
        for j in range(k):
            if j != i:
                h += heads[s, j] * q[j]
        p[s] = slot_w[s] * h
        tot += p[s]
    if tot > 0.0:
        return p / tot
    n = 0
    for s in range(n_slots):
        if slot_w[s] > 0.0:
            n += 1
    for s in range(n_slots):
        p[s] = 1.0 / n if slot_w[s] > 0.0 else 0.0
    return p


@nb.njit(cache=True)
def chain_rows(slot_w, heads, n_slots):
    """``(k, k + 1)`` the chain's weights from the slots: ``w[i] = sum_s slot_w[i, s]
    heads[i, s]`` (``heads``: ``(k, K, k + 1)`` first-entry distributions), diagonal 0."""
    k = slot_w.shape[0]
    w = np.zeros((k, k + 1))
    for i in range(k):
        for s in range(n_slots[i]):
            for j in range(k + 1):
                w[i, j] += slot_w[i, s] * heads[i, s, j]
        w[i, i] = 0.0
    return w


@nb.njit(cache=True)
def draw_observed_exits(slot_w, heads, n_slots):
    """One exact joint draw of the states' exits (slots) under the route prior (module
    docstring), states taken in index order; the caller seeds numba's generator."""
    k = slot_w.shape[0]
    w = chain_rows(slot_w, heads, n_slots)
    out = np.zeros(k, np.int64)
    for i in range(k):
        p = exit_probabilities(w, i, slot_w[i], heads[i], n_slots[i])
        u = np.random.random()
        c = 0.0
        s = -1
        for t in range(n_slots[i]):  # the first slot whose cumulative weight passes u
            if p[t] > 0.0:
                s = t
                c += p[t]
                if u < c:
                    break
        out[i] = s
        for j in range(k + 1):  # i now moves to its head's first-entry distribution
            w[i, j] = heads[i, s, j]
        w[i, i] = 0.0
    return out
