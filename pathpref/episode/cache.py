"""Per-process caches: a map file is read, a world built and a human model computed once.

A map may also arrive by content (:func:`ship_maps`): a sweep's coordinator sends each worker
the maps of its episodes, keyed by the name or path the episodes give, with their content
hashes; a worker on another machine then needs no copy of the file."""

from __future__ import annotations

from functools import lru_cache
from typing import Any

import numpy as np

from ..errors import MapError
from ..geometry.maps import MapSpec, load_map, parse_map
from ..geometry.world import World
from ..inference.human import ObservationModel

#: maps received by content (:func:`ship_maps`), by the source the episodes name
_SHIPPED: dict[str, MapSpec] = {}


@lru_cache(maxsize=64)
def cached_map(source: str) -> MapSpec:
    """The map at ``source`` (a built-in name or a JSON path), read once per process; a map
    shipped under that name (:func:`ship_maps`) is used instead of the file."""
    shipped = _SHIPPED.get(source)
    return shipped if shipped is not None else load_map(source)


@lru_cache(maxsize=8)
def cached_world(source: str) -> World:
    """The world (arrangement, graph, grid motion) of ``source``, built once per process."""
    return World.from_spec(cached_map(source))


@lru_cache(maxsize=128)
def cached_model(source: str, goals: tuple[int, ...], normalize: bool) -> ObservationModel:
    """The human model of ``source`` for the goal candidate cells ``goals``."""
    return ObservationModel.build(cached_world(source), np.array(goals), normalize=normalize)


def map_payload(sources: set[str] | list[str]) -> dict[str, tuple[str, dict[str, Any]]]:
    """What a coordinator ships of the maps ``sources``: ``{source: (content hash, the map in
    file format)}`` (read through :func:`cached_map`, so from the coordinator's cache)."""
    return {s: (cached_map(s).content_hash, cached_map(s).to_dict()) for s in sorted(sources)}


def ship_maps(payload: dict[str, tuple[str, dict[str, Any]]]) -> None:
    """Use the maps of ``payload`` (:func:`map_payload`) for their sources in this process.

    Each map is parsed again and its content hash must equal the one shipped (MapError
    otherwise: a damaged transfer, or a pathpref whose map identity differs from the
    coordinator's). A map already shipped with the same hash changes nothing; a new or changed
    one clears the caches above, so nothing built from an older map is reused."""
    changed = False
    for source, (digest, raw) in payload.items():
        old = _SHIPPED.get(source)
        if old is not None and old.content_hash == digest:
            continue
        spec = parse_map(raw, default_name=str(raw.get("name", "map")))
        if spec.content_hash != digest:
            raise MapError(f"map {source!r} arrived with content hash {spec.content_hash}, not "
                           f"the coordinator's {digest}; is pathpref the same version on every "
                           "node?")
        _SHIPPED[source] = spec
        changed = True
    if changed:
        cached_map.cache_clear()
        cached_world.cache_clear()
        cached_model.cache_clear()
