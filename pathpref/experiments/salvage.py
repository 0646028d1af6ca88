"""Damage reports and rescue of results databases (``pathpref db check``, ``db salvage``).

Both read the file on an immutable read-only connection (nothing is written beside it).
:func:`damage_report` reports whether the file is pathpref's (:class:`.store.ResultStore`'s
rules), SQLite's ``integrity_check``, the rows, episodes without step rows and step rows
without an episode. :func:`salvage` copies every episode that can still be read whole (its row
and its step rows) into a new database, row by row, so a damaged page costs only the rows on it.
"""

from __future__ import annotations

import sqlite3
from pathlib import Path
from typing import Any
from urllib.parse import quote

from ..errors import ConfigError, PathprefError
from .store import EPISODE_COLUMNS, STEP_COLUMNS, ResultStore, check_results_file


def _readonly(path: str | Path) -> sqlite3.Connection:
    p = Path(path)
    if not p.is_file():
        raise ConfigError(f"no results database at {p} (not a regular file)")
    wal = "" if Path(f"{p}-wal").exists() else "&immutable=1"
    return sqlite3.connect(f"file:{quote(str(p.resolve()))}?mode=ro{wal}", uri=True)


def _try(conn: sqlite3.Connection, sql: str, args: tuple = ()) -> list | None:
    try:
        return conn.execute(sql, args).fetchall()
    except sqlite3.DatabaseError:
        return None


def damage_report(path: str | Path) -> dict[str, Any]:
    """What is wrong with ``path``, if anything: ``{"intact": bool, "problems": [...], ...}``."""
    problems: list[str] = []
    try:
        check_results_file(path)
    except PathprefError as e:
        problems.append(str(e))
    conn = _readonly(path)
    try:
        integrity = _try(conn, "PRAGMA integrity_check")
        integrity = ["unreadable"] if integrity is None else [r[0] for r in integrity]
        if integrity != ["ok"]:
            problems.append("integrity_check: " + "; ".join(integrity[:5]))
        n_ep = _try(conn, "SELECT COUNT(*) FROM episodes")
        n_st = _try(conn, "SELECT COUNT(*) FROM steps")
        no_steps = _try(conn, "SELECT COUNT(*) FROM episodes WHERE status = 'ok' AND key NOT IN "
                              "(SELECT key FROM steps)")
        orphans = _try(conn, "SELECT COUNT(*) FROM steps WHERE key NOT IN "
                             "(SELECT key FROM episodes)")
        schema = _try(conn, "SELECT value FROM meta WHERE key = 'schema_version'")
    finally:
        conn.close()
    for what, rows in (("episodes", n_ep), ("steps", n_st)):
        if rows is None:
            problems.append(f"the {what} table cannot be read")
    if no_steps and no_steps[0][0]:
        problems.append(f"{no_steps[0][0]} finished episodes have no step rows")
    if orphans and orphans[0][0]:
        problems.append(f"{orphans[0][0]} step rows belong to no episode")
    return {"intact": not problems, "problems": problems,
            "schema": schema[0][0] if schema else None,
            "episodes": n_ep[0][0] if n_ep else None, "steps": n_st[0][0] if n_st else None}


def salvage(path: str | Path, out: str | Path) -> dict[str, int]:
    """Copy every episode of ``path`` whose row and step rows read whole into a new pathpref
    database ``out`` (which must not exist). Returns ``{"saved", "lost", "steps"}``."""
    out = Path(out)
    if out.exists():
        raise ConfigError(f"{out} exists; salvage writes a new database, give another path")
    src = _readonly(path)
    try:
        top = _try(src, "SELECT MAX(rowid) FROM episodes")
        last = top[0][0] if top and top[0][0] is not None else 0
        if top is None:  # the table's root is damaged: probe rowids until a long gap
            last = 10**6
        cols = ", ".join(EPISODE_COLUMNS)
        saved = lost = steps = misses = 0
        with ResultStore(out) as dst:
            for rowid in range(1, last + 1):
                row = _try(src, f"SELECT {cols} FROM episodes WHERE rowid = ?", (rowid,))
                if row is None:
                    lost += 1
                    continue
                if not row:
                    misses += 1
                    if top is None and misses > 10_000:
                        break
                    continue
                misses = 0
                key = row[0][0]
                st = _try(src, f"SELECT {', '.join(STEP_COLUMNS)} FROM steps WHERE key = ? "
                               "ORDER BY t", (key,))
                if st is None:
                    lost += 1
                    continue
                with dst.conn:
                    dst.conn.execute(f"INSERT INTO episodes ({cols}) VALUES "
                                     f"({', '.join('?' for _ in EPISODE_COLUMNS)})", row[0])
                    dst.conn.executemany(f"INSERT INTO steps VALUES "
                                         f"({', '.join('?' for _ in STEP_COLUMNS)})", st)
                saved += 1
                steps += len(st)
    finally:
        src.close()
    return {"saved": saved, "lost": lost, "steps": steps}
