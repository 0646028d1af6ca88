"""Methods on floor plans drawn for the test: strict, homotopy-level and goal-reached success
with Wilson 95 % intervals, why episodes failed, and success by time slack.

    .venv/bin/python scripts/heldout_eval.py --open 9401 9402 9403 9404 --loop 9501 9502 9503 \\
        --presets robust-slack robust-check --methods path_preference goal_only blended oracle \\
        --delta-t 1 5 --instances 4 --runs 5 --db heldout.sqlite \\
        --out docs/results/heldout_slack.md

**Plans.** ``--open`` and ``--loop`` seeds give floor plans of
:func:`scripts.homotopy_prior_eval.held_out_plan` (24 x 16, 7 rotated rectangles and 2 boxes,
sizes 1.5..4; an open preferred route through four waypoints, or a loop round the map), written
to ``--plans``. A held-out set is drawn *after* the design it tests was frozen, and never used
to choose a setting.

Every episode has the consistent human (``--human consistent``; instance ``i``, run ``r`` of
``pathpref evaluate --seed 0``), so the presets and methods see the same instances and human
draws. ``path_preference`` runs under each ``--presets``; the other methods under the first.
The episodes run through the project's sweep into ``--db`` (resumable).

**Why an episode failed**: *time-out* (goal not reached), *wrong side* (reached, not in the
human route's homotopy class), *out of order* (reached, homotopic, a transition against the
preference), *not run* (the episode did not run: a failure on every measure), as
:func:`pathpref.experiments.outcomes.failure_kind` sorts them. **Slack**: the stored ``slack``
of each episode, ``T_max`` minus the moves of the human's route to the true goal (the
oracle's), in the bins of :data:`pathpref.experiments.outcomes.SLACK_BINS`.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections import defaultdict
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "disable")
sys.path.insert(0, str(Path(__file__).resolve().parent))

from homotopy_prior_eval import held_out_plan  # noqa: E402

from pathpref.experiments.outcomes import (  # noqa: E402
    SLACK_BINS,
    failure_split,
    slack_bin,
)
from pathpref.experiments.report import wilson  # noqa: E402
from pathpref.experiments.store import ResultStore  # noqa: E402
from pathpref.experiments.sweep import run_sweep, sweep_specs  # noqa: E402


def rate(k: int, n: int) -> str:
    """``k / n`` with its Wilson 95 % interval."""
    lo, hi = wilson(k, n)
    return f"{k / n:.2f} [{lo:.2f}, {hi:.2f}]"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--open", nargs="*", type=int, default=[], help="open-route plan seeds")
    ap.add_argument("--loop", nargs="*", type=int, default=[], help="loop-route plan seeds")
    ap.add_argument("--maps", nargs="*", default=[], help="more maps (names or files)")
    ap.add_argument("--plans", type=Path, default=Path("heldout_plans"))
    ap.add_argument("--presets", nargs="+", default=["robust-slack"])
    ap.add_argument("--methods", nargs="+", default=["path_preference", "goal_only"])
    ap.add_argument("--delta-t", nargs="+", type=int, default=[1, 5])
    ap.add_argument("--instances", type=int, default=4)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--db", default="heldout.sqlite")
    ap.add_argument("--out", type=Path)
    args = ap.parse_args(argv)
    args.plans.mkdir(parents=True, exist_ok=True)
    maps = list(args.maps)
    for kind, seeds in (("open", args.open), ("loop", args.loop)):
        for seed in seeds:
            path = args.plans / f"heldout_{kind}_{seed}.json"
            path.write_text(json.dumps(held_out_plan(seed, kind), indent=1))
            maps.append(str(path))
    specs = []
    for m in maps:
        for i, preset in enumerate(args.presets):
            methods = [x for x in args.methods if x == "path_preference" or i == 0]
            specs += sweep_specs(m, methods, args.delta_t, args.instances, args.runs, seed=0,
                                 human="consistent", preset=preset)
    run_sweep(specs, args.db, workers=args.workers)
    wanted = {s.key() for s in specs}
    cells: dict = defaultdict(list)
    with ResultStore(args.db, create=False) as store:
        for r in store.episodes():
            if r["key"] not in wanted:
                continue
            label = r["method"] if r["method"] != "path_preference" else \
                f"path_preference ({r['preset']})"
            cells[(r["delta_t"], label)].append(dict(r))
    lines = [f"{len(maps)} plans, {args.instances} instances x {args.runs} runs, consistent "
             "human; 95% Wilson intervals", "",
             "| ΔT | method | n | strict | homotopy-level | goal reached | time-out | wrong side "
             "| out of order | not run |", "|---|---|---|---|---|---|---|---|---|---|"]
    for (dt, label), rows in sorted(cells.items()):
        n = len(rows)
        split = failure_split(rows)
        ok = [r for r in rows if r["status"] == "ok"]
        lines.append(f"| {dt} | {label} | {n} | {rate(sum(r['success'] for r in ok), n)} | "
                     f"{rate(sum(r['homotopy_success'] for r in ok), n)} | "
                     f"{rate(sum(r['goal_reached'] for r in ok), n)} | "
                     + " | ".join(str(split[k]) for k in
                                  ("time_out", "wrong_side", "out_of_order", "not_run"))
                     + " |")
    labels = [label for _, label, *_ in SLACK_BINS]
    lines += ["", "Goal reached / strict success by slack (T_max minus the moves of the "
              "human's route, the oracle's; `pathpref.experiments.outcomes.SLACK_BINS`), "
              "n per bin:", "",
              "| ΔT | method | " + " | ".join(labels) + " |",
              "|---|---|" + "---|" * len(labels)]
    for (dt, label), rows in sorted(cells.items()):
        bins: dict = defaultdict(list)
        for r in rows:
            bins[slack_bin(r.get("slack"))].append(r)
        parts = []
        for key, *_ in SLACK_BINS:
            rs = bins.get(key, [])
            ok = [r for r in rs if r["status"] == "ok"]
            parts.append(f"{sum(r['goal_reached'] for r in ok)} / "
                         f"{sum(r['success'] for r in ok)} of {len(rs)}" if rs else "-")
        lines.append(f"| {dt} | {label} | " + " | ".join(parts) + " |")
    text = "\n".join(lines) + "\n"
    print(text)
    if args.out:
        args.out.write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
