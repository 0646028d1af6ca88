"""What a sharded sweep costs to store, merge and read: bytes per episode, `db merge` CPU per
episode (all shards at once, or pairwise in a tree), and reading the shards together without
merging them (docs/experiments.md, "A 1M-episode run").

    python scripts/merge_cost.py [--shards 4] [--per-shard 1000] [--out merge_cost.json]

The shards hold synthetic results as ``coordinator_episodes_per_s`` writes them: one compliant
``classroom`` episode (61 steps) copied under ``shards x per-shard`` keys, written a chunk of
16 at a time, with the per-step rows (``steps``) and without (``no_steps``). Times are CPU
seconds of this process (``time.process_time``; SQLite runs in it), wall beside them.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path


def write_shards(tmp: Path, shards: int, per_shard: int, steps: bool) -> list[Path]:
    """``shards`` databases of ``per_shard`` synthetic episodes each (disjoint keys)."""
    from pathpref.episode import run_episode
    from pathpref.experiments.backends import failed
    from pathpref.experiments.store import ResultStore
    from pathpref.experiments.sweep import sweep_specs

    spec = sweep_specs("classroom", ["compliant"], [5], instances=1, runs=1, queries=200)[0]
    res = run_episode(spec)
    paths = []
    for s in range(shards):
        path = tmp / f"shard-{s}{'' if steps else '-ns'}.sqlite"
        results = [replace(res, spec=replace(spec, run=s * per_shard + i))
                   for i in range(per_shard)]
        with ResultStore(path, steps=steps) as store:
            for i in range(0, per_shard, 16):
                part = results[i:i + 16]
                store.claim_many([failed(r.spec, "") for r in part])
                store.add_many(part)
            store.conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
        paths.append(path)
    return paths


def timed(fn):
    """``fn()``'s value, CPU seconds and wall seconds."""
    c, t = time.process_time(), time.perf_counter()
    v = fn()
    return v, time.process_time() - c, time.perf_counter() - t


def size(path: Path) -> int:
    """Bytes of a database file with its write-ahead log folded in."""
    import sqlite3

    with sqlite3.connect(path) as conn:
        conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    return os.path.getsize(path)


def measure(tmp: Path, shards: int, per_shard: int, steps: bool) -> dict[str, float]:
    """Bytes per episode, flat and tree merges, and a report read over the shards."""
    from itertools import chain

    from pathpref.experiments.migrate import merge_databases
    from pathpref.experiments.report import load_records, success_table
    from pathpref.experiments.store import ResultStore

    n = shards * per_shard
    paths = write_shards(tmp, shards, per_shard, steps)
    tag = "" if steps else "-ns"
    out: dict[str, float] = {"episodes": n,
                             "shard_bytes_per_episode": sum(map(size, paths)) / n}
    flat = tmp / f"flat{tag}.sqlite"
    r, cpu, wall = timed(lambda: merge_databases(flat, paths))
    assert r["episodes"] == n and r["conflicts"] == 0
    out.update(merged_bytes_per_episode=size(flat) / n,
               flat_merge_cpu_ms_per_episode=1e3 * cpu / n,
               flat_merge_wall_ms_per_episode=1e3 * wall / n)
    # a tree: pairs merged level by level until one file is left
    level, cpu_sum, wall_sum, written, depth = list(paths), 0.0, 0.0, 0, 0
    while len(level) > 1:
        depth += 1
        nxt = []
        for j in range(0, len(level), 2):
            pair = level[j:j + 2]
            if len(pair) == 1:
                nxt.append(pair[0])
                continue
            dst = tmp / f"tree{tag}-{depth}-{j // 2}.sqlite"
            _, c, w = timed(lambda dst=dst, pair=pair: merge_databases(dst, pair))
            cpu_sum, wall_sum, written = cpu_sum + c, wall_sum + w, written + size(dst)
            nxt.append(dst)
        level = nxt
    out.update(tree_levels=depth, tree_merge_cpu_ms_per_episode=1e3 * cpu_sum / n,
               tree_merge_wall_ms_per_episode=1e3 * wall_sum / n,
               tree_bytes_written_per_episode=written / n)
    # Table I from the merged file, and from the shards read together (no merge): the same
    merged, cpu_m, _ = timed(lambda: load_records(flat))

    def together():
        stores = [ResultStore(p, create=False) for p in paths]
        try:
            return success_table(list(chain.from_iterable(s.episodes() for s in stores)))
        finally:
            for s in stores:
                s.close()

    joint, cpu_j, _ = timed(together)
    same = json.dumps(joint, default=str) == json.dumps(merged, default=str)  # NaN == NaN
    assert same, "the shards read together differ from the merged file"
    out.update(report_merged_cpu_ms_per_episode=1e3 * cpu_m / n,
               report_shards_together_cpu_ms_per_episode=1e3 * cpu_j / n)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--shards", type=int, default=4, help="shards (default 4)")
    ap.add_argument("--per-shard", type=int, default=1000, help="episodes per shard "
                    "(default 1000)")
    ap.add_argument("--out", default=None, help="also write the figures to this JSON file")
    args = ap.parse_args(argv)
    if not (2 <= args.shards <= 64 and 16 <= args.per_shard <= 100_000):
        print("--shards must be 2..64 and --per-shard 16..100000", file=sys.stderr)
        return 2
    res = {}
    with tempfile.TemporaryDirectory() as tmp:
        for steps in (True, False):
            res["steps" if steps else "no_steps"] = measure(Path(tmp), args.shards,
                                                            args.per_shard, steps)
    text = json.dumps(res, indent=1)
    print(text)
    if args.out:
        Path(args.out).write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
