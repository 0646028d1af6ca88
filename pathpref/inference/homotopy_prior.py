"""The homotopy prior: a person prefers a way round the obstacles, and one push tells which.

Under the route prior (:mod:`.routes`) every polytope's exit is its own unknown, tied to the
others only by "no cycle"; a push in one thin polytope says little about the next, and a route
on a floor plan crosses 10-24 of them. People choose a way round the obstacles. The homotopy
prior is a mixture, for a goal ``g`` with polytope ``r`` and the robot's start polytope ``s``::

    P(theta | g) = a * A_g(theta) + (1 - a) * (1 / K_g) * sum_c prod_v pi_gc(v, theta_v)

* ``A_g``: the route prior (uniform over in-arborescences rooted at ``r``, :mod:`.routes`), with
  weight ``a =`` :data:`TREE_SHARE`: every route stays possible, whatever the ways below;
* ``c`` ranges over the ``K_g`` *ways* from ``s`` to ``r``
  (:func:`pathpref.geometry.ways.find_ways`: the shortest route of each of the few shortest
  homotopy classes), equally likely;
* given a way, the exits are independent::

      pi_gc(v, u) = (1 - EPS) softmax_{u in N(v)}(-BETA * phi_c(u)) + EPS / deg(v)

  with ``phi_c`` the way's potential (:func:`~pathpref.geometry.ways.way_potential`: the length
  to the goal along the way, rejoining it counted twice), so that on the way the exit is its
  next polytope, off it the way back, and thin polytopes crossed in another order by the same
  way cost little. ``r`` itself and polytopes outside its component have uniform rows.

**The posterior is exact.** The likelihood factorises over polytopes, ``P(o | g, theta) =
prod_v T_v(g, theta_v)`` (the tables of :class:`.PreferenceBelief`), so each component's
evidence is closed-form::

    P(o | g, c) = prod_{v observed} sum_u pi_gc(v, u) T_v(g, u),
    P(o | g, A) = the route prior's (matrix-tree theorem, :class:`.RouteBelief`),

and ``P(g, component | o) ~ P0(g) * weight * P(o | g, component)``. Given a way the exits stay
independent: ``P(theta_v = u | g, c, o) ~ pi_gc(v, u) T_v(g, u)``. One push in the way's
corridor raises that way's weight, and with it the exit of every polytope along it.

**Particles** for the robust search (:meth:`HomotopyBelief.particles`): ``(g, component)`` drawn
from the posterior; a way's particle draws every exit from its conditional above, a tree
particle is drawn by Wilson's algorithm (the search's :func:`~pathpref.planning.guided.tree_pool`,
given the goals' conditional under the tree component).
"""

from __future__ import annotations

import numpy as np

from ..errors import ConfigError
from ..geometry.ways import find_ways, sketch, way_potential
from .human import ObservationModel
from .routes import RouteBelief

#: the route prior's share ``a`` of the mixture (module docstring)
TREE_SHARE = 0.2
#: how sharply a way's potential picks the exit (per cell of potential)
BETA = 1.0
#: the share of a way's exit rows spread uniformly over the neighbours
EPS = 0.05


def _logsumexp(a: np.ndarray, axis: int) -> np.ndarray:
    top = np.max(a, axis=axis, keepdims=True)
    top = np.where(np.isfinite(top), top, 0.0)
    with np.errstate(divide="ignore"):
        return np.squeeze(top, axis) + np.log(np.sum(np.exp(a - top), axis=axis))


def exit_rows(p: np.ndarray, undefined: np.ndarray, r: int, valid: np.ndarray) -> np.ndarray:
    """``(P, K)`` a component's exit rows ``(1 - EPS) p + EPS / deg(v)`` over each polytope's
    neighbours (``valid``); uniform where the component says nothing (``undefined``) and at
    the goal's polytope ``r``; a polytope with no neighbour gets slot 0 (never read)."""
    deg = valid.sum(axis=1)
    uniform = valid / np.maximum(deg, 1)[:, None]
    uniform[deg == 0, 0] = 1.0
    rows = (1.0 - EPS) * p + EPS * uniform
    free = undefined | (deg == 0)
    rows[free] = uniform[free]
    rows[r] = uniform[r]
    return rows


