"""Entry points other packages declare (:mod:`.registry` has the contract): the groups and
the look-up of a map by name (the tasks resolve ``map="<name>"`` through it, below the
registry, which imports the tasks)."""

from __future__ import annotations

from importlib.metadata import entry_points
from typing import Any

from pathpref.errors import ConfigError

#: the entry-point group of tasks other packages provide
TASK_GROUP = "pathpref.tasks"
#: the entry-point group of maps other packages provide
MAP_GROUP = "pathpref.maps"


def entries(group: str) -> dict[str, Any]:
    """The entry points of ``group`` by name (read afresh: a package installed later is seen)."""
    return {ep.name: ep for ep in entry_points(group=group)}


def entry_point_map(name: str) -> Any | None:
    """The map of entry point ``name`` in :data:`MAP_GROUP` (a callable's result), or None
    when no package provides one."""
    ep = entries(MAP_GROUP).get(name)
    if ep is None:
        return None
    try:
        value = ep.load()
        return value() if callable(value) else value
    except Exception as e:  # noqa: BLE001 - any failure of another package's code
        raise ConfigError(f"entry point {name!r} of group {MAP_GROUP} ({ep.value}) failed to "
                          f"load: {type(e).__name__}: {e}") from None
