"""Paired sweep of the robust search's root pool on plans of several sizes: the fixed pool of 128
trees against the pool bounded by plan size (``POOL_POLYTOPE_TREES / P``,
:meth:`pathpref.planning.pomcp.POMCP.pool_size`).

For each plan (random floor plans with rotated obstacles and a loop preference, drawn from a
seed) the same episodes (instances, runs, seeds) run under both pools: the default preset,
path preference, ΔT = 5, 5000 queries. Printed and written as Markdown: the polytope count,
both pool sizes, the median CPU time of the first decision (instances' first decisions in this
process, after one warm-up), and per pool the goal-reached, homotopy-level and strict success
counts, each with its discordant pairs (episodes that succeed under one pool only: a sign
test's input).

    python scripts/pool_by_plan_size.py --instances 12 --out docs/results/pool_by_plan_size.md
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from pathpref.episode import EpisodeSpec  # noqa: E402
from pathpref.episode.runner import EpisodeRunner  # noqa: E402
from pathpref.experiments.sweep import run_sweep, sweep_specs  # noqa: E402
from pathpref.geometry.generate import random_floor_plan, with_loop_preference  # noqa: E402
from pathpref.geometry.maps import load_map  # noqa: E402
from pathpref.geometry.world import World  # noqa: E402
from pathpref.planning import pomcp  # noqa: E402

#: (width, height, rotated obstacles) of the plans, seed 1 each
PLANS = ((24, 16, 7), (32, 32, 16), (40, 40, 32))
FIXED = 10**12  # POOL_POLYTOPE_TREES that leaves the pool at TREE_POOL on any plan


def first_decision_ms(path: str, instances: int) -> float:
    """Median CPU ms of the first decision (robust-check, 5000 queries) over ``instances``."""
    t_max = load_map(path).t_max
    times = []
    for i in range(instances + 1):
        ep = EpisodeSpec(map=path, method="path_preference", delta_t=5, instance=i, run=0,
                         instance_seed=100 + i, run_seed=7, queries=5000, t_max=t_max,
                         preset="robust-check")
        runner = EpisodeRunner(ep)
        c = time.process_time()
        runner.step()
        times.append((time.process_time() - c) * 1000)
    return statistics.median(times[1:])  # the first one warms the compiled kernels


def outcomes(db: str) -> dict[str, tuple[int, int, int]]:
    """key -> (goal_reached, homotopy_success, success) of the ``ok`` rows of ``db``."""
    import sqlite3

    with sqlite3.connect(db) as c:
        return {k: (g, h or 0, s) for k, g, h, s in c.execute(
            "SELECT key, goal_reached, homotopy_success, success FROM episodes "
            "WHERE status = 'ok'")}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--instances", type=int, default=12)
    ap.add_argument("--runs", type=int, default=1)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    lines = ["| plan | P | pool 128 -> by size | first decision ms (128 / by size) | n | "
             "goal reached (128 / by size; only 128, only by size) | homotopy | strict |",
             "|---|---|---|---|---|---|---|---|"]
    with tempfile.TemporaryDirectory() as tmp:
        for w, h, n in PLANS:
            name = f"r{w}x{h}"
            path = os.path.join(tmp, f"{name}.json")
            Path(path).write_text(json.dumps(with_loop_preference(
                random_floor_plan(w, h, n, seed=1, name=name))))
            P = World.from_spec(load_map(path)).n_polytopes
            specs = sweep_specs(path, ["path_preference"], [5], args.instances, args.runs,
                                seed=11, queries=5000)
            res, ms, pools = {}, {}, {}
            for arm, trees in (("fixed", FIXED), ("sized", pomcp.POOL_POLYTOPE_TREES)):
                saved = pomcp.POOL_POLYTOPE_TREES
                pomcp.POOL_POLYTOPE_TREES = trees  # inherited by the forked workers
                try:
                    pools[arm] = min(pomcp.TREE_POOL, -(-5000 // pomcp.SIMS_PER_TREE),
                                     max(pomcp.POOL_MIN, -(-trees // P)))
                    ms[arm] = first_decision_ms(path, 5)
                    db = os.path.join(tmp, f"{name}-{arm}.sqlite")
                    run_sweep(specs, db, workers=args.workers, progress=False)
                    res[arm] = outcomes(db)
                finally:
                    pomcp.POOL_POLYTOPE_TREES = saved
            keys = sorted(set(res["fixed"]) & set(res["sized"]))
            cells = []
            for j in range(3):
                a = [res["fixed"][k][j] for k in keys]
                b = [res["sized"][k][j] for k in keys]
                only_a = sum(x > y for x, y in zip(a, b, strict=True))
                only_b = sum(y > x for x, y in zip(a, b, strict=True))
                cells.append(f"{sum(a)} / {sum(b)}; {only_a}, {only_b}")
            row = (f"| {w} x {h}, {n} rotated | {P} | {pools['fixed']} -> {pools['sized']} | "
                   f"{ms['fixed']:.1f} / {ms['sized']:.1f} | {len(keys)} | "
                   + " | ".join(cells) + " |")
            print(row, flush=True)
            lines.append(row)
    if args.out:
        Path(args.out).write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
