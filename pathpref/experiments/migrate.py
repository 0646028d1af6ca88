"""``pathpref db``: upgrade, check, salvage and merge results databases.

**upgrade.** Schema 2 keyed an episode by its map's *path*; schema 3 keys it by the map's
content hash (:attr:`pathpref.geometry.maps.MapSpec.content_hash`) and stores that hash in a
``map_hash`` column. The upgrade reads every row of the old file, loads each map it names
(``--map OLD=NEW`` points a stored name at a file that has moved), recomputes the key of each
episode under the current :class:`~pathpref.episode.EpisodeSpec` (fields the old
schema lacks take the values that reproduce the old behaviour), and writes a new file with
every episode and step.
Rows of one map stored under two paths become one episode when everything else agrees; the row
kept is the first successful one. The old file is kept beside the new one as
``NAME.schema2.bak``; nothing is changed when any map cannot be loaded. Schema 3 or 4 -> 5
only adds columns, in place: ``physics``, ``prior`` and ``push_rule`` (empty in old rows: the
legacy physics, the independent prior and the periodic human they ran with), the
``homotopy_success`` and ``slack`` of each episode and the ``is_intervention`` of each step
(NULL in old rows: not measured; a schema 5 file without ``slack`` gets it in place too),
and to a schema 3 file the (empty) study tables of :mod:`.trials`; to any file, schema 5
included, the (empty) ``episode_path`` table of recorded paths; every row and key stays as it
was. A schema 2 file's rows get these columns empty too.

**homotopy** (:func:`recompute_homotopy`, run by ``pathpref db upgrade`` after the schema is
current) fills the NULL ``homotopy_success`` of old rows where it follows from what is stored,
without running anything: 0 for an episode that did not reach the goal or did not run; for
one that did, the class test of the stored step cells against the human's route, once the
row's map loads with its stored content hash and its instance, drawn again from its seeds,
has the stored start, candidates and true goal. Any other row stays NULL (its map moved:
``--map OLD=NEW``). ``is_intervention`` is not recomputed (which steps had a push is not
stored in old rows; the periodic human's are every ``Delta_T``, but a NULL stays honest).

**slack** (:func:`recompute_slack`, run by ``pathpref db upgrade`` too) fills the NULL
``slack`` of old rows that ran (``status = 'ok'``), exactly as the episode would have stored it
(:func:`~pathpref.episode.results.route_slack` of the human's route), where the row's map loads
with its stored content hash and its instance, drawn again from its seeds, matches the stored
one: a search over the map's cells per row, nothing is run. Rows that did not run, or whose
map moved, stay NULL (reports: *not measured*).

**check** (:func:`check_database`) reads a database without changing it and reports SQLite's
integrity check, whether it is pathpref's (:func:`~pathpref.experiments.store.schema_version`),
how many episode and step rows read back, and which episodes lack step rows (an episode that ran
has one per time step ``0..steps``, a failed one none) or which step rows belong to no episode;
likewise the recorded paths (``episode_path``: rows ``k = 0..n-1`` of an episode that ran,
none of a failed one, none of no episode).

**salvage** (:func:`salvage_database`) copies every episode that reads back whole, with its step
rows and its recorded path, into a new database; rows on damaged pages are read around (one
rowid range at a time, then row by row), and an episode with a missing step row is left out, so
a rerun of the sweep redoes exactly what was lost. The study tables (schema 4) are salvaged the
same way: a trial is kept, with every row of its tables, when its ``trials`` row reads back and
its rows are whole (:func:`_whole_trials`); a trial missing rows is left out whole and counted
lost (``study run --resume`` on the new database runs that trial again, the participant's other
trials stay), with its NASA-TLX answers; the participant's gamepad calibrations are kept as they
read back. The study rows are read into memory as the episodes are (a salvage is a one-off
repair).

**merge** (:func:`merge_databases`, :mod:`.merge`) joins sweep databases (the shards of a
sweep) into one, each episode once, all or nothing: written into a temporary database beside
the output and moved onto it only when every input has been checked and copied. """

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import sqlite3
import tempfile
from collections import defaultdict
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from ..episode import EpisodeSpec, cached_map, cached_world
from ..episode.instances import Instance, episode_instance, human_preference
from ..episode.results import route_slack
from ..errors import ConfigError, PathprefError
from ..geometry.following import human_route
from ..geometry.homotopy import route_homotopic
from ..geometry.world import World
from .store import (
    ADDITIVE,
    EPISODE_COLUMNS,
    PATH_COLUMNS,
    SCHEMA_VERSION,
    STEP_COLUMNS,
    UPGRADABLE,
    ResultStore,
    damaged,
    inspect_results_file,
    missing_base_tables,
    open_readonly,
    require_sqlite_file,
    row_spec,
    schema_version,
)
from .trials import (
    SESSION_TABLES,
    STUDY_TABLE_NAMES,
    STUDY_TABLES,
    has_study_tables,
    missing_study_tables,
)


