"""Errors a user can act on.

Every error raised on bad input derives from :class:`PathprefError`; the CLI turns one into a
single line on stderr and exit status 2. Messages name the bad field and, where there is one,
the fix.
"""

from __future__ import annotations

import errno

#: errors of a full disk or quota (:func:`is_disk_full`)
DISK_FULL = (errno.ENOSPC, getattr(errno, "EDQUOT", errno.ENOSPC))


class PathprefError(ValueError):
    """Base class of every error caused by bad user input (a ValueError: the Python API
    refuses a bad value the way Python does)."""


class MapError(PathprefError):
    """A map file or map dictionary is not valid (names the obstacle/field and the problem)."""


class ConfigError(PathprefError):
    """An experiment, planner or CLI parameter is out of range or inconsistent."""


class EpisodeError(RuntimeError):
    """An episode could not finish (timeout, non-finite belief); recorded as a failed episode."""


def did_you_mean(value: object, choices) -> str:
    """``" (did you mean 'x'?)"`` naming the choice closest to ``value`` (difflib's ratio
    at least 0.6, or a choice that starts with ``value``), else ``""``: the tail of an error
    line about an unknown name."""
    import difflib

    if not isinstance(value, str) or not value:
        return ""
    names = [str(c) for c in choices]
    close = difflib.get_close_matches(value, names, n=1, cutoff=0.6)
    if not close:
        close = [c for c in names if c.startswith(value)][:1]
    return f" (did you mean '{close[0]}'?)" if close else ""


def is_disk_full(e: BaseException) -> bool:
    """True for an error of a full disk or quota (OSError ENOSPC/EDQUOT, SQLite's "database or
    disk is full")."""
    if isinstance(e, OSError):
        return e.errno in DISK_FULL
    return "database or disk is full" in str(e)
