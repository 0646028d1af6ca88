"""The route prior: preferences that lead to the goal, with an exact posterior (matrix-tree
theorem) and exact sampling (Wilson's algorithm).

The paper's prior draws each ``p_v`` independently and uniformly, so almost every preference
vector sends the human round in circles: mutual pairs (``p_v = u``, ``p_u = v``) and longer
cycles that never reach the goal. A person never prefers a route that cannot reach where they
want to go. The *route prior* says so: given the goal ``g`` with polytope ``r``, the preferred
exits form an **in-arborescence rooted at** ``r`` (every polytope of ``r``'s component points to
a neighbour, and following the pointers from anywhere reaches ``r``: no cycle), uniform over
such trees::

    P(theta | g) = 1 / N_g  for theta in A_g,  0 otherwise.

Polytopes outside ``r``'s component keep the independent uniform prior, and ``r`` itself has no
preferred exit. The likelihood of the observations still factorises over polytopes,
``P(o | g, theta) = prod_v L_v(g, theta_v)`` (paper Fig. 3), so the posterior is a product of
per-polytope weights restricted to arborescences::

    P(theta | g, o)  ~  prod_{v != r} W_g(v, theta_v),    W_g(v, u) = L_v(g, u).

**Matrix-tree theorem** (Tutte): with the out-degree Laplacian ``L_g = diag(W_g 1) - W_g`` and
``~L_g`` its minor without ``r``'s row and column, ``sum_{theta in A_g} prod_v W_g(v, theta_v) =
det ~L_g``. Hence, exactly,

* ``P(g | o)  ~  P0(g) * det ~L_g(W) / det ~L_g(1) * prod_{v not in A} mean_k L_v(g, k) * L_r(g)``
  (``A``: ``r``'s component; ``L_r(g)`` the root's likelihood, which does not depend on an exit);
* ``P(p_v = u | g, o) = W_g(v, u) ([~L_g^-1]_{vv} - [~L_g^-1]_{uv})`` (the derivative of
  ``log det``; the second term is 0 when ``u = r``).

**Wilson's algorithm** (:func:`pathpref.planning.guided.tree_pool`, compiled) draws ``theta``
from ``P(theta | g, o)`` exactly: from each polytope not
yet in the tree, a random walk that leaves ``v`` toward ``u`` with probability
``W_g(v, u) / sum_u W_g(v, u)`` until it meets the tree, loop-erased, joins the tree. The walk's
transition rows are the per-polytope tables the independent belief keeps
(:meth:`PreferenceBelief.local_given_goal`), so the planners sample trees with no extra
state (:mod:`pathpref.planning.guided`). A mutual preference is a 2-cycle, so this prior also
forbids what the paper's coupling heuristic discourages, exactly and with no order dependence.

**Stable arithmetic.** Evidence in two neighbouring polytopes pointing at each other makes
``~L_g`` nearly singular, and its LU then returns noise (a ``det`` near the rounding error, and
marginals by cancellation, 0/0). Only observed polytopes have non-uniform weights, so ``r``'s
component is split into the observed set ``S`` and the rest ``U``::

    det ~L_g = det L_UU * det(L_UU's Schur complement on S),

``L_UU`` the uniform-weight block (well conditioned; the evidence does not enter it, so it
changes only when a push falls in a polytope not yet observed, and then loses that polytope's
row and column: ``det`` times ``[L_UU^-1]_vv`` and a rank-one correction of the solves, no new
factorisation, :meth:`_Split.extend`) and the Schur complement the Laplacian of the walk watched on
``S`` (weights ``W(x, y)`` to ``S`` and ``r`` plus ``W(x, u) H(u, .)`` through unobserved
``u``, ``H = L_UU^-1 B`` the first-entry distribution), whose determinant and absorption
probabilities the GTH elimination of :mod:`.chains` computes with no subtraction. The
marginal is ``P(p_v = u | g, o) = W(v, u) q_u / sum_w W(v, w) q_w`` with ``q_u = P_u(reach r
before v)`` (the same quantity as ``[~L^-1]_vv - [~L^-1]_uv`` up to a factor, without the
cancellation); an unobserved ``v`` joins ``S`` for the query. Every row of ``T_v`` is kept
with its largest entry 1 and its scale apart (:meth:`.PreferenceBelief._multiply`), so no
weight underflows.
"""

from __future__ import annotations

import warnings

import numba as nb
import numpy as np
import scipy.sparse as sp
from scipy.linalg import LinAlgError, LinAlgWarning, lu_factor
from scipy.linalg.lapack import dgetrs, dpotrf, dpotrs
from scipy.sparse.linalg import splu

from .belief import PreferenceBelief
from .chains import chain_rows, exit_probabilities, gth_logdet
from .human import ObservationModel

#: an empty column map: a dense split's ``hcol`` (:func:`_support`)
_NO_COLUMNS = np.zeros(0, np.int64)
#: unobserved blocks up to this many rows are factorised densely (:func:`_factor`)
DENSE_MAX = 400
#: a split's block is factorised afresh after this many polytopes were observed since its
#: factor (:meth:`_Split.extend`; the low-rank correction costs ``O(|U| REFACTOR_AFTER)`` per
#: solve)
REFACTOR_AFTER = 64
#: ... or sooner on a large block, when the correction's columns (``8 |U|`` bytes each, one
#: per removal, :class:`_Block`) would pass this many bytes (:func:`_refactor_after`)
BLOCK_BYTES = 16 * 2**20
#: a split of more unobserved rows than this holds the first-entry distribution ``H`` only at
#: the heads of its observed polytopes' slots (:class:`_Split`, "lean"): ``8 |U| (|S| + 1)``
#: bytes per goal otherwise, 12 MB per observed polytope for the 10 goals of a 500 x 500 map
LEAN_ROWS = 32_768


