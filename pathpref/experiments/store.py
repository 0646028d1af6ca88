"""SQLite results store: one row per episode (full configuration and seeds), per-step logs.

Finished episodes are written as they arrive, each batch in one transaction
(:meth:`ResultStore.add_many`: episode rows and their steps together), so a sweep killed at
any moment leaves only whole episodes; WAL journaling keeps the file consistent. The primary
key is :meth:`EpisodeSpec.key`, so a rerun of the same sweep skips what is done.

Two sweeps may share one database: each claims an episode just before running it
(:meth:`ResultStore.claim`; a chunk of them at once, :meth:`ResultStore.claim_many`), in one
write transaction, by writing its row with ``status = 'running'`` and the claim's owner (host,
process id and the process's start time) in ``reason``; a row another live sweep has claimed
is left to it. A claim whose owner is gone (on this host: no such process, or the process id
reused; from another host: older than four times the wall-time limits of its chunk) is stale,
and the next sweep takes it over, so a crashed sweep's claims are run on resume. A sweep
removes its unfinished claims when it ends (Ctrl-C, SIGTERM, an error); readers leave
``running`` rows out (they are not results).

An existing file is checked before it is opened for writing (:func:`check_results_file`), on a
read-only connection that leaves no side file: it must be a regular file holding exactly
pathpref's tables (no views, triggers or other objects, which could falsify what a report reads),
with pathpref's columns, this schema version and no damaged page. Anything else is refused with
one line and left untouched. A read or write error later becomes one line too.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import os
import re
import socket
import sqlite3
import stat
import time
import weakref
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

from ..episode import EpisodeResult, EpisodeSpec, result_row
from ..episode.safety import contact_safe
from ..errors import ConfigError
from .trials import (
    LATE_STUDY_TABLES,
    STUDY_TABLE_NAMES,
    complete_study_tables,
    complete_trial_columns,
    create_study_tables,
    missing_study_tables,
    missing_trial_columns,
    study_sql,
    trial_columns_ok,
)

#: 2: per-episode physical metrics (JSON); 3: keys by map content hash; 4: the physical
#: parameters of each episode (``physics``, JSON; "" = the legacy physics of older rows), the
#: belief's preference prior (``prior``; empty = the independent one older rows ran with) and
#: the study tables (trials with people, :mod:`.trials`); 5: ``homotopy_success`` per episode,
#: the human's push rule (``push_rule``; empty = the periodic human of older rows) and
#: ``is_intervention`` per step (and, added later in place, the late ``trials`` columns
#: ``physics`` and ``robot``: :data:`~.trials.LATE_TRIAL_COLUMNS`, the late study tables
#: of calibrations and NASA-TLX answers: :data:`~.trials.LATE_STUDY_TABLES`, and the late
#: episode column ``slack``: :data:`LATE_EPISODE_COLUMNS`)
SCHEMA_VERSION = 5
UPGRADABLE = (2,)  # older schemas that 'pathpref db upgrade' migrates
#: older schemas whose tables are a subset of this one's: read as they are; opened for writing
#: (a sweep, a study or 'db upgrade'), the missing columns and the study tables are added in
#: place and the version set to 5, so every stored episode reads and replays as before. The
#: added columns of the old rows stay NULL: the legacy physics, the independent prior and the
#: periodic human they ran with (keys unchanged), and ``homotopy_success`` and
#: ``is_intervention`` *not measured* (reports count them over the rows that have them;
#: 'pathpref db upgrade' fills ``homotopy_success`` from the stored steps where it can)
ADDITIVE = (3, 4)
#: the first schema with the study tables
STUDY_SCHEMA = 4

EPISODE_COLUMNS = {
    "key": "TEXT PRIMARY KEY",
    "map": "TEXT", "map_hash": "TEXT", "sim": "TEXT", "task": "TEXT", "method": "TEXT",
    "delta_t": "INTEGER",
    "instance": "INTEGER", "run": "INTEGER", "instance_seed": "INTEGER", "run_seed": "INTEGER",
    "preset": "TEXT", "queries": "INTEGER", "t_max": "INTEGER", "n_goals": "INTEGER",
    "normalize": "INTEGER", "coupling": "INTEGER", "fixed": "TEXT",
    "start": "TEXT", "goals": "TEXT", "true_goal": "INTEGER",
    "status": "TEXT", "reason": "TEXT", "goal_reached": "INTEGER", "pref_followed": "INTEGER",
    "success": "INTEGER", "steps": "INTEGER", "inputs": "INTEGER", "violations": "INTEGER",
    "wall_s": "REAL", "ucb_c": "REAL", "metrics": "TEXT", "time_budget_ms": "REAL",
    "human": "TEXT", "back_crossings": "INTEGER", "physics": "TEXT",
    "prior": "TEXT", "homotopy_success": "INTEGER", "push_rule": "TEXT",
    "slack": "INTEGER",
}
#: episode columns added to schema 5 in place, after its release (at the end of the table, in
#: this order): ``slack``, the time to spare of each episode
#: (:func:`~pathpref.episode.results.route_slack`; NULL in older rows: not measured, or filled
#: by ``pathpref db upgrade``: :func:`~.migrate.recompute_slack`). A schema 5 file without
#: them reads as it is; opened for writing they are added
LATE_EPISODE_COLUMNS = ("slack",)
#: the columns of the steps table (the last added by schema 5) and its primary key
STEP_COLUMNS = {
    "key": "TEXT", "t": "INTEGER", "x": "INTEGER", "y": "INTEGER", "action": "INTEGER",
    "heading": "INTEGER", "p_true_goal": "REAL", "goal_entropy": "REAL",
    "is_intervention": "INTEGER",
}

#: the columns of ``episode_path``, an episode's continuous path when it was recorded
#: (``--record-path``: :attr:`~pathpref.episode.EpisodeSpec.record_path_hz`): sample ``k =
#: 0, 1, ...`` at ``time_s`` (simulated s since the episode's start), the base's pose (``x``,
#: ``y`` m in the scene's world frame, ``yaw`` rad), the end effector (m; NULL for the plain
#: base) and the force the human applied then (``fx``, ``fy`` N, world x-y); the fields of
#: :data:`~pathpref.episode.body.PATH_FIELDS` after ``key`` and ``k``
PATH_COLUMNS = {
    "key": "TEXT", "k": "INTEGER", "time_s": "REAL", "x": "REAL", "y": "REAL", "yaw": "REAL",
    "ee_x": "REAL", "ee_y": "REAL", "ee_z": "REAL", "fx": "REAL", "fy": "REAL",
}
PATH_SQL = (f"CREATE TABLE episode_path ({', '.join(f'{c} {t}' for c, t in PATH_COLUMNS.items())}"
            ", PRIMARY KEY (key, k))")
#: tables added to schema 5 after its release: a file may lack them (read as empty; created
#: in place when opened for writing, and by 'pathpref db upgrade')
LATE_BASE_TABLES = ("episode_path",)

#: The CREATE statements of pathpref's tables (``episodes`` takes its column list).
META_SQL = "CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT)"


def steps_sql(columns: Iterable[str] = STEP_COLUMNS) -> str:
    """The ``CREATE TABLE steps`` statement with ``columns`` (all of them by default), as
    SQLite stores it, also after ``ALTER TABLE steps ADD COLUMN`` (new columns go before the
    primary key)."""
    return (f"CREATE TABLE steps ({', '.join(f'{c} {STEP_COLUMNS[c]}' for c in columns)}, "
            "PRIMARY KEY (key, t))")


STEPS_SQL = steps_sql()
BASE_TABLES = ("meta", "episodes", "steps")  # schema 3
TABLES = BASE_TABLES + STUDY_TABLE_NAMES


def episodes_sql(columns: Iterable[str] = EPISODE_COLUMNS) -> str:
    """The ``CREATE TABLE episodes`` statement with ``columns`` (pathpref's own by default)."""
    return f"CREATE TABLE episodes ({', '.join(f'{c} {EPISODE_COLUMNS[c]}' for c in columns)})"


def one_line(text: object, limit: int = 300) -> str:
    """``text`` on one line: SQLite's integrity reports span lines (``*** in database main
    ***`` then one line per problem); these are joined with ``; ``, cut at ``limit``."""
    parts = [" ".join(p.split()) for p in str(text).splitlines()]
    flat = "; ".join(p for p in parts if p and p != "*** in database main ***")
    return flat if len(flat) <= limit else flat[:limit - 3] + "..."


def damaged(path: str | Path, err: BaseException | str) -> ConfigError:
    """The one-line error of a database that cannot be read (names the repair commands)."""
    return ConfigError(
        f"{path} is damaged ({one_line(err)}); 'pathpref db check {path}' lists the damage and "
        f"'pathpref db salvage {path} NEW.sqlite' copies the intact episodes")


def new_file_mode() -> int:
    """The mode a new file gets from ``open()``: ``0o666`` less the process's umask (read
    without changing it, through ``os.umask`` twice)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return 0o666 & ~mask


def require_regular_file(path: str | Path, missing_ok: bool = False) -> bool:
    """True when ``path`` is a regular file, False when it is missing and ``missing_ok``;
    a directory, device, FIFO or socket is refused (by ``os.stat``, without opening it)."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        if missing_ok:
            return False
        raise ConfigError(f"no results database at {path}") from None
    except OSError as e:
        raise ConfigError(f"cannot read {path}: {e.strerror}") from None
    if stat.S_ISDIR(mode):
        raise ConfigError(f"{path} is a directory, not a results database; give a file path")
    if not stat.S_ISREG(mode):
        raise ConfigError(f"{path} is not a regular file (a device, FIFO or socket), not a "
                          "results database; give a file path")
    return True


def open_readonly(path: str | Path) -> sqlite3.Connection:
    """A read-only connection to the SQLite file ``path`` that writes nothing beside it.

    It is immutable (no lock, no journal, no ``-shm``) unless a ``-wal`` file lies beside the
    database: then a pathpref sweep is running or was killed, its last episodes are only in the
    WAL, and an ordinary read-only connection reads them (it may add the ``-shm`` index).
    """
    uri = Path(os.path.abspath(path)).as_uri()
    wal = Path(f"{path}-wal")
    live = wal.is_file() and wal.stat().st_size > 0
    return sqlite3.connect(f"{uri}?mode=ro" + ("" if live else "&immutable=1"), uri=True,
                           timeout=30)


def schema_version(conn: sqlite3.Connection, path: str | Path) -> int | None:
    """Schema version of a pathpref database, None when it holds no objects at all.

    Raises :class:`ConfigError` unless ``sqlite_master`` holds exactly pathpref's tables
    ``meta``, ``episodes`` and ``steps`` (and, from schema 4 on, the study tables of
    :mod:`.trials`) with their primary-key indexes, each created by pathpref's own statement
    (the episode columns are a subset of :data:`EPISODE_COLUMNS`, all of them at
    :data:`SCHEMA_VERSION`), and ``meta`` names an integer schema version. A view or trigger,
    another table or index, or a changed column is refused: each could make a report print
    rows that were never run.
    """
    objects = {(r[0], r[1]): r for r in conn.execute(
        "SELECT type, name, tbl_name, sql FROM sqlite_master")}
    if not objects:
        return None

    def foreign(what: str) -> ConfigError:
        return ConfigError(f"{path} is an SQLite file not written by pathpref ({what}); it is "
                           "left untouched: give another --db path")

    study = any(("table", t) in objects for t in STUDY_TABLE_NAMES)
    # a study file written before the late study tables may lack them (read as empty), and
    # any file the late base tables
    tables = tuple(t for t in TABLES if t not in LATE_STUDY_TABLES or ("table", t) in objects
                   ) if study else BASE_TABLES
    tables += tuple(t for t in LATE_BASE_TABLES if ("table", t) in objects)
    expected = {("table", t) for t in tables} | {
        ("index", f"sqlite_autoindex_{t}_1") for t in tables}
    extra = sorted(set(objects) - expected)
    if extra:
        listed = ", ".join(f"{kind} {name!r}" for kind, name in extra[:4])
        raise foreign(f"it holds {listed}{' ...' if len(extra) > 4 else ''}, which "
                      "pathpref never creates")
    missing = sorted(name for _, name in expected - set(objects))
    if missing:
        raise foreign(f"it lacks {', '.join(missing)}")
    for t in tables:
        if objects[("index", f"sqlite_autoindex_{t}_1")][2:] != (t, None):
            raise foreign(f"its index of {t} is not pathpref's")
    columns = [r[1] for r in conn.execute("PRAGMA table_xinfo(episodes)")]
    if not set(columns) <= set(EPISODE_COLUMNS):
        raise foreign(f"episodes has columns {sorted(set(columns) - set(EPISODE_COLUMNS))}")
    step_columns = [r[1] for r in conn.execute("PRAGMA table_xinfo(steps)")]
    if not set(step_columns) <= set(STEP_COLUMNS):
        raise foreign(f"steps has columns {sorted(set(step_columns) - set(STEP_COLUMNS))}")
    sqls = [("meta", META_SQL), ("steps", steps_sql(step_columns)),
            ("episodes", episodes_sql(columns))]
    sqls += [("episode_path", PATH_SQL)] if "episode_path" in tables else []
    trial_columns = [r[1] for r in conn.execute("PRAGMA table_xinfo(trials)")] if study else []
    if study and not trial_columns_ok(trial_columns):
        raise foreign(f"trials has columns {trial_columns}")
    sqls += [(t, study_sql(t, trial_columns if t == "trials" else None))
             for t in tables if t in STUDY_TABLE_NAMES]
    for t, sql in sqls:
        if objects[("table", t)][2:] != (t, sql):
            raise foreign(f"its table {t} is not defined as pathpref defines it")
    row = conn.execute("SELECT value FROM meta WHERE key = 'schema_version'").fetchone()
    if row is None or not str(row[0]).isdigit():
        raise foreign("it has no schema version")
    version = int(row[0])
    known = (*UPGRADABLE, *ADDITIVE, SCHEMA_VERSION)  # any other version is incompatible
    if version in known and (version >= STUDY_SCHEMA) != study:
        raise foreign(f"schema {version} {'with' if study else 'without'} the study tables")
    if version == SCHEMA_VERSION and (not episode_columns_ok(columns)
                                      or step_columns != list(STEP_COLUMNS)):
        lacking = [c for c in (*EPISODE_COLUMNS, *STEP_COLUMNS)
                   if c not in columns and c not in step_columns]
        raise ConfigError(
            f"{path} was written by a development version of pathpref (schema "
            f"{SCHEMA_VERSION} without the columns {', '.join(lacking)}); use a new --db path")
    return version


def episode_columns_ok(columns: Iterable[str]) -> bool:
    """``columns`` (of a stored schema 5 ``episodes`` table) are pathpref's, the late ones
    (:data:`LATE_EPISODE_COLUMNS`) possibly missing from the end."""
    columns = list(columns)
    every = list(EPISODE_COLUMNS)
    return len(columns) >= len(every) - len(LATE_EPISODE_COLUMNS) and \
        columns == every[:len(columns)]


def missing_base_tables(conn: sqlite3.Connection) -> list[str]:
    """The late base tables (:data:`LATE_BASE_TABLES`) the file lacks."""
    have = {r[0] for r in conn.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
    return [t for t in LATE_BASE_TABLES if t not in have]


def complete_base_tables(conn: sqlite3.Connection) -> None:
    """Create the late base tables the file lacks (inside the caller's transaction)."""
    if "episode_path" in missing_base_tables(conn):
        conn.execute(PATH_SQL)


def missing_episode_columns(conn: sqlite3.Connection) -> list[str]:
    """The late ``episodes`` columns (:data:`LATE_EPISODE_COLUMNS`) the file lacks."""
    have = {r[1] for r in conn.execute("PRAGMA table_xinfo(episodes)")}
    return [c for c in LATE_EPISODE_COLUMNS if c not in have]


#: results files a :class:`ResultStore` of this process holds open, by ``(st_dev, st_ino)``:
#: how many stores. POSIX drops all of a process's locks on a file when any descriptor of it
#: is closed, so :func:`require_sqlite_file` never opens one of these to read its header (a
#: store that did would make another process, closing its own connection, fold and delete the
#: WAL the held store still writes to); SQLite's own connections share their locks.
_HELD: dict[tuple[int, int], int] = {}


def _release(held: tuple[int, int]) -> None:
    """One store of the file ``held`` is closed (:data:`_HELD`)."""
    left = _HELD.pop(held, 0) - 1
    if left > 0:
        _HELD[held] = left


def _file_id(path: str | Path) -> tuple[int, int] | None:
    try:
        st = os.stat(path)
    except OSError:
        return None
    return st.st_dev, st.st_ino


def require_sqlite_file(path: str | Path, missing_ok: bool = False) -> bool:
    """:func:`require_regular_file`, and False for an empty file; else the file must start with
    the SQLite header. A file a store of this process holds (:data:`_HELD`) is one, and is not
    opened again."""
    if not require_regular_file(path, missing_ok):
        return False
    if _file_id(path) in _HELD:
        return True
    if os.stat(path).st_size == 0:
        return False
    try:
        with open(path, "rb") as f:
            header = f.read(16)
    except OSError as e:
        raise ConfigError(f"cannot read {path}: {e.strerror}") from None
    if header != b"SQLite format 3\x00":
        raise ConfigError(
            f"{path} is not a pathpref results database (not SQLite); give another --db path")
    return True


def inspect_results_file(path: str | Path, create: bool = False) -> int | None:
    """Schema version of the intact pathpref database ``path``; None for a missing (when
    ``create``) or empty file, or one without any table, that pathpref may create its tables in.

    Reads only, through :func:`open_readonly`: a refused file, and its folder, are left exactly
    as they were. Checked in order: a regular file with the SQLite header
    (:func:`require_sqlite_file`), pathpref's objects and columns (:func:`schema_version`), then
    ``PRAGMA quick_check`` (every page readable and well formed). Any failure is one line.
    """
    if not require_sqlite_file(path, missing_ok=create):
        return None
    try:
        ro = open_readonly(path)
        try:
            version = schema_version(ro, path)
            problems = ["ok"] if version is None else [
                r[0] for r in ro.execute("PRAGMA quick_check(3)")]
        finally:
            ro.close()
    except sqlite3.DatabaseError as e:
        raise damaged(path, e) from None
    except sqlite3.Error as e:
        raise ConfigError(f"cannot read results database {path}: {e}") from None
    if problems != ["ok"]:
        raise damaged(path, "; ".join(problems))
    return version


def check_results_file(path: str | Path, create: bool = True) -> bool:
    """True for an intact pathpref database of this schema (or of an :data:`ADDITIVE` one),
    False for a file to create the tables in (see :func:`inspect_results_file`); an older
    schema is pointed at ``pathpref db upgrade``, any other at a new path."""
    version = inspect_results_file(path, create)
    if version is None:
        return False
    if version in ADDITIVE:
        return True
    if version in UPGRADABLE:
        raise ConfigError(
            f"{path} was written by an older pathpref (schema {version}, this version "
            f"reads {SCHEMA_VERSION}); run 'pathpref db upgrade {path}' to migrate it")
    if version != SCHEMA_VERSION:
        raise ConfigError(
            f"{path} was written by an incompatible pathpref (schema {version}, this "
            f"version reads {SCHEMA_VERSION}); use a new --db path")
    return True


#: the episode columns reports and resumes read, and what pathpref writes in each: ``text`` a
#: string, ``count`` an integer >= 1, ``seed`` an integer >= 0, ``number`` a finite number,
#: ``flag`` 0 or 1, ``tally`` an integer >= 0
ROW_RULES = {
    "key": "text", "map": "text", "map_hash": "text", "sim": "text", "task": "text",
    "method": "text", "preset": "text", "status": "text",
    "delta_t": "count", "queries": "count", "t_max": "count", "instance_seed": "seed",
    "ucb_c": "number",
    "normalize": "flag", "coupling": "flag", "success": "flag", "goal_reached": "flag",
    "pref_followed": "flag", "homotopy_success": "flag or NULL", "slack": "integer or NULL",
    "steps": "tally", "inputs": "tally", "violations": "tally",
}
#: the other episode columns, checked where a command reads or copies them (``db merge``,
#: ``dataset``: :func:`check_copied_rows`); columns added by a later schema may be NULL in
#: older rows
COPY_RULES = {
    "instance": "tally", "run": "tally", "run_seed": "seed", "n_goals": "count",
    "fixed": "text", "start": "text", "goals": "text", "true_goal": "integer",
    "reason": "text or NULL", "wall_s": "number", "metrics": "text or NULL",
    "time_budget_ms": "number or NULL", "human": "text or NULL",
    "back_crossings": "integer or NULL", "physics": "text or NULL", "prior": "text or NULL",
    "push_rule": "text or NULL",
}
#: what each column of a step row (:data:`STEP_COLUMNS`) holds: the step ``t >= 0``, the
#: cell, the action (-1: stay) and the observed heading (-1: none, 0..7), the belief's
#: probability of the true goal and its entropy (nats), and whether the human pushed
#: (NULL in rows written before the column)
STEP_RULES = {
    "key": "text", "t": "tally", "x": "integer", "y": "integer", "action": "action",
    "heading": "heading", "p_true_goal": "probability", "goal_entropy": "number",
    "is_intervention": "flag or NULL",
}
#: what each column of a recorded path row (:data:`PATH_COLUMNS`) holds (the end effector
#: is NULL for a base without an arm)
PATH_RULES = {
    "key": "text", "k": "tally", "time_s": "time", "x": "number", "y": "number",
    "yaw": "number", "ee_x": "number or NULL", "ee_y": "number or NULL",
    "ee_z": "number or NULL", "fx": "number", "fy": "number",
}
_RULE_TEXT = {"text": "a string", "count": "an integer >= 1", "seed": "an integer >= 0",
              "number": "a finite number", "flag": "0 or 1",
              "flag or NULL": "0, 1 or NULL (not measured)",
              "integer or NULL": "an integer or NULL (not measured)",
              "tally": "an integer >= 0", "integer": "an integer",
              "text or NULL": "a string or NULL", "number or NULL": "a finite number or NULL",
              "action": "an action -1..7", "heading": "a heading -1..7",
              "probability": "a probability in 0..1", "time": "a time >= 0 s"}
#: the largest magnitude of a stored number (larger is not pathpref's: positions are metres or
#: cells, forces newtons, times seconds)
MAX_STORED = 1e12


def _breaks_rule(value: Any, rule: str) -> bool:
    """Whether ``value`` is not what ``rule`` (a key of :data:`_RULE_TEXT`) allows."""
    if rule.endswith(" or NULL"):
        return value is not None and _breaks_rule(value, rule[:-len(" or NULL")])
    if rule == "text":
        return not isinstance(value, str)
    if rule in ("number", "probability", "time"):
        if not (isinstance(value, int | float) and not isinstance(value, bool)):
            return True
        try:
            v = float(value)
        except OverflowError:
            return True
        return not (math.isfinite(v) and abs(v) <= MAX_STORED) or \
            (rule == "probability" and not 0.0 <= v <= 1.0) or (rule == "time" and v < 0)
    if not isinstance(value, int) or isinstance(value, bool):
        return True
    return {"count": value < 1, "seed": not 0 <= value <= 2**63 - 1,
            "flag": value not in (0, 1), "tally": value < 0, "integer": False,
            "action": not -1 <= value <= 7, "heading": not -1 <= value <= 7}[rule]


def stored_value_error(path: str | Path, where: str, col: str, value: Any, rule: str,
                       fix: str) -> ConfigError:
    """The one line of a stored value that breaks its ``rule``: the file, the row
    (``where``), the column, the value (cut at 40 characters) and what it must be."""
    shown = "NULL" if value is None else repr(value)
    shown = shown if len(shown) <= 40 else shown[:37] + "..."
    return ConfigError(f"{path}: {where} has {col} = {shown}, not {_RULE_TEXT[rule]}; {fix}")


#: the fix of a stored row pathpref cannot have written
CHANGED = "the file was changed outside pathpref"


def check_rows_of(table: str, rows: Iterable[dict[str, Any]], path: str | Path,
                  rules: dict[str, str]) -> Iterator[dict[str, Any]]:
    """``rows`` of ``table`` (each with its ``rowid``, when selected), each checked against
    ``rules`` as it passes: a value that breaks its rule is one ConfigError naming the file,
    the table's row (by rowid) and the column."""
    for i, row in enumerate(rows):
        for col, rule in rules.items():
            if col in row and _breaks_rule(row[col], rule):
                rowid = row.get("rowid")
                where = f"{table} row {rowid if isinstance(rowid, int) else i + 1}"
                if table != "episodes" and isinstance(row.get("t", row.get("k")), int):
                    where += f" ({'t' if 't' in row else 'k'} = {row.get('t', row.get('k'))})"
                fix = (f"{CHANGED}: delete that row (DELETE FROM {table} WHERE rowid = "
                       f"{rowid}) or use another database" if isinstance(rowid, int) else
                       f"{CHANGED}: use another database")
                raise stored_value_error(path, where, col, row[col], rule, fix)
        yield row


def check_copied_rows(rows: Iterable[dict[str, Any]], path: str | Path
                      ) -> Iterator[dict[str, Any]]:
    """Episode rows checked by :func:`check_episode_rows` and :data:`COPY_RULES`, and, for a
    row that ran (``ok``), its instance: ``start`` a JSON cell ``[x, y]``, ``goals`` a JSON
    list of cells and ``true_goal`` an index into it. Each row passes on once checked."""
    for row in check_rows_of("episodes", rows, path, COPY_RULES):
        check_episode_rows([row], path)
        if row.get("status") == "ok" and {"start", "goals", "true_goal"} <= set(row):
            goals = _json_or_none(row["goals"])
            where = f"episodes row {row.get('rowid', '?')}"
            fix = f"{CHANGED}: use another database"
            if not _is_cell(_json_or_none(row["start"])):
                raise stored_value_error(path, where, "start", row["start"], "cell", fix)
            if not (isinstance(goals, list) and goals and all(_is_cell(g) for g in goals)):
                raise stored_value_error(path, where, "goals", row["goals"], "cells", fix)
            if not 0 <= row["true_goal"] < len(goals):
                raise stored_value_error(path, where, "true_goal", row["true_goal"], "goal",
                                         fix)
        yield row


_RULE_TEXT.update({"cell": "a JSON cell [x, y]", "cells": "a JSON list of cells [x, y]",
                   "goal": "an index into its goals"})


def _json_or_none(text: Any) -> Any:
    try:
        return json.loads(text)
    except (TypeError, ValueError, RecursionError):
        return None


def _is_cell(v: Any) -> bool:
    return isinstance(v, list) and len(v) == 2 and all(
        isinstance(c, int) and not isinstance(c, bool) and abs(c) <= 10**6 for c in v)


def check_episode_rows(rows: Iterable[dict[str, Any]], path: str | Path) -> None:
    """Refuse (one ConfigError line naming the row, the column and the fix) an episode row that
    pathpref cannot have written: a column of :data:`ROW_RULES` holding another type or value
    (``success = 'x'``, ``success = 5``, ``ucb_c = NULL``, ``delta_t = 'x'``, ``map = NULL``),
    or a ``success`` that contradicts the row's own outcome (an ``ok`` row succeeds exactly when
    it reached the goal and followed the preference)."""
    for i, row in enumerate(rows):
        key = row.get("key")
        plain = isinstance(key, str) and re.fullmatch(r"[\w.-]{1,80}", key, re.ASCII)
        rowid = row.get("rowid")
        numbered = isinstance(rowid, int) and not isinstance(rowid, bool)
        where = f"episode {key}" if plain else (f"episodes row {rowid}" if numbered
                                                else f"episode row {i + 1}")
        fix = (f"{CHANGED}: delete that row (DELETE FROM episodes WHERE key = '{key}') and "
               "run the sweep again to recompute it" if plain else
               f"{CHANGED}: delete that row (DELETE FROM episodes WHERE rowid = {rowid}) and "
               "run the sweep again to recompute it" if numbered else
               f"{CHANGED}: use another --db")
        for col, rule in ROW_RULES.items():
            if col in row and _breaks_rule(row[col], rule):
                raise stored_value_error(path, where, col, row[col], rule, fix)
        if row.get("status") == "ok" and "success" in row and "goal_reached" in row and \
                row["success"] != (row["goal_reached"] and row.get("pref_followed", 1)
                                   and contact_safe(row.get("metrics"))):
            raise ConfigError(f"{path}: {where} has success = {row['success']} but "
                              f"goal_reached = {row['goal_reached']}, pref_followed = "
                              f"{row.get('pref_followed')} and contact-safe = "
                              f"{int(contact_safe(row.get('metrics')))}; {fix}")
        if row.get("homotopy_success") == 1 and row.get("goal_reached") == 0:
            raise ConfigError(f"{path}: {where} has homotopy_success = 1 but goal_reached = 0; "
                              f"{fix}")


def check_stored_rows(conn: sqlite3.Connection, path: str | Path) -> None:
    """:func:`check_episode_rows` on the :data:`ROW_RULES` columns of every episode of
    ``conn``."""
    have = [r[1] for r in conn.execute("PRAGMA table_xinfo(episodes)")]
    cols = ["rowid", *(c for c in ROW_RULES if c in have)]
    cur = conn.execute(f"SELECT {', '.join(cols)} FROM episodes")
    check_episode_rows((dict(zip(cols, r, strict=True)) for r in cur), path)


#: ``status`` of an episode row that a sweep has claimed and not finished
RUNNING = "running"
#: how many times opening a file asks for WAL journaling while another process holds it
#: (:meth:`ResultStore._wal`)
WAL_TRIES = 80


def process_start(pid: int) -> str | None:
    """The start time of process ``pid`` (clock ticks after boot, ``/proc/PID/stat`` field 22),
    which tells a process from a later one given the same id; None where there is no /proc or
    no such process."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            stat_line = f.read().decode(errors="replace")
    except OSError:
        return None
    return stat_line.rsplit(")", 1)[-1].split()[19]


def this_owner() -> dict[str, Any]:
    """The claim owner of this process: host, process id and the process's start time."""
    pid = os.getpid()
    return {"host": socket.gethostname(), "pid": pid, "start": process_start(pid)}


def claim_is_live(claim: dict[str, Any], max_age_s: float, now: float | None = None) -> bool:
    """Whether the sweep that made ``claim`` (:func:`this_owner` plus ``at``, the time of the
    claim) may still be running its episode (module docstring: the stale-claim rule)."""
    try:
        host, pid, start, at = claim["host"], int(claim["pid"]), claim.get("start"), \
            float(claim["at"])
    except (KeyError, TypeError, ValueError):
        return False  # not a claim this version wrote: take it
    if host != socket.gethostname():
        return (time.time() if now is None else now) - at <= max_age_s
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process: alive
        pass
    now_start = process_start(pid)
    return start is None or now_start is None or now_start == start


class ResultStore:
    """Open (or create) a results database at ``path``, after :func:`check_results_file`.

    ``create=False`` opens it for reading only (``report``, ``replay``, the curves): through
    :func:`open_readonly`, so the file, its journal mode (a rollback-journal file stays one) and
    its folder are left exactly as they were; a write through such a store is refused.
    ``check_rows``: :meth:`check_rows` on that read-only connection first, so that a file with
    a row pathpref cannot have written is refused before it is opened for writing.
    ``steps=False``: episodes are written without their per-step rows (:data:`STEP_COLUMNS`;
    a sweep's ``--no-steps``), which make most of a results file."""

    def __init__(self, path: str | Path, create: bool = True, check_rows: bool = False,
                 steps: bool = True):
        self.path = Path(path)
        self.keep_steps = steps
        if create and not self.path.exists():
            parent = self.path.parent
            if not parent.is_dir():
                raise ConfigError(f"cannot create {self.path}: folder {parent} does not exist")
        existing = check_results_file(self.path, create)  # a refused file is never modified
        if not create and not existing:
            raise ConfigError(f"{self.path} holds no episodes yet (an empty results database)")
        if check_rows and existing:  # before the file is opened for writing (WAL set)
            try:
                reader = open_readonly(self.path)
                try:
                    check_stored_rows(reader, self.path)
                finally:
                    reader.close()
            except sqlite3.DatabaseError as e:
                raise damaged(self.path, e) from None
        try:
            self.conn = (sqlite3.connect(self.path, timeout=30) if create
                         else open_readonly(self.path))
        except sqlite3.Error as e:
            raise ConfigError(f"cannot open results database {self.path}: {e}") from None
        self._release = None
        if create:
            with self._errors("open"):
                self._wal()
                self.conn.execute("PRAGMA synchronous=NORMAL")
                if not existing:
                    self._create_schema()
                else:
                    self._complete_schema()
        held = _file_id(self.path)
        if held is not None:  # released by close() or when the store is collected
            _HELD[held] = _HELD.get(held, 0) + 1
            self._release = weakref.finalize(self, _release, held)

    def _wal(self) -> None:
        """``PRAGMA journal_mode=WAL``. Switching a file's journal mode needs it alone, and
        SQLite answers "database is locked" at once, without waiting, while another sweep
        opening the same file holds it: asked again after 10, 20, ... ms, at most
        :data:`WAL_TRIES` times (about 30 s in all); the last refusal is raised."""
        for k in range(WAL_TRIES):
            try:
                self.conn.execute("PRAGMA journal_mode=WAL")
                return
            except sqlite3.OperationalError as e:
                if "locked" not in str(e) or k == WAL_TRIES - 1:
                    raise
                time.sleep(min(0.01 * (k + 1), 0.5))

    @contextlib.contextmanager
    def _errors(self, doing: str) -> Iterator[None]:
        """Turn an SQLite error while reading or writing into one line naming the file."""
        try:
            yield
        except sqlite3.DatabaseError as e:
            if doing == "open":
                self.conn.close()
            if isinstance(e, sqlite3.IntegrityError | sqlite3.OperationalError):
                raise ConfigError(f"cannot {doing} results database {self.path}: {e}") from None
            raise damaged(self.path, e) from None

    def _create_schema(self) -> None:
        """pathpref's tables in a new file; in one write transaction that first looks whether
        another sweep, started at the same moment on the same new file, made them already.

        Those tables are checked on this connection, not by opening the file again: closing
        any descriptor of a file drops every POSIX lock the process holds on it, this
        connection's shared lock included, and the other sweep, closing last, would then
        take itself for the last connection, fold the WAL into the file and delete it while
        this one still writes there (its episodes lost)."""
        c = self.conn
        c.execute("BEGIN IMMEDIATE")
        if c.execute("SELECT count(*) FROM sqlite_master").fetchone()[0]:
            c.rollback()
            version = schema_version(c, self.path)  # the other sweep's: pathpref's tables
            if version != SCHEMA_VERSION:
                raise ConfigError(f"{self.path} was made by another pathpref at the same "
                                  f"moment (schema {version}, this version writes "
                                  f"{SCHEMA_VERSION}); use a new --db path")
            return
        with c:
            c.execute(META_SQL)
            c.execute("INSERT INTO meta VALUES ('schema_version', ?)", (str(SCHEMA_VERSION),))
            c.execute(episodes_sql())
            c.execute(STEPS_SQL)
            c.execute(PATH_SQL)
            create_study_tables(c)

    def _complete_schema(self) -> None:
        """Bring an :data:`ADDITIVE` (schema 3 or 4) file to this schema: add the missing
        episode and step columns (NULL in the old rows, see :data:`ADDITIVE`) and, to a schema
        3 file, the study tables; to a schema 5 file the late episode columns it lacks
        (:data:`LATE_EPISODE_COLUMNS`); to a schema 4 or 5 file the late ``trials`` columns and
        study tables it lacks (:data:`~.trials.LATE_TRIAL_COLUMNS`,
        :data:`~.trials.LATE_STUDY_TABLES`); to any the late base tables it lacks
        (:data:`LATE_BASE_TABLES`)."""
        c = self.conn
        row = c.execute("SELECT value FROM meta WHERE key = 'schema_version'").fetchone()
        version = int(row[0])
        if version not in ADDITIVE:
            if version == SCHEMA_VERSION and (missing_trial_columns(c)
                                              or missing_study_tables(c)
                                              or missing_episode_columns(c)
                                              or missing_base_tables(c)):
                c.execute("BEGIN IMMEDIATE")  # another process may be adding them now
                with c:
                    for name in missing_episode_columns(c):
                        c.execute(f"ALTER TABLE episodes ADD COLUMN {name} "
                                  f"{EPISODE_COLUMNS[name]}")
                    complete_base_tables(c)
                    complete_trial_columns(c)
                    complete_study_tables(c)
            return
        with c:
            for table, wanted in (("episodes", EPISODE_COLUMNS), ("steps", STEP_COLUMNS)):
                have = [r[1] for r in c.execute(f"PRAGMA table_xinfo({table})")]
                for name, kind in wanted.items():
                    if name not in have:
                        c.execute(f"ALTER TABLE {table} ADD COLUMN {name} {kind}")
            complete_base_tables(c)
            if version < STUDY_SCHEMA:
                create_study_tables(c)
            else:
                complete_trial_columns(c)
                complete_study_tables(c)
            c.execute("UPDATE meta SET value = ? WHERE key = 'schema_version'",
                      (str(SCHEMA_VERSION),))

    def done_keys(self, include_failed: bool = True) -> set[str]:
        """Keys of the stored episodes (only successful runs when ``include_failed`` is False);
        a claimed, unfinished episode (``running``) is not done."""
        q = "SELECT key FROM episodes WHERE " + (f"status != '{RUNNING}'" if include_failed
                                                 else "status = 'ok'")
        with self._errors("read"):
            return {r[0] for r in self.conn.execute(q)}

    def claim(self, placeholder: EpisodeResult, retry_failed: bool = False,
              max_age_s: float = float("inf"), owner: dict[str, Any] | None = None) -> str:
        """Claim the episode of ``placeholder`` (its spec; the row written while it runs) for
        this process, atomically (``BEGIN IMMEDIATE``). Returns ``"done"`` when its row is
        there, finished (``ok``, or failed unless ``retry_failed``), ``"busy"`` when a live
        sweep has claimed it (:func:`claim_is_live` with ``max_age_s``), ``"claimed"`` when it
        is now this process's (a claim it holds already included)."""
        return self.claim_many([placeholder], retry_failed, max_age_s, owner)[0]

    def claim_many(self, placeholders: list[EpisodeResult], retry_failed: bool = False,
                   max_age_s: float = float("inf"), owner: dict[str, Any] | None = None
                   ) -> list[str]:
        """:meth:`claim` for each of ``placeholders`` (a chunk of a sweep), all in one write
        transaction; the answers in order."""
        owner = owner or this_owner()
        c = self.conn
        answers = []
        with self._errors("write to"):
            c.execute("BEGIN IMMEDIATE")
            try:
                at = time.time()
                for placeholder in placeholders:
                    answer = self._claim_one(placeholder, retry_failed, max_age_s, owner)
                    if answer == "new":
                        self._write(dataclasses.replace(
                            placeholder, status=RUNNING,
                            reason=json.dumps({**owner, "at": at}, sort_keys=True)))
                        answer = "claimed"
                    answers.append(answer)
                c.commit()
            except BaseException:
                c.rollback()
                raise
        return answers

    def _claim_one(self, placeholder: EpisodeResult, retry_failed: bool, max_age_s: float,
                   owner: dict[str, Any]) -> str:
        """What :meth:`claim` answers for ``placeholder``, ``"new"`` when its claim row is
        to be written (inside the caller's transaction)."""
        row = self.conn.execute("SELECT status, reason FROM episodes WHERE key = ?",
                                (placeholder.spec.key(),)).fetchone()
        if row is None:
            return "new"
        status, reason = row
        if status == RUNNING:
            try:
                held = json.loads(reason)
            except (TypeError, ValueError):
                held = {}
            if not isinstance(held, dict):
                held = {}
            if all(held.get(k) == v for k, v in owner.items()):
                return "claimed"
            return "busy" if claim_is_live(held, max_age_s) else "new"
        if status == "ok" or not retry_failed:
            return "done"
        return "new"

    def release_claims(self, owner: dict[str, Any] | None = None) -> int:
        """Remove this process's unfinished claims (a sweep ending early); their number."""
        owner = owner or this_owner()
        with self._errors("write to"), self.conn:
            rows = self.conn.execute("SELECT key, reason FROM episodes WHERE status = ?",
                                     (RUNNING,)).fetchall()
            mine = []
            for key, reason in rows:
                try:
                    held = json.loads(reason)
                except (TypeError, ValueError):
                    continue
                if isinstance(held, dict) and all(held.get(k) == v for k, v in owner.items()):
                    mine.append((key,))
            self.conn.executemany(f"DELETE FROM episodes WHERE key = ? AND status = "
                                  f"'{RUNNING}'", mine)
        return len(mine)

    def add(self, res: EpisodeResult) -> None:
        """Write one episode and its steps in one transaction (replacing a failed attempt or
        the episode's claim)."""
        self.add_many([res])

    def add_many(self, results: Iterable[EpisodeResult]) -> None:
        """Write episodes and their steps in one transaction (a batch of a sweep: all or
        none of them stored)."""
        with self._errors("write to"), self.conn:
            for res in results:
                self._write(res)

    def _write(self, res: EpisodeResult) -> None:
        """The statements of :meth:`add`, inside the caller's transaction."""
        row = result_row(res)
        cols = list(EPISODE_COLUMNS)
        vals = [row.get(k) for k in cols]
        vals = [int(v) if isinstance(v, bool) else v for v in vals]
        key = row["key"]
        self.conn.execute("DELETE FROM steps WHERE key = ?", (key,))
        self.conn.execute("DELETE FROM episode_path WHERE key = ?", (key,))
        if res.path:  # the path rows go in the episode's transaction (a resume stays exact)
            self.conn.executemany(
                f"INSERT INTO episode_path VALUES ({', '.join('?' * len(PATH_COLUMNS))})",
                [(key, k, *sample) for k, sample in enumerate(res.path)])
        self.conn.execute(
            f"INSERT OR REPLACE INTO episodes ({', '.join(cols)}) "
            f"VALUES ({', '.join('?' for _ in cols)})",
            vals,
        )
        if not self.keep_steps:
            return
        self.conn.executemany(
            f"INSERT INTO steps ({', '.join(STEP_COLUMNS)}) "
            f"VALUES ({', '.join('?' for _ in STEP_COLUMNS)})",
            [(key, s.t, s.x, s.y, s.action, s.heading, s.p_true_goal, s.goal_entropy,
              s.is_intervention) for s in res.log],
        )

    def episodes(self, where: str = "", params: Iterable[Any] = ()) -> list[dict[str, Any]]:
        """Episode rows (as dicts), optionally filtered by an SQL ``where`` with ``params``;
        a row pathpref cannot have written is refused (:func:`check_episode_rows`)."""
        rows = self._rows(f"SELECT rowid, * FROM episodes {where}", params)
        check_episode_rows(rows, self.path)  # a refused row is named by its rowid
        for row in rows:
            del row["rowid"]
        return rows

    def check_rows(self) -> None:
        """:func:`check_episode_rows` on every stored episode."""
        with self._errors("read"):
            check_stored_rows(self.conn, self.path)

    def steps(self, key: str) -> list[dict[str, Any]]:
        """The per-step rows of episode ``key``, in step order."""
        return self._rows("SELECT * FROM steps WHERE key = ? ORDER BY t", (key,))

    def recorded_path(self, key: str) -> list[dict[str, Any]]:
        """The recorded path of episode ``key`` (``episode_path`` rows, in order; empty when
        it was not recorded or the file predates the table)."""
        if missing_base_tables(self.conn):
            return []
        return self._rows("SELECT * FROM episode_path WHERE key = ? ORDER BY k", (key,))

    def _rows(self, query: str, params: Iterable[Any]) -> list[dict[str, Any]]:
        with self._errors("read"):
            cur = self.conn.execute(query, tuple(params))
            names = [d[0] for d in cur.description]
            return [dict(zip(names, r, strict=True)) for r in cur]

    def close(self) -> None:
        """Close the database connection (and release the file, :data:`_HELD`)."""
        self.conn.close()
        if self._release is not None:
            self._release()  # once: a finalizer runs at most once

    def __enter__(self) -> ResultStore:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def row_spec(row: dict[str, Any]) -> EpisodeSpec:
    """The :class:`EpisodeSpec` of a stored row: ``run_episode(row_spec(row))`` replays it."""
    spec = {name: row.get(stored) for stored, name in EpisodeSpec.field_names().items()}
    # rows before schema 4: the independent prior and the legacy physics they ran with;
    # before schema 5: the periodic human
    spec["prior"] = spec["prior"] or "independent"
    spec["physics"] = spec["physics"] or ""
    spec["push_rule"] = spec["push_rule"] or ""
    spec["normalize"], spec["coupling"] = bool(spec["normalize"]), bool(spec["coupling"])
    return EpisodeSpec(**spec)