def _read_old(path: Path) -> tuple[int, list[dict[str, Any]], list[tuple]]:
    """Schema version, episode rows and step rows of ``path`` (read-only, no side files), after
    the checks of :func:`~pathpref.experiments.store.inspect_results_file`."""
    version = inspect_results_file(path)
    if version is None:
        raise ConfigError(f"{path} holds no pathpref tables; there is nothing to upgrade")
    try:
        ro = open_readonly(path)
        try:
            cur = ro.execute("SELECT * FROM episodes")
            names = [d[0] for d in cur.description]
            rows = [dict(zip(names, r, strict=True)) for r in cur]
            steps = ro.execute("SELECT * FROM steps ORDER BY key, t").fetchall()
        finally:
            ro.close()
    except sqlite3.Error as e:
        raise damaged(path, e) from None
    return version, rows, steps


def _new_spec(row: dict[str, Any], map_paths: dict[str, str]) -> EpisodeSpec:
    """The current spec of an old row (missing fields default; the map possibly re-pointed)."""
    fields = {name: row[stored] for stored, name in EpisodeSpec.field_names().items()
              if stored in row and row[stored] is not None}
    fields["map"] = map_paths.get(row["map"], row["map"])
    fields.setdefault("prior", "independent")  # rows before schema 4 ran with the paper's prior
    fields.setdefault("physics", "")  # ... and the legacy physics
    for flag in ("normalize", "coupling"):
        if flag in fields:
            fields[flag] = bool(fields[flag])
    try:
        cached_map(fields["map"])
    except PathprefError as e:
        raise ConfigError(
            f"cannot upgrade: stored map '{row['map']}' does not load ({e}); run from the folder "
            f"the sweep ran in, or point it at the file with --map '{row['map']}=PATH'"
        ) from None
    return EpisodeSpec(**fields)


def upgrade_database(path: str | Path, map_paths: dict[str, str] | None = None
                     ) -> dict[str, Any]:
    """Migrate ``path`` in place (see module docstring); returns counts of what was done."""
    path = Path(path)
    version, rows, steps = _read_old(path)
    if version == SCHEMA_VERSION:
        ResultStore(path).close()  # adds the late columns a schema 5 file lacks
        return {"from": version, "to": version, "episodes": len(rows), "merged": 0,
                "backup": None}
    if version in ADDITIVE:  # columns (and the study tables) added in place: no row changes
        ResultStore(path).close()
        return {"from": version, "to": SCHEMA_VERSION, "episodes": len(rows), "merged": 0,
                "steps": len(steps), "backup": "(none: tables added in place)"}
    if version not in UPGRADABLE:
        raise ConfigError(f"{path} has schema {version}; 'db upgrade' migrates schema "
                          f"{', '.join(map(str, UPGRADABLE))} to {SCHEMA_VERSION}")
    map_paths = map_paths or {}
    new_key: dict[str, str] = {}
    kept: dict[str, dict[str, Any]] = {}
    for row in sorted(rows, key=lambda r: (r["status"] != "ok", r["key"])):
        spec = _new_spec(row, map_paths)
        key = spec.key()
        if key in kept:
            continue
        new_key[row["key"]] = key
        kept[key] = {**row, **spec.stored(), "key": key, "map_hash": spec.map_hash}
    backup = path.with_name(path.name + f".schema{version}.bak")
    if backup.exists():
        raise ConfigError(f"{backup} exists; move it away before upgrading {path}")
    steps = [(new_key[s[0]], *s[1:]) for s in steps if s[0] in new_key]
    with _new_database(path, kept.values(), steps) as tmp:
        os.replace(path, backup)
        os.replace(tmp, path)
    return {"from": version, "to": SCHEMA_VERSION, "episodes": len(kept), "steps": len(steps),
            "merged": len(rows) - len(kept), "backup": str(backup)}


