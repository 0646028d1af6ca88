"""Environment switches: the ``PATHPREF_*`` variables that turn a behaviour on or off.

A switch is read by :func:`switch`, the one parser of every switch: its value must be one of
``1``, ``true``, ``on`` (on) or ``0``, ``false``, ``off`` (off), in any letter case; unset, it
takes its default (:data:`SWITCHES`). Any other value (``yes``, ``2``, an empty value) is a
:class:`~pathpref.errors.ConfigError` of one line naming the variable and the values it
takes; the command line checks every switch before any work (:func:`check_switches`), and so
does a sweep.
"""

from __future__ import annotations

import os

from .errors import ConfigError

#: the values that turn a switch on, and off
ON = ("1", "true", "on")
OFF = ("0", "false", "off")
#: every switch: name -> (default, what it turns on)
SWITCHES: dict[str, tuple[bool, str]] = {
    "PATHPREF_COMPILED_STEPS": (True, "the MuJoCo base's compiled move phase "
                                "(docs/physics.md)"),
}


def switch(name: str) -> bool:
    """Whether the switch ``name`` (a key of :data:`SWITCHES`) is on (module docstring)."""
    default = SWITCHES[name][0]
    text = os.environ.get(name)
    if text is None:
        return default
    value = text.lower()
    if value in ON:
        return True
    if value in OFF:
        return False
    shown = text if len(text) <= 20 else text[:17] + "..."
    raise ConfigError(f"{name}={shown!r} is not a switch value: set it to 1, true or on "
                      f"(turns on {SWITCHES[name][1]}), 0, false or off, or unset it "
                      f"(default {'on' if default else 'off'})")


def check_switches() -> None:
    """Read every switch of :data:`SWITCHES` once: a bad value is refused before any work."""
    for name in SWITCHES:
        switch(name)
