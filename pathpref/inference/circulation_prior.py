"""The circulation prior: a person keeps to one direction round the building, and one push
tells which.

Where a route prior (:mod:`.routes`) leaves every polytope's exit its own unknown, people who
share a floor keep to a one-way flow: round the desks clockwise, up one aisle and down the
next. The circulation prior is a mixture, for a goal ``g`` with polytope ``r``::

    P(theta | g) = a * A_g(theta) + (1 - a) * (1 / F_g) * sum_f prod_v pi_gf(v, theta_v)

* ``A_g``: the route prior (uniform over in-arborescences rooted at ``r``), weight
  ``a =`` :data:`TREE_SHARE`: every route stays possible;
* ``f`` ranges over the ``F_g`` distinct goal completions of the map's circulations
  (:func:`pathpref.geometry.circulation.circulations`), equally likely: each flow ``f`` is
  completed for ``r`` as the consistent human completes the map's preference
  (:func:`pathpref.geometry.following.consistent_preference`: the fewest departures from the
  flow that lead to ``r``, then the fewest polytope changes), giving the tree ``q_gf``;
* given a completed flow, the exits are independent::

      pi_gf(v, u) = (1 - EPS) [u = q_gf(v)] + EPS / deg(v)

  (:data:`~.homotopy_prior.EPS`, :func:`~.homotopy_prior.exit_rows`): a person mostly keeps
  the flow, now and then not;
  ``r`` itself and polytopes with no exit in ``q_gf`` have uniform rows.

The posterior is exact and computed as the homotopy prior's
(:class:`~.homotopy_prior.HomotopyBelief`, the same mixture with ways in place of flows): the
likelihood factorises over polytopes, so each component's evidence is a product over the
observed polytopes of ``sum_u pi_gf(v, u) T_v(g, u)``, and the route prior's is the
matrix-tree theorem's. One push along the flow raises every flow that agrees with it, and with
them the exits of every polytope those flows share; the search's particles are drawn the same
way (:meth:`~.homotopy_prior.HomotopyBelief.particles`).
"""

from __future__ import annotations

import numpy as np

from ..geometry.circulation import circulations
from ..geometry.following import consistent_preference
from .homotopy_prior import HomotopyBelief, exit_rows

#: the route prior's share ``a`` of the mixture (module docstring)
TREE_SHARE = 0.3


class CirculationBelief(HomotopyBelief):
    """Exact posterior over ``(g, theta)`` under the circulation prior (module docstring).

    Args:
        model: likelihood tables for the world and goal set.
        start: the robot's start cell (not used by this prior; -1 is accepted).
        prior: goal prior ``P0`` (uniform when None).
    """

    tree_share = TREE_SHARE

    def _component_rows(self, start: int, nbr: np.ndarray) -> dict[int, list[np.ndarray]]:
        """Per goal polytope ``r``, the rows ``pi_gf`` of each distinct completed flow."""
        world = self.model.world
        flows = circulations(world)
        valid = nbr >= 0
        out = {}
        for r in np.unique(self.goal_polytope).tolist():
            trees = np.unique(np.array([consistent_preference(world, f, r)[0] for f in flows],
                                       dtype=np.int64).reshape(len(flows), -1), axis=0)
            out[r] = [exit_rows(((nbr == q[:, None]) & valid).astype(float), q < 0, r, valid)
                      for q in trees]
        return out
