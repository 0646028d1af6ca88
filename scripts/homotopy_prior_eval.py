"""Route-structured priors against the route prior on held-out floor plans (issue 27, item 1).

    .venv/bin/python scripts/homotopy_prior_eval.py --out docs/results/homotopy_prior.json
    .venv/bin/python scripts/homotopy_prior_eval.py --plan-set loop --priors routes circulation \
        --out docs/results/circulation_prior.json

**Held-out plans**, drawn before any setting of the prior under test was chosen and never used
to choose one: ``random_floor_plan(24, 16, 7 rotated, 2 boxes, sizes 1.5..4, seed)``
(:mod:`pathpref.geometry.generate`), written to ``--plans``. ``--plan-set open`` (seeds
9001..9006, drawn for the homotopy prior): an open preference route through four waypoints
drawn (seed = the plan's) from the largest 4-connected free area. ``--plan-set loop`` (seeds
9101..9106, drawn for the circulation prior): the closed route round the map of
:func:`~pathpref.geometry.generate.with_loop_preference`, the kind of preference the example
plans have.

Two measurements, both with the consistent human:

1. **Prediction.** Per plan and instance, pushes are drawn (the Boltzmann human, true goal and
   preference) at every third cell of the human's own route; after ``k`` pushes the
   log-probability of the human's route is ``sum_v log P(p_v = next_v | g*, o_1:k)`` over the
   route's polytope exits (``next_v``: the polytope the route enters from ``v``) under each
   prior. Mean over plans and instances with a 95 % t interval of the paired difference from
   the route prior.
2. **Success.** Robust episodes of ``path_preference`` at each ``--delta-t`` under each prior:
   strict and homotopy-level success with Wilson 95 % intervals, pushes per episode
   (databases in ``--db-dir``, resumable).
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "disable")

import numpy as np  # noqa: E402
from scipy import stats  # noqa: E402

from pathpref.episode.instances import sample_instance  # noqa: E402
from pathpref.experiments.report import wilson  # noqa: E402
from pathpref.experiments.store import ResultStore  # noqa: E402
from pathpref.experiments.sweep import run_sweep, sweep_specs  # noqa: E402
from pathpref.geometry.following import consistent_preference, human_route  # noqa: E402
from pathpref.geometry.footprint import POINT_ROBOT  # noqa: E402
from pathpref.geometry.generate import floor_plan  # noqa: E402
from pathpref.geometry.world import load_world  # noqa: E402
from pathpref.inference.circulation_prior import CirculationBelief  # noqa: E402
from pathpref.inference.homotopy_prior import HomotopyBelief  # noqa: E402
from pathpref.inference.human import ObservationModel, SimulatedHuman  # noqa: E402
from pathpref.inference.routes import RouteBelief  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
#: the held-out plan sets: ``open`` and ``loop`` drawn for the priors (above); ``check-open``
#: and ``check-loop`` drawn the same ways for the crossing check (scripts/paired_presets.py,
#: docs/robust.md "Look before crossing"), before any episode was run on them
SEEDS = {"open": range(9001, 9007), "loop": range(9101, 9107),
         "check-open": range(9201, 9207), "check-loop": range(9301, 9307)}
#: what each set was held out for (written into its plans' descriptions)
HELD_OUT_FOR = {"open": "the homotopy prior", "loop": "the circulation prior",
                "check-open": "the crossing check", "check-loop": "the crossing check"}
PUSHES = (0, 1, 2, 4, 8)
#: the beliefs compared, by ``--prior`` name
BELIEFS = {"routes": lambda model, start: RouteBelief(model),
           "homotopy": HomotopyBelief, "circulation": CirculationBelief}


def held_out_plan(seed: int, kind: str = "open") -> dict:
    """The held-out plan of ``seed`` of the plan set ``kind`` (:data:`SEEDS`; module
    docstring): :func:`~pathpref.geometry.generate.floor_plan` with a loop preference for the
    ``loop`` sets, an open route otherwise. The set was drawn for a point robot
    (:data:`~pathpref.geometry.footprint.POINT_ROBOT`), before moves were restricted to the
    robot's footprint; 5 of its 24 plans need a passage the default robot cannot make and are
    refused when loaded for it."""
    why = (f"held out for {HELD_OUT_FOR[kind]} (scripts/homotopy_prior_eval.py); never used "
           "to choose its settings")
    return floor_plan(seed, "loop" if kind.endswith("loop") else "open",
                      name=f"heldout_{seed}", description=why, footprint=POINT_ROBOT)


def route_logprob(belief, world, g: int, exits: list[tuple[int, int]]) -> float:
    """``sum log P(p_v = u | g, o)`` over the route's exits ``(v, u)``."""
    total = 0.0
    for v, u in exits:
        k = int(np.flatnonzero(world.graph.neighbors[v] == u)[0])
        total += float(np.log(max(belief.preference_given_goal(v)[g, k], 1e-300)))
    return total


