"""The human's rationality ``gamma_h`` learned online: the exact posterior over a grid of values.

The observation model (:mod:`.human`) has one free number, the Boltzmann rationality
``gamma`` of ``P(h | s, g, p; gamma) ~ exp(-gamma Delta)``. Instead of assuming it
(:data:`.human.GAMMA_H`), put a prior ``pi`` on a grid ``gamma_1 .. gamma_M`` and infer it with
the goal and the preference. The joint posterior is::

    P(gamma, g, theta | o_1:t)  ~  pi(gamma) P0(g) P(theta) prod_t P(o_t | s_t, g, theta; gamma)

For a fixed ``gamma`` this is the posterior an inner belief already computes exactly (one
:class:`.belief.PreferenceBelief` per grid value, each with its own likelihood tables, sharing
the cost tables). Write ``J_gamma(g) = P0(g) P(o_1:t | g; gamma)`` for the inner belief's
*unnormalised, absolutely scaled* goal weight (:meth:`.belief.PreferenceBelief.log_joint`) and
``Z_gamma = sum_g J_gamma(g) = P(o_1:t; gamma)`` for its evidence. Then, exactly,

* ``P(gamma, g | o) = pi(gamma) J_gamma(g) / sum_gamma' pi(gamma') Z_gamma'``;
* ``P(gamma | o) ~ pi(gamma) Z_gamma``, i.e. the mixture weight is multiplied at every
  observation by that belief's marginal likelihood of it,
  ``P(o_t | o_1:t-1; gamma) = Z_gamma(t) / Z_gamma(t-1)`` (the change of its log normaliser);
  a rule-out (``g != k``) is such an observation too, with likelihood ``P(g != k | o; gamma)``;
* ``P(p_v | g, o) = sum_gamma P(gamma | g, o) P(p_v | g, o; gamma)`` with
  ``P(gamma | g, o) ~ pi(gamma) J_gamma(g)``, and ``P(g, p_v | o) = P(g | o) P(p_v | g, o)``.

A tempered update (``weight != 1``) or a force direction (von Mises weights, whose normaliser
depends on ``kappa`` alone, not on ``gamma``) multiplies every inner belief by its factor, and
the weights follow the same rule with that factor as the likelihood.

Given the goal, the preferences of two polytopes are no longer independent (both depend on
``gamma``); the marginals above are exact, and a planner that draws each ``p_v`` from
:meth:`GammaBelief.local_given_goal` on its own draws from their product (the independent
prior's sampler, unchanged).
"""

from __future__ import annotations

import numpy as np

from .belief import Belief, PreferenceBelief, entropy
from .human import ObservationModel

#: the rationality grid of the learned-gamma belief (uniform prior): the values the issue's
#: mis-specified humans use (0.5, 5) around the assumed :data:`.human.GAMMA_H` (1.5)
GAMMA_GRID = (0.5, 1.5, 5.0)


def grid_models(model: ObservationModel, gammas=GAMMA_GRID) -> list[ObservationModel]:
    """One observation model per ``gamma`` of the grid, sharing ``model``'s cost tables (and
    ``model`` itself for its own ``gamma``)."""
    return [model if g == model.gamma else
            ObservationModel(model.world, model.tables, float(g), model.normalize)
            for g in gammas]


