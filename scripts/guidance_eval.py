"""Guidance against taps on the same clock: success, crossings the person led, contacts.

    MUJOCO_GL=egl .venv/bin/python scripts/guidance_eval.py --plans-seeds 7741 7742 7743 \\
        --instances 6 --runs 5 --db guidance.sqlite --out docs/results/guidance.md

**Conditions** (every condition runs the same specs: map, instance and run seeds; path
preference, the default preset, default physics; one simulated person, whose heading
choice is the human model at ``--gamma-h``, the same for taps and guidance):

* ``taps-interval``: pushes at any time on the ``interval`` clock, ΔT 5 (a tap, the move
  stops, the robot replans); ``taps-corrective``: the episode's corrective rule
  (``--push-rule 'corrective delay=0 miss=0.0'``, ΔT 1): a tap after a step that left the
  person's route, is about to, or made no headway;
* ``guidance-interval``: the closed-loop person of :mod:`pathpref.sim.guiding_human` taking
  the handle on the same clock; ``guidance-corrective``: the same person under the same
  corrective rule, taking the handle a reaction delay after the robot starts such a move;
* ``guidance-open``: the earlier open-loop person (one drawn heading held for the push;
  ``--open``, interval clock).

**Maps**: the three built-in maps and one floor plan per ``--plans-seeds`` seed
(:func:`pathpref.geometry.generate.floor_plan` at its defaults: rotated obstacles, a route of
four waypoints; seeds drawn after the design and never used to tune it), ``--instances`` x
``--runs`` episodes per map and condition.

**Measures**: strict success (goal reached, no violation by the robot's own crossings, no
unsafe contact; guided episodes are judged along the continuous path, the person's crossings
reported beside), success when the person's crossings count too, goal reached, pushes, person
crossings and contacts per episode, the largest impact speed, the person's effort (``integral
|F| dt`` per episode, mean with its 95 % t interval, and per success: all the episodes'
impulse over the successes); Wilson 95 % intervals, failed episodes counted as failures.
Every episode runs through the project's sweep into ``--db`` (resumable).
"""

from __future__ import annotations

import argparse
import json
import os
from collections import defaultdict
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

import pathpref.sim  # noqa: E402, F401  (registers the MuJoCo body)
from pathpref.experiments.report import range_interval, wilson  # noqa: E402
from pathpref.experiments.store import ResultStore  # noqa: E402
from pathpref.experiments.sweep import run_sweep, sweep_specs  # noqa: E402
from pathpref.geometry.generate import floor_plan  # noqa: E402

#: the corrective rule of both corrective conditions (the episode's ``--push-rule``)
CORRECTIVE = "corrective delay=0 miss=0.0"
#: the conditions: physics (their rationality added per run: ``gamma_h``), ΔT, push rule
CONDITIONS = {"taps-interval": ({"timing": "interval"}, 5, ""),
              "guidance-interval": ({"timing": "guidance"}, 5, ""),
              "taps-corrective": ({"timing": "decision"}, 1, CORRECTIVE),
              "guidance-corrective": ({"timing": "guidance"}, 1, CORRECTIVE),
              "guidance-open": ({"timing": "guidance", "guide": "open"}, 5, "")}


def rate(k: int, n: int) -> str:
    """``k / n`` with its Wilson 95 % interval."""
    lo, hi = wilson(k, n)
    return f"{k / n:.2f} [{lo:.2f}, {hi:.2f}]" if n else "-"


def condition_of(physics: str, push_rule: str | None) -> str:
    """The condition name of a stored row (its physics JSON and push rule), with its
    rationality."""
    p = json.loads(physics)
    rule = "corrective" if push_rule else "interval"
    if p.get("timing") in ("interval", "decision"):
        name = f"taps-{rule}"
    elif p.get("guide") == "open":
        name = "guidance-open"
    else:
        name = f"guidance-{rule}"
    return f"{name} γ{p.get('gamma_h', 1.5):g}"


def mean_interval(values: list[float]) -> str:
    """The mean with its 95 % t interval, clipped at 0 (:func:`~pathpref.experiments.report.
    range_interval`)."""
    if not values:
        return "-"
    m, lo, hi = range_interval(values)
    return f"{m:.1f} [{lo:.1f}, {hi:.1f}]"


