"""Exact Bayesian belief over goal and path preference (paper Eq. 2, Sec. IV-B; SPEC 5).

Given the robot's cell ``s_t``, the goal ``g`` and the preference ``p_{v(s_t)}``, an observation is
independent of every other ``p_u`` (paper Fig. 3). With a uniform, independent prior over each
``p_v`` the posterior therefore factorises::

    P(g, theta | o_1:t)  ~  P0(g) * prod_v [ L_v(g, p_v) / deg(v) ]

where ``L_v(g, k)`` is the product of the likelihoods of the observations made while in ``v``.
:class:`PreferenceBelief` keeps one ``|Omega_g| x deg(v)`` table ``T_v`` per visited polytope
(scaled to a largest entry of 1, its scales kept in ``log_scale``) and the per-goal
sum ``lw(g) = sum_v log r_v(g)`` of log row means ``r_v(g) = mean_k T_v(g, k)``. The goal
marginal is ``P(g) ~ P0(g) exp(lw(g))``; an update touches one table and one entry of ``lw`` per
goal, so it costs ``O(|Omega_g| deg(v))`` whatever the number of polytopes.

:class:`GoalBelief` is the goal-only baseline (Best and Fitch): a vector over goals updated with
the unconstrained likelihood.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from ..geometry.grid import ACTION_ANGLES
from .human import ObservationModel

COUPLING_FLOOR = 1e-6
#: the smallest weight of an exit relative to the likeliest exit of its polytope (see
#: :meth:`PreferenceBelief._multiply`): far below any probability an episode can resolve,
#: far above the smallest double, so products of a few such weights stay representable
ROW_FLOOR = 1e-280
#: a row whose largest entry falls below this (relative to its table's largest) is rescaled on
#: its own (:meth:`PreferenceBelief._multiply`)
ROW_RESCALE = 1e-100


def direction_weights(angle: float, kappa: float) -> np.ndarray:
    """``(8,)`` von Mises weights ``exp(kappa (cos(theta - mu_h) - 1))`` of a force direction
    ``theta`` (radians) for the eight headings' directions ``mu_h`` (the density up to its
    normaliser, which no hypothesis sees; the largest weight is at most 1)."""
    return np.exp(kappa * (np.cos(angle - ACTION_ANGLES) - 1.0))


def entropy(p: np.ndarray) -> float:
    """Shannon entropy in nats of a (possibly unnormalised) non-negative array."""
    p = np.asarray(p, dtype=float).ravel()
    s = p.sum()
    if s <= 0:
        return 0.0
    q = p[p > 0] / s
    return float(-(q * np.log(q)).sum())


class Belief(ABC):
    """What a method knows of the human's goal (and, for some, preference).

    The episode feeds every belief the same three events: a heading given at a cell
    (:meth:`update`), a candidate the robot stood on that was not the goal (:meth:`rule_out`)
    and a polytope change (:meth:`enter`); planners and logs read :meth:`goal_marginal`, the
    entropies, and the polytopes whose preference the belief has evidence on.
    """

    @abstractmethod
    def update(self, cell: int, heading: int, weight: float = 1.0) -> None:
        """Condition on the human's heading ``heading`` (0..7) given at free cell ``cell``;
        ``weight`` tempers the likelihood, ``P(h | .)^weight`` (1: the plain update; above 1
        a more confident observation, below 1 a less confident one)."""

    def update_direction(self, cell: int, angle: float, kappa: float,
                         weight: float = 1.0) -> None:
        """Condition on a force direction ``angle`` (radians) felt at ``cell``: the continuous
        likelihood ``P(theta | s, g, p) = sum_h P(h | s, g, p) VM(theta; mu_h, kappa)`` (the
        human picks a heading by the model, then pushes along it with von Mises spread
        ``kappa``) to the power ``weight`` (the share of one observation this sample carries:
        online updates during a sustained push). ``kappa -> inf`` at ``mu_h`` is
        :meth:`update` with ``h``; ``kappa = 0`` is no evidence."""
        self._update_mixture(cell, direction_weights(angle, kappa), weight)

    @abstractmethod
    def _update_mixture(self, cell: int, a: np.ndarray, weight: float) -> None:
        """Multiply by ``(sum_h a_h P(h | s, .))^weight``."""

    @abstractmethod
    def rule_out(self, goal_index: int) -> None:
        """The robot stood on candidate ``goal_index`` and it was not the goal."""

    @abstractmethod
    def goal_marginal(self) -> np.ndarray:
        """``P(g | o_1:t)`` over the goal candidates."""

    def enter(self, v_from: int, v_to: int) -> None:  # noqa: B027 - a no-op by design
        """The robot moved from polytope ``v_from`` into ``v_to`` (ignored by default)."""

    def goal_entropy(self) -> float:
        """``H(g)`` of the goal marginal (nats)."""
        return entropy(self.goal_marginal())

    def joint_entropy(self, v: int) -> float:
        """``H(g, p_v)`` at polytope ``v`` (nats); ``H(g)`` for a belief without preferences."""
        return self.goal_entropy()

    def observed_polytopes(self) -> list[int]:
        """Polytopes whose preference the belief has evidence on (none by default)."""
        return []

    #: True when the preferences are a route to the goal (:mod:`.routes`): the robust
    #: search's root particles are then trees drawn by Wilson's algorithm
    #: (:func:`pathpref.planning.guided.tree_pool`); False: each ``p_v`` drawn lazily, on its
    #: own (the independent prior)
    route_prior = False

    def particles(self, m: int, rng: np.random.Generator):
        """Root particles the prior draws itself (:meth:`.homotopy_prior.HomotopyBelief.particles`
        gives the format), or None: the search draws them from the belief's rows."""
        return None


