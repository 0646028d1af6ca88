"""Two presets on the same episodes: strict, homotopy-level and goal-reached counts per map and
ΔT, and the exact two-sided sign test on the discordant pairs of strict success.

    .venv/bin/python scripts/paired_presets.py --presets robust robust-wait --delta-t 1 5 \\
        --instances 6 --runs 4 --workers 2 \\
        --maps classroom office simple examples/maps/atrium.json examples/maps/hall.json \\
               examples/maps/lab.json examples/maps/warehouse.json

Every episode is ``path_preference`` with the consistent human (the spec of ``pathpref
evaluate --seed 0``: instance ``i``, run ``r``), so the two presets see the same start, goals,
true goal and human draws; a pair is discordant when one preset succeeds and the other does
not. The episodes run through the project's sweep (:func:`pathpref.experiments.sweep.run_sweep`)
into ``--db`` (resumable: a rerun skips what is there); ``--out FILE`` writes every episode's
outcome as JSON lines. An episode that failed (an error, recorded by the sweep) counts as a
failure on every measure and is listed; ``--retry-failed`` runs failed episodes again. Under
each line, each preset's failures split by why (:mod:`pathpref.experiments.outcomes`).
"""

from __future__ import annotations

import argparse
import json
import os
from collections import defaultdict
from math import comb
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "disable")

from pathpref.experiments.outcomes import FAILURE_KINDS, failure_kind  # noqa: E402
from pathpref.experiments.store import ResultStore  # noqa: E402
from pathpref.experiments.sweep import run_sweep, sweep_specs  # noqa: E402


def sign_test(wins: int, losses: int) -> float:
    """Exact two-sided sign test of ``wins`` against ``losses`` (p of a split this uneven)."""
    n = wins + losses
    if n == 0:
        return 1.0
    tail = sum(comb(n, i) for i in range(min(wins, losses) + 1)) / 2 ** n
    return min(1.0, 2 * tail)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--presets", nargs=2, default=["robust", "robust-wait"])
    ap.add_argument("--maps", nargs="+", default=["classroom"])
    ap.add_argument("--delta-t", nargs="+", type=int, default=[1, 5])
    ap.add_argument("--instances", type=int, default=6)
    ap.add_argument("--runs", type=int, default=4)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--db", default="paired.sqlite", help="the sweep's database (resumable)")
    ap.add_argument("--out", type=Path)
    ap.add_argument("--retry-failed", action="store_true", help="re-run failed episodes")
    args = ap.parse_args(argv)
    a, b = args.presets
    specs = [s for m in args.maps for p in (a, b)
             for s in sweep_specs(m, ["path_preference"], args.delta_t, args.instances,
                                  args.runs, seed=0, human="consistent", preset=p)]
    run_sweep(specs, args.db, workers=args.workers, retry_failed=args.retry_failed)
    wanted = {(s.preset, s.map, s.delta_t, s.instance, s.run) for s in specs}
    with ResultStore(args.db, create=False) as store:
        rows = [{"preset": r["preset"], "map": r["map"], "delta_t": r["delta_t"],
                 "instance": r["instance"], "run": r["run"], "success": bool(r["success"]),
                 "homotopy": bool(r["homotopy_success"]), "reached": bool(r["goal_reached"]),
                 "steps": r["steps"], "inputs": r["inputs"], "status": r["status"],
                 "why": failure_kind(r), "slack": r.get("slack")}
                for r in store.episodes()
                if (r["preset"], r["map"], r["delta_t"], r["instance"], r["run"]) in wanted]
    for r in rows:
        if r["status"] != "ok":  # a failed episode is a failure on every measure
            r.update(success=False, homotopy=False, reached=False)
            print(f"failed episode (counted as a failure): {r['preset']} {r['map']} "
                  f"ΔT={r['delta_t']} instance {r['instance']} run {r['run']}")
    if args.out:
        args.out.write_text("".join(json.dumps(r) + "\n" for r in rows))
    by = {(r["preset"], r["map"], r["delta_t"], r["instance"], r["run"]): r for r in rows}
    cells: dict = defaultdict(lambda: defaultdict(int))
    for m in args.maps:
        for dt in args.delta_t:
            for i in range(args.instances):
                for r in range(args.runs):
                    x, y = by[(a, m, dt, i, r)], by[(b, m, dt, i, r)]
                    for key in [(Path(m).stem, dt), ("all", dt)]:
                        c = cells[key]
                        c["n"] += 1
                        for k in ("success", "homotopy", "reached"):
                            c[f"{k}_a"] += x[k]
                            c[f"{k}_b"] += y[k]
                        for kind in FAILURE_KINDS:
                            c[f"{kind}_a"] += x["why"] == kind
                            c[f"{kind}_b"] += y["why"] == kind
                        c["b_wins"] += y["success"] and not x["success"]
                        c["a_wins"] += x["success"] and not y["success"]
    print(f"{a} -> {b} (counts of n; discordant strict pairs: {b} wins / {a} wins, sign test)")
    for (m, dt), c in sorted(cells.items(), key=lambda kv: (kv[0][0] == "all", kv[0])):
        print(f"{m:>10} ΔT={dt}: n={c['n']:3d} strict {c['success_a']:3d} -> "
              f"{c['success_b']:3d}, homotopy {c['homotopy_a']:3d} -> {c['homotopy_b']:3d}, "
              f"reached {c['reached_a']:3d} -> {c['reached_b']:3d}; "
              f"{c['b_wins']}/{c['a_wins']}, p = {sign_test(c['b_wins'], c['a_wins']):.3f}")
        print(" " * 17 + "why failed (time-out / wrong side / out-of-order / not run): "
              + " -> ".join("/".join(str(c[f"{k}_{s}"]) for k in FAILURE_KINDS[1:4] + ("not_run",))
                            for s in "ab"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
