"""Per-process caches: a map file is read, a world built and a human model computed once."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..geometry.maps import MapSpec, load_map
from ..geometry.world import World
from ..inference.human import ObservationModel


@lru_cache(maxsize=64)
def cached_map(source: str) -> MapSpec:
    """The map at ``source`` (a built-in name or a JSON path), read once per process."""
    return load_map(source)


@lru_cache(maxsize=8)
def cached_world(source: str) -> World:
    """The world (arrangement, graph, grid motion) of ``source``, built once per process."""
    return World.from_spec(cached_map(source))


@lru_cache(maxsize=128)
def cached_model(source: str, goals: tuple[int, ...], normalize: bool) -> ObservationModel:
    """The human model of ``source`` for the goal candidate cells ``goals``."""
    return ObservationModel.build(cached_world(source), np.array(goals), normalize=normalize)
