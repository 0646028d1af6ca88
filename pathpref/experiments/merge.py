"""``pathpref db merge``: join sweep databases (the shards of a sweep, one per node) into one,
all or nothing.

**What is kept.** Databases are keyed as every results database is, by the episode's key, so
each episode is stored once: an episode new to the output is copied with its step rows (and
recorded path); one the output holds already is kept as it is, except that a finished (``ok``)
row replaces a failed one, and that the step rows (and the recorded path) of a copy run with
steps are added to a copy run without them (``--no-steps``), whatever the order the
databases are given in. Claims (``running`` rows) are not copied. A database holding study
trials is refused as an input (merge joins sweeps).

**Disagreements.** The episodes are deterministic: two ``ok`` rows of one key whose outcomes
differ (:data:`OUTCOME`: status, success, goal, steps, inputs, violations) mean that two
nodes ran different code. The merge is then refused, naming the episode, the fields, both
values and the two databases.

**All or nothing.** Every input is checked before anything is written (a regular SQLite file,
pathpref's tables, intact pages, rows pathpref can have written), the output too when it
exists (and it must not be in use: a write-ahead log beside it means a sweep writes to it or
was stopped before closing it). The merge is then written into a temporary database made
exclusively (``mkstemp``) in the output's folder: a copy of the output (SQLite's online
backup of a read-only connection), into which each input's rows are copied, each row checked
as it is read (:func:`~.store.check_copied_rows`, :data:`~.store.STEP_RULES`,
:data:`~.store.PATH_RULES`, an ``ok`` episode's step rows ``t = 0..steps`` or none, its path
rows ``k = 0..n-1``). Only when every input has been copied, and the output has not changed
meanwhile, is the temporary file moved onto the output (``os.replace``, with the output's
mode). Any refusal (a damaged or tampered input, a disagreement, a full disk) removes the
temporary file: the output is left byte for byte as it was, and no new file is left behind.
The price is room for one copy of the output beside it while merging into an existing one.
"""

from __future__ import annotations

import contextlib
import os
import sqlite3
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from ..errors import ConfigError, is_disk_full
from .store import (
    CHANGED,
    EPISODE_COLUMNS,
    PATH_COLUMNS,
    PATH_RULES,
    STEP_COLUMNS,
    STEP_RULES,
    ResultStore,
    check_copied_rows,
    check_results_file,
    check_rows_of,
    check_stored_rows,
    damaged,
    missing_base_tables,
    new_file_mode,
    open_readonly,
    require_sqlite_file,
)
from .trials import has_study_tables

#: the columns whose values two runs of one episode must share
OUTCOME = ("status", "success", "goal_reached", "steps", "inputs", "violations")
#: episodes read per batch (and written per transaction into the temporary database)
MERGE_BATCH = 500
#: the episodes without step rows named in the result (``no_steps_named``)
NAMED = 5


def episode_label(row: dict[str, Any]) -> str:
    """An episode as a person reads it: method, ΔT, instance, run, map and body (the key has
    every field)."""
    return (f"{row.get('method')} ΔT={row.get('delta_t')} instance {row.get('instance')} run "
            f"{row.get('run')} on {row.get('map')} ({row.get('sim')}, {row.get('task')})")


