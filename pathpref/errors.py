"""Errors a user can act on.

Every error raised on bad input derives from :class:`PathprefError`; the CLI turns one into a
single line on stderr and exit status 2. Messages name the bad field and, where there is one,
the fix.
"""

from __future__ import annotations


class PathprefError(ValueError):
    """Base class of every error caused by bad user input (a ValueError: the Python API
    refuses a bad value the way Python does)."""


class MapError(PathprefError):
    """A map file or map dictionary is not valid (names the obstacle/field and the problem)."""


class ConfigError(PathprefError):
    """An experiment, planner or CLI parameter is out of range or inconsistent."""


class EpisodeError(RuntimeError):
    """An episode could not finish (timeout, non-finite belief); recorded as a failed episode."""
