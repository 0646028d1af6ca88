"""pathpref: infer where a person wants a robot to go, and by which path, from sparse nudges.

An implementation of Peltzer et al., "Incorporating Human Path Preferences in Robot Navigation
with Minimal Interventions" (arXiv 2303.03530), from the grid world to MuJoCo.

The public API, in the order a new user meets it::

    import pathpref as pp

    world = pp.load_world("office")                  # or a JSON path / dict (see maps.py)
    model = pp.ObservationModel.build(world, goals)  # human model for goal candidate cells
    belief = pp.PreferenceBelief(model)              # exact posterior over (goal, preference)
    belief.update(cell, heading)                     # a nudge: heading 0..7 (N, NE, ..., NW)
    planner = pp.POMCP(world, goals, pp.get_preset("paper").path_preference)
    action = planner.search(cell, belief, depth=30, seed=0).action

    result = pp.run_episode(pp.EpisodeSpec(map="office", method="path_preference",
                                           delta_t=5, instance=0, run=0,
                                           instance_seed=1, run_seed=2))
    pp.run_sweep(pp.sweep_specs("office", ["path_preference"], [1, 5], 6, 10), "r.sqlite")

Names are imported on first use, so ``import pathpref`` stays light.
"""

from importlib import import_module
from importlib.metadata import PackageNotFoundError, version
from typing import Any

try:
    __version__ = version("pathpref")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0+unknown"

#: public name -> module that defines it
_API = {
    "load_world": "pathpref.geometry.world",
    "World": "pathpref.geometry.world",
    "load_map": "pathpref.geometry.maps",
    "MapSpec": "pathpref.geometry.maps",
    "ObservationModel": "pathpref.inference.human",
    "SimulatedHuman": "pathpref.inference.human",
    "PreferenceBelief": "pathpref.inference.belief",
    "GoalBelief": "pathpref.inference.belief",
    "POMCP": "pathpref.planning.pomcp",
    "get_preset": "pathpref.planning.pomdp",
    "make_policy": "pathpref.planning.policies",
    "register_method": "pathpref.planning.policies",
    "EpisodeSpec": "pathpref.episode",
    "run_episode": "pathpref.episode",
    "Body": "pathpref.episode",
    "register_body": "pathpref.episode",
    "Belief": "pathpref.inference.belief",
    "sweep_specs": "pathpref.experiments.sweep",
    "run_sweep": "pathpref.experiments.sweep",
    "load_records": "pathpref.experiments.report",
    "markdown_tables": "pathpref.experiments.report",
    "PathprefError": "pathpref.errors",
    "MapError": "pathpref.errors",
    "ConfigError": "pathpref.errors",
}

__all__ = ["__version__", *_API]


def __getattr__(name: str) -> Any:
    if name in _API:
        value = getattr(import_module(_API[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'pathpref' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