def prediction(paths: list[Path], instances: int, priors: list[str]) -> dict:
    """Measurement 1 of the module docstring."""
    rows = []
    for path in paths:
        world = load_world(str(path))
        for i in range(instances):
            inst = sample_instance(world, 1000 + i, 10, consistent=True,
                                   t_max=world.spec.t_max)
            goals = np.array(inst.goals)
            g = inst.true_goal
            r = int(world.cell_polytope[goals[g]])
            pref = consistent_preference(world, world.preference, r)[0]
            cells = human_route(world, pref, inst.start, goals[g])
            polys = [int(world.cell_polytope[c]) for c in cells]
            seq = [polys[0]] + [p for a, p in zip(polys, polys[1:], strict=False) if p != a]
            exits = list(zip(seq[:-1], seq[1:], strict=True))
            if not exits:
                continue
            model = ObservationModel.build(world, goals, normalize=True)
            human = SimulatedHuman(model, g, pref)
            beliefs = {name: BELIEFS[name](model, inst.start) for name in priors}
            rng = np.random.default_rng(i)
            at = cells[::3]
            heads = [human.sample(c, rng) for c in at]
            row = {"plan": path.stem, "instance": i, "exits": len(exits)}
            done = 0
            for k in PUSHES:
                for c, h in zip(at[done:k], heads[done:k], strict=False):
                    for b in beliefs.values():
                        b.update(int(c), int(h))
                done = max(done, min(k, len(at)))
                for name, b in beliefs.items():
                    row[f"{name}_{k}"] = route_logprob(b, world, g, exits)
            rows.append(row)
    out = {"n": len(rows), "rows": rows, "mean": {}}
    for k in PUSHES:
        a = np.array([r[f"routes_{k}"] for r in rows])
        out["mean"][k] = {"routes": float(a.mean())}
        for name in priors:
            if name == "routes":
                continue
            b = np.array([r[f"{name}_{k}"] for r in rows])
            d = b - a
            half = stats.t.ppf(0.975, len(d) - 1) * d.std(ddof=1) / np.sqrt(len(d))
            suffix = "" if name == "homotopy" else f"_{name}"  # the first file's keys stay
            out["mean"][k] |= {name: float(b.mean()), f"difference{suffix}": float(d.mean()),
                               f"difference_ci{suffix}": [float(d.mean() - half),
                                                          float(d.mean() + half)]}
    return out


