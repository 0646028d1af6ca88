"""Helpers for the results-store tests: small synthetic databases and directory snapshots."""

from __future__ import annotations

import os
import sqlite3
from pathlib import Path

from pathpref.experiments.store import EPISODE_COLUMNS, ResultStore

BASE = {"map": "simple", "map_hash": "h0", "sim": "grid", "task": "navigate", "run": 0,
        "preset": "paper", "queries": 100, "t_max": 30, "n_goals": 10, "normalize": 1,
        "coupling": 1, "fixed": "", "start": "[0, 0]", "goals": "[[1, 1]]", "true_goal": 0,
        "status": "ok", "reason": "", "pref_followed": 1, "inputs": 1, "violations": 0,
        "wall_s": 0.1, "ucb_c": 1.0, "metrics": "{}", "time_budget_ms": 0.0, "human": "map",
        "back_crossings": 0, "physics": "", "prior": "independent", "push_rule": "",
        "slack": 20}


def synthetic_db(path: str | Path, cells: dict[tuple[str, int], tuple[int, int]],
                 steps: int = 5) -> Path:
    """A results database with, per ``(method, delta_t)`` cell, ``n`` episodes of which ``k``
    succeed (``cells[(method, dt)] = (k, n)``), each with its ``steps + 1`` step rows."""
    with ResultStore(path) as st, st.conn:
        cols = list(EPISODE_COLUMNS)
        for (method, dt), (k, n) in cells.items():
            for i in range(n):
                key = f"{method}-{dt}-{i:04d}-" + "k" * 40
                row = {**BASE, "key": key, "method": method, "delta_t": dt, "instance": i,
                       "instance_seed": i, "run_seed": 1000 + i, "success": int(i < k),
                       "goal_reached": int(i < k), "homotopy_success": int(i < k),
                       "steps": steps}
                st.conn.execute(f"INSERT INTO episodes ({', '.join(cols)}) VALUES "
                                f"({', '.join('?' * len(cols))})", [row[c] for c in cols])
                st.conn.executemany("INSERT INTO steps VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
                                    [(key, t, t, 0, 1, -1, 0.5, 1.0, int(t == 0))
                                     for t in range(steps + 1)])
    return Path(path)


def snapshot(folder: str | Path) -> dict[str, tuple]:
    """Names, sizes, mtimes and bytes of every regular file in ``folder``."""
    out = {}
    for name in sorted(os.listdir(folder)):
        p = Path(folder) / name
        st = p.lstat()
        out[name] = (st.st_size, st.st_mtime_ns,
                     p.read_bytes() if p.is_file() and not p.is_symlink() else None)
    return out


def leaf_page_of(path: str | Path, table: str, which: int = 1) -> int:
    """Page number of the ``which``-th leaf page of ``table`` (for corrupting it)."""
    with sqlite3.connect(f"file:{path}?mode=ro&immutable=1", uri=True) as c:
        pages = [r[0] for r in c.execute(
            "SELECT pageno FROM dbstat WHERE name = ? AND pagetype = 'leaf' ORDER BY pageno",
            (table,))]
    c.close()
    return pages[which]


def corrupt_page(path: str | Path, pageno: int) -> None:
    """Overwrite page ``pageno`` (1-based) of an SQLite file with garbage."""
    with sqlite3.connect(f"file:{path}?mode=ro&immutable=1", uri=True) as c:
        size = c.execute("PRAGMA page_size").fetchone()[0]
    c.close()
    with open(path, "r+b") as f:
        f.seek((pageno - 1) * size)
        f.write(bytes((i * 37 + 11) % 256 for i in range(size)))