class HomotopyBelief(RouteBelief):
    """Exact posterior over ``(g, theta)`` under the homotopy prior (module docstring).

    Args:
        model: likelihood tables for the world and goal set.
        start: the robot's start cell (the ways begin in its polytope).
        prior: goal prior ``P0`` (uniform when None).
    """

    #: the route prior's share ``a`` of the mixture (module docstring)
    tree_share = TREE_SHARE

    def __init__(self, model: ObservationModel, start: int, prior: np.ndarray | None = None):
        super().__init__(model, prior=prior)
        nbr = self.model.world.graph.neighbor_table()
        self._nbr = nbr
        per_root = self._component_rows(start, nbr)
        #: the components per goal and their exit rows ``pi_gc`` (``(P, K)``, zero-padded)
        self.ways = [per_root[int(r)] for r in self.goal_polytope]
        self.n_ways = np.array([len(w) for w in self.ways], dtype=np.int64)
        G = len(self.goal_polytope)
        C = max(1, int(self.n_ways.max()))
        self._C = C
        # log prior weight of each component given g: the tree, then the others (-inf: padding)
        a = self.tree_share
        self._log_w = np.full((G, 1 + C), -np.inf)
        for g in range(G):
            n = int(self.n_ways[g])
            if n:
                self._log_w[g, 0] = np.log(a)
                self._log_w[g, 1: 1 + n] = np.log((1.0 - a) / n)
            else:
                self._log_w[g, 0] = 0.0
        #: per observed polytope, ``(G, C)`` ``log sum_u pi_gc(v, u) T_v(g, u)``
        self._way_terms: dict[int, np.ndarray] = {}
        self._comp: np.ndarray | None = None  # component_log_joint, until the next update

    def _component_rows(self, start: int, nbr: np.ndarray) -> dict[int, list[np.ndarray]]:
        """Per goal polytope ``r``, the exit rows of its components: one per way from the
        start's polytope to ``r`` (module docstring)."""
        if start < 0:
            raise ConfigError("the homotopy prior needs the robot's start cell (start=-1); "
                              "pass the episode's start")
        world = self.model.world
        sk = sketch(world)
        s = int(world.cell_polytope[start])
        valid = nbr >= 0
        return {r: [self._rows(way_potential(sk, c), r, nbr, valid)
                    for c in find_ways(sk, s, r).routes]
                for r in np.unique(self.goal_polytope).tolist()}

    @staticmethod
    def _rows(phi: np.ndarray, r: int, nbr: np.ndarray, valid: np.ndarray) -> np.ndarray:
        """``(P, K)`` ``pi_c(v, .)`` from the way's potential ``phi`` (module docstring)."""
        ph = np.where(valid, phi[np.maximum(nbr, 0)], np.inf)
        low = ph.min(axis=1, keepdims=True)
        with np.errstate(invalid="ignore"):
            e = np.where(valid & np.isfinite(ph), np.exp(-BETA * (ph - low)), 0.0)
        soft = e / np.where(e.sum(axis=1, keepdims=True) > 0, e.sum(axis=1, keepdims=True), 1)
        return exit_rows(soft, ~np.isfinite(low[:, 0]), r, valid)

    def rule_out(self, goal_index: int) -> None:
        """The robot stood on candidate ``goal_index`` and it was not the goal."""
        super().rule_out(goal_index)
        self._comp = None

    def _multiply(self, v: int, factor: np.ndarray) -> None:
        super()._multiply(v, factor)
        self._comp = None
        t = self.tables[v]
        deg = t.shape[1]
        terms = np.full((len(self.log_prior), self._C), -np.inf)
        with np.errstate(divide="ignore"):
            for g, rows in enumerate(self.ways):
                for c, pi in enumerate(rows):
                    terms[g, c] = np.log(pi[v, :deg] @ t[g]) + self.log_scale[v][g]
        self._way_terms[v] = terms

    # --- the mixture ------------------------------------------------------------------------
    def component_log_joint(self) -> np.ndarray:
        """``(G, 1 + C)`` ``log P0(g) + log w + log P(o | g, component)``: column 0 the route
        prior, columns ``1..K_g`` the ways (``-inf`` beyond; ruled-out goals ``-inf``)."""
        if self._comp is not None:
            return self._comp
        tree = np.array([ll for ll, _ in self._solved()])
        comp = self._log_w.copy()
        comp[:, 0] += tree
        ways = np.zeros((len(self.log_prior), self._C))
        for terms in self._way_terms.values():
            ways += terms
        comp[:, 1:] += ways
        comp += self.log_prior[:, None]
        comp[self.ruled_out | np.isnan(comp).any(axis=1)] = -np.inf
        self._comp = np.where(np.isnan(comp), -np.inf, comp)
        return self._comp

    def goal_log_weights(self) -> np.ndarray:
        """``log P0(g) + log P(o | g)`` under the mixture (unnormalised, absolutely scaled)."""
        return _logsumexp(self.component_log_joint(), axis=1)

    def log_joint(self) -> np.ndarray:
        """``log P0(g) + log P(o_1:t | g)``, absolutely scaled."""
        return self.goal_log_weights()

    def component_posterior(self) -> np.ndarray:
        """``(G, 1 + C)`` ``P(g, component | o)``."""
        c = self.component_log_joint()
        top = c.max()
        w = np.exp(c - top) if np.isfinite(top) else np.zeros_like(c)
        return w / w.sum() if w.sum() > 0 else w

    def way_given(self, g: int, c: int, v: int) -> np.ndarray:
        """``(deg v,)`` ``P(theta_v = N(v)[k] | g, way c, o) ~ pi_gc(v, k) T_v(g, k)``."""
        deg = len(self.neighbors[v])
        pi = self.ways[g][c][v, :max(deg, 1)]
        t = self.tables.get(v)
        p = pi if t is None else pi * t[g, :max(deg, 1)]
        return p / p.sum()

    def preference_given_goal(self, v: int) -> np.ndarray:
        """``(G, deg v)`` exact ``P(p_v = N(v)[k] | g, o)``: the components' conditionals
        weighted by ``P(component | g, o)``."""
        tree = super().preference_given_goal(v)
        post = self.component_posterior()
        out = np.zeros_like(tree)
        for g in range(len(self.log_prior)):
            z = post[g].sum()
            if z <= 0:
                out[g] = tree[g]
                continue
            out[g] = post[g, 0] / z * tree[g]
            for c in range(int(self.n_ways[g])):
                if post[g, 1 + c] > 0:
                    out[g, :len(self.neighbors[v]) or 1] += post[g, 1 + c] / z * \
                        self.way_given(g, c, v)
        return out

    def particles(self, m: int, rng: np.random.Generator):
        """``m`` exact draws of ``(g, theta)`` split by component: returns ``(m_tree,
        tree_goal_cdf, goals, slots)``, the number of tree particles and the cumulative
        ``P(g | tree, o)`` to draw them from (Wilson's algorithm, the caller's), and the way
        particles' goals ``(m - m_tree,)`` and exit slots ``(m - m_tree, P)`` (``-1`` at the
        goal's polytope)."""
        post = self.component_posterior()
        flat = post.ravel()
        pick = rng.choice(flat.size, size=m, p=flat / flat.sum())
        g_all, comp = np.divmod(pick, post.shape[1])
        is_tree = comp == 0
        tree_g = post[:, 0]
        tree_cdf = np.cumsum(tree_g / tree_g.sum()) if tree_g.sum() > 0 else \
            np.cumsum(np.full(len(tree_g), 1.0 / len(tree_g)))
        goals = g_all[~is_tree]
        ways = comp[~is_tree] - 1
        P = self._nbr.shape[0]
        top_slot = np.maximum((self._nbr >= 0).sum(axis=1), 1) - 1
        slots = np.zeros((len(goals), P), dtype=np.int64)
        for (g, c) in set(zip(goals.tolist(), ways.tolist(), strict=True)):
            rows = self.ways[g][c].copy()
            for v, t in self.tables.items():
                deg = t.shape[1]
                p = rows[v, :deg] * t[g]
                rows[v, :deg] = p / p.sum()
            cdf = np.cumsum(rows, axis=1)
            idx = np.flatnonzero((goals == g) & (ways == c))
            u = rng.random((len(idx), P, 1))
            s = (cdf[None, :, :] < u * cdf[None, :, -1:]).sum(axis=2)
            slots[idx] = np.minimum(s, top_slot)
        for g in np.unique(goals).tolist():
            slots[goals == g, int(self.goal_polytope[g])] = -1
        return int(is_tree.sum()), tree_cdf, goals.astype(np.int64), slots
