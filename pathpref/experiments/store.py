"""SQLite results store: one row per episode (full configuration and seeds), per-step logs.

Each finished episode is written at once, in one transaction (episode row and its steps
together), so a sweep killed at any moment leaves only whole episodes; WAL journaling keeps the
file consistent. The primary key is :meth:`EpisodeSpec.key`, so a rerun of the same sweep skips
what is done. A file written by another schema version, or not written by pathpref, is refused
and never modified.
"""

from __future__ import annotations

import dataclasses
import os
import sqlite3
import stat
from collections.abc import Iterable
from pathlib import Path
from typing import Any
from urllib.parse import quote

from ..episode import EpisodeResult, EpisodeSpec, result_row
from ..errors import ConfigError

SCHEMA_VERSION = 3  # 2: per-episode physical metrics (JSON); 3: keys by map content hash

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
    "human": "TEXT", "back_crossings": "INTEGER",
}
STEP_COLUMNS = ("key", "t", "x", "y", "action", "heading", "p_true_goal", "goal_entropy")


def check_results_file(path: str | Path) -> bool:
    """True for a compatible pathpref database at ``path``, False for a new or empty file,
    else a one-line ConfigError. Checked before any read-write connection, on a read-only one
    (immutable, so no side file appears, unless the file already has its ``-wal``): a
    regular file; SQLite; exactly pathpref's tables (``meta``, ``episodes``, ``steps``, and
    SQLite's own indexes of their keys) with pathpref's columns and no view, trigger or
    other table (a file from elsewhere could otherwise rewrite or invent results); the
    schema row; and SQLite's ``quick_check``."""
    p = Path(path)
    try:
        st = os.stat(p)
    except FileNotFoundError:
        return False
    except OSError as e:
        raise ConfigError(f"cannot read results database {p}: {e}") from None
    if not stat.S_ISREG(st.st_mode):
        raise ConfigError(f"{p} is not a regular file (a folder or a device); give the path "
                          "of a results database with --db")
    if st.st_size == 0:
        return False
    with open(p, "rb") as f:
        if f.read(16) != b"SQLite format 3\x00":
            raise ConfigError(f"{p} is not a pathpref results database (not SQLite); "
                              "give another --db path")
    immutable = "" if Path(f"{p}-wal").exists() else "&immutable=1"
    uri = f"file:{quote(str(p.resolve()))}?mode=ro{immutable}"
    try:
        ro = sqlite3.connect(uri, uri=True, timeout=30)
        try:
            objects = ro.execute("SELECT type, name, tbl_name FROM sqlite_master").fetchall()
            _check_objects(p, objects)
            if not objects:
                return False
            row = ro.execute("SELECT value FROM meta WHERE key='schema_version'").fetchone()
            found = int(row[0]) if row and str(row[0]).isdigit() else None
            _check_schema(p, found)
            for table, want in (("episodes", set(EPISODE_COLUMNS)), ("steps", STEP_COLUMNS)):
                have = {r[1] for r in ro.execute(f"PRAGMA table_info({table})")}
                if have != set(want):
                    raise ConfigError(f"{p}: table '{table}' does not have pathpref's "
                                      "columns; it is not a pathpref results database")
            check = ro.execute("PRAGMA quick_check").fetchone()[0]
        finally:
            ro.close()
    except sqlite3.Error as e:
        raise ConfigError(f"cannot read results database {p}: {e} (the file is damaged or "
                          "not a pathpref database)") from None
    if check != "ok":
        raise ConfigError(f"{p} is damaged (SQLite: {check}); give a new --db path (sqlite3's "
                          "'.recover' can copy what is intact)")
    return True

def _check_objects(path: Path, objects: list[tuple[str, str, str]]) -> None:
    """Refuse a file holding anything pathpref does not create (see _check_existing)."""
    ours = {"meta", "episodes", "steps"}
    foreign = [f"{kind} '{name}'" for kind, name, table in objects
               if not (kind == "table" and name in ours)
               and not (kind == "index" and name.startswith("sqlite_autoindex_")
                        and table in ours)]
    if foreign:
        raise ConfigError(f"{path} holds {', '.join(foreign[:3])}, which pathpref does "
                          "not write: it is not a pathpref results database (refused "
                          "untouched); give another --db path")
    if objects and {name for kind, name, _ in objects if kind == "table"} != ours:
        raise ConfigError(f"{path} is an SQLite file not written by pathpref (its "
                          "tables are not pathpref's); give another --db path")

