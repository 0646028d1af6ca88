"""The episode layer: what determines an episode (:class:`EpisodeSpec`), its instance, the
robot's :class:`Body` (a plug-in registry; the grid body lives here), the runner and the
result. Above the method (``planning``), below sweeps (``experiments``) and simulators
(``sim``), which register their bodies here."""

from .body import BODIES, Body, Felt, GridBody, body_class, make_body, register_body, simulator_rng
from .cache import cached_map, cached_model, cached_world
from .instances import FIG4, HUMANS, Instance, fixed_instance, sample_instance, seed_for
from .physics import Physics
from .results import EpisodeResult, StepLog, result_row
from .runner import EpisodeRunner, run_episode
from .spec import EpisodeSpec

__all__ = ["BODIES", "FIG4", "HUMANS", "Body", "EpisodeResult", "EpisodeRunner", "EpisodeSpec",
           "Felt", "GridBody", "Instance", "Physics", "StepLog", "body_class", "cached_map",
           "cached_model", "cached_world", "fixed_instance", "make_body", "register_body",
           "result_row", "run_episode", "sample_instance", "seed_for", "simulator_rng"]