class GammaBelief(Belief):
    """Exact posterior over ``(gamma, g, theta)``: a mixture of one inner belief per ``gamma``
    of a grid (module docstring).

    Args:
        inner: one belief per grid value (each conditioned on its own ``gamma``), all over the
            same goal candidates and world, each with a ``log_joint()``.
        gammas: the grid values, in the order of ``inner``.
        gamma_prior: ``pi(gamma)`` (uniform when None).
    """

    def __init__(self, inner: list[PreferenceBelief], gammas, gamma_prior=None):
        if len(inner) != len(gammas) or not inner:
            raise ValueError("one inner belief per gamma, at least one")
        self.inner = list(inner)
        self.gammas = np.asarray(gammas, dtype=float)
        M = len(self.inner)
        pi = np.full(M, 1.0 / M) if gamma_prior is None else np.asarray(gamma_prior, float)
        with np.errstate(divide="ignore"):
            self.log_gamma_prior = np.log(pi)
        self.model = self.inner[0].model
        self._cache: np.ndarray | None = None

    @classmethod
    def independent(cls, model: ObservationModel, prior: np.ndarray | None = None,
                    coupling: bool = False, gammas=GAMMA_GRID) -> GammaBelief:
        """Inner :class:`.belief.PreferenceBelief` (independent preference prior, goal prior
        ``prior``, ``coupling``) for each ``gamma`` of ``gammas``, uniform over the grid."""
        return cls([PreferenceBelief(m, prior=prior, coupling=coupling)
                    for m in grid_models(model, gammas)], gammas)

    # --- events: every inner belief sees them --------------------------------------------
    def update(self, cell: int, heading: int, weight: float = 1.0) -> None:
        """Condition every inner belief on the heading (``weight``: tempered likelihood)."""
        for b in self.inner:
            b.update(cell, heading, weight)
        self._cache = None

    def _update_mixture(self, cell: int, a: np.ndarray, weight: float) -> None:
        for b in self.inner:
            b._update_mixture(cell, a, weight)
        self._cache = None

    def rule_out(self, goal_index: int) -> None:
        """The candidate was not the goal: every inner belief rules it out."""
        for b in self.inner:
            b.rule_out(goal_index)
        self._cache = None

    def enter(self, v_from: int, v_to: int) -> None:
        """A polytope change, told to every inner belief."""
        for b in self.inner:
            b.enter(v_from, v_to)
        self._cache = None

    # --- queries -------------------------------------------------------------------------
    def joint_gamma_goal(self) -> np.ndarray:
        """``(M, G)`` ``P(gamma, g | o_1:t)``."""
        if self._cache is None:
            lj = np.stack([b.log_joint() for b in self.inner]) + self.log_gamma_prior[:, None]
            top = lj.max()
            p = np.exp(lj - top) if np.isfinite(top) else np.ones_like(lj)
            self._cache = p / p.sum()
        return self._cache

    def gamma_marginal(self) -> np.ndarray:
        """``(M,)`` ``P(gamma | o_1:t)`` over :attr:`gammas`."""
        return self.joint_gamma_goal().sum(axis=1)

    def goal_marginal(self) -> np.ndarray:
        """``P(g | o_1:t) = sum_gamma P(gamma, g | o_1:t)``."""
        return self.joint_gamma_goal().sum(axis=0)

    def _gamma_given_goal(self) -> np.ndarray:
        """``(M, G)`` ``P(gamma | g, o_1:t)`` (the prior ``pi`` for a goal of probability 0)."""
        j = self.joint_gamma_goal()
        s = j.sum(axis=0, keepdims=True)
        pi = np.exp(self.log_gamma_prior)[:, None]
        return np.where(s > 0, j / np.where(s > 0, s, 1.0), pi / pi.sum())

    def _mix(self, tables: list[np.ndarray]) -> np.ndarray:
        w = self._gamma_given_goal()
        return np.einsum("mg,mgk->gk", w, np.stack(tables))

    def local_given_goal(self, v: int) -> np.ndarray:
        """``(G, deg v)`` ``P(p_v = N(v)[k] | g, o_1:t)``: the inner beliefs' tables mixed by
        ``P(gamma | g, o_1:t)`` (what a planner draws each ``p_v`` from)."""
        return self._mix([b.local_given_goal(v) for b in self.inner])

    def preference_given_goal(self, v: int) -> np.ndarray:
        """``(G, deg v)`` exact ``P(p_v = N(v)[k] | g, o_1:t)``."""
        return self._mix([b.preference_given_goal(v) for b in self.inner])

    def preference_marginal(self, v: int) -> np.ndarray:
        """``P(p_v = N(v)[k] | o_1:t)``."""
        return self.goal_marginal() @ self.preference_given_goal(v)

    def joint(self, v: int) -> np.ndarray:
        """``(G, deg v)`` ``P(g, p_v | o_1:t)``."""
        return self.goal_marginal()[:, None] * self.preference_given_goal(v)

    def joint_entropy(self, v: int) -> float:
        """``H(g, p_v)`` (nats)."""
        return entropy(self.joint(v))

    def observed_polytopes(self) -> list[int]:
        """Polytopes any inner belief has evidence on (they all see the same events)."""
        return self.inner[0].observed_polytopes()
