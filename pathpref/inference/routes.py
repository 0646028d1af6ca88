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

import numpy as np

from .belief import PreferenceBelief
from .human import ObservationModel


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
        self._cache: tuple[np.ndarray, list] | None = None
        # log det ~L_g(1): the number of arborescences, the prior's normaliser
        self._log_trees = np.array([self._solve(g, unweighted=True)[0]
                                    for g in range(len(self.log_prior))])

    def _multiply(self, v: int, factor: np.ndarray) -> None:
        super()._multiply(v, factor)
        self._cache = None

    def _weights(self, g: int, v: int) -> np.ndarray:
        """``W_g(v, N(v)[k])`` (the table row scaled by a constant, which cancels)."""
        t = self.tables.get(v)
        return np.ones(len(self.neighbors[v])) if t is None else t[g, : len(self.neighbors[v])]

    def _solve(self, g: int, unweighted: bool = False):
        """``(log det ~L_g, ~L_g^-1, index of each polytope in the minor or -1)``."""
        r = self.goal_polytope[g]
        members = np.flatnonzero(self.component == self.component[r])
        members = members[members != r]
        index = -np.ones(len(self.neighbors), dtype=np.int64)
        index[members] = np.arange(len(members))
        lap = np.zeros((len(members), len(members)))
        for i, v in enumerate(members):
            w = np.ones(len(self.neighbors[v])) if unweighted else self._weights(g, v)
            lap[i, i] = w.sum()
            for u, wu in zip(self.neighbors[v], w, strict=True):
                if index[u] >= 0:
                    lap[i, index[u]] -= wu
        if len(members) == 0:
            return 0.0, lap, index
        sign, logdet = np.linalg.slogdet(lap)
        if sign <= 0:  # every tree has weight 0: the observations rule this goal out
            return -np.inf, None, index
        return logdet, np.linalg.inv(lap), index

    def _solved(self) -> tuple[np.ndarray, list]:
        """Per goal: ``log P(o | g)`` up to a constant, and the minor's inverse and index."""
        if self._cache is None:
            G = len(self.log_prior)
            loglik = np.zeros(G)
            inv = []
            for g in range(G):
                logdet, linv, index = self._solve(g)
                r = self.goal_polytope[g]
                ll = logdet - self._log_trees[g]
                for v, t in self.tables.items():
                    if v == r or index[v] < 0:  # the root, or outside r's component
                        ll += np.log(t[g].mean())
                loglik[g] = ll
                inv.append((linv, index))
            self._cache = (loglik, inv)
        return self._cache

    def goal_log_weights(self) -> np.ndarray:
        """``log P0(g) + log P(o | g)`` (unnormalised), ``-inf`` for ruled-out candidates."""
        w = self.log_prior + self._solved()[0]
        return np.where(self.ruled_out, -np.inf, w)

    def preference_given_goal(self, v: int) -> np.ndarray:
        """``(G, deg v)`` exact ``P(p_v = N(v)[k] | g, o_1:t)`` under the route prior (uniform
        outside the goal's component; the goal's own polytope has no preferred exit, shown as
        uniform)."""
        deg = len(self.neighbors[v])
        out = np.full((len(self.log_prior), self.degree[v]), 1.0 / self.degree[v])
        if deg == 0:
            return out
        for g, (linv, index) in enumerate(self._solved()[1]):
            i = index[v]
            if v == self.goal_polytope[g] or linv is None:
                continue  # no preferred exit at the goal; no tree for an impossible goal
            if i < 0:  # outside the goal's component: the independent posterior
                out[g, :deg] = self.local_given_goal(v)[g, :deg]
                continue
            w = self._weights(g, v)
            col = np.array([linv[i, i] - (linv[index[u], i] if index[u] >= 0 else 0.0)
                            for u in self.neighbors[v]])
            p = np.maximum(w * col, 0.0)
            out[g, :deg] = p / p.sum()
        return out