def _stored_instance(row: dict[str, Any], map_paths: dict[str, str]
                     ) -> tuple[World, Instance, np.ndarray] | None:
    """The world, instance and human preference of a stored episode, when its map loads with
    its stored content hash and its instance, drawn again from its seeds, has the stored start,
    candidates and true goal; else None."""
    spec = dataclasses.replace(row_spec(row), map=map_paths.get(row["map"], row["map"]))
    try:
        world = cached_world(spec.map)
        if world.spec.content_hash != row["map_hash"]:
            return None
        inst, free_goal = episode_instance(world, spec.fixed, spec.instance_seed, spec.n_goals,
                                           spec.human, spec.t_max)
    except PathprefError:
        return None
    cells = world.cells
    if (json.dumps(cells[inst.start].tolist()) != row["start"]
            or json.dumps(cells[list(inst.goals)].tolist()) != row["goals"]
            or inst.true_goal != row["true_goal"]):
        return None
    return world, inst, human_preference(world, inst, free_goal, spec.human)


def _stored_homotopy(store: ResultStore, row: dict[str, Any], map_paths: dict[str, str]
                     ) -> int | None:
    """The ``homotopy_success`` of a stored episode from its row and step rows (module
    docstring, **homotopy**); None when it cannot be known."""
    if row["status"] != "ok" or not row["goal_reached"]:
        return 0
    found = _stored_instance(row, map_paths)
    if found is None:
        return None
    world, inst, pref = found
    path = [(s["x"], s["y"]) for s in store.steps(row["key"])]
    if len(path) != row["steps"] + 1 or list(path[-1]) != world.cells[inst.goal_cell].tolist():
        return None
    return int(route_homotopic(world, pref, inst.start, inst.goal_cell, path))


def _stored_slack(row: dict[str, Any], map_paths: dict[str, str]) -> int | None:
    """The ``slack`` of a stored episode (module docstring, **slack**); None when it cannot
    be known."""
    if row["status"] != "ok":
        return None
    found = _stored_instance(row, map_paths)
    if found is None:
        return None
    world, inst, pref = found
    return route_slack(row["t_max"], human_route(world, pref, inst.start, inst.goal_cell))


def recompute_slack(path: str | Path, map_paths: dict[str, str] | None = None
                    ) -> dict[str, int]:
    """Fill the NULL ``slack`` of the episodes of ``path`` that ran, where the stored rows
    determine it (module docstring, **slack**); the numbers filled and left."""
    return _fill_nulls(path, "slack", "status = 'ok'",
                       lambda store, row: _stored_slack(row, map_paths or {}))


def recompute_homotopy(path: str | Path, map_paths: dict[str, str] | None = None
                       ) -> dict[str, int]:
    """Fill the NULL ``homotopy_success`` of the finished episodes of ``path`` where the
    stored rows determine it (module docstring, **homotopy**); the numbers filled and left."""
    return _fill_nulls(path, "homotopy_success", "status != 'running'",
                       lambda store, row: _stored_homotopy(store, row, map_paths or {}))


def _fill_nulls(path: str | Path, column: str, which: str, value) -> dict[str, int]:
    """Set the NULL ``column`` of the episodes of ``path`` matching the SQL condition ``which``
    to ``value(store, row)`` where that is not None, in one transaction; the numbers filled
    and left."""
    with ResultStore(path) as store:
        rows = store.episodes(f"WHERE {column} IS NULL AND {which}")
        filled = []
        for row in rows:
            v = value(store, row)
            if v is not None:
                filled.append((v, row["key"]))
        with store.conn:
            store.conn.executemany(f"UPDATE episodes SET {column} = ? WHERE key = ? "
                                   f"AND {column} IS NULL", filled)
    return {"recomputed": len(filled), "left": len(rows) - len(filled)}


