"""The one registry of tasks (and of maps other packages bring): the built-in tasks, plus every
task another installed package declares in the entry-point group :data:`TASK_GROUP`, and the
Gymnasium id of each, derived from its name (:func:`gym_id`: ``navigate_control`` is
``pathpref/NavigateControl-v0``).

Another package registers a task by naming a subclass of :class:`~.navigate.Navigate` (the
contract :func:`pathpref_tasks.load` builds an environment from: ``decides``, ``scene``,
``dt``, ...) in its metadata::

    [project.entry-points."pathpref.tasks"]
    patrol = "my_package.tasks:Patrol"

and a map (a map dictionary, a :class:`~pathpref.geometry.maps.MapSpec`, a JSON path, or a
callable returning one of them) under :data:`MAP_GROUP`, usable as ``map="<name>"`` by every
task::

    [project.entry-points."pathpref.maps"]
    ring = "my_package.maps:RING"

Entry points are read at each look-up (``importlib.metadata``: a package installed after
``import pathpref_tasks`` is seen; Gymnasium ids are registered by
:func:`pathpref_tasks.gym.register_envs`, at import and when called again, by name only:
another package's code is imported when its task is loaded). Built-in names come first (a
map or task of the same name is not used; :func:`all_tasks` refuses such a task); an entry
point that fails to load or is not a task is a one-line :class:`~pathpref.errors.ConfigError`
when it is asked for.
"""

from __future__ import annotations

from pathpref.errors import ConfigError

from .carry import Carry, CarryControl
from .navigate import Navigate
from .navigate_control import NavigateControl
from .plugins import MAP_GROUP, TASK_GROUP, entries, entry_point_map

__all__ = ["MAP_GROUP", "TASK_GROUP", "entry_point_map"]

#: the built-in tasks: name -> task class
BUILTIN_TASKS: dict[str, type[Navigate]] = {
    "navigate": Navigate, "navigate_control": NavigateControl, "carry": Carry,
    "carry_control": CarryControl}


def gym_id(name: str) -> str:
    """The Gymnasium id of task ``name``: ``pathpref/`` + its words capitalised + ``-v0``."""
    return "pathpref/" + "".join(w[:1].upper() + w[1:] for w in name.split("_")) + "-v0"


def task_names() -> list[str]:
    """The names of every task: the built-in ones, then those of :data:`TASK_GROUP` (nothing
    of another package is imported; a name clashing with a built-in one is left out here and
    refused by :func:`all_tasks`)."""
    return [*BUILTIN_TASKS, *(n for n in entries(TASK_GROUP) if n not in BUILTIN_TASKS)]


def task_class(name: str) -> type[Navigate]:
    """The class of task ``name``: built-in, else the entry point's, loaded and checked (a
    one-line ConfigError when it fails to load or is not a task; KeyError when unknown)."""
    if name in BUILTIN_TASKS:
        return BUILTIN_TASKS[name]
    ep = entries(TASK_GROUP)[name]
    try:
        cls = ep.load()
    except Exception as e:  # noqa: BLE001 - any import failure of another package
        raise ConfigError(f"entry point {name!r} of group {TASK_GROUP} ({ep.value}) "
                          f"failed to load: {type(e).__name__}: {e}") from None
    if not (isinstance(cls, type) and issubclass(cls, Navigate)):
        raise ConfigError(f"entry point {name!r} of group {TASK_GROUP} ({ep.value}) must "
                          f"name a subclass of pathpref_tasks.navigate.Navigate")
    return cls


def all_tasks() -> dict[str, type[Navigate]]:
    """Every task by name (module docstring), every entry point loaded and checked; an entry
    point clashing with a built-in name is a one-line ConfigError."""
    for name, ep in entries(TASK_GROUP).items():
        if name in BUILTIN_TASKS:
            raise ConfigError(f"entry point {name!r} of group {TASK_GROUP} ({ep.value}) "
                              f"clashes with a built-in task; rename it in its package")
    return {name: task_class(name) for name in task_names()}


def gym_ids() -> dict[str, str]:
    """Gymnasium id -> task name, for every task of :func:`task_names` (the classes are
    loaded when an id is made)."""
    return {gym_id(name): name for name in task_names()}