def components(neighbors: list[np.ndarray]) -> np.ndarray:
    """``(P,)`` connected-component label of each polytope of the (symmetric) polytope graph."""
    P = len(neighbors)
    label = -np.ones(P, dtype=np.int64)
    for s in range(P):
        if label[s] >= 0:
            continue
        label[s] = s
        stack = [s]
        while stack:
            v = stack.pop()
            for u in neighbors[v]:
                if label[u] < 0:
                    label[u] = s
                    stack.append(int(u))
    return label


class RouteBelief(PreferenceBelief):
    """Exact posterior over ``(g, theta)`` under the route prior (module docstring).

    Keeps the independent belief's per-polytope likelihood tables ``T_v`` (its updates are
    inherited unchanged) and computes the goal marginal and the preference marginals from them,
    per goal ``g`` with polytope ``r``, by splitting ``r``'s component (without ``r``) into the
    observed polytopes ``S`` and the unobserved ones ``U`` (module docstring, "Stable
    arithmetic"): ``det ~L_g = det L_UU * det(L_S^chain)``, the first from an LU of the
    uniform-weight block ``L_UU`` (factorised once per goal polytope; a push in a new
    polytope updates it, :meth:`_Split.extend`), the second and every marginal of an
    observed polytope by the GTH elimination of :mod:`.chains` on ``S``. Cached until the
    next update.

    Args:
        model: likelihood tables for the world and goal set.
        prior: goal prior ``P0`` (uniform when None).
    """

    route_prior = True

    def __init__(self, model: ObservationModel, prior: np.ndarray | None = None):
        super().__init__(model, prior=prior, coupling=False)
        self.component = components(self.neighbors)
        self.goal_polytope = model.world.cell_polytope[model.goals].astype(np.int64)
        slots: dict = {}  # per component: its slots, shared by the goals' minors
        self._minors = {int(r): _Minor(self.neighbors, self.component, int(r), slots)
                        for r in np.unique(self.goal_polytope)}
        self._splits: dict[tuple, _Split] = {}
        self._last_split: dict[int, _Split] = {}  # per root: the split asked for last
        self._cache: list | None = None
        #: preference_given_goal per polytope, dropped with _cache at every update
        self._given: dict[int, np.ndarray] = {}
        # log det ~L_g(1): the number of arborescences, the prior's normaliser
        self._log_trees = np.array([self._split(int(r), ()).logdet_u
                                    for r in self.goal_polytope])

    def _multiply(self, v: int, factor: np.ndarray) -> None:
        super()._multiply(v, factor)
        self._cache = None
        self._given = {}

    def _split(self, r: int, S: tuple) -> _Split:
        """The unobserved block of ``r``'s minor for observed set ``S`` (cached, one per goal
        polytope: a new one drops ``r``'s older split, its first-entry distributions ``H``
        (``|U| (|S| + 1)`` numbers) and, after a refactorisation, its factor; the observed
        set only grows, so an older one is rarely asked for again). A new ``S`` that
        contains the last one of ``r`` is reached from it by :meth:`_Split.extend`, one
        polytope at a time (no new factorisation); any other is factorised afresh."""
        key = (r, S)
        sp_ = self._splits.get(key)
        last = self._last_split.get(r)
        if sp_ is None and last is not None and last.S == S:
            sp_ = last
        if sp_ is None:
            if last is not None and len(last.S) < len(S) and set(last.S) <= set(S):
                sp_ = last
                for v in sorted(set(S) - set(last.S)):
                    sp_ = sp_.extend(v, self.neighbors)
            else:
                sp_ = _Split(self._minors[r], self.neighbors, S)
            for old in [k for k in self._splits if k[0] == r]:
                del self._splits[old]
            self._splits[key] = sp_
        self._last_split[r] = sp_
        return sp_

    def observed_chain(self, g: int) -> _Chain:
        """Goal ``g``'s chain on its observed polytopes: the states, their slot weights and
        heads."""
        r = int(self.goal_polytope[g])
        minor = self._minors[r]
        S = tuple(sorted(v for v in self.tables if minor.index[v] >= 0))
        split = self._split(r, S)
        k = len(S)
        K = int(self.degree.max())
        slot_w = np.zeros((k, K))
        for i, v in enumerate(S):
            deg = len(self.neighbors[v])
            t = self.tables.get(v)
            slot_w[i, :deg] = 1.0 if t is None else t[g, :deg]
        return _Chain(S, split, slot_w)

    def _solved(self) -> list:
        """Per goal: ``(log P(o | g)`` up to a constant, its :class:`_Chain`)."""
        if self._cache is None:
            G = len(self.log_prior)
            out = []
            for g in range(G):
                minor = self._minors[int(self.goal_polytope[g])]
                chain = self.observed_chain(g)
                ll = chain.split.logdet_u + gth_logdet(chain.rows()) - self._log_trees[g]
                for v, t in self.tables.items():
                    ls = self.log_scale[v][g]  # each row's scale (PreferenceBelief._multiply)
                    # the root and polytopes outside its component keep the independent prior
                    ll += ls if minor.index[v] >= 0 else ls + np.log(t[g].mean())
                out.append((ll, chain))
            self._cache = out
        return self._cache

    def goal_log_weights(self) -> np.ndarray:
        """``log P0(g) + log P(o | g)`` (unnormalised), ``-inf`` for ruled-out candidates."""
        w = self.log_prior + np.array([ll for ll, _ in self._solved()])
        return np.where(self.ruled_out | np.isnan(w), -np.inf, w)

    def log_joint(self) -> np.ndarray:
        """``log P0(g) + log P(o_1:t | g)``, absolutely scaled: :meth:`goal_log_weights`
        already holds every row's scale (``log_scale``, the table scales included)."""
        return self.goal_log_weights()

    def preference_given_goal(self, v: int) -> np.ndarray:
        """``(G, deg v)`` exact ``P(p_v = N(v)[k] | g, o_1:t)`` under the route prior (uniform
        outside the goal's component; the goal's own polytope has no preferred exit, shown as
        uniform): ``W(v, u) q_u`` normalised, ``q_u = P_u(reach r before v)`` computed without
        cancellation (:func:`.chains.exit_probabilities`). Kept until the next update (the
        wait budget, the crossing check and the policy ask for one polytope several times per
        decision)."""
        kept = self._given.get(v)
        if kept is None:
            kept = self._given[v] = self._preference_given_goal(v)
        return kept.copy()

    def _preference_given_goal(self, v: int) -> np.ndarray:
        """:meth:`preference_given_goal`, computed."""
        nb = self.neighbors[v]
        deg = len(nb)
        out = np.full((len(self.log_prior), self.degree[v]), 1.0 / self.degree[v])
        if deg == 0:
            return out
        for g, (ll, chain) in enumerate(self._solved()):
            minor = self._minors[int(self.goal_polytope[g])]
            if v == minor.root or not np.isfinite(ll):
                continue  # no preferred exit at the goal; no tree for an impossible goal
            if minor.index[v] < 0:  # outside the goal's component: the independent posterior
                out[g, :deg] = self.local_given_goal(v)[g, :deg]
                continue
            if v in self.tables:
                i = chain.states.index(v)
                rows, slot_w, heads = chain.rows(), chain.slot_w[i], chain.heads[i]
            else:  # v joins the chain as one more state, uniform weights
                aug = chain.split.with_state(v, tuple(chain.states), self.neighbors)
                if aug is None:
                    continue
                heads_all, n_slots = aug
                i = len(chain.states)
                w_all = np.vstack([chain.slot_w, np.zeros(chain.slot_w.shape[1])])
                w_all[i, :deg] = 1.0
                rows, slot_w, heads = chain_rows(w_all, heads_all, n_slots), w_all[i], \
                    heads_all[i]
            out[g, :deg] = exit_probabilities(rows, i, slot_w, heads, deg)[:deg]
        return out