@contextlib.contextmanager
def _new_database(beside: Path, episodes: Iterable[dict[str, Any]], steps: list[tuple],
                  study: dict[str, list[tuple]] | None = None,
                  paths: list[tuple] = ()) -> Iterator[str]:
    """A new pathpref database holding ``episodes`` and ``steps`` (the study tables'
    ``study[table]`` rows and the ``episode_path`` rows ``paths``), written to a temporary
    file in the folder of ``beside`` (rollback journal, no side file) for the caller to move
    into place; whatever is left of it afterwards is removed."""
    fd, tmp = tempfile.mkstemp(dir=beside.parent, prefix=f".{beside.stem}.", suffix=".new")
    os.close(fd)
    os.unlink(tmp)  # ResultStore creates the file itself
    try:
        store = ResultStore(tmp)
        cols = list(EPISODE_COLUMNS)
        with store.conn:
            store.conn.executemany(
                f"INSERT INTO episodes ({', '.join(cols)}) VALUES ({', '.join('?' * len(cols))})",
                [[_plain(r.get(c)) for c in cols] for r in episodes])
            width = len(STEP_COLUMNS)  # older files' steps lack the last columns: NULL
            store.conn.executemany(
                f"INSERT INTO steps VALUES ({', '.join('?' * width)})",
                [(*s, *(None,) * (width - len(s))) for s in steps])
            store.conn.executemany(
                f"INSERT INTO episode_path VALUES ({', '.join('?' * len(PATH_COLUMNS))})",
                paths)
            for table, rows in (study or {}).items():
                if rows:  # a file without the late trials columns: NULL, as it reads
                    n = len(next(c for t, c, _ in STUDY_TABLES if t == table))
                    store.conn.executemany(
                        f"INSERT INTO {table} VALUES ({', '.join('?' * n)})",
                        [(*r, *(None,) * (n - len(r))) for r in rows])
        store.conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
        store.conn.execute("PRAGMA journal_mode=DELETE")
        store.close()
        yield tmp
    finally:
        for side in (tmp, tmp + "-wal", tmp + "-shm", tmp + "-journal"):
            if os.path.exists(side):
                os.unlink(side)


def _read_table(conn: sqlite3.Connection, table: str, chunk: int = 512
                ) -> tuple[list[dict[str, Any]], int, bool]:
    """Every row of ``table`` that reads back, the number lost, and whether that number is exact.

    Rows are read one rowid range at a time and, in a range that raises, row by row, so a
    damaged page costs only its own rows. The rowid bounds come from the table or, when its
    edge pages are damaged, from its primary-key index; failing both, the scan stops after 16
    empty ranges. The number lost is ``count(*)`` (the index usually still counts) minus the
    rows read; when nothing counts, it is the number of rowids whose read raised (an upper
    bound: rowids have gaps).
    """
    def first(*queries: str) -> Any:
        for q in queries:
            try:
                return conn.execute(q).fetchone()[0]
            except sqlite3.DatabaseError:
                continue
        return None

    index = f"INDEXED BY sqlite_autoindex_{table}_1"
    lo = first(f"SELECT min(rowid) FROM {table}", f"SELECT min(rowid) FROM {table} {index}")
    hi = first(f"SELECT max(rowid) FROM {table}", f"SELECT max(rowid) FROM {table} {index}")
    total = first(f"SELECT count(*) FROM {table}", f"SELECT count(*) FROM {table} NOT INDEXED")
    cur = conn.execute(f"SELECT * FROM {table} LIMIT 0")
    names = [d[0] for d in cur.description]
    query = f"SELECT * FROM {table} WHERE rowid BETWEEN ? AND ?"
    rows: list[tuple] = []
    failed = empty = 0
    start = 1 if lo is None else lo
    while (start <= hi) if hi is not None else (empty < 16):
        end = start + chunk - 1
        try:
            got = conn.execute(query, (start, end)).fetchall()
        except sqlite3.DatabaseError:
            got = []
            for rowid in range(start, end + 1):
                try:
                    got += conn.execute(query, (rowid, rowid)).fetchall()
                except sqlite3.DatabaseError:
                    failed += 1
        rows += got
        empty = 0 if got else empty + 1
        start = end + 1
    lost = failed if total is None else max(0, total - len(rows))
    return [dict(zip(names, r, strict=True)) for r in rows], lost, total is not None


