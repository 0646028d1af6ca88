"""The preference priors of the path-preference belief, by name (:attr:`Preset.prior
<pathpref.planning.pomdp.Preset>`, ``--prior``), and how to add one.

A prior is a factory taking :class:`PriorInputs` (the human model, the robot's start cell,
the goal prior, the preset's coupling switch) and returning a
:class:`~pathpref.inference.belief.Belief` over goal and preference:

* ``independent``: each polytope's preferred exit independent of the others (the paper's,
  :class:`~.belief.PreferenceBelief`, with the preset's coupling);
* ``routes``: preferences that lead to the goal (:mod:`.routes`);
* ``learned-gamma``: independent, with the human's rationality inferred too
  (:mod:`.rationality`);
* ``homotopy``: routes and the ways around the obstacles from the start (:mod:`.homotopy_prior`);
* ``circulation``: ways as flows from the start (:mod:`.circulation_prior`).

**Adding one** is one file with the belief class and one entry: a line in :data:`PRIORS`
for a built-in prior, or :func:`register_prior` called from any module, or, from another
package, the entry-point group ``pathpref.priors`` (:mod:`pathpref.plugins`), loaded the
first time its name is asked for. What the robust search needs of a belief besides its
rows it reads from the belief's own attributes: :attr:`~.belief.Belief.route_prior` (root
particles are trees drawn by Wilson's algorithm) and :meth:`~.belief.Belief.particles`
(particles the prior draws itself).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .. import plugins
from ..errors import ConfigError
from .belief import Belief, PreferenceBelief
from .circulation_prior import CirculationBelief
from .homotopy_prior import HomotopyBelief
from .human import ObservationModel
from .rationality import GammaBelief
from .routes import RouteBelief


@dataclass(frozen=True)
class PriorInputs:
    """What a prior may build its belief from."""

    model: ObservationModel
    #: the robot's start cell (-1: unknown; the homotopy and circulation priors need it)
    start: int = -1
    #: ``P(g)`` over the goal candidates (None: uniform)
    goal_prior: np.ndarray | None = None
    #: the preset's back-edge coupling (the independent priors read it)
    coupling: bool = True


PriorFactory = Callable[[PriorInputs], Belief]

#: the priors by name, in the order help texts list them
PRIORS: dict[str, PriorFactory] = {
    "independent": lambda i: PreferenceBelief(i.model, prior=i.goal_prior,
                                              coupling=i.coupling),
    "routes": lambda i: RouteBelief(i.model, prior=i.goal_prior),
    "learned-gamma": lambda i: GammaBelief.independent(i.model, prior=i.goal_prior,
                                                       coupling=i.coupling),
    "homotopy": lambda i: HomotopyBelief(i.model, i.start, prior=i.goal_prior),
    "circulation": lambda i: CirculationBelief(i.model, i.start, prior=i.goal_prior),
}


def register_prior(name: str, factory: PriorFactory) -> None:
    """Add a prior (a class or function taking :class:`PriorInputs`) under ``name``."""
    PRIORS[name] = factory


def prior_choices() -> str:
    """The registered priors as an error message lists them."""
    names = list(PRIORS)
    return ", ".join(names[:-1]) + " or " + names[-1]


def known_prior(name: object) -> bool:
    """True when ``name`` is a registered prior, or one another package declares (then
    registered here)."""
    if not isinstance(name, str):
        return False
    if name in PRIORS:
        return True
    found = plugins.load_callable(plugins.PRIORS, name,
                                  "a prior (a class or function taking PriorInputs)")
    if found is None:
        return False
    register_prior(name, found)
    return True


def check_prior(name: object) -> None:
    """Refuse a name that is no prior (one line listing the choices)."""
    if not known_prior(name):
        raise ConfigError(f"unknown prior '{name}'; choose {prior_choices()}")


def make_belief(name: str, inputs: PriorInputs) -> Belief:
    """The path-preference belief of prior ``name`` built from ``inputs``."""
    check_prior(name)
    return PRIORS[name](inputs)