class _Chain:
    """One goal's absorbing chain on its observed polytopes (:mod:`.chains`): ``states`` (the
    polytopes, sorted), ``slot_w[i, s]`` the weight of state ``i``'s slot ``s``, and
    ``heads[i, s]`` where the walk first enters ``states`` or ``r`` after taking that slot."""

    def __init__(self, states: tuple, split: _Split, slot_w: np.ndarray):
        self.states = list(states)
        self.split = split
        self.slot_w = slot_w
        self.heads = split.heads
        self.n_slots = split.n_slots
        self._rows = None

    def rows(self) -> np.ndarray:
        """``(k, k + 1)`` the chain's weights (:func:`.chains.chain_rows`)."""
        if self._rows is None:
            self._rows = chain_rows(self.slot_w, self.heads, self.n_slots)
        return self._rows


class _Split:
    """``r``'s minor split into observed polytopes ``S`` and the rest ``U``: the uniform-weight
    block ``L_UU`` (every unobserved polytope weighs each neighbour 1), its ``log det`` and the
    first-entry distributions (harmonic measure) ``H = L_UU^-1 B`` of the walk from each
    unobserved polytope into ``S`` (columns ``0..k-1``) or ``r`` (column ``k``); ``heads[i,
    s]``: that distribution for the head of slot ``s`` of ``S[i]`` (a unit vector when the
    head is in ``S`` or is ``r``).

    Built from a factorisation of ``L_UU`` (this constructor) or from the split of ``S``
    without one polytope (:meth:`extend`, a push in a polytope not yet observed), whose
    ``L_UU`` is then held as an earlier factor and a low-rank correction (:class:`_Block`).

    **Lean splits** (``|U|`` above :data:`LEAN_ROWS`): only the rows of ``H`` the heads read
    are held, those of the unobserved neighbours of ``S`` (``O(|S|^2 K)`` numbers instead of
    ``|U| (|S| + 1)``); a row not held is ``H(u, .) = (L_UU^-1 e_u)^T B`` (``L_UU``
    symmetric), one solve, needed only for the new heads when ``v`` joins ``S``
    (:meth:`_with_v`). Smaller blocks hold every row: the rank-one update of the whole ``H``
    costs less than those solves there."""

    def __init__(self, minor: _Minor, neighbors: list[np.ndarray], S: tuple):
        k = len(S)
        P = len(neighbors)
        self.minor = minor
        self.S = S
        state = -np.ones(P, dtype=np.int64)  # S[i] -> i, the root -> k, else -1
        state[np.array(S, dtype=np.int64)] = np.arange(k)
        state[minor.root] = k
        unobserved = (minor.index >= 0) & (state < 0)
        n = int(unobserved.sum())
        self.u_index = u_index = -np.ones(P, dtype=np.int64)
        u_index[unobserved] = np.arange(n)
        self.state = state
        self.n = n
        self.block = None
        H = np.zeros((n, k + 1))
        self.logdet_u = 0.0
        if n:
            src, dst = minor.src, minor.dst  # every slot of the component's members
            in_u = unobserved[src]
            a, b = u_index[src[in_u]], dst[in_u]
            off = u_index[b] >= 0
            diag = np.bincount(a, minlength=n).astype(float)  # deg(u): every neighbour 1
            rows = np.concatenate([np.arange(n), a[off]])
            cols = np.concatenate([np.arange(n), u_index[b[off]]])
            data = np.concatenate([diag, -np.ones(int(off.sum()))])
            B = np.zeros((n, k + 1))
            np.add.at(B, (a[~off], state[b[~off]]), 1.0)
            self.logdet_u, lu = _factor(n, rows, cols, data)
            if lu is not None:
                self.block = _Block(lu, n)
                H = np.maximum(lu.solve(B), 0.0)
        #: lean: ``Ht`` holds the rows of the unobserved heads of ``S``'s slots only, column
        #: ``hcol[u]`` for factor row ``u`` (-1: not held); dense: every row, ``hcol`` None
        self.hcol = None
        if n > LEAN_ROWS:
            kept = self._kept(S, neighbors, u_index)
            self.hcol = _positions(kept, n)
            H = H[kept]
        self.Ht = np.ascontiguousarray(H.T)  # (k + 1, rows held): a row per column of H
        K = max((len(nb) for nb in neighbors), default=1)
        self.K = max(K, 1)
        self.heads, self.n_slots = self._heads(S, state, self.Ht, self.hcol)

    @property
    def lean(self) -> bool:
        """Whether this split holds ``H`` at the heads only (class docstring)."""
        return self.hcol is not None

    @staticmethod
    def _kept(S, neighbors, u_index: np.ndarray) -> np.ndarray:
        """The factor rows (sorted) of the unobserved heads of the slots of ``S``: the rows
        of ``H`` a lean split holds (the only ones :meth:`_heads` reads)."""
        if not len(S):
            return np.zeros(0, np.int64)
        y = u_index[np.concatenate([np.asarray(neighbors[v], dtype=np.int64) for v in S])]
        return np.unique(y[y >= 0])

    def _heads(self, S, state: np.ndarray, Ht: np.ndarray, hcol):
        """``(heads (len(S), K, m), n_slots)``: for each slot of each state, where the walk
        first enters the states or ``r`` (``m`` columns, ``state[]`` numbering them) after
        stepping to its head: a unit vector for a state or ``r``, the head's row of ``H``
        otherwise (``Ht``: ``H`` transposed, factor row ``u`` at column ``hcol[u]``, or at
        ``u`` when ``hcol`` is None)."""
        minor = self.minor
        heads, n_slots, cleared = _support(
            np.asarray(S, dtype=np.int64), minor.src, minor.dst, minor.first, state,
            self.u_index, Ht, _NO_COLUMNS if hcol is None else hcol, self.K,
            (minor.index >= 0) & (state < 0))
        _renormalise(heads, cleared)
        return heads, n_slots

    def _boundary(self, neighbors) -> tuple[np.ndarray, np.ndarray]:
        """``(w, j)``: the nonzeros of ``B`` (one per slot from unobserved factor row ``w``
        into state ``j``, ``S`` or ``r``), read from the states' own slots (the graph is
        symmetric)."""
        states = np.flatnonzero(self.state >= 0)  # S and r
        w = self.u_index[np.concatenate([np.asarray(neighbors[x], dtype=np.int64)
                                         for x in states])]
        j = np.repeat(self.state[states], [len(neighbors[x]) for x in states])
        return w[w >= 0], j[w >= 0]

    def _row(self, iu: int, col: np.ndarray, boundary) -> np.ndarray:
        """``H(u, .)`` for factor row ``iu`` given ``col = L_UU^-1 e_u``: the row held, or
        (a lean split's other rows) ``col^T B`` by symmetry of ``L_UU`` (``boundary``: the
        nonzeros of ``B``, :meth:`_boundary`; clipped at 0 as the rows held are)."""
        if self.hcol is None:
            return self.Ht[:, iu]
        if self.hcol[iu] >= 0:
            return self.Ht[:, self.hcol[iu]]
        w, j = boundary
        return np.maximum(np.bincount(j, weights=col[w], minlength=self.Ht.shape[0]), 0.0)

    def _with_v(self, v: int, p: int, neighbors):
        """``(H'^T, hcol', g_vv, raw)``: the first-entry distribution into ``S``, ``v`` and
        ``r`` from each unobserved polytope, for an unobserved ``v`` put at column ``p``
        (``S``'s columns after it and ``r``'s move one on), from the column ``g = L_UU^-1
        e_v`` (:meth:`_Block.column`; ``raw``: the factor's column it was corrected from, for
        :meth:`_Block.without`): with ``h(y) = P_y(reach v before leaving U) = g_y / g_v``,
        ``H'(y, .) = H(y, .) - h(y) H(v, .)`` on ``S`` and ``r`` and ``h(y)`` on ``v`` (strong
        Markov at the visit to ``v``). Dense: every row (those of polytopes observed since the
        factor are kept, stale, never read: their ``u_index`` is -1). Lean: the rows of the
        heads of ``S + {v}``; a head of ``v`` not held before costs one more solve
        (:meth:`_row`)."""
        iv = int(self.u_index[v])
        col, raw = self.block.column(iv)
        boundary = None if self.hcol is None else self._boundary(neighbors)
        Hv = self._row(iv, col, boundary)
        if self.hcol is None:
            h, old, hcol = np.clip(col / col[iv], 0.0, 1.0), self.Ht, None
        else:
            held = np.flatnonzero(self.hcol >= 0)
            nb = self.u_index[np.asarray(neighbors[v], dtype=np.int64)]
            new = np.setdiff1d(nb[nb >= 0], held)
            kept = np.union1d(held, new)
            kept = kept[kept != iv]
            hcol = _positions(kept, self.hcol.shape[0])
            old = np.empty((self.Ht.shape[0], len(kept)))
            old[:, hcol[held[held != iv]]] = self.Ht[:, self.hcol[held[held != iv]]]
            for iu in new.tolist():
                if iu != iv:
                    old[:, hcol[iu]] = self._row(iu, self.block.column(iu)[0], boundary)
            h = np.clip(col[kept] / col[iv], 0.0, 1.0)
        m = old.shape[0]
        Ht = np.empty((m + 1, old.shape[1]))
        for lo, hi, at in ((0, p, 0), (p, m, p + 1)):  # contiguous rows, no temporaries
            out = Ht[at: at + hi - lo]
            np.multiply(Hv[lo:hi, None], h[None, :], out=out)
            np.subtract(old[lo:hi], out, out=out)
        Ht[p] = h
        np.maximum(Ht, 0.0, out=Ht)
        return Ht, hcol, float(col[iv]), raw

    def with_state(self, v: int, S: tuple, neighbors: list[np.ndarray]):
        """The heads and slot counts of the chain on ``S + (v,)`` for an unobserved ``v``
        (states ``0..k-1``, ``v`` as ``k``, ``r`` as ``k + 1``), from this split and one more
        solve (:meth:`_with_v`). None when the block could not be factorised."""
        if self.block is None:
            return None
        k = len(S)
        H, hcol, _, _ = self._with_v(v, k, neighbors)
        state = self.state.copy()
        state[self.state == k] = k + 1  # r moves one column on
        state[v] = k
        return self._heads((*S, v), state, H, hcol)

    def extend(self, v: int, neighbors: list[np.ndarray]) -> _Split:
        """The split of ``S + {v}`` (sorted) for an unobserved ``v``, without a factorisation:
        ``L_U'U'`` (``U' = U - {v}``) is ``L_UU`` without ``v``'s row and column, so
        ``det L_U'U' = det L_UU [L_UU^-1]_vv`` (the cofactor), its first-entry distributions
        are :meth:`_with_v`'s on ``U'``, and its solves are :meth:`_Block.without`'s. After
        :func:`_refactor_after` removals from one factor (or when the block could not be
        factorised) the split is factorised afresh, which bounds the correction's cost, its
        memory and its rounding."""
        S = tuple(sorted((*self.S, v)))
        if self.block is None or len(self.block.removed) >= _refactor_after(self.block.n0):
            return _Split(self.minor, neighbors, S)
        p = S.index(v)
        H, hcol, g_vv, raw = self._with_v(v, p, neighbors)
        if not (np.isfinite(g_vv) and g_vv > 0):
            return _Split(self.minor, neighbors, S)
        out = object.__new__(_Split)
        out.minor, out.S, out.K, out.n, out.Ht = self.minor, S, self.K, self.n - 1, H
        out.hcol = hcol
        out.state = state = self.state.copy()
        state[state >= p] += 1  # the states after v and r move one column on
        state[v] = p
        out.u_index = self.u_index.copy()
        out.u_index[v] = -1
        out.logdet_u = self.logdet_u + float(np.log(g_vv))
        out.block = self.block.without(int(self.u_index[v]), raw)
        out.heads, out.n_slots = out._heads(S, state, H, hcol)
        return out