def _read_path(conn: sqlite3.Connection) -> tuple[list[dict[str, Any]], int, bool]:
    """:func:`_read_table` of ``episode_path`` (no rows, none lost, when the file predates
    it)."""
    if missing_base_tables(conn):
        return [], 0, True
    return _read_table(conn, "episode_path")


def _whole_episodes(episodes: list[dict[str, Any]], steps: list[dict[str, Any]],
                    paths: list[dict[str, Any]] = ()
                    ) -> tuple[dict[str, dict[str, Any]], list[str], int, int]:
    """The episodes whose step rows are all there (one per time step ``0..steps`` for an
    episode that ran, none for a failed one) and whose recorded path, if any, has no gap
    (``episode_path`` rows ``k = 0..n-1``; none for a failed one), keyed by key; the keys of
    the others; the number of step rows and of path rows of no episode."""
    ts: dict[str, list[int]] = defaultdict(list)
    for s in steps:
        ts[s["key"]].append(s["t"])
    ks: dict[str, list[int]] = defaultdict(list)
    for r in paths:
        ks[r["key"]].append(r["k"])
    whole: dict[str, dict[str, Any]] = {}
    broken: list[str] = []
    for e in episodes:
        got, n = ts.get(e["key"], []), e["steps"]
        if e["status"] != "ok":
            ok = not got
        else:
            ok = (isinstance(n, int) and all(isinstance(t, int) for t in got)
                  and sorted(got) == list(range(n + 1)))
        path = ks.get(e["key"], [])
        ok = ok and (sorted(path) == list(range(len(path))) if e["status"] == "ok" else
                     not path)
        if ok and e["key"] not in whole:
            whole[e["key"]] = e
        else:
            broken.append(e["key"])
    keys = {e["key"] for e in episodes}
    orphans = sum(len(t) for k, t in ts.items() if k not in keys)
    path_orphans = sum(len(v) for k, v in ks.items() if k not in keys)
    return whole, broken, orphans, path_orphans


#: the tables of a trial's rows that must run without gaps
PER_TRIAL = ("trial_steps", "trial_forces", "trial_pushes", "trial_cues", "trial_beliefs",
             "trial_path")


def _whole_trials(tables: dict[str, list[dict[str, Any]]]) -> tuple[set[tuple], int]:
    """The ``(participant, trial)`` of the study trials whose rows are whole, and the number
    of trials left out. Whole: the ``trials`` row reads back; ``trial_steps`` has ``t = 0..n``
    (``n = steps`` for a finished trial), ``trial_forces`` and ``trial_beliefs`` have
    ``k = 0..m`` for some ``m`` (``trial_path`` too, possibly empty), and a finished trial
    has ``k = 0..pushes-1`` pushes and ``k = 0..cues-1`` cues. An unfinished trial (``study
    run --resume`` runs it again) needs only gap-free rows."""
    seq: dict[tuple[str, tuple], list[int]] = defaultdict(list)
    for table in PER_TRIAL:
        col = "t" if table == "trial_steps" else "k"
        for r in tables.get(table, ()):  # trial_path: absent from older files
            seq[(table, (r["participant"], r["trial"]))].append(r[col])
    whole: set[tuple] = set()
    broken = 0
    for r in tables["trials"]:
        key = (r["participant"], r["trial"])
        got = {t: sorted(seq.get((t, key), [])) for t in PER_TRIAL}
        ok = all(v == list(range(len(v))) for v in got.values())
        if r["status"] == "done":
            ok = ok and (len(got["trial_steps"]) == (r["steps"] or 0) + 1
                         and len(got["trial_pushes"]) == r["pushes"]
                         and len(got["trial_cues"]) == r["cues"]
                         and bool(got["trial_forces"]) and bool(got["trial_beliefs"]))
        if ok and key not in whole:
            whole.add(key)
        else:
            broken += 1
    return whole, broken


