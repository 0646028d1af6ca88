"""Success against planning time: the robust planner under wall-time budgets.

    .venv/bin/python scripts/budget_figure.py --out docs/budget.png

For every map and budget ``B`` (ms per decision) one ``pathpref evaluate --preset robust
--time-budget-ms B`` sweep (goal only and path preference, consistent human) is written to
``DB_DIR/<map>_<B>ms.sqlite`` (resumable: rerun after a crash and finished episodes are
skipped); the query cap is high enough that the budget, not the count, ends every search. Then,
per map and budget, the number of queries the search completes at a first decision (median
over 5 random instances, after one push, route prior) is measured in this process, and the
figure (success with Wilson 95 % intervals against the budget, log scale, one panel per map)
and a JSON of every point are written. Budgets are wall time: the figure depends on the
machine and on what else runs on it (the JSON records the queries actually run).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path
from statistics import median

os.environ.setdefault("MUJOCO_GL", "disable")

import numpy as np  # noqa: E402

from pathpref.experiments.report import load_records  # noqa: E402
from pathpref.geometry.maps import load_map  # noqa: E402
from pathpref.geometry.world import World  # noqa: E402
from pathpref.inference.human import ObservationModel  # noqa: E402
from pathpref.inference.routes import RouteBelief  # noqa: E402
from pathpref.planning.pomcp import POMCP  # noqa: E402
from pathpref.planning.pomdp import get_preset  # noqa: E402
from pathpref.viz.plots import budget_figure  # noqa: E402

#: the search's query cap under a budget (rows are allocated, not touched, up front)
QUERY_CAP = 1_000_000


def queries_within(map_name: str, budget_ms: float, n: int = 5) -> float:
    """Median queries the robust path-preference search completes in ``budget_ms`` at a first
    decision (depth T_max, one push seen) over ``n`` random instances."""
    world = World.from_spec(load_map(map_name))
    robust = get_preset("robust")
    rng = np.random.default_rng(0)
    done = []
    for i in range(n + 1):
        goals = rng.choice(world.n_cells, size=10, replace=False)
        start = int(rng.integers(world.n_cells))
        model = ObservationModel.build(world, goals)
        belief = RouteBelief(model)
        belief.update(start, int(rng.integers(8)))
        planner = POMCP(world, goals, robust.path_preference.for_mission(world.spec.t_max),
                        queries=QUERY_CAP, tables=model.tables, budget_ms=budget_ms)
        res = planner.search(start, belief, world.spec.t_max, seed=i)
        if i > 0:  # the first search loads the compiled kernel
            done.append(res.queries)
    return float(median(done))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--maps", nargs="+", default=["simple", "office"])
    ap.add_argument("--budgets", nargs="+", type=float, default=[1, 5, 20, 100])
    ap.add_argument("--delta-t", type=int, default=5)
    ap.add_argument("--instances", type=int, default=6)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--db-dir", default="results/budget")
    ap.add_argument("--out", default="docs/budget.png")
    args = ap.parse_args(argv)
    pathpref = str(Path(sys.executable).with_name("pathpref"))
    Path(args.db_dir).mkdir(parents=True, exist_ok=True)
    points = []
    for m in args.maps:
        for b in args.budgets:
            db = Path(args.db_dir) / f"{Path(m).stem}_{b:g}ms.sqlite"
            subprocess.run([pathpref, "evaluate", "--map", m, "--preset", "robust", "--human",
                            "consistent", "--methods", "goal_only", "path_preference",
                            "--delta-t", str(args.delta_t), "--time-budget-ms", f"{b:g}",
                            "--queries", str(QUERY_CAP), "--instances", str(args.instances),
                            "--runs", str(args.runs), "--db", str(db), "--no-progress"],
                           check=True, stdout=subprocess.DEVNULL)
            q = queries_within(m, b)
            for r in load_records(db):
                points.append({"map": Path(m).stem, "budget_ms": b, "method": r["method"],
                               "n": r["n"], "success": r["success_rate"],
                               "ci": [r["ci_low"], r["ci_high"]], "queries": q})
                print(f"{m} {b:g} ms {r['method']}: {r['success_rate']:.2f} "
                      f"[{r['ci_low']:.2f}, {r['ci_high']:.2f}] (n = {r['n']}, "
                      f"{q:.0f} queries at a first decision)", flush=True)
    budget_figure(points, args.out)
    Path(args.out).with_suffix(".json").write_text(json.dumps(points, indent=1))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
