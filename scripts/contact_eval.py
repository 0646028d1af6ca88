"""Contacts of the physical base on floor plans with rotated obstacles, and what the footprint
rule costs the grid's success there.

    MUJOCO_GL=egl .venv/bin/python scripts/contact_eval.py --seeds 9831 9832 9833 \\
        --db contact.sqlite --out docs/results/contact_free.md

**Plans.** Seed ``k`` of ``--seeds`` gives a floor plan of
:func:`pathpref.geometry.generate.floor_plan` of the ``k mod 3``-th kind of :data:`KINDS` (the
three kinds of the measurement that found the contacts: 14 x 14 with 5 rotated polygons, 12 x 9
with 3, 22 x 14 mostly boxes with 3 rotated), written to ``--plans``. Seeds are drawn after the
rule was designed and never used to tune it.

**Physics.** Per plan and clock (``--timings``: taps at any time, ``interval``, and
``guidance``), path preference and compliant under the default physics, ΔT 5,
``--instances`` x ``--runs`` episodes each: contacts with obstacles and walls per episode, the
largest impact speed and peak contact force, and success (contact-unsafe episodes are failures,
:mod:`pathpref.episode.safety`).

**Grid.** ``--grid`` adds, per plan, the grid world's strict and goal-reached success of path
preference (robust-slack) and goal-only over the same instances: run once with this code (the
robot's footprint) and once with ``PYTHONPATH`` pointing at a checkout from before the rule, to
compare (``--grid-only`` skips the physics). Every episode runs through the project's sweep into
``--db`` (resumable).
"""

from __future__ import annotations

import argparse
import json
import os
from collections import defaultdict
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

import pathpref.sim  # noqa: E402, F401  (registers the MuJoCo body)
from pathpref.experiments.report import wilson  # noqa: E402
from pathpref.experiments.store import ResultStore  # noqa: E402
from pathpref.experiments.sweep import run_sweep, sweep_specs  # noqa: E402
from pathpref.geometry.generate import floor_plan  # noqa: E402

#: the plan kinds (floor_plan arguments)
KINDS = (
    dict(width=14, height=14, rotated=5, boxes=0, size_range=(1.5, 4.0)),
    dict(width=12, height=9, rotated=3, boxes=0, size_range=(1.5, 3.5)),
    dict(width=22, height=14, rotated=3, boxes=17, size_range=(1.0, 3.0)),
)


def rate(k: int, n: int) -> str:
    """``k / n`` with its Wilson 95 % interval."""
    lo, hi = wilson(k, n)
    return f"{k / n:.2f} [{lo:.2f}, {hi:.2f}]" if n else "-"


def plan_files(seeds: list[int], where: Path) -> list[str]:
    """Write the plans of ``seeds`` (module docstring; a plan file already there is kept, so
    a run under other code reads the same plans); their paths."""
    where.mkdir(parents=True, exist_ok=True)
    paths = []
    for s in seeds:
        kind = KINDS[s % len(KINDS)]
        path = where / f"contact_{s}.json"
        if not path.exists():
            path.write_text(json.dumps(floor_plan(s, name=f"contact_{s}", **kind), indent=1))
        paths.append(str(path))
    return paths


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", nargs="+", type=int, required=True)
    ap.add_argument("--plans", type=Path, default=Path("contact_plans"))
    ap.add_argument("--timings", nargs="+", default=["interval", "guidance"])
    ap.add_argument("--instances", type=int, default=4)
    ap.add_argument("--runs", type=int, default=4)
    ap.add_argument("--grid", action="store_true", help="add the grid world's success")
    ap.add_argument("--grid-only", action="store_true")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--db", default="contact.sqlite")
    ap.add_argument("--out", type=Path)
    args = ap.parse_args(argv)
    maps = plan_files(args.seeds, args.plans)
    specs, lines = [], []
    if not args.grid_only:
        for m in maps:
            for timing in args.timings:
                physics = json.dumps({"timing": timing})
                specs += sweep_specs(m, ["path_preference", "compliant"], [5], args.instances,
                                     args.runs, sim="mujoco", physics=physics)
    if args.grid or args.grid_only:
        for m in maps:
            specs += sweep_specs(m, ["path_preference", "goal_only"], [5], args.instances,
                                 args.runs)
    run_sweep(specs, args.db, workers=args.workers)
    wanted = {s.key() for s in specs}
    cells: dict = defaultdict(list)
    with ResultStore(args.db, create=False) as store:
        for r in store.episodes():
            if r["key"] in wanted:
                timing = json.loads(r["physics"]).get("timing", "?") if r["sim"] == "mujoco" \
                    else "grid"
                cells[(r["map"], timing, r["method"])].append(dict(r))
    lines = [f"{len(maps)} plans (seeds {' '.join(map(str, args.seeds))}), ΔT 5, "
             f"{args.instances} instances x {args.runs} runs per method; 95% Wilson intervals",
             "", "| plan | clock | method | episodes | contacts per episode | max impact speed "
             "(m/s) | max peak contact force (N) | success (strict) | goal reached |",
             "|---|---|---|---|---|---|---|---|---|"]
    for (name, timing, method), rows in sorted(cells.items()):
        n = len(rows)
        met = [json.loads(r["metrics"] or "{}") for r in rows]
        ok = [r for r in rows if r["status"] == "ok"]
        if timing == "grid":
            contacts = speed = force = "-"
        else:
            contacts = f"{sum(x.get('collisions', 0.0) for x in met) / n:.2f}"
            speed = f"{max(x.get('contact_impact_speed', 0.0) for x in met):.2f}"
            force = f"{max(x.get('contact_peak_force_n', 0.0) for x in met):.0f}"
        lines.append(f"| {Path(name).stem} | {timing} | {method} | {n} | {contacts} | {speed} | "
                     f"{force} | "
                     f"{rate(sum(r['success'] for r in ok), n)} | "
                     f"{rate(sum(r['goal_reached'] for r in ok), n)} |")
    text = "\n".join(lines) + "\n"
    print(text)
    if args.out:
        args.out.write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
