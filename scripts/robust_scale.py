"""CPU time of the robust preset at floor-plan scale for this tree against an older commit, in
one run: the two trees take turns in fresh processes (so a load that comes and goes hits both
alike). Two measurements:

* ``episode``: one path-preference episode on the bench's 200 x 200 floor plan
  (``pathpref bench --json``, ``scale.map_200_*``: ΔT = 5, 1000 queries, instance seed 1, run
  seed 2) under ``--preset``: CPU seconds of ``run_episode`` (world, tables, every decision),
  the process's peak RSS, steps, goal reached;
* ``route``: the route prior's update on a map (``simple``, ``classroom``, ``map_200``): CPU
  ms of ``update`` + ``goal_marginal`` per push, 40 pushes at random cells (10 candidates).

    python scripts/robust_scale.py episode --before 4569e9a --preset robust --warmup 0
    python scripts/robust_scale.py route --before 4569e9a --map classroom --rounds 3

The older tree is ``git archive``-d into a temporary directory and put first on
``PYTHONPATH``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _world(name: str):
    from pathpref.apps.benchmarks.scale import scale_map
    from pathpref.geometry.maps import load_map
    from pathpref.geometry.world import World

    return World.from_spec(load_map(scale_map() if name == "map_200" else name))


def child_episode(preset: str) -> dict:
    """One bench-spec episode on the 200 x 200 floor plan under ``preset``."""
    import time

    from pathpref.apps.benchmarks.peak import peak_rss_mb
    from pathpref.apps.benchmarks.scale import scale_map
    from pathpref.episode import EpisodeSpec, run_episode
    from pathpref.geometry.maps import load_map

    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "floor_200.json")
        with open(path, "w") as f:
            json.dump(scale_map(), f)
        spec = EpisodeSpec(map=path, method="path_preference", delta_t=5, instance=0, run=0,
                           instance_seed=1, run_seed=2, queries=1000,
                           t_max=load_map(path).t_max, preset=preset)
        c = time.process_time()
        ep = run_episode(spec)
        return {"cpu_s": time.process_time() - c,
                "peak_mb": peak_rss_mb(),
                "steps": ep.steps, "goal_reached": bool(ep.goal_reached)}


def child_route(name: str, pushes: int) -> dict:
    """CPU ms per push of the route prior's update and goal marginal (10 candidates)."""
    import time

    import numpy as np

    from pathpref.inference.human import ObservationModel
    from pathpref.inference.routes import RouteBelief

    world = _world(name)
    rng = np.random.default_rng(0)
    model = ObservationModel.build(world, rng.choice(world.n_cells, size=10, replace=False))
    model.likelihood  # noqa: B018 - build the tables outside the timing
    warm = RouteBelief(model)  # compile (or load) the chain kernels outside the timing
    for c in rng.integers(0, world.n_cells, size=3).tolist():
        warm.update(c, 0)
        warm.goal_marginal()
    belief = RouteBelief(model)
    belief.goal_marginal()
    out, pg = [], None
    for c, h in zip(rng.integers(0, world.n_cells, size=pushes).tolist(),
                    rng.integers(0, 8, size=pushes).tolist(), strict=True):
        t = time.process_time()
        belief.update(c, h)
        pg = belief.goal_marginal()
        out.append(1e3 * (time.process_time() - t))
    return {"median_ms": statistics.median(out), "mean_ms": statistics.fmean(out),
            "goal_marginal": pg.tolist(), "polytopes": world.n_polytopes}


def main() -> None:
    """Parse arguments; alternate the two trees; print each run and the ratios."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("what", choices=["episode", "route"])
    ap.add_argument("--before", required=True, help="git revision to compare against")
    ap.add_argument("--rounds", type=int, default=1)
    ap.add_argument("--preset", default="robust")
    ap.add_argument("--map", default="map_200")
    ap.add_argument("--pushes", type=int, default=40)
    ap.add_argument("--warmup", type=int, default=1,
                    help="uncounted first rounds (the archived tree compiles its kernels)")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.child:
        out = child_episode(a.preset) if a.what == "episode" else child_route(a.map, a.pushes)
        print(json.dumps(out))
        return
    key = "cpu_s" if a.what == "episode" else "median_ms"
    runs: dict[str, list[dict]] = {"before": [], "after": []}
    with tempfile.TemporaryDirectory() as tmp:
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", a.before, "pathpref"],
                                 capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", tmp], input=archive, check=True)
        for i in range(a.warmup + a.rounds):
            for name in ("before", "after"):
                env = dict(os.environ, PYTHONPATH=tmp if name == "before" else str(ROOT))
                res = subprocess.run([sys.executable, __file__, a.what, "--before", a.before,
                                      "--preset", a.preset, "--map", a.map, "--pushes",
                                      str(a.pushes), "--child"], env=env, cwd=tmp,
                                     capture_output=True, text=True, check=True)
                d = json.loads(res.stdout.strip().splitlines()[-1])
                if i >= a.warmup:
                    runs[name].append(d)
                shown = {k: v for k, v in d.items() if k != "goal_marginal"}
                print(name if i >= a.warmup else f"({name}, warm-up)", json.dumps(shown),
                      flush=True)
    med = {k: statistics.median(r[key] for r in v) for k, v in runs.items()}
    print(f"{a.what} ({a.preset if a.what == 'episode' else a.map}): {key} {med['before']:.3g} "
          f"before, {med['after']:.3g} after: {med['before'] / med['after']:.2f}x")
    if a.what == "route":
        diff = max(abs(x - y) for b, f in zip(runs["before"], runs["after"], strict=True)
                   for x, y in zip(b["goal_marginal"], f["goal_marginal"], strict=True))
        print(f"largest difference of the final goal marginal: {diff:.1e}")


if __name__ == "__main__":
    main()