class _Block:
    """A block ``A = L_UU`` held as the factor ``lu`` of an earlier, larger block ``A0 =
    L_{U0 U0}`` (``U`` in ``U0``; rows numbered as in ``A0``) and the ``m`` rows ``R = U0 -
    U`` removed since. ``A0`` is symmetric (every weight 1), so with ``G0 = A0^-1`` and ``C =
    G0[:, R]``, the inverse of the principal submatrix is the Schur complement of ``G0`` on
    ``R``::

        A^-1 = G0[U, U] - C[U] (G0[R, R])^-1 C[U]^T,

    ``G0[R, R]`` symmetric positive definite (Cholesky; ``m`` at most :data:`REFACTOR_AFTER`).
    A solve ``A^-1 e_i`` costs one solve with ``lu`` and ``O(|U0| m)``; removing one more row
    appends one column to ``C`` (a rank-one update per push). ``C`` lives in a buffer shared
    along a chain of removals (``cols``, ``(|U0|, capacity)``, its first ``m`` columns
    this block's); a removal from a block that is not the buffer's last copies the prefix,
    and so does one that finds the buffer full (its capacity doubles from 4 columns up to
    :func:`_refactor_after`, so ``m`` removals hold ``O(|U0| m)`` numbers, not ``|U0|
    REFACTOR_AFTER``)."""

    def __init__(self, lu, n0: int):
        self.lu = lu
        self.n0 = n0
        self.removed = np.zeros(0, np.int64)
        self.cols: list | None = None  # [buffer, columns in use by its longest block]
        self._chol = None

    def _C(self) -> np.ndarray:
        return self.cols[0][:, : len(self.removed)]

    def column(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """``(A^-1 e_i, G0 e_i)`` over ``A0``'s rows (those in ``R``: 0 up to rounding, not
        to be read): the block's inverse column ``i``, and the factor's column it was
        corrected from."""
        e = np.zeros(self.n0)
        e[i] = 1.0
        raw = self.lu.solve(e)
        if self._chol is None:
            return raw, raw
        return raw - self._C() @ _lapack(dpotrs(self._chol, raw[self.removed], lower=0,
                                                overwrite_b=0), "potrs"), raw

    def without(self, i: int, raw: np.ndarray) -> _Block:
        """The block without its row and column ``i``, ``raw = G0 e_i``."""
        m = len(self.removed)
        out = object.__new__(_Block)
        out.lu, out.n0 = self.lu, self.n0
        out.removed = np.append(self.removed, i)
        if self.cols is not None and self.cols[1] == m and self.cols[0].shape[1] > m:
            out.cols = self.cols  # this block is the buffer's last: append in place
        else:  # a fork, or a full buffer: a larger one (doubling, up to _refactor_after)
            buf = np.empty((self.n0, max(m + 1, min(max(2 * m, 4), _refactor_after(self.n0)))))
            if m:
                buf[:, :m] = self._C()
            out.cols = [buf, m]
        out.cols[0][:, m] = raw
        out.cols[1] = m + 1
        c, info = dpotrf(out._C()[out.removed], lower=0, clean=0, overwrite_a=0)
        if info > 0:
            raise LinAlgError(f"{info}-th leading minor of the array is not positive definite")
        out._chol = _lapack((c, info), "potrf")
        return out


def _lapack(result: tuple, name: str) -> np.ndarray:
    """The array of a LAPACK call's ``(array, info)`` (:mod:`scipy.linalg.lapack`: the
    routines SciPy's ``lu_solve``, ``cho_factor`` and ``cho_solve`` call, called as they call
    them, without their argument checks and batch wrappers, tens of microseconds a call
    here); a negative ``info`` (an illegal argument) raises."""
    x, info = result
    if info < 0:
        raise ValueError(f"illegal value in {-info}th argument of internal {name}")
    return x


class _Minor:
    """``r``'s component without ``r`` (``index[v]``: ``v``'s row, -1 outside).

    ``src``, ``dst``: every slot ``(v, N(v)[k])`` of the component's polytopes, ``r``'s own
    included (the pattern of ``~L`` once ``r``'s row is dropped, which :class:`_Split` does:
    it reads the rows of unobserved polytopes only), each polytope's slots in a run from
    ``first[v]`` (-1 outside the component), as arrays shared through ``slots`` (a dict keyed
    by component label) by every goal polytope of the component."""

    def __init__(self, neighbors: list[np.ndarray], component: np.ndarray, root: int,
                 slots: dict | None = None):
        self.root = root
        label = int(component[root])
        members = np.flatnonzero(component == label)
        slots = {} if slots is None else slots
        if label not in slots:
            deg = np.array([len(neighbors[v]) for v in members.tolist()], dtype=np.int64)
            first = -np.ones(len(neighbors), dtype=np.int64)
            first[members] = np.cumsum(deg) - deg
            slots[label] = (np.repeat(members, deg),
                            np.concatenate([np.asarray(neighbors[v], dtype=np.int64)
                                            for v in members.tolist()]), first)
        self.src, self.dst, self.first = slots[label]
        members = members[members != root]
        self.n = len(members)
        self.index = -np.ones(len(neighbors), dtype=np.int64)
        self.index[members] = np.arange(self.n)


@nb.njit(cache=True)
def _support(S, src, dst, first, state, u_index, Ht, hcol, K, in_u):
    """``(heads (len(S), K, m), n_slots, cleared (c, 2))`` of :meth:`_Split._heads`: for each
    slot ``s`` of each state ``S[i]`` (its head ``y = dst[first[S[i]] + s]``), a unit vector
    at ``state[y]`` when ``y`` is a state, else ``y``'s first-entry row ``H(y, .)`` (``Ht``'s
    column ``u_index[y]``, or ``hcol[u_index[y]]`` when ``hcol`` is not empty) with its
    structural zeros restored: the walk from ``y`` through the unobserved set ``U``
    (``in_u``) can first enter only a state (``S`` or ``r``, ``state >= 0``) next to ``y``'s
    component of ``U`` (:func:`_entry_allowed`), so the other entries are exactly 0, and the
    row sums to 1 (every component of ``U`` reaches a state: ``r``'s component is
    connected). A solve or a rank-one update leaves rounding (about 1e-16) there, which the
    chain's elimination would read as an exit: next to a pocket that the walk leaves with
    probability 1e-8 (a dead-end branch of leaves between observed polytopes), that is a
    relative error of 1e-8 in ``det``, growing with the evidence. ``cleared`` lists the
    slots ``(i, s)`` whose row lost a nonzero entry; only they are renormalised
    (:func:`_renormalise`), so exact rows keep their bits. ``O(E + len(S) K m)``."""
    k = S.shape[0]
    m = Ht.shape[0]
    heads = np.zeros((k, K, m))
    n_slots = np.empty(k, np.int64)
    n_unknown = 0
    for i in range(k):
        n_slots[i] = 0
        for e in range(first[S[i]], src.shape[0]):
            if src[e] != S[i]:
                break
            n_slots[i] += 1
            if state[dst[e]] < 0:
                n_unknown += 1
    ys = np.empty(n_unknown, np.int64)  # the unobserved heads, slot by slot
    at = np.empty((n_unknown, 2), np.int64)
    j = 0
    for i in range(k):
        for s in range(n_slots[i]):
            y = dst[first[S[i]] + s]
            if state[y] >= 0:
                heads[i, s, state[y]] = 1.0
            else:
                ys[j] = y
                at[j, 0] = i
                at[j, 1] = s
                j += 1
    ok = _entry_allowed(src, dst, in_u, state, ys, m)
    cleared = np.empty((n_unknown, 2), np.int64)
    n_cleared = 0
    for j in range(n_unknown):
        u = u_index[ys[j]]
        c = u if hcol.shape[0] == 0 else hcol[u]
        lost = False
        for x in range(m):
            if ok[j, x]:
                heads[at[j, 0], at[j, 1], x] = Ht[x, c]
            elif Ht[x, c] != 0.0:
                lost = True
        if lost:
            cleared[n_cleared] = at[j]
            n_cleared += 1
    return heads, n_slots, cleared[:n_cleared]


def _renormalise(heads: np.ndarray, cleared: np.ndarray) -> None:
    """Rows ``heads[i, s]`` of the slots ``cleared`` (:func:`_support`) divided by their sums
    (left as they are where the sum is 0), in place."""
    if len(cleared):
        i, s = cleared[:, 0], cleared[:, 1]
        rows = heads[i, s]
        tot = rows.sum(axis=1, keepdims=True)
        heads[i, s] = np.where(tot > 0, rows / np.where(tot > 0, tot, 1.0), rows)


@nb.njit(cache=True)
def _entry_allowed(src, dst, in_u, state, heads, m):
    """``(len(heads), m)`` whether the walk from ``heads[j]`` through the unobserved set
    ``in_u`` can first enter state ``c`` (``state[x] = c``, :func:`_support`): some slot
    ``(src[e], dst[e])`` leads from ``heads[j]``'s component of ``in_u``
    (:func:`_u_components`) into a polytope of state ``c``. ``O(E + len(heads) m)``."""
    comp = _u_components(src, dst, in_u)
    row = -np.ones(in_u.shape[0], np.int64)  # a head's component -> its row of the table
    n_rows = 0
    for j in range(heads.shape[0]):
        if row[comp[heads[j]]] < 0:
            row[comp[heads[j]]] = n_rows
            n_rows += 1
    table = np.zeros((n_rows, m), np.bool_)
    for e in range(src.shape[0]):
        a, b = src[e], dst[e]
        if in_u[a] and state[b] >= 0 and row[comp[a]] >= 0:
            table[row[comp[a]], state[b]] = True
    ok = np.empty((heads.shape[0], m), np.bool_)
    for j in range(heads.shape[0]):
        for c in range(m):
            ok[j, c] = table[row[comp[heads[j]]], c]
    return ok


@nb.njit(cache=True)
def _u_components(src, dst, in_u):
    """``comp[v]``: a label of ``v``'s connected component in the graph of the slots
    ``(src[e], dst[e])`` with both ends in ``in_u`` (the smallest member's index; a polytope
    outside ``in_u`` is alone). Union-find, each root the smaller index, so every ``find``
    walks toward smaller indices and ends: ``O(E log P)`` with no graph built, where a sparse
    matrix and SciPy's ``connected_components`` cost milliseconds a call (:func:`_support`
    runs at every goal's split)."""
    n = in_u.shape[0]
    parent = np.arange(n)
    for e in range(src.shape[0]):
        a, b = src[e], dst[e]
        if not (in_u[a] and in_u[b]):
            continue
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        while parent[b] != b:
            parent[b] = parent[parent[b]]
            b = parent[b]
        if a < b:
            parent[b] = a
        elif b < a:
            parent[a] = b
    comp = np.empty(n, np.int64)
    for v in range(n):  # parent[v] <= v: a root's label is final before v reads it
        comp[v] = v if parent[v] == v else comp[parent[v]]
    return comp


def _positions(rows: np.ndarray, n: int) -> np.ndarray:
    """``(n,)`` each of the sorted ``rows``' position in it, -1 elsewhere."""
    out = -np.ones(n, np.int64)
    out[rows] = np.arange(len(rows))
    return out


def _refactor_after(n0: int) -> int:
    """Removals from a factor of ``n0`` rows before :meth:`_Split.extend` factorises afresh:
    :data:`REFACTOR_AFTER`, or fewer (at least 4) when that many columns of ``n0`` numbers
    would pass :data:`BLOCK_BYTES` (``n0`` above 32,768 rows at the defaults)."""
    return max(4, min(REFACTOR_AFTER, BLOCK_BYTES // (8 * max(n0, 1))))


def _factor(n: int, rows: np.ndarray, cols: np.ndarray, data: np.ndarray):
    """``(log det A, its LU)`` of the ``n x n`` M-matrix ``A`` given by triplets;
    ``(-inf, None)`` when singular. Dense LAPACK up to :data:`DENSE_MAX` rows (scipy's sparse
    constructors cost more than the factorisation there), SuperLU above, kept as
    :class:`_SparseLDL`."""
    if n <= DENSE_MAX:
        a = np.bincount(rows * n + cols, weights=data, minlength=n * n).reshape(n, n)
        lu = _DenseLU(a)
        d = np.diagonal(lu.lu)
    else:
        a = sp.csc_matrix((data, (rows, cols)), shape=(n, n))
        try:
            # symmetric pattern and values: a minimum-degree ordering of A + A^T with
            # diagonal pivots (an M-matrix needs no pivoting: any nonzero diagonal is taken)
            # halves the fill and the solves
            slu = splu(a, permc_spec="MMD_AT_PLUS_A",
                       options={"SymmetricMode": True, "DiagPivotThresh": 0.0})
        except RuntimeError:  # exactly singular
            return -np.inf, None
        del a
        lu, d = _SparseLDL.of(slu)
    if not np.all(np.isfinite(d)) or np.any(d == 0):
        return -np.inf, None
    # an M-matrix has det > 0: the sign of the factors is not needed
    return float(np.sum(np.log(np.abs(d)))), lu


class _SparseLDL:
    """SuperLU's ``P_r A P_c = L U`` of a symmetric ``A`` kept as ``L`` alone: with diagonal
    pivots (``P_r = P_c^T``, what the symmetric mode of :func:`_factor` gives an M-matrix)
    the factorisation is ``P_c^T A P_c = L D L^T``, ``D = diag(U)``, ``L`` unit lower
    triangular (``U = D L^T`` up to rounding), so a solve is

        x = P_c L^-T D^-1 L^-1 P_c^T b

    (:func:`_ldl_solve`: a forward sweep down ``L``'s columns, a backward one up them) and
    only ``L``'s columns (compressed, ``nnz(L)`` values and 32-bit row indices) and ``D`` are
    held: about a quarter of SuperLU's supernodal ``L`` and ``U``. With row pivots
    (``P_r != P_c^T``, a zero on the diagonal) :meth:`of` keeps SuperLU's factor as it is.

    Attributes:
        d: ``(n,)`` the pivots ``diag(U)`` (``det A = prod d`` up to sign).
    """

    def __init__(self, L, d: np.ndarray, perm: np.ndarray):
        self.ptr = L.indptr
        self.idx = L.indices
        self.val = L.data
        self.d = d
        self.perm = perm

    @staticmethod
    def of(slu):
        """``(factor, pivots diag(U))`` of the SuperLU object ``slu``: the factor a
        :class:`_SparseLDL` under diagonal pivots, ``slu`` itself (the same ``solve``)
        when a zero diagonal made SuperLU pivot off it."""
        d = slu.U.diagonal()
        if not np.array_equal(slu.perm_r, slu.perm_c):
            return slu, d
        return _SparseLDL(slu.L.tocsc(), d, np.asarray(slu.perm_c, dtype=np.int64)), d

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``A^-1 b`` for ``b`` of shape ``(n,)`` or ``(n, m)``."""
        b2 = np.asarray(b, dtype=np.float64).reshape(len(self.d), -1)
        out = np.empty(b2.shape)
        _ldl_solve(self.ptr, self.idx, self.val, self.d, self.perm, b2, out)
        return out.reshape(np.shape(b))


@nb.njit(cache=True)
def _ldl_solve(ptr, idx, val, d, perm, b, out):
    """``out[:, j] = P L^-T D^-1 L^-1 P^T b[:, j]`` for each column (:class:`_SparseLDL`):
    ``L`` unit lower triangular in compressed columns (its stored unit diagonal skipped),
    ``perm`` the column permutation (``(P y)[i] = y[perm[i]]``)."""
    n = d.shape[0]
    z = np.empty(n)
    for c in range(b.shape[1]):
        for i in range(n):
            z[perm[i]] = b[i, c]
        for j in range(n):  # L w = z, column by column (w_j final once reached)
            zj = z[j]
            if zj != 0.0:
                for p in range(ptr[j], ptr[j + 1]):
                    i = idx[p]
                    if i != j:
                        z[i] -= val[p] * zj
        for j in range(n):
            z[j] /= d[j]
        for j in range(n - 1, -1, -1):  # L^T y = w: row j of L^T is column j of L
            s = z[j]
            for p in range(ptr[j], ptr[j + 1]):
                i = idx[p]
                if i != j:
                    s -= val[p] * z[i]
            z[j] = s
        for i in range(n):
            out[i, c] = z[perm[i]]


class _DenseLU:
    """A dense LU factorisation with the ``solve`` of SuperLU's factor object."""

    def __init__(self, a: np.ndarray):
        with warnings.catch_warnings():  # a singular minor is reported by its zero pivot
            warnings.simplefilter("ignore", LinAlgWarning)
            self.lu, self.piv = lu_factor(a, check_finite=False)

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``A^-1 b`` (LAPACK's ``getrs``, :func:`_lapack`)."""
        return _lapack(dgetrs(self.lu, self.piv, b, trans=0, overwrite_b=0), "getrs")