class GoalBelief(Belief):
    """Posterior over goal candidates alone (goal-only baseline)."""

    def __init__(self, model: ObservationModel, prior: np.ndarray | None = None):
        self.model = model
        G = len(model.goals)
        with np.errstate(divide="ignore"):  # a zero prior is log 0 = -inf: ruled out
            self.log_w = np.log(np.full(G, 1.0 / G) if prior is None
                                else np.asarray(prior, float))
        self.ruled_out = np.zeros(G, dtype=bool)

    def update(self, cell: int, heading: int, weight: float = 1.0) -> None:
        """Condition on the human's heading ``heading`` given at free cell ``cell``
        (likelihood to the power ``weight``)."""
        log_lik = np.log(self.model.goal_likelihood[cell, heading])
        self.log_w = self.log_w + (log_lik if weight == 1.0 else weight * log_lik)

    def _update_mixture(self, cell: int, a: np.ndarray, weight: float) -> None:
        with np.errstate(divide="ignore"):
            self.log_w = self.log_w + weight * np.log(a @ self.model.goal_likelihood[cell])

    def rule_out(self, goal_index: int) -> None:
        """The robot stood on candidate ``goal_index`` and it was not the goal."""
        self.ruled_out[goal_index] = True

    def goal_marginal(self) -> np.ndarray:
        """``P(g | o_1:t) ~ P0(g) prod_t P(o_t | g)`` with ruled-out candidates at 0."""
        w = np.where(self.ruled_out, -np.inf, self.log_w)
        w = np.exp(w - w.max())
        return w / w.sum()