def check_database(path: str | Path) -> dict[str, Any]:
    """What is wrong with the results database ``path``, read without changing it: SQLite's
    ``integrity_check`` (``["ok"]`` when sound), ``pathpref`` (None when the file is pathpref's,
    else why not), ``schema``, the readable and lost ``episodes`` and ``steps`` rows, the
    ``incomplete`` episodes (missing step rows) and ``orphans`` (step rows of no episode), and
    ``intact``: all of these are clean. A missing, non-SQLite or empty file is a ConfigError."""
    path = Path(path)
    if not require_sqlite_file(path):
        raise ConfigError(f"{path} is empty: it holds no results")
    out: dict[str, Any] = {"path": str(path), "pathpref": None, "schema": None}
    try:
        ro = open_readonly(path)
    except sqlite3.Error as e:
        raise ConfigError(f"cannot read results database {path}: {e}") from None
    try:
        try:
            out["integrity"] = [r[0] for r in ro.execute("PRAGMA integrity_check(20)")]
        except sqlite3.DatabaseError as e:
            out["integrity"] = [str(e)]
        try:
            out["schema"] = schema_version(ro, path)
            if out["schema"] is None:
                out["pathpref"] = "it holds no tables"
        except ConfigError as e:
            out["pathpref"] = str(e)
        except sqlite3.DatabaseError as e:
            out["pathpref"] = f"its schema cannot be read ({e})"
        if out["pathpref"] is None:
            episodes, out["episodes_lost"], exact_e = _read_table(ro, "episodes")
            steps, out["steps_lost"], exact_s = _read_table(ro, "steps")
            paths, out["path_lost"], exact_p = _read_path(ro)
            out["lost_exact"] = exact_e and exact_s and exact_p
            out["episodes"], out["steps"] = len(episodes), len(steps)
            out["path_rows"] = len(paths)
            _, out["incomplete"], out["orphans"], out["path_orphans"] = _whole_episodes(
                episodes, steps, paths)
            out["trials"] = _trial_counts(ro)
    finally:
        ro.close()
    out["intact"] = (out["integrity"] == ["ok"] and out["pathpref"] is None
                     and not (out["episodes_lost"] or out["steps_lost"] or out["incomplete"]
                              or out["orphans"] or out["path_lost"] or out["path_orphans"]))
    return out


def _trial_counts(conn: sqlite3.Connection) -> tuple[int, int] | None:
    """Finished and unfinished study trials (None without study tables or when unreadable)."""
    try:
        if not has_study_tables(conn):
            return None
        done, total = conn.execute("SELECT count(*) FILTER (WHERE status = 'done'), count(*) "
                                   "FROM trials").fetchone()
    except sqlite3.DatabaseError:
        return None
    return int(done), int(total - done)


def check_text(r: dict[str, Any]) -> str:
    """The report of :func:`check_database` as printed by ``pathpref db check``."""
    db, problems = r["path"], r["integrity"]
    lines = [f"{db}: {'intact' if r['intact'] else 'DAMAGED'}",
             "  integrity check: " + ("ok" if problems == ["ok"] else
                                      f"{len(problems)} problem(s): " + "; ".join(problems[:3])),
             "  pathpref database: " + (f"yes, schema {r['schema']}" if r["pathpref"] is None
                                        else f"no: {r['pathpref']}")]
    if r["schema"] in UPGRADABLE:
        lines.append(f"  'pathpref db upgrade {db}' migrates it to schema {SCHEMA_VERSION}")
    if r["pathpref"] is None:
        about = "" if r["lost_exact"] else "at most "
        incomplete = r["incomplete"]
        lines += [f"  episodes: {r['episodes']} readable, {about}{r['episodes_lost']} unreadable",
                  f"  step rows: {r['steps']} readable, {about}{r['steps_lost']} unreadable",
                  f"  episodes with missing step rows: {len(incomplete)}",
                  *(f"    {k}" for k in incomplete[:10]), *(["    ..."] * (len(incomplete) > 10)),
                  f"  orphan step rows (of no episode): {r['orphans']}"]
        if r["path_rows"] or r["path_lost"] or r["path_orphans"]:
            lines += [f"  recorded path rows: {r['path_rows']} readable, {about}{r['path_lost']} "
                      f"unreadable, {r['path_orphans']} of no episode"]
        if r.get("trials"):
            done, running = r["trials"]
            lines.append(f"  study trials: {done} finished, {running} unfinished" + (
                " (a session was stopped; 'study run --resume' runs them again)" if running
                else ""))
        if not r["intact"]:
            lines.append(f"'pathpref db salvage {db} NEW.sqlite' copies the intact episodes")
    return "\n".join(lines)


