"""What other installed packages add to pathpref through entry points (``importlib.metadata``):

* ``pathpref.bodies``: a :class:`~pathpref.episode.body.Body` subclass, used as
  ``EpisodeSpec(sim=name)`` / ``--sim name``;
* ``pathpref.methods``: a method (a class or function taking a
  :class:`~pathpref.planning.policies.PolicyContext`), used as ``--methods name``;
* ``pathpref.priors``: a preference prior (a class or function taking
  :class:`~pathpref.inference.priors.PriorInputs`), used as ``--prior name``;
* ``pathpref.maps``: a map (a dictionary, a ``MapSpec``, the path of a JSON map, or a function
  returning one), used wherever a map name goes (``--map name``, ``pathpref map info name``);
* ``pathpref.tasks``: dm_control tasks (``pathpref_tasks``).

A package declares them in its metadata, e.g.::

    [project.entry-points."pathpref.methods"]
    cautious = "my_package.methods:Cautious"

Entry points are read when a name is looked up and not found among the built-in ones (a
built-in name always wins), so a broken package breaks only the name it provides, with one
line naming the entry point: whatever its import raises, ``SystemExit`` (``exit()``) included.
"""

from __future__ import annotations

from importlib.metadata import entry_points
from typing import Any

from .errors import ConfigError

BODIES = "pathpref.bodies"
METHODS = "pathpref.methods"
PRIORS = "pathpref.priors"
MAPS = "pathpref.maps"


def names(group: str) -> list[str]:
    """The names other packages declare in ``group``."""
    return sorted({ep.name for ep in entry_points(group=group)})


def load(group: str, name: str) -> Any | None:
    """The object entry point ``name`` of ``group`` names, or None when no package declares
    one; a failure to import it is a one-line ConfigError."""
    found = [ep for ep in entry_points(group=group) if ep.name == name]
    if not found:
        return None
    ep = found[0]
    try:
        return ep.load()
    except (Exception, SystemExit) as e:  # noqa: BLE001 - any failure of another package's
        # code, its exit() too: pathpref ends with its own one line, never the plug-in's
        text = " ".join(str(e).split())[:200]
        raise ConfigError(f"entry point {name!r} of group {group} ({ep.value}) failed to "
                          f"load: {type(e).__name__}: {text}; fix or uninstall the package "
                          "that declares it") from None


def load_callable(group: str, name: str, what: str) -> Any | None:
    """:func:`load`, checked: the object must be callable (``what`` names what it must be,
    for the one-line ConfigError, e.g. "a method (a class or function taking a
    PolicyContext)"); None when no package declares ``name``."""
    found = load(group, name)
    if found is not None and not callable(found):
        raise ConfigError(f"entry point {name!r} of group {group} must name {what}, got "
                          f"{found!r}")
    return found