def merge_databases(out: str | Path, inputs: list[str | Path]) -> dict[str, Any]:
    """Copy the episodes of each of ``inputs`` into ``out`` (created when missing), each key
    once, all or nothing (module docstring). Returns the counts ``copied``, ``replaced`` (a
    failed row replaced by an ``ok`` one), ``duplicates`` (left out: the output had the key),
    ``conflicts`` (always 0: a disagreement is refused), ``steps`` and ``path_rows`` (rows
    copied), ``episodes`` (in ``out`` afterwards), ``with_steps`` and ``no_steps`` (its
    finished episodes with and without step rows), ``no_steps_from`` (per database the
    episodes without step rows came from; ``out`` for its own) and ``no_steps_named`` (the
    first :data:`NAMED` of them, :func:`episode_label`)."""
    out = Path(os.path.realpath(out)) if os.path.islink(out) else Path(out)
    before = _check_output(out)
    names = [str(p) for p in inputs]
    _check_inputs(out, [Path(p) for p in inputs])
    counts: dict[str, Any] = dict.fromkeys(("copied", "replaced", "duplicates", "conflicts",
                                            "steps", "path_rows"), 0)
    parent = out.parent if str(out.parent) else Path(".")
    mode = (os.stat(out).st_mode & 0o7777) if before is not None else new_file_mode()
    tmp: str | None = None
    try:
        fd, tmp = tempfile.mkstemp(dir=parent, prefix=f".{out.name}.", suffix=".merge")
        os.close(fd)
        if before is not None and before[2] > 0:
            _copy_database(out, tmp)
        store = open_staging(tmp)
        try:
            conn = store.conn
            conn.execute("CREATE TEMP TABLE origin (key TEXT PRIMARY KEY, source INTEGER)")
            for index, src in enumerate(inputs):
                _merge_one(conn, Path(src), index, names, out, counts)
            _count(conn, names, out, counts)
            conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
            conn.execute("PRAGMA journal_mode=DELETE")
        finally:
            store.close()
        os.chmod(tmp, mode)
        with open(tmp, "rb+") as f:
            os.fsync(f.fileno())
        if _fingerprint(out) != before:
            raise ConfigError(f"{out} changed while the merge was written (a sweep writes to "
                              "it?); it is left as it is now: merge again when no sweep runs "
                              "on it")
        os.replace(tmp, out)
        tmp = None
    except (OSError, sqlite3.Error, ConfigError) as e:
        if is_disk_full(e):
            raise ConfigError(f"cannot write {out}: no space left on device; free some space "
                              f"and run again ({_left(out, before)}, no partial file was "
                              "kept)") from None
        if isinstance(e, ConfigError):
            raise
        reason = e.strerror if isinstance(e, OSError) and e.strerror else str(e)
        raise ConfigError(f"cannot write {out}: {reason} ({_left(out, before)}, no partial "
                          "file was kept)") from None
    finally:
        if tmp is not None:
            for side in ("", "-journal", "-wal", "-shm"):
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(tmp + side)
    return counts


def open_staging(path: str) -> ResultStore:
    """The store of the temporary database the merge is written into (a seam for tests that
    fill the disk)."""
    return ResultStore(path)


def _left(out: Path, before) -> str:
    return f"{out} is unchanged" if before is not None else f"{out} was not created"


def _fingerprint(out: Path) -> tuple | None:
    """What tells whether ``out`` changed: its identity, size and time, and its WAL's size."""
    try:
        st = os.stat(out)
    except FileNotFoundError:
        return None
    try:
        wal = os.stat(f"{out}-wal").st_size
    except FileNotFoundError:
        wal = 0
    return (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns, wal)


def _check_output(out: Path) -> tuple | None:
    """The output's :func:`_fingerprint` (None when it does not exist), after checking that it
    can be merged into: a writable folder, and an existing output intact, pathpref's, with
    sane rows and no write-ahead log (nothing is written)."""
    parent = out.parent if str(out.parent) else Path(".")
    if not parent.is_dir():
        raise ConfigError(f"cannot write {out}: folder {parent} does not exist")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ConfigError(f"cannot write {out}: folder {parent} is not writable (the merge is "
                          "written beside it first)")
    if not os.path.lexists(out):
        return None
    wal = Path(f"{out}-wal")
    if wal.is_file() and wal.stat().st_size > 0:
        raise ConfigError(f"{out} has a write-ahead log beside it ({wal.name}): a sweep is "
                          "writing it, or one was stopped before it closed the file; merge "
                          "when no sweep runs on it (running the sweep's command again "
                          "finishes and closes it), or merge into a new file")
    if check_results_file(out, create=True):
        try:
            ro = open_readonly(out)
            try:
                check_stored_rows(ro, out)
            finally:
                ro.close()
        except sqlite3.DatabaseError as e:
            raise damaged(out, e) from None
    return _fingerprint(out)


def _check_inputs(out: Path, inputs: list[Path]) -> None:
    """Every input is a distinct pathpref sweep database, not the output, intact, with rows
    pathpref can have written, and no study trials (read only, before any work)."""
    ids = set()
    for src in inputs:
        if not require_sqlite_file(src):
            raise ConfigError(f"{src} is empty: it holds no results")
        if out.exists() and os.path.samefile(src, out):
            raise ConfigError(f"{src} is the output database; give it once, as OUT")
        ids.add((os.stat(src).st_dev, os.stat(src).st_ino))
    if len(ids) < len(inputs):
        raise ConfigError("an input database is given twice")
    for src in inputs:
        ResultStore(src, create=False, check_rows=True).close()  # pathpref's, intact, sane
        try:
            ro = open_readonly(src)
            try:
                study = has_study_tables(ro) and ro.execute(
                    "SELECT COUNT(*) FROM trials").fetchone()[0]
            finally:
                ro.close()
        except sqlite3.DatabaseError as e:
            raise damaged(src, e) from None
        if study:
            raise ConfigError(f"{src} holds study trials; 'db merge' joins sweep databases "
                              "(copy a study with 'pathpref study export')")