def success(paths: list[Path], args) -> list[dict]:
    """Measurement 2 of the module docstring."""
    out = []
    db_dir = Path(args.db_dir)
    db_dir.mkdir(parents=True, exist_ok=True)
    for prior in args.priors:
        plan_set = "maps" if args.maps is not None else args.plan_set
        db = db_dir / f"{plan_set}_{prior}.sqlite" if plan_set != "open" else \
            db_dir / f"{prior}.sqlite"  # (the first plan set's file names stay)
        specs = []
        for p in paths:
            specs += sweep_specs(str(p), ["path_preference"], args.delta_t, args.instances,
                                 args.runs, seed=args.seed, human="consistent", prior=prior,
                                 preset="robust", queries=args.queries)
        counts = run_sweep(specs, str(db), workers=args.workers, progress=False)
        print(f"{prior}: {counts['ran']} run, {counts['skipped']} already there", flush=True)
        with ResultStore(str(db)) as store:
            rows = store.episodes()
        for dt in args.delta_t:
            rs = [r for r in rows if r["delta_t"] == dt]
            n = len(rs)
            k = sum(bool(r["success"]) for r in rs)
            kh = sum(bool(r["homotopy_success"]) for r in rs)
            out.append({"prior": prior, "delta_t": dt, "n": n, "success": k / n,
                        "ci": wilson(k, n), "homotopy": kh / n, "homotopy_ci": wilson(kh, n),
                        "pushes": sum(r["inputs"] for r in rs) / n})
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "docs" / "results" / "homotopy_prior.json"))
    ap.add_argument("--plans", default=str(ROOT / "docs" / "results" / "heldout_plans"))
    ap.add_argument("--db-dir", default="homotopy_dbs")
    ap.add_argument("--instances", type=int, default=4)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--queries", type=int, default=None)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--delta-t", type=int, nargs="+", default=[1, 5])
    ap.add_argument("--skip-success", action="store_true")
    ap.add_argument("--plan-set", choices=sorted(SEEDS), default="open")
    ap.add_argument("--maps", nargs="+", default=None,
                    help="measure on these maps instead of a held-out plan set (names or map "
                         "files; not held out if the prior's settings were chosen on them)")
    ap.add_argument("--priors", nargs="+", choices=sorted(BELIEFS),
                    default=["routes", "homotopy"], help="routes must come first")
    args = ap.parse_args()
    if args.priors[0] != "routes":
        ap.error("--priors: the first must be routes (the others are compared with it)")
    plans = Path(args.plans)
    plans.mkdir(parents=True, exist_ok=True)
    paths = []
    for s in SEEDS[args.plan_set] if args.maps is None else ():
        p = plans / (f"heldout_{s}.json" if args.plan_set == "open" else
                     f"heldout_{args.plan_set}_{s}.json")
        if not p.exists():
            p.write_text(json.dumps(held_out_plan(s, args.plan_set), indent=1))
        paths.append(p)
    if args.maps is not None:
        paths = [Path(m) for m in args.maps]
    flags = " ".join(f"--{k.replace('_', '-')} " + (" ".join(map(str, v)) if isinstance(v, list)
                                                    else str(v))
                     for k, v in vars(args).items() if v not in (None, False, True)
                     and k not in ("out", "plans")
                     and not (k == "plan_set" and args.maps is not None))
    result = {"command": f"python scripts/homotopy_prior_eval.py {flags}",
              "prediction": prediction(paths, args.instances, args.priors)}
    for k, m in result["prediction"]["mean"].items():
        for name in args.priors[1:]:
            suffix = "" if name == "homotopy" else f"_{name}"
            lo, hi = m[f"difference_ci{suffix}"]
            print(f"after {k} pushes: route log-prob routes {m['routes']:.2f}, {name} "
                  f"{m[name]:.2f}, difference {m[f'difference{suffix}']:+.2f} "
                  f"[{lo:+.2f}, {hi:+.2f}] (n = {result['prediction']['n']})", flush=True)
    if not args.skip_success:
        result["success"] = success(paths, args)
        for r in result["success"]:
            print(f"{r['prior']:11s} ΔT={r['delta_t']}: strict {r['success']:.2f} "
                  f"[{r['ci'][0]:.2f}, {r['ci'][1]:.2f}], homotopy-level {r['homotopy']:.2f} "
                  f"[{r['homotopy_ci'][0]:.2f}, {r['homotopy_ci'][1]:.2f}], "
                  f"{r['pushes']:.1f} pushes (n = {r['n']})", flush=True)
    Path(args.out).write_text(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
