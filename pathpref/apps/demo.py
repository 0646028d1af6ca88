"""The main job (``make demo``): on the paper's Fig. 4 instance, success rates of every method
over many runs (grid world), then one representative episode per method of the paper, in
MuJoCo with force cues (``--sim grid`` for the grid world only). Preset: ``robust`` (the
applications' default); ``--preset paper`` for the paper's planner.

Writes to the output folder:

* ``rollout_<method>.mp4`` (MuJoCo): top-down and perspective views, belief-tinted goals, pushes;
* ``rollout_path_preference.rrd``: a rerun recording (open with ``rerun FILE``);
* ``map_simple.png``: the map with polytopes, graph and the human's preference;
* ``trajectories.png``: the path of each rendered episode, with the human's pushes as arrows;
* ``belief.png``: P(true goal) and goal entropy along each rendered episode;
* ``rates.csv``: per method, runs reaching the goal by the preferred route (success), by another
  route, or not at all, with the success rate's 95% Wilson interval;
* ``summary.csv`` and a table on stdout: the rendered episodes, and one line per method saying
  what it did.
"""

from __future__ import annotations

import csv
from collections import Counter
from pathlib import Path

from ..episode import FIG4, EpisodeResult, EpisodeSpec, cached_world, run_episode
from ..experiments.report import wilson
from ..planning.policies import METHODS, REFERENCE_METHODS
from ..planning.pomdp import DEFAULT_PRESET

DEMO_DELTA_T = 3
#: grid-world runs per method behind the demo's rates
DEMO_RUNS = 30
OUTCOMES = ("by the preferred route", "by another route", "not at all")


def demo_spec(method: str, seed: int = 0, delta_t: int = DEMO_DELTA_T, sim: str = "mujoco",
              preset: str = DEFAULT_PRESET) -> EpisodeSpec:
    """The demo's episode: the paper's Fig. 4 instance on ``simple``, run seed ``seed``."""
    return EpisodeSpec.single("simple", method, delta_t, seed=seed, fixed=FIG4, sim=sim,
                              preset=preset)


def outcome(r: EpisodeResult) -> str:
    """Which of :data:`OUTCOMES` an episode had."""
    return OUTCOMES[0] if r.success else OUTCOMES[1] if r.goal_reached else OUTCOMES[2]


def run_demo(out: Path, seed: int = 0, sim: str = "mujoco", runs: int = DEMO_RUNS,
             preset: str = DEFAULT_PRESET) -> list[EpisodeResult]:
    """Run the demo, write videos, figures and tables (see module docstring)."""
    from ..viz.episodes import belief_figure, trajectories_figure
    from ..viz.mapdraw import save_map_figure

    out.mkdir(parents=True, exist_ok=True)
    world = cached_world("simple")
    print(f"pathpref demo: {runs} grid runs per method (preset {preset})", flush=True)
    rates, pick = [], {}
    for m in METHODS:
        res = [run_episode(demo_spec(m, seed + k, sim="grid", preset=preset))
               for k in range(runs)]
        kinds = Counter(outcome(r) for r in res)
        typical = kinds.most_common(1)[0][0]
        pick[m] = seed + next(k for k, r in enumerate(res) if outcome(r) == typical)
        wins = kinds[OUTCOMES[0]]
        lo, hi = wilson(wins, runs)
        rates.append({"method": m, "runs": runs, "success": wins / runs, "ci_low": round(lo, 3),
                      "ci_high": round(hi, 3), "other_route": kinds[OUTCOMES[1]],
                      "not_reached": kinds[OUTCOMES[2]], "rendered_run": pick[m]})
        print(f"  {m}: success {wins}/{runs}", flush=True)
    results = []
    for m in (m for m in METHODS if m not in REFERENCE_METHODS):
        spec = demo_spec(m, pick[m], sim=sim, preset=preset)
        if sim == "mujoco":
            from .rollout import record_rollout

            rrd = out / f"rollout_{m}.rrd" if m == "path_preference" else None
            rec = record_rollout(spec, video=out / f"rollout_{m}.mp4", rerun=rrd)
            results.append(rec.result)
            print(f"  {m}: {rec.frames} frames -> {out}/rollout_{m}.mp4", flush=True)
        else:
            results.append(run_episode(spec))
    save_map_figure(world, out / "map_simple.png")
    trajectories_figure(world, results, out / "trajectories.png")
    belief_figure(results, out / "belief.png")
    rows = [{"method": r.spec.method, "success": r.success, "goal_reached": r.goal_reached,
             "preference_followed": r.pref_followed, "steps": r.steps, "inputs": r.inputs,
             "p_true_goal_end": round(r.log[-1].p_true_goal, 3)} for r in results]
    with open(out / "summary.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    with open(out / "rates.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rates[0]))
        w.writeheader()
        w.writerows(rates)
    print(f"\npathpref demo ({sim}, preset {preset}): map 'simple', start (1,1), 10 candidates "
          f"on row 8, true goal (1,8), human push every {DEMO_DELTA_T} steps (seed {seed})\n")
    print(f"Over {runs} grid runs per method (success rate, 95% Wilson interval):\n")
    for r in rates:
        print(f"- {r['method']}: reached the goal by the preferred route in "
              f"{round(r['success'] * runs)}/{runs} runs ({r['success']:.2f} "
              f"[{r['ci_low']:.2f}, {r['ci_high']:.2f}]), by another route in "
              f"{r['other_route']}, not at all in {r['not_reached']}")
    print("\nRendered episodes (each method's most common outcome):\n")
    print("| method | success | goal reached | preference followed | steps | P(true goal) |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['method']} | {r['success']} | {r['goal_reached']} | "
              f"{r['preference_followed']} | {r['steps']} | {r['p_true_goal_end']} |")
    videos = ", rollout_*.mp4, rollout_path_preference.rrd" if sim == "mujoco" else ""
    print(f"\nwrote {out}/map_simple.png, trajectories.png, belief.png, summary.csv{videos}")
    return results
