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
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.sparse as sp
from scipy.linalg import LinAlgWarning, lu_factor, lu_solve
from scipy.sparse.linalg import splu

from .belief import PreferenceBelief
from .human import ObservationModel

#: minors up to this many rows are factorised densely (:meth:`_Minor.factor`)
DENSE_MAX = 400


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
    inherited unchanged) and computes the goal marginal and the preference marginals from them
    with one ``|A| x |A|`` determinant and inverse per goal, cached until the next update.

    Args:
        model: likelihood tables for the world and goal set.
        prior: goal prior ``P0`` (uniform when None).
    """

    route_prior = True

    def __init__(self, model: ObservationModel, prior: np.ndarray | None = None):
        super().__init__(model, prior=prior, coupling=False)
        self.component = components(self.neighbors)
        self.goal_polytope = model.world.cell_polytope[model.goals].astype(np.int64)
        P, K = len(self.neighbors), int(self.degree.max())
        self._slots = np.zeros((P, K), dtype=bool)  # slot k of v holds a neighbour
        for v, nb in enumerate(self.neighbors):
            self._slots[v, : len(nb)] = True
        self._minors = {int(r): _Minor(self.neighbors, self.component, int(r))
                        for r in np.unique(self.goal_polytope)}
        self._cache: tuple[np.ndarray, list] | None = None
        # log det ~L_g(1): the number of arborescences, the prior's normaliser
        ones = self._slots.astype(float)
        self._log_trees = np.array([self._minors[int(r)].factor(ones)[0]
                                    for r in self.goal_polytope])

    def _multiply(self, v: int, factor: np.ndarray) -> None:
        super()._multiply(v, factor)
        self._cache = None

    def _weights_all(self) -> np.ndarray:
        """``(G, P, K)`` weights ``W_g(v, N(v)[k])``: the table rows of observed polytopes
        (scaled by a constant per polytope, which cancels), 1 elsewhere, 0 in empty slots."""
        G = len(self.log_prior)
        W = np.broadcast_to(self._slots.astype(float), (G, *self._slots.shape)).copy()
        for v, t in self.tables.items():
            W[:, v, : len(self.neighbors[v])] = t[:, : len(self.neighbors[v])]
        return W

    def _solved(self) -> tuple[np.ndarray, list]:
        """Per goal: ``log P(o | g)`` up to a constant, and the minor's factorisation
        (:class:`_Minor`), None where every tree has weight 0."""
        if self._cache is None:
            W = self._weights_all()
            G = len(self.log_prior)
            loglik = np.zeros(G)
            lus = []
            obs = np.fromiter(self.tables, dtype=np.int64, count=len(self.tables))
            for g in range(G):
                minor = self._minors[int(self.goal_polytope[g])]
                logdet, lu = minor.factor(W[g])
                ll = logdet - self._log_trees[g]
                # the root and polytopes outside its component keep the independent prior
                free = obs[minor.index[obs] < 0]
                for v in free.tolist():
                    ll += np.log(self.tables[v][g].mean())
                loglik[g] = ll
                lus.append(lu)
            self._cache = (loglik, lus)
        return self._cache

    def goal_log_weights(self) -> np.ndarray:
        """``log P0(g) + log P(o | g)`` (unnormalised), ``-inf`` for ruled-out candidates."""
        w = self.log_prior + self._solved()[0]
        return np.where(self.ruled_out, -np.inf, w)

    def preference_given_goal(self, v: int) -> np.ndarray:
        """``(G, deg v)`` exact ``P(p_v = N(v)[k] | g, o_1:t)`` under the route prior (uniform
        outside the goal's component; the goal's own polytope has no preferred exit, shown as
        uniform). Column ``i`` of ``~L_g^-1`` is one solve with the cached factorisation."""
        nb = self.neighbors[v]
        deg = len(nb)
        out = np.full((len(self.log_prior), self.degree[v]), 1.0 / self.degree[v])
        if deg == 0:
            return out
        for g, lu in enumerate(self._solved()[1]):
            minor = self._minors[int(self.goal_polytope[g])]
            i = minor.index[v]
            if v == minor.root:
                continue  # no preferred exit at the goal
            if i < 0:  # outside the goal's component: the independent posterior
                out[g, :deg] = self.local_given_goal(v)[g, :deg]
                continue
            if lu is None:
                continue  # no tree for an impossible goal
            e = np.zeros(minor.n)
            e[i] = 1.0
            col = lu.solve(e)  # column i of ~L_g^-1
            j = minor.index[nb]
            p = np.maximum(self._weights(g, v) * (col[i] - np.where(j >= 0, col[j], 0.0)), 0.0)
            out[g, :deg] = p / p.sum()
        return out

    def _weights(self, g: int, v: int) -> np.ndarray:
        """``W_g(v, N(v)[k])`` (the table row scaled by a constant, which cancels)."""
        t = self.tables.get(v)
        return np.ones(len(self.neighbors[v])) if t is None else t[g, : len(self.neighbors[v])]


class _Minor:
    """The sparsity pattern of ``~L`` for one root polytope ``r``: the rows and columns of
    ``r``'s component without ``r`` (``index[v]``: ``v``'s row, -1 outside), and for every
    slot ``(v, k)`` of a member the diagonal entry it adds to and the off-diagonal entry it
    subtracts from (none when ``N(v)[k]`` is the root). :meth:`factor` assembles ``~L(W)``
    and factorises it (a sparse LU, SuperLU, above :data:`DENSE_MAX` rows, so a map of
    thousands of polytopes costs what its sparse factor costs, not a dense ``n^3``)."""

    def __init__(self, neighbors: list[np.ndarray], component: np.ndarray, root: int):
        self.root = root
        members = np.flatnonzero(component == component[root])
        members = members[members != root]
        self.n = len(members)
        self.index = -np.ones(len(neighbors), dtype=np.int64)
        self.index[members] = np.arange(self.n)
        vs, ks, us = [], [], []
        for v in members.tolist():
            for k, u in enumerate(neighbors[v]):
                vs.append(v)
                ks.append(k)
                us.append(int(u))
        self.v, self.k = np.array(vs, dtype=np.int64), np.array(ks, dtype=np.int64)
        row = self.index[self.v]
        col = self.index[np.array(us, dtype=np.int64)]
        off = col >= 0
        self.off = off
        self.rows = np.concatenate([row, row[off]])
        self.cols = np.concatenate([row, col[off]])

    def factor(self, W: np.ndarray):
        """``(log det ~L(W), its LU)`` for weights ``W[v, k]``; ``(-inf, None)`` when the minor
        is singular (every tree has weight 0: the observations rule the goal out), ``(0, None)``
        when the root is its component's only polytope. Dense LAPACK up to
        :data:`DENSE_MAX` rows (scipy's sparse constructors cost more than the factorisation
        there), SuperLU above."""
        if self.n == 0:
            return 0.0, None
        w = W[self.v, self.k]
        data = np.concatenate([w, -w[self.off]])
        if self.n <= DENSE_MAX:
            lap = np.bincount(self.rows * self.n + self.cols, weights=data,
                              minlength=self.n * self.n).reshape(self.n, self.n)
            lu = _DenseLU(lap)
            d = np.diagonal(lu.lu)
        else:
            lap = sp.csc_matrix((data, (self.rows, self.cols)), shape=(self.n, self.n))
            try:
                lu = splu(lap)
            except RuntimeError:  # exactly singular
                return -np.inf, None
            d = lu.U.diagonal()
        if not np.all(np.isfinite(d)) or np.any(d == 0):
            return -np.inf, None
        # ~L is a non-singular M-matrix here, so det > 0: the sign of the factors is not needed
        return float(np.sum(np.log(np.abs(d)))), lu


class _DenseLU:
    """A dense LU factorisation with the ``solve`` of SuperLU's factor object."""

    def __init__(self, a: np.ndarray):
        with warnings.catch_warnings():  # a singular minor is reported by its zero pivot
            warnings.simplefilter("ignore", LinAlgWarning)
            self.lu, self.piv = lu_factor(a, check_finite=False)

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``A^-1 b``."""
        return lu_solve((self.lu, self.piv), b, check_finite=False)
