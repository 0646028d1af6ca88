"""The outcome tables of docs/robust.md: per method and ΔT, success / goal reached /
back-crossings per episode (and the oracle's share), from one or more results databases of
``pathpref evaluate``.

    .venv/bin/python scripts/outcome_table.py results/office_paper_consistent.sqlite \\
        results/office_robust_consistent.sqlite

One column block per database (labelled by its preset), one row per method; an episode whose
status is not ``ok`` (it failed to run) counts as a failure (no success, no goal) and the
number of them is given below the table; ``--exclude-failed`` leaves them out of the rates
instead. ``--ci`` adds the 95 % Wilson interval of each success rate. A second table splits
each cell's failures by why they failed (:mod:`pathpref.experiments.outcomes`).
"""

from __future__ import annotations

import argparse
import sqlite3
import sys
from pathlib import Path

from pathpref.experiments.outcomes import failure_split
from pathpref.experiments.report import wilson

ORDER = ("compliant", "goal_only", "path_preference", "blended", "hindsight", "goal_known",
         "oracle")
LABEL = {"goal_only": "goal only", "path_preference": "path preference",
         "blended": "path preference + blend", "hindsight": "hindsight optimisation"}


def why(db: Path, exclude_failed: bool = False) -> dict[tuple[str, int], dict[str, int]]:
    """``{(method, ΔT): failure split}`` of ``db`` (time-out, wrong side, out-of-order
    crossing, not run: :func:`pathpref.experiments.outcomes.failure_split`)."""
    con = sqlite3.connect(f"file:{db}?mode=ro", uri=True)
    con.row_factory = sqlite3.Row
    try:
        rows = [dict(r) for r in con.execute("SELECT * FROM episodes WHERE status != 'running'")]
    finally:
        con.close()
    groups: dict[tuple[str, int], list[dict]] = {}
    for r in rows:
        groups.setdefault((r["method"], r["delta_t"]), []).append(r)
    return {k: failure_split(v, exclude_failed) for k, v in groups.items()}


def cells(db: Path, exclude_failed: bool = False
          ) -> tuple[str, dict[tuple[str, int], tuple[int, int, int, int]], int]:
    """``(preset, {(method, ΔT): (n, successes, goals reached, back-crossings)}, not ok)``;
    ``n`` counts the rows that are not ok too (as failures) unless ``exclude_failed``."""
    con = sqlite3.connect(f"file:{db}?mode=ro", uri=True)
    ok = "status = 'ok'"
    try:
        rows = con.execute(
            f"SELECT preset, method, delta_t, count(*), sum(success * ({ok})), "
            f"sum(goal_reached * ({ok})), sum(back_crossings * ({ok})) FROM episodes "
            + (f"WHERE {ok} " if exclude_failed else "")
            + "GROUP BY preset, method, delta_t").fetchall()
        bad = con.execute("SELECT count(*) FROM episodes WHERE status != 'ok'").fetchone()[0]
    finally:
        con.close()
    presets = {r[0] for r in rows}
    if len(presets) != 1:
        raise SystemExit(f"{db}: expected one preset, found {sorted(presets)}")
    return presets.pop(), {(m, dt): (n, s, g, b) for _, m, dt, n, s, g, b in rows}, bad


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dbs", nargs="+", type=Path)
    ap.add_argument("--ci", action="store_true", help="add the success rate's 95%% interval")
    ap.add_argument("--exclude-failed", action="store_true",
                    help="leave episodes that failed to run out of the rates (by default each "
                    "counts as a failure)")
    args = ap.parse_args(argv)
    blocks = [cells(db, args.exclude_failed) for db in args.dbs]
    cols = [(preset, dt) for preset, c, _ in blocks for dt in sorted({dt for _, dt in c})]
    print("| method | " + " | ".join(f"{p} ΔT={dt}" for p, dt in cols) + " |")
    print("|---" * (len(cols) + 1) + "|")
    methods = [m for m in ORDER if any(k[0] == m for _, c, _ in blocks for k in c)]
    for m in methods:
        out = []
        for _, c, _ in blocks:
            for dt in sorted({d for _, d in c}):
                if (m, dt) not in c:
                    out.append("-")
                    continue
                n, s, g, b = c[(m, dt)]
                cell = f"{s / n:.2f} / {g / n:.2f} / {b / n:.2f}"
                if args.ci:
                    lo, hi = wilson(s, n)
                    cell += f" [{lo:.2f}, {hi:.2f}]"
                out.append(cell)
        print(f"| {LABEL.get(m, m)} | " + " | ".join(out) + " |")
    sizes = sorted({c[k][0] for _, c, _ in blocks for k in c})
    bad = sum(b for _, _, b in blocks)
    print(f"\nsuccess / goal reached / back-crossings per episode; n = {sizes} per cell"
          + f"; {bad} failed episodes, "
          + ("left out" if args.exclude_failed else "counted as failures"))
    splits = [why(db, args.exclude_failed) for db in args.dbs]
    print("\n| why failed | " + " | ".join(f"{p} ΔT={dt}" for p, dt in cols) + " |")
    print("|---" * (len(cols) + 1) + "|")
    for m in methods:
        out = []
        for (_, c, _), split in zip(blocks, splits, strict=True):
            for dt in sorted({d for _, d in c}):
                f = split.get((m, dt))
                out.append("-" if f is None else
                           f"{f['time_out']} / {f['wrong_side']} / {f['out_of_order']}"
                           + (f" (+{f['not_run']} not run)" if f["not_run"] else "")
                           + (f" (+{f['unclassified']} unclassified)" if f["unclassified"]
                              else ""))
        print(f"| {LABEL.get(m, m)} | " + " | ".join(out) + " |")
    print("\nfailed episodes: time-out / wrong side (goal reached the other way round) / "
          "out-of-order crossing (right way round, a polytope left by a face the preference "
          "forbids); unclassified: no homotopy_success stored (an older row)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