def _copy_database(out: Path, tmp: str) -> None:
    """The output's content into the (empty) temporary file ``tmp``, through SQLite's online
    backup from a connection that writes nothing beside ``out``."""
    src = open_readonly(out)
    try:
        dst = sqlite3.connect(tmp)
        try:
            src.backup(dst)
        finally:
            dst.close()
    except sqlite3.DatabaseError as e:
        if is_disk_full(e):
            raise
        raise damaged(out, e) from None
    finally:
        src.close()


def _reading(src: Path, rows: Iterator[tuple]) -> Iterator[tuple]:
    """``rows`` of a cursor on ``src``, a read error as :func:`~.store.damaged`."""
    try:
        yield from rows
    except sqlite3.DatabaseError as e:
        raise damaged(src, e) from None


def _fetch(ro: sqlite3.Connection, src: Path, sql: str, params: tuple = ()
           ) -> list[dict[str, Any]]:
    try:
        cur = ro.execute(sql, params)
        names = [d[0] for d in cur.description]
        return [dict(zip(names, r, strict=True)) for r in cur.fetchall()]
    except sqlite3.DatabaseError as e:
        raise damaged(src, e) from None


def _merge_one(conn: sqlite3.Connection, src: Path, index: int, names: list[str], out: Path,
               counts: dict[str, Any]) -> None:
    """Copy the episodes of ``src`` into the temporary database ``conn``."""
    try:
        ro = open_readonly(src)
    except sqlite3.Error as e:
        raise ConfigError(f"cannot read results database {src}: {e}") from None
    try:
        have = {r["name"] for r in _fetch(ro, src, "PRAGMA table_xinfo(episodes)")}
        have_steps = [c for c in STEP_COLUMNS if c in
                      {r["name"] for r in _fetch(ro, src, "PRAGMA table_xinfo(steps)")}]
        try:
            paths = not missing_base_tables(ro)
            cur = ro.execute(f"SELECT rowid, {', '.join(c for c in EPISODE_COLUMNS if c in have)}"
                             " FROM episodes WHERE status != 'running' ORDER BY key")
        except sqlite3.DatabaseError as e:
            raise damaged(src, e) from None
        cols = [d[0] for d in cur.description]
        batches = _reading(src, iter(lambda: cur.fetchmany(MERGE_BATCH), []))
        for batch in batches:
            rows = check_copied_rows((dict(zip(cols, r, strict=True)) for r in batch), src)
            with conn:
                for row in rows:
                    _merge_row(conn, ro, src, index, names, out, row, have_steps, paths,
                               counts)
    finally:
        ro.close()


def _steps_of(ro: sqlite3.Connection, src: Path, row: dict[str, Any], cols: list[str]
              ) -> list[tuple]:
    """The checked step rows of ``row``'s episode in ``src``: none, or ``t = 0..steps`` of an
    episode that ran (as stored, padded with NULL to :data:`STEP_COLUMNS`)."""
    got = list(check_rows_of("steps", _fetch(
        ro, src, f"SELECT rowid, {', '.join(cols)} FROM steps WHERE key = ? ORDER BY t",
        (row["key"],)), src, STEP_RULES))
    if got and (row["status"] != "ok" or [s["t"] for s in got] != list(range(row["steps"] + 1))):
        ts = [s["t"] for s in got]
        raise ConfigError(f"{src}: episode {episode_label(row)} (episodes row {row['rowid']}) "
                          f"has step rows t = {ts[0]}..{ts[-1]} ({len(ts)} rows) but status "
                          f"{row['status']!r} and steps = {row['steps']}: {CHANGED} or damaged; "
                          f"'pathpref db check {src}' lists it and 'pathpref db salvage' "
                          "leaves it out")
    width = len(STEP_COLUMNS)
    return [(*(s[c] for c in cols), *(None,) * (width - len(cols))) for s in got]


def _path_of(ro: sqlite3.Connection, src: Path, row: dict[str, Any], paths: bool
             ) -> list[tuple]:
    """The checked recorded path of ``row``'s episode in ``src`` (rows ``k = 0..n-1``)."""
    if not paths:
        return []
    got = list(check_rows_of("episode_path", _fetch(
        ro, src, "SELECT rowid, * FROM episode_path WHERE key = ? ORDER BY k", (row["key"],)),
        src, PATH_RULES))
    if got and (row["status"] != "ok" or [r["k"] for r in got] != list(range(len(got)))):
        raise ConfigError(f"{src}: episode {episode_label(row)} (episodes row {row['rowid']}) "
                          f"has a recorded path with gaps or of an episode that did not run: "
                          f"{CHANGED} or damaged; 'pathpref db check {src}' lists it")
    return [tuple(r[c] for c in PATH_COLUMNS) for r in got]