class PreferenceBelief(Belief):
    """Exact factored posterior over ``(g, theta)`` (see module docstring).

    Args:
        model: likelihood tables for the world and goal set.
        prior: goal prior ``P0`` (uniform when None).
        coupling: when True, entering ``u`` from ``v`` multiplies the weight of ``p_u = v`` by
            ``1 - P(p_v = u | g)`` (the paper's remark: a human who wanted to go from ``v`` to
            ``u`` rarely wants to go straight back). Off by default; floored at 1e-6 so that no
            row of a table becomes all zeros.
    """

    def __init__(
        self, model: ObservationModel, prior: np.ndarray | None = None, coupling: bool = False
    ):
        self.model = model
        world = model.world
        self.neighbors = world.graph.neighbors
        # table width per polytope: its degree, or one "no preference" slot when it has none
        self.degree = np.maximum([len(nb) for nb in self.neighbors], 1)
        G = len(model.goals)
        p0 = np.full(G, 1.0 / G) if prior is None else np.asarray(prior, float)
        with np.errstate(divide="ignore"):  # a zero prior is log 0 = -inf: ruled out
            self.log_prior = np.log(p0)
        self.tables: dict[int, np.ndarray] = {}
        self.log_scale: dict[int, np.ndarray] = {}  # per table row, see _multiply
        self.log_rowmean = np.zeros(G)  # sum over visited v of log r_v(g)
        self.ruled_out = np.zeros(G, dtype=bool)
        #: the sum of the whole-table scales ``log top`` taken out by :meth:`_multiply` (the
        #: same for every goal, so the goal marginal never needs it; :meth:`log_joint` does)
        self.log_top = 0.0
        self.coupling = coupling
        self.cell_polytope = world.cell_polytope

    # --- updates -------------------------------------------------------------------------
    def _table(self, v: int) -> np.ndarray:
        t = self.tables.get(v)
        if t is None:
            t = self.tables[v] = np.ones((len(self.log_prior), self.degree[v]))
            self.log_scale[v] = np.zeros(len(self.log_prior))
        return t

    def _multiply(self, v: int, factor: np.ndarray) -> None:
        """``T_v *= factor`` (broadcast to ``(G, deg)``), keeping ``log_rowmean`` in step.

        The table is kept with its largest entry 1 (one scale for the whole table: the
        paper's arithmetic, bit for bit), and a row whose largest entry falls below
        :data:`ROW_RESCALE` is rescaled on its own, so no row underflows to all zeros (a 0/0 in
        the normalised tables) however many observations it holds. The scales are kept in
        ``log_scale[v]`` (``T_v(g, .) = t[g, .] exp(log_scale[v][g])``). An entry is floored at
        :data:`ROW_FLOOR` of its row's largest (the posterior is exact while no exit is that
        much less likely than another given one goal; beyond, those exits keep that relative
        weight instead of underflowing to an impossible 0)."""
        t = self._table(v)
        old = np.log(t.mean(axis=1))
        t *= factor
        top = t.max()
        with np.errstate(divide="ignore"):
            if top > 0:
                t /= top
                self.log_scale[v] += np.log(top)
                self.log_top += float(np.log(top))
            self.log_rowmean += np.log(t.mean(axis=1)) - old
            row = t.max(axis=1)
            low = row < ROW_RESCALE
            if low.any():
                self.log_scale[v][low] += np.log(row[low])  # -inf: impossible for that goal
                t[low] /= np.where(row[low] > 0, row[low], 1.0)[:, None]
                t[low & (row <= 0)] = 1.0  # its shape no longer matters: the goal's weight is 0
        np.maximum(t, ROW_FLOOR, out=t)

    def update(self, cell: int, heading: int, weight: float = 1.0) -> None:
        """Condition on the heading ``heading`` (0..7) given at free cell ``cell``
        (likelihood to the power ``weight``)."""
        v = int(self.cell_polytope[cell])
        lik = self.model.cell_likelihood[cell][heading]
        self._multiply(v, lik if weight == 1.0 else lik ** weight)

    def _update_mixture(self, cell: int, a: np.ndarray, weight: float) -> None:
        v = int(self.cell_polytope[cell])
        # a fresh copy of the block, as the padded table's slice was copied before the product
        lik = np.tensordot(a, self.model.cell_likelihood[cell].copy(), axes=1)
        self._multiply(v, lik ** weight)

    def enter(self, v_from: int, v_to: int) -> None:
        """Tell the belief that the robot moved from polytope ``v_from`` into ``v_to``.

        Does nothing unless ``coupling`` is on.
        """
        if not self.coupling or v_from == v_to:
            return
        k_to = int(np.flatnonzero(self.neighbors[v_from] == v_to)[0])
        k_back = int(np.flatnonzero(self.neighbors[v_to] == v_from)[0])
        t = self._table(v_from)
        p_went = t[:, k_to] / t.sum(axis=1)  # P(p_from = to | g)
        factor = np.ones((len(self.log_prior), self.degree[v_to]))
        factor[:, k_back] = np.maximum(1.0 - p_went, COUPLING_FLOOR)
        self._multiply(v_to, factor)

    def rule_out(self, goal_index: int) -> None:
        """The robot stood on candidate ``goal_index`` and it was not the goal."""
        self.ruled_out[goal_index] = True

    # --- queries -------------------------------------------------------------------------
    def goal_log_weights(self) -> np.ndarray:
        """``log P0(g) + lw(g)`` (unnormalised), ``-inf`` for ruled-out candidates."""
        w = self.log_prior + self.log_rowmean
        return np.where(self.ruled_out, -np.inf, w)

    def log_joint(self) -> np.ndarray:
        """``log P0(g) + log P(o_1:t | g)``, absolutely scaled (not up to a constant), ``-inf``
        for ruled-out candidates: ``lw(g) = sum_v log mean_k T_v(g, k)`` plus the table scales
        :attr:`log_top` (every factor :meth:`_multiply` took out of a table, the same for every
        goal; a row's own rescale is already in ``lw``). Its log-sum-exp over goals is the
        evidence ``log P(o_1:t)`` (:mod:`.rationality`)."""
        return self.goal_log_weights() + self.log_top

    def goal_marginal(self) -> np.ndarray:
        """``P(g | o_1:t)``."""
        w = self.goal_log_weights()
        w = np.exp(w - w.max())
        return w / w.sum()


    def local_given_goal(self, v: int) -> np.ndarray:
        """``(G, deg v)`` table ``T_v`` normalised per goal: ``P(p_v = N(v)[k] | g, o_1:t)``
        under this independent prior."""
        t = self.tables.get(v)
        if t is None:
            return np.full((len(self.log_prior), self.degree[v]), 1.0 / self.degree[v])
        return t / t.sum(axis=1, keepdims=True)

    def preference_given_goal(self, v: int) -> np.ndarray:
        """``(G, deg v)`` table ``P(p_v = N(v)[k] | g, o_1:t)``."""
        return self.local_given_goal(v)

    def preference_marginal(self, v: int) -> np.ndarray:
        """``P(p_v = N(v)[k] | o_1:t)`` over the neighbours of ``v``."""
        return self.goal_marginal() @ self.preference_given_goal(v)

    def joint(self, v: int) -> np.ndarray:
        """``(G, deg v)`` joint ``P(g, p_v | o_1:t)``."""
        return self.goal_marginal()[:, None] * self.preference_given_goal(v)

    def observed_polytopes(self) -> list[int]:
        """Polytopes with at least one observation (or coupling factor): those with a table."""
        return list(self.tables)

    def joint_entropy(self, v: int) -> float:
        """``H(g, p_v)`` of the joint table at polytope ``v`` (nats)."""
        return entropy(self.joint(v))
