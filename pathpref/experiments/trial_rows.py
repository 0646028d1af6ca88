"""What a stored study row must hold before anything reads it (report, replay, export,
the rationality fit): the rows :class:`~.trials.TrialWriter` writes, and nothing else.

**The rule.** Every column of a study table holds its SQL type (:data:`~.trials.STUDY_TABLES`):
an ``INTEGER`` column a whole number (not a float, a string or a bool), a ``REAL`` column a
finite number of magnitude at most :data:`MAX_ABS`, a ``TEXT`` column a string; NULL only
where pathpref writes one (a running trial's outcome columns, the late columns). Times
(``time_s``, ``t_start``, ``t_end``, ``time_limit_s``, ``duration_s``) lie in
``0..MAX_TIME_S``; positions (``trial``) in ``1..MAX_TRIAL``; counters (``k``, ``t``) are
``>= 0``. A ``trials`` row also holds JSON where pathpref writes JSON (``condition`` an
object; ``start``, ``goal`` a cell ``[x, y]``; ``candidates`` a non-empty list of cells with
``goal`` among them; ``route`` a list of cells), a ``seed >= 0``, a ``started_utc`` ISO time,
``status`` ``running`` or ``done``, and, once done, ``success`` 0 or 1 agreeing with
``outcome`` (``success``/``timeout``). A ``trial_beliefs`` row's ``goals`` is a JSON list of
one probability in ``[0, 1]`` per candidate of its trial.

A row that breaks the rule was changed outside pathpref: it is refused with one
:class:`~pathpref.errors.ConfigError` line naming the file, the table, the row and the column.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Iterator
from datetime import datetime
from pathlib import Path
from typing import Any

from ..episode.spec import LIMITS
from ..errors import ConfigError
from .trials import STUDY_TABLES

#: a trial's position is at most this (a study file holds far fewer trials; ``replay
#: --trial``'s range)
MAX_TRIAL = LIMITS["trial"][1]
#: seconds: the largest time a study row may hold (115 days; a trial is bounded by its limit)
MAX_TIME_S = 1e7
#: the largest magnitude of any other REAL column (forces, impulses, efforts)
MAX_ABS = 1e12
#: the largest seed (the planner's generator takes 64-bit seeds)
MAX_SEED = 2**63 - 1
TIME_COLUMNS = ("time_s", "t_start", "t_end", "time_limit_s", "duration_s")
#: trials columns NULL while the trial runs, or in rows written before they existed
TRIAL_NULLABLE = ("outcome", "success", "time_s", "steps", "pushes", "cues", "effort_ns",
                  "violations", "wall_s", "physics", "robot", "homotopy_success", "rerun",
                  "condition", "map_hash", "study", "study_hash", "front_end")
#: the columns of the other tables that may be NULL (a trial's answer's name)
NULLABLE = {"study_tlx": ("name",), "study_calibrations": ("device",),
            "trial_path": ("ee_x", "ee_y", "ee_z")}
FIX = "the row was changed outside pathpref; restore the database from a copy"
TYPES = {t: dict(cols) for t, cols, _ in STUDY_TABLES}


def _shown(v: Any) -> str:
    s = "NULL" if v is None else repr(v)
    return s if len(s) <= 40 else s[:37] + "..."


def where(table: str, row: dict[str, Any]) -> str:
    """``table`` row (participant, trial[, k or t]) as the message names it."""
    keys = [f"participant {_shown(row.get('participant'))}"]
    for c in ("trial", "k", "t"):
        if c in row:
            keys.append(f"{c} {_shown(row[c])}")
    return f"{table} row ({', '.join(keys)})"


def _bad(path, table: str, row: dict, col: str, what: str) -> ConfigError:
    return ConfigError(f"{path}: {where(table, row)} has {col} = {_shown(row.get(col))}, not "
                       f"{what}; {FIX}")


def _int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _number(v: Any) -> bool:
    if not isinstance(v, int | float) or isinstance(v, bool):
        return False
    try:
        return math.isfinite(float(v)) and abs(float(v)) <= MAX_ABS
    except OverflowError:
        return False


def check_row(table: str, row: dict[str, Any], path: str | Path) -> dict[str, Any]:
    """``row`` of ``table`` when every column holds its type and range (module docstring);
    else a ConfigError naming the column. The row is returned unchanged."""
    types = TYPES[table]
    nullable = TRIAL_NULLABLE if table == "trials" else NULLABLE.get(table, ())
    for col, v in row.items():
        ty = types.get(col)
        if ty is None:
            continue
        if v is None:
            if col in nullable:
                continue
            raise _bad(path, table, row, col, {"INTEGER": "an integer", "REAL": "a number",
                                               "TEXT": "a string"}[ty])
        if ty == "TEXT":
            if not isinstance(v, str):
                raise _bad(path, table, row, col, "a string")
        elif ty == "INTEGER":
            if not _int(v):
                raise _bad(path, table, row, col, "an integer")
            if col == "trial" and not (0 if table == "study_calibrations" else 1) <= v \
                    <= MAX_TRIAL:
                raise _bad(path, table, row, col, f"a trial position in 1..{MAX_TRIAL}")
            if col in ("k", "t") and v < 0:
                raise _bad(path, table, row, col, "an integer >= 0")
        elif not _number(v):
            raise _bad(path, table, row, col, f"a finite number within +-{MAX_ABS:g}")
        elif col in TIME_COLUMNS and not 0.0 <= v <= MAX_TIME_S:
            raise _bad(path, table, row, col, f"a time in 0..{MAX_TIME_S:g} s")
    return row


def _json(path, row: dict, col: str) -> Any:
    text = row.get(col)
    try:
        return json.loads(text)
    except (TypeError, ValueError, RecursionError):
        raise _bad(path, "trials", row, col, "JSON as pathpref writes it") from None


def _cell(v: Any) -> bool:
    return isinstance(v, list) and len(v) == 2 and all(_int(c) and abs(c) <= MAX_TRIAL
                                                       for c in v)


def check_trial_row(row: dict[str, Any], path: str | Path) -> dict[str, Any]:
    """A ``trials`` row checked by :func:`check_row` and the trial rules of the module
    docstring (JSON columns, seed, goal among the candidates, start time, outcome)."""
    check_row("trials", row, path)
    t = "trials"
    if row.get("condition") is not None and not isinstance(_json(path, row, "condition"),
                                                           dict):
        raise _bad(path, t, row, "condition", "a JSON object")
    for col in ("start", "goal"):
        if col in row and not _cell(_json(path, row, col)):
            raise _bad(path, t, row, col, "a cell [x, y]")
    if "candidates" in row:
        cands = _json(path, row, "candidates")
        if not isinstance(cands, list) or not cands or not all(_cell(c) for c in cands):
            raise _bad(path, t, row, "candidates", "a non-empty JSON list of cells [x, y]")
        if "goal" in row and _json(path, row, "goal") not in cands:
            raise _bad(path, t, row, "goal", "one of the trial's candidates")
    if "route" in row:
        route = _json(path, row, "route")
        if not isinstance(route, list) or not all(_cell(c) for c in route):
            raise _bad(path, t, row, "route", "a JSON list of cells [x, y]")
    if "seed" in row and not 0 <= row["seed"] <= MAX_SEED:
        raise _bad(path, t, row, "seed", "an integer >= 0")
    if "queries" in row and row["queries"] < 1:
        raise _bad(path, t, row, "queries", "an integer >= 1")
    if "show_belief" in row and row["show_belief"] not in (0, 1):
        raise _bad(path, t, row, "show_belief", "0 or 1")
    if "started_utc" in row:
        try:
            datetime.fromisoformat(row["started_utc"]).timestamp()
        except (ValueError, OverflowError, OSError):
            raise _bad(path, t, row, "started_utc", "an ISO time") from None
    status = row.get("status")
    if "status" in row and status not in ("running", "done"):
        raise _bad(path, t, row, "status", "'running' or 'done'")
    if status == "done":
        for col in ("success", "time_s", "steps", "pushes", "cues", "effort_ns"):
            if col in row and row[col] is None:
                raise _bad(path, t, row, col, "a value (the trial is done)")
        if "success" in row and row["success"] not in (0, 1):
            raise _bad(path, t, row, "success", "0 or 1")
        if "outcome" in row and row["outcome"] not in ("success", "timeout"):
            raise _bad(path, t, row, "outcome", "'success' or 'timeout'")
        if "success" in row and "outcome" in row and \
                row["success"] != int(row["outcome"] == "success"):
            raise _bad(path, t, row, "success", f"what outcome {row['outcome']!r} says")
        for col in ("steps", "pushes", "cues", "violations"):
            if row.get(col) is not None and row[col] < 0:
                raise _bad(path, t, row, col, "an integer >= 0")
        if row.get("homotopy_success") not in (None, 0, 1):
            raise _bad(path, t, row, "homotopy_success", "0, 1 or NULL")
    return row


def check_goals(row: dict[str, Any], n_candidates: int, path: str | Path) -> list[float]:
    """The probabilities of a ``trial_beliefs`` row: one in ``[0, 1]`` per candidate."""
    check_row("trial_beliefs", row, path)
    try:
        p = json.loads(row["goals"])
    except (TypeError, ValueError, RecursionError):
        p = None
    if not isinstance(p, list) or len(p) != n_candidates or not all(
            _number(v) and 0.0 <= v <= 1.0 for v in p):
        raise _bad(path, "trial_beliefs", row, "goals",
                   f"a JSON list of {n_candidates} probabilities (one per candidate)")
    return p


def checked(table: str, rows: Iterable[dict[str, Any]], path: str | Path
            ) -> Iterator[dict[str, Any]]:
    """``rows`` of ``table``, each checked as it passes (:func:`check_trial_row` for
    ``trials``, :func:`check_row` else)."""
    check = check_trial_row if table == "trials" else (
        lambda r, p: check_row(table, r, p))
    for r in rows:
        yield check(r, path)
