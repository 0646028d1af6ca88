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
preference), *error* (the episode did not run: a failure on every measure). **Slack**:
``T_max`` minus the length of the route that follows the human's preference to the true goal
(the oracle's), in bins ``< 10, 10-19, 20-39, >= 40`` steps.
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

from pathpref.episode.instances import consistent_reach  # noqa: E402
from pathpref.experiments.report import wilson  # noqa: E402
from pathpref.experiments.store import ResultStore  # noqa: E402
from pathpref.experiments.sweep import run_sweep, sweep_specs  # noqa: E402
from pathpref.geometry.world import load_world  # noqa: E402

#: the slack bins' lower edges (steps)
SLACK_BINS = (0, 10, 20, 40)


def slack_bin(slack: float) -> str:
    """The bin label of ``slack`` (:data:`SLACK_BINS`)."""
    edges = [*SLACK_BINS[1:], float("inf")]
    if slack < SLACK_BINS[1]:
        return f"<{SLACK_BINS[1]}"
    for lo, hi in zip(SLACK_BINS[1:], edges[1:], strict=True):
        if slack < hi:
            return f"{lo}-{hi - 1}" if hi != float("inf") else f">={lo}"
    return f">={SLACK_BINS[-1]}"


def outcome(r: dict) -> str:
    """``success`` or why the episode failed (module docstring)."""
    if r["status"] != "ok":
        return "error"
    if r["success"]:
        return "success"
    if not r["goal_reached"]:
        return "time-out"
    return "wrong side" if not r["homotopy_success"] else "out of order"


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
    worlds: dict = {}
    cells: dict = defaultdict(list)
    with ResultStore(args.db, create=False) as store:
        for r in store.episodes():
            if r["key"] not in wanted:
                continue
            r = dict(r)
            w = worlds.setdefault(r["map"], load_world(r["map"]))
            goal = tuple(json.loads(r["goals"])[r["true_goal"]])
            r["slack"] = r["t_max"] - consistent_reach(w, w.cell(goal),
                                                       w.cell(tuple(json.loads(r["start"]))))
            label = r["method"] if r["method"] != "path_preference" else \
                f"path_preference ({r['preset']})"
            cells[(r["delta_t"], label)].append(r)
    lines = [f"{len(maps)} plans, {args.instances} instances x {args.runs} runs, consistent "
             "human; 95% Wilson intervals", "",
             "| ΔT | method | n | strict | homotopy-level | goal reached | time-out | wrong side "
             "| out of order | error |", "|---|---|---|---|---|---|---|---|---|---|"]
    for (dt, label), rows in sorted(cells.items()):
        n = len(rows)
        kinds = defaultdict(int)
        for r in rows:
            kinds[outcome(r)] += 1
        ok = [r for r in rows if r["status"] == "ok"]
        lines.append(f"| {dt} | {label} | {n} | {rate(kinds['success'], n)} | "
                     f"{rate(sum(r['homotopy_success'] for r in ok), n)} | "
                     f"{rate(sum(r['goal_reached'] for r in ok), n)} | {kinds['time-out']} | "
                     f"{kinds['wrong side']} | {kinds['out of order']} | {kinds['error']} |")
    labels = [slack_bin(x) for x in (*SLACK_BINS, 10**9)][:len(SLACK_BINS)]
    lines += ["", "Goal reached / strict success by slack (T_max minus the oracle's route, "
              "steps), n per bin:", "",
              "| ΔT | method | " + " | ".join(labels) + " |",
              "|---|---|" + "---|" * len(labels)]
    for (dt, label), rows in sorted(cells.items()):
        bins: dict = defaultdict(list)
        for r in rows:
            bins[slack_bin(r["slack"])].append(r)
        parts = []
        for b in labels:
            rs = bins.get(b, [])
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
