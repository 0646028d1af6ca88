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

**Bodies** (``--bodies``, :data:`BODIES`): the disk (``navigate``), the TidyBot
(``navigate --robot-model tidybot``), the Jaco carrying the tray on the disk (``carry``) and
the Gen3 carrying it on the TidyBot (``carry --robot-model tidybot``); ``--clocks`` adds
``decision`` to the default ``interval`` and ``guidance``; ``--maps`` built-in maps (e.g.
``office``) beside the plans; ``--preset`` the policy preset (e.g. ``robust``). The table
counts **unsafe** episodes, those with a contact above :data:`~pathpref.episode.safety.
CONTACT_LIMITS` (0.05 m/s or 20 N), per body, map and clock.

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
from pathpref.episode.safety import contact_safe  # noqa: E402
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


#: the bodies of the sweep: name -> the episode's ``robot`` (task) and ``robot_model``
BODIES = {"disk": ("navigate", "disk"), "tidybot": ("navigate", "tidybot"),
          "jaco_carry": ("carry", "disk"), "gen3_carry": ("carry", "tidybot")}


def unsafe(metrics: dict) -> bool:
    """Whether an episode's contact measurements break a limit of ``CONTACT_LIMITS``."""
    return not contact_safe(metrics)


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
    ap.add_argument("--timings", "--clocks", nargs="+", default=["interval", "guidance"])
    ap.add_argument("--bodies", nargs="+", default=["disk"], choices=sorted(BODIES))
    ap.add_argument("--maps", nargs="*", default=[], help="built-in maps beside the plans")
    ap.add_argument("--preset", default=None, help="the policy preset (default: the default)")
    ap.add_argument("--methods", nargs="+", default=["path_preference", "compliant"])
    ap.add_argument("--instances", type=int, default=4)
    ap.add_argument("--runs", type=int, default=4)
    ap.add_argument("--grid", action="store_true", help="add the grid world's success")
    ap.add_argument("--grid-only", action="store_true")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--db", default="contact.sqlite")
    ap.add_argument("--out", type=Path)
    args = ap.parse_args(argv)
    maps = [*args.maps, *plan_files(args.seeds, args.plans)]
    specs, lines = [], []
    extra = {} if args.preset is None else {"preset": args.preset}
    if not args.grid_only:
        for m in maps:
            for body in args.bodies:
                task, model = BODIES[body]
                for timing in args.timings:
                    physics = {"timing": timing}
                    if model != "disk":
                        physics["robot_model"] = model
                    specs += sweep_specs(m, args.methods, [5], args.instances, args.runs,
                                         sim="mujoco", robot=task,
                                         physics=json.dumps(physics), **extra)
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
                ph = json.loads(r["physics"] or "{}") if r["sim"] == "mujoco" else {}
                timing = ph.get("timing", "?") if r["sim"] == "mujoco" else "grid"
                body = "-" if timing == "grid" else next(
                    k for k, (t, m) in BODIES.items()
                    if t == r["task"] and m == ph.get("robot_model", "disk"))
                cells[(body, r["map"], timing, r["method"])].append(dict(r))
    n_all = sum(len(v) for k, v in cells.items() if k[0] != "-")
    bad = sum(unsafe(json.loads(r["metrics"] or "{}")) for k, v in cells.items()
              if k[0] != "-" for r in v)
    lines = [f"{len(args.maps)} built-in maps ({' '.join(args.maps) or 'none'}) and "
             f"{len(maps) - len(args.maps)} plans (seeds {' '.join(map(str, args.seeds))}), "
             f"ΔT 5, {args.instances} instances x {args.runs} runs per method, preset "
             f"{args.preset or 'default'}; 95% Wilson intervals", "",
             f"**{bad} unsafe of {n_all} physical episodes** (a contact above 0.05 m/s or 20 N)",
             "", "| body | map | clock | method | episodes | unsafe | contacts per episode | "
             "max impact speed (m/s) | max peak contact force (N) | success (strict) | "
             "goal reached |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for (body, name, timing, method), rows in sorted(cells.items()):
        n = len(rows)
        met = [json.loads(r["metrics"] or "{}") for r in rows]
        ok = [r for r in rows if r["status"] == "ok"]
        if timing == "grid":
            contacts = speed = force = n_bad = "-"
        else:
            n_bad = str(sum(unsafe(x) for x in met))
            contacts = f"{sum(x.get('collisions', 0.0) for x in met) / n:.2f}"
            speed = f"{max(x.get('contact_impact_speed', 0.0) for x in met):.2f}"
            force = f"{max(x.get('contact_peak_force_n', 0.0) for x in met):.0f}"
        lines.append(f"| {body} | {Path(name).stem} | {timing} | {method} | {n} | {n_bad} | "
                     f"{contacts} | {speed} | {force} | "
                     f"{rate(sum(r['success'] for r in ok), n)} | "
                     f"{rate(sum(r['goal_reached'] for r in ok), n)} |")
    text = "\n".join(lines) + "\n"
    print(text)
    if args.out:
        args.out.write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