def _check_schema(path: Path, found: int | None) -> None:
    """Refuse another schema version (an older one can be upgraded)."""
    if found is not None and 2 <= found < SCHEMA_VERSION:
        raise ConfigError(
            f"{path} was written by an older pathpref (schema {found}, this version "
            f"reads {SCHEMA_VERSION}); run 'pathpref db upgrade {path}' to migrate it"
        )
    if found != SCHEMA_VERSION:
        raise ConfigError(
            f"{path} was written by an incompatible pathpref (schema {found}, this "
            f"version reads {SCHEMA_VERSION}); use a new --db path"
        )


class ResultStore:
    """Open (or create) a results database at ``path``."""

    def __init__(self, path: str | Path, create: bool = True):
        self.path = Path(path)
        if not self.path.exists():
            if not create:
                raise ConfigError(f"no results database at {self.path}")
            parent = self.path.parent
            if not parent.is_dir():
                raise ConfigError(f"cannot create {self.path}: folder {parent} does not exist")
        existing = check_results_file(self.path)  # read-only: a refused file is untouched
        try:
            self.conn = sqlite3.connect(self.path, timeout=30)
            self.conn.execute("PRAGMA journal_mode=WAL")
            self.conn.execute("PRAGMA synchronous=NORMAL")
        except sqlite3.Error as e:
            raise ConfigError(f"cannot open results database {self.path}: {e}") from None
        if not existing:
            self._create_schema()

    def _create_schema(self) -> None:
        c = self.conn
        cols = ", ".join(f"{k} {t}" for k, t in EPISODE_COLUMNS.items())
        with c:
            c.execute("CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT)")
            c.execute("INSERT INTO meta VALUES ('schema_version', ?)", (str(SCHEMA_VERSION),))
            c.execute(f"CREATE TABLE episodes ({cols})")
            c.execute(
                "CREATE TABLE steps (key TEXT, t INTEGER, x INTEGER, y INTEGER, action INTEGER, "
                "heading INTEGER, p_true_goal REAL, goal_entropy REAL, PRIMARY KEY (key, t))"
            )

    def done_keys(self, include_failed: bool = True) -> set[str]:
        """Keys of the stored episodes (only successful runs when ``include_failed`` is False)."""
        q = "SELECT key FROM episodes" + ("" if include_failed else " WHERE status = 'ok'")
        return {r[0] for r in self.conn.execute(q)}

    def add(self, res: EpisodeResult) -> None:
        """Write one episode and its steps in one transaction (replacing a failed attempt)."""
        row = result_row(res)
        cols = list(EPISODE_COLUMNS)
        vals = [row.get(k) for k in cols]
        vals = [int(v) if isinstance(v, bool) else v for v in vals]
        key = row["key"]
        with self.conn:
            self.conn.execute("DELETE FROM steps WHERE key = ?", (key,))
            self.conn.execute(
                f"INSERT OR REPLACE INTO episodes ({', '.join(cols)}) "
                f"VALUES ({', '.join('?' for _ in cols)})",
                vals,
            )
            self.conn.executemany(
                "INSERT INTO steps VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                [(key, s.t, s.x, s.y, s.action, s.heading, s.p_true_goal, s.goal_entropy)
                 for s in res.log],
            )

    def episodes(self, where: str = "", params: Iterable[Any] = ()) -> list[dict[str, Any]]:
        """Episode rows (as dicts), optionally filtered by an SQL ``where`` with ``params``."""
        cur = self.conn.execute(f"SELECT * FROM episodes {where}", tuple(params))
        names = [d[0] for d in cur.description]
        return [dict(zip(names, r, strict=True)) for r in cur]

    def steps(self, key: str) -> list[dict[str, Any]]:
        """The per-step rows of episode ``key``, in step order."""
        cur = self.conn.execute("SELECT * FROM steps WHERE key = ? ORDER BY t", (key,))
        names = [d[0] for d in cur.description]
        return [dict(zip(names, r, strict=True)) for r in cur]

    def close(self) -> None:
        """Close the database connection."""
        self.conn.close()

    def __enter__(self) -> ResultStore:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def row_spec(row: dict[str, Any]) -> EpisodeSpec:
    """The :class:`EpisodeSpec` of a stored row: ``run_episode(row_spec(row))`` replays it."""
    names = {f.name for f in dataclasses.fields(EpisodeSpec)} - {"timeout_s"}
    spec = {k: row[k] for k in names}
    spec["normalize"], spec["coupling"] = bool(spec["normalize"]), bool(spec["coupling"])
    return EpisodeSpec(**spec)