def _insert_rows(conn: sqlite3.Connection, steps: list[tuple], path: list[tuple],
                 counts: dict[str, Any]) -> None:
    conn.executemany(f"INSERT INTO steps VALUES ({', '.join('?' * len(STEP_COLUMNS))})", steps)
    conn.executemany(f"INSERT INTO episode_path VALUES ({', '.join('?' * len(PATH_COLUMNS))})",
                     path)
    counts["steps"] += len(steps)
    counts["path_rows"] += len(path)


def _merge_row(conn: sqlite3.Connection, ro: sqlite3.Connection, src: Path, index: int,
               names: list[str], out: Path, row: dict[str, Any], step_cols: list[str],
               paths: bool, counts: dict[str, Any]) -> None:
    """Copy one episode row (and its steps and path) from ``src`` unless the temporary
    database's row of its key stays; refuse a disagreement (module docstring)."""
    key = row["key"]
    cols = list(EPISODE_COLUMNS)
    stored = conn.execute(f"SELECT {', '.join(OUTCOME)}, EXISTS (SELECT 1 FROM steps WHERE "
                          "key = ?), EXISTS (SELECT 1 FROM episode_path WHERE key = ?) FROM "
                          "episodes WHERE key = ?", (key, key, key)).fetchone()
    if stored is not None:
        have = dict(zip(OUTCOME, stored, strict=False))
        if have["status"] == "ok" and row["status"] == "ok":
            differ = [c for c in OUTCOME if have[c] != row.get(c)]
            if differ:
                kept = conn.execute("SELECT source FROM temp.origin WHERE key = ?",
                                    (key,)).fetchone()
                first = str(out) if kept is None else names[kept[0]]
                values = ", ".join(f"{c} = {have[c]!r} in {first} but {row.get(c)!r} in {src}"
                                   for c in differ)
                raise ConfigError(
                    f"{first} and {src} disagree on episode {episode_label(row)}: {values}; "
                    "the episodes are deterministic, so the two ran different code: merge "
                    f"databases of one pathpref version (nothing was written; key {key})")
            counts["duplicates"] += 1
            steps = [] if stored[-2] else _steps_of(ro, src, row, step_cols)
            path = [] if stored[-1] else _path_of(ro, src, row, paths)
            _insert_rows(conn, steps, path, counts)  # a copy run with steps completes one without
            return
        if have["status"] == "ok" or row["status"] != "ok":
            counts["duplicates"] += 1
            return
        counts["replaced"] += 1
        conn.execute("DELETE FROM steps WHERE key = ?", (key,))
        conn.execute("DELETE FROM episode_path WHERE key = ?", (key,))
    steps, path = _steps_of(ro, src, row, step_cols), _path_of(ro, src, row, paths)
    conn.execute(f"INSERT OR REPLACE INTO episodes ({', '.join(cols)}) "
                 f"VALUES ({', '.join('?' * len(cols))})", [row.get(c) for c in cols])
    conn.execute("INSERT OR REPLACE INTO temp.origin VALUES (?, ?)", (key, index))
    _insert_rows(conn, steps, path, counts)
    counts["copied"] += stored is None


def _count(conn: sqlite3.Connection, names: list[str], out: Path,
           counts: dict[str, Any]) -> None:
    """The episodes of the merged database, and its finished episodes with and without step
    rows (the latter by the database they came from)."""
    counts["episodes"] = conn.execute(
        "SELECT COUNT(*) FROM episodes WHERE status != 'running'").fetchone()[0]
    bare = ("FROM episodes e LEFT JOIN temp.origin o USING (key) WHERE e.status = 'ok' AND "
            "NOT EXISTS (SELECT 1 FROM steps s WHERE s.key = e.key)")
    counts["no_steps_from"] = {
        (str(out) if src is None else names[src]): n
        for src, n in conn.execute(f"SELECT o.source, COUNT(*) {bare} GROUP BY o.source")}
    counts["no_steps"] = sum(counts["no_steps_from"].values())
    counts["with_steps"] = conn.execute(
        "SELECT COUNT(*) FROM episodes e WHERE status = 'ok' AND EXISTS (SELECT 1 FROM steps s "
        "WHERE s.key = e.key)").fetchone()[0]
    cur = conn.execute(f"SELECT e.* {bare} ORDER BY e.key LIMIT {NAMED}")
    cols = [d[0] for d in cur.description]
    counts["no_steps_named"] = [episode_label(dict(zip(cols, r, strict=True))) for r in cur]