def salvage_database(path: str | Path, out: str | Path) -> dict[str, Any]:
    """Copy every episode of ``path`` that reads back whole, with its step rows, into a new
    database ``out`` (refused when it exists); returns the counts of rows saved and lost."""
    path, out = Path(path), Path(out)
    if os.path.lexists(out):
        raise ConfigError(f"{out} exists; salvage writes a new database, give a new path")
    if not out.parent.is_dir() or not os.access(out.parent, os.W_OK):
        raise ConfigError(f"cannot write {out}: folder {out.parent} does not exist or is not "
                          "writable")
    if not require_sqlite_file(path):
        raise ConfigError(f"{path} is empty: it holds no results")
    try:
        ro = open_readonly(path)
        try:
            version = schema_version(ro, path)
            if version != SCHEMA_VERSION and version not in ADDITIVE:
                raise ConfigError(f"{path} has schema {version}; salvage copies schema "
                                  f"{', '.join(map(str, (*ADDITIVE, SCHEMA_VERSION)))} "
                                  "databases")
            episodes, episodes_lost, exact_e = _read_table(ro, "episodes")
            steps, steps_lost, exact_s = _read_table(ro, "steps")
            paths, path_lost, exact_p = _read_path(ro)
            absent = missing_study_tables(ro) if has_study_tables(ro) else []
            study = ({t: _read_table(ro, t) for t in STUDY_TABLE_NAMES if t not in absent}
                     if has_study_tables(ro) else None)
        finally:
            ro.close()
    except sqlite3.DatabaseError as e:
        raise ConfigError(f"{path} cannot be salvaged: its table list is unreadable ({e})"
                          ) from None
    whole, broken, orphans, path_orphans = _whole_episodes(episodes, steps, paths)
    kept = [tuple(s.values()) for s in steps if s["key"] in whole]
    kept_path = [tuple(r.values()) for r in paths if r["key"] in whole]
    trials = trial_rows = trials_lost = 0
    study_rows: dict[str, list[tuple]] = {}
    if study is not None:
        good, broken_trials = _whole_trials({t: v[0] for t, v in study.items()})
        # a trial's rows go with it (its NASA-TLX answers too); the participant's
        # calibrations (SESSION_TABLES) are kept whenever they read back
        study_rows = {t: [tuple(r.values()) for r in v[0]
                          if t in SESSION_TABLES or (r["participant"], r["trial"]) in good]
                      for t, v in study.items()}
        trials, trial_rows = len(good), sum(len(v) for v in study_rows.values())
        # a trial whose `trials` row did not read back is lost too (its other rows go with it)
        trials_lost = broken_trials + study["trials"][1]
        exact_e = exact_e and study["trials"][2]
    with _new_database(out, whole.values(), kept, study_rows, kept_path) as tmp:
        os.replace(tmp, out)
    return {"episodes": len(whole), "steps": len(kept), "trials": trials,
            "trial_rows": trial_rows, "trials_lost": trials_lost,
            "study": study is not None,
            "episodes_lost": episodes_lost + len(broken),
            "steps_lost": steps_lost + len(steps) - len(kept), "incomplete": len(broken),
            "path_rows": len(kept_path), "path_orphans": path_orphans,
            "path_lost": path_lost + len(paths) - len(kept_path),
            "unreadable": episodes_lost, "orphans": orphans,
            "lost_exact": exact_e and exact_s and exact_p}


def _plain(v: Any) -> Any:
    return int(v) if isinstance(v, bool) else v


from .merge import OUTCOME, merge_databases  # noqa: E402, F401 - its older home