def per_success(ok: list[dict], met: list[dict]) -> str:
    """All the episodes' impulse over the strict successes (N s; ``-`` without one)."""
    wins = sum(r["success"] for r in ok)
    total = sum(m.get("person_impulse_ns", 0.0) for m in met)
    return f"{total / wins:.1f}" if wins else "-"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--maps", nargs="*", default=["simple", "office", "classroom"])
    ap.add_argument("--plans-seeds", nargs="*", type=int, default=[])
    ap.add_argument("--plans", type=Path, default=Path("guidance_plans"))
    ap.add_argument("--open", action="store_true", help="add the open-loop person")
    ap.add_argument("--gamma-h", nargs="*", type=float, default=[1.5],
                    help="the person's rationality (each value a set of conditions)")
    ap.add_argument("--rules", nargs="*", choices=["interval", "corrective"],
                    default=["interval", "corrective"], help="when the person intervenes")
    ap.add_argument("--instances", type=int, default=6)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--db", default="guidance.sqlite")
    ap.add_argument("--out", type=Path)
    args = ap.parse_args(argv)
    maps = list(args.maps)
    args.plans.mkdir(parents=True, exist_ok=True)
    for s in args.plans_seeds:
        path = args.plans / f"guidance_{s}.json"
        if not path.exists():
            path.write_text(json.dumps(floor_plan(s, name=f"guidance_{s}"), indent=1))
        maps.append(str(path))
    conditions = [c for c in CONDITIONS if (c.split("-")[1] in args.rules)
                  or (c == "guidance-open" and args.open)]
    specs = []
    for m in maps:
        for c in conditions:
            physics, delta_t, rule = CONDITIONS[c]
            for g in args.gamma_h:
                specs += sweep_specs(m, ["path_preference"], [delta_t], args.instances,
                                     args.runs, sim="mujoco", push_rule=rule,
                                     physics=json.dumps({**physics, "gamma_h": g}))
    run_sweep(specs, args.db, workers=args.workers)
    wanted = {s.key() for s in specs}
    cells: dict = defaultdict(list)
    with ResultStore(args.db, create=False) as store:
        for r in store.episodes():
            if r["key"] in wanted:
                cells[(Path(r["map"]).stem, condition_of(r["physics"], r["push_rule"]))
                      ].append(dict(r))
    lines = [f"{len(maps)} maps, path preference, ΔT 5 on the interval clock (1 for the "
             f"corrective rule, {CORRECTIVE!r}), {args.instances} instances x "
             f"{args.runs} runs per map and condition; 95% Wilson intervals", "",
             "| map | condition | episodes | success (robot's crossings) | success (all "
             "crossings) | goal reached | pushes | person crossings | contacts | max impact "
             "(m/s) | effort N s / episode | effort N s / success | contact s / episode | "
             "wall s |", "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    pooled: dict = defaultdict(list)
    for (_, c), rows in sorted(cells.items()):
        pooled[c] += rows
    for (name, c), rows in [*sorted(cells.items()), *((("pooled", c), r)
                                                       for c, r in sorted(pooled.items()))]:
        n = len(rows)
        ok = [r for r in rows if r["status"] == "ok"]
        met = [json.loads(r["metrics"] or "{}") for r in ok]
        strict_all = sum(r["success"] and m.get("person_violations", 0.0) == 0
                         for r, m in zip(ok, met, strict=True))
        lines.append(
            f"| {name} | {c} | {n} | {rate(sum(r['success'] for r in ok), n)} | "
            f"{rate(strict_all, n)} | {rate(sum(r['goal_reached'] for r in ok), n)} | "
            f"{sum(m.get('pushes', 0.0) for m in met) / n:.1f} | "
            f"{sum(m.get('person_crossings', 0.0) for m in met) / n:.2f} | "
            f"{sum(m.get('collisions', 0.0) for m in met) / n:.2f} | "
            f"{max([m.get('contact_impact_speed', 0.0) for m in met] or [0.0]):.2f} | "
            f"{mean_interval([m['person_impulse_ns'] for m in met if 'person_impulse_ns' in m])}"
            f" | {per_success(ok, met)} | "
            f"{sum(m.get('person_contact_s', 0.0) for m in met) / max(1, len(met)):.1f} | "
            f"{sum(r['wall_s'] for r in ok) / max(1, len(ok)):.1f} |")
    text = "\n".join(lines) + "\n"
    print(text)
    if args.out:
        args.out.write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
