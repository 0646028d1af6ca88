"""``pathpref db upgrade``: migrate an older results database to the current schema.

Schema 2 keyed an episode by its map's *path*; schema 3 keys it by the map's content hash
(:attr:`pathpref.geometry.maps.MapSpec.content_hash`) and stores that hash in a ``map_hash``
column. The upgrade reads every row of the old file, loads each map it names (``--map OLD=NEW``
points a stored name at a file that has moved), recomputes the key of each episode under the
current :class:`~pathpref.experiments.episode.EpisodeSpec` (fields the old schema lacks take their
defaults, which reproduce the old behaviour), and writes a new file with every episode and step.
Rows of one map stored under two paths become one episode when everything else agrees; the row
kept is the first successful one. The old file is kept beside the new one as
``NAME.schema2.bak``; nothing is changed when any map cannot be loaded.
"""

from __future__ import annotations

import dataclasses
import os
import sqlite3
import tempfile
from pathlib import Path
from typing import Any

from ..errors import ConfigError, PathprefError
from .episode import EpisodeSpec, cached_map
from .store import (
    EPISODE_COLUMNS,
    SCHEMA_VERSION,
    UPGRADABLE,
    ResultStore,
    damaged,
    inspect_results_file,
    open_readonly,
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
    names = {f.name for f in dataclasses.fields(EpisodeSpec)} - {"timeout_s"}
    fields = {k: row[k] for k in names if k in row and row[k] is not None}
    fields["map"] = map_paths.get(row["map"], row["map"])
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
        return {"from": version, "to": version, "episodes": len(rows), "merged": 0,
                "backup": None}
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
        kept[key] = {**row, **dataclasses.asdict(spec), "key": key, "map_hash": spec.map_hash}
    backup = path.with_name(path.name + f".schema{version}.bak")
    if backup.exists():
        raise ConfigError(f"{backup} exists; move it away before upgrading {path}")
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.", suffix=".upgrade")
    os.close(fd)
    os.unlink(tmp)  # ResultStore creates the file itself
    try:
        store = ResultStore(tmp)
        cols = list(EPISODE_COLUMNS)
        with store.conn:
            store.conn.executemany(
                f"INSERT INTO episodes ({', '.join(cols)}) VALUES ({', '.join('?' * len(cols))})",
                [[_plain(r.get(c)) for c in cols] for r in kept.values()])
            store.conn.executemany(
                "INSERT INTO steps VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                [(new_key[s[0]], *s[1:]) for s in steps if s[0] in new_key])
            n_steps = store.conn.execute("SELECT COUNT(*) FROM steps").fetchone()[0]
        store.conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
        store.conn.execute("PRAGMA journal_mode=DELETE")
        store.close()
        os.replace(path, backup)
        os.replace(tmp, path)
    finally:
        for side in (tmp, tmp + "-wal", tmp + "-shm"):
            if os.path.exists(side):
                os.unlink(side)
    return {"from": version, "to": SCHEMA_VERSION, "episodes": len(kept), "steps": n_steps,
            "merged": len(rows) - len(kept), "backup": str(backup)}


def _plain(v: Any) -> Any:
    return int(v) if isinstance(v, bool) else v
