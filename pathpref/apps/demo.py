"""The main job (``make demo``): what inferring the human's path preference is for.

The setting (found by ``scripts/demo_sweep.sh``, 1080 grid episodes; every cell in
``docs/results/demo_sweep.json`` and ``docs/results.md``): map ``simple``, random instances
(start, 10 goal candidates, true goal), a *corrective* human who pushes only when the robot
leaves the preferred route (reaction delay 1 step, misses 20% of needs; ΔT = 1). There path
preference reaches the goal by the preferred route in 29/30 runs, goal only in 12/30 and
compliant in 14/30, the oracle (knows the preference) in 30/30 and goal_known (told the true
goal) in 29/30; goal only reaches the goal by another route in 16/30. With a periodic human (a push
every ΔT steps) on ``simple``, and on ``office``, the gap to goal only is within the intervals:
there inferring the preference does not measurably matter. The demo prints that table from the
stored sweep, then re-runs the setting itself.

Steps: ``--runs`` grid runs per method (the paper's four and the references ``goal_known``
and ``oracle``; the first 30 are the sweep's episodes, so the rates reproduce its cell), then
one episode per method of the paper (:func:`film_index`: not picked for its outcome) rendered in
MuJoCo with force cues. The corrective human exists in the grid world only, so the MuJoCo
episodes use the periodic human at ΔT = :data:`FILM_DELTA_T` on the same instance (``--sim
grid``: the corrective episodes, no video). Preset: the default
(:data:`~pathpref.planning.pomdp.DEFAULT_PRESET`); ``--preset paper`` for the paper's planner.

Writes to the output folder:

* ``rollout_<method>.mp4`` (MuJoCo): top-down and perspective views, belief-tinted goals,
  pushes; the final step, then an outcome card (success, route, homotopy-level success, pushes,
  steps) held 1 s;
* ``rollout_path_preference.rrd``: a rerun recording (open with ``rerun FILE``);
* ``map_simple.png``: the map with polytopes, graph and the human's preference;
* ``trajectories.png``: the path of each rendered episode, with the human's pushes as arrows;
* ``belief.png``: P(true goal) and goal entropy along each rendered episode;
* ``success_vs_pushes.png``: success against pushes per episode of the stored sweep, one point
  per method and human setting with its Wilson interval;
* ``rates.csv``: per method, runs reaching the goal by the preferred route (success), by another
  route, or not at all, with the success rate's 95% Wilson interval;
* ``summary.csv`` and a table on stdout: the rendered episodes.
"""

from __future__ import annotations

import csv
import json
import math
from collections import Counter
from dataclasses import replace
from pathlib import Path

from ..episode import EpisodeResult, EpisodeSpec, cached_world, run_episode
from ..experiments.report import wilson
from ..experiments.sweep import sweep_specs
from ..planning.policies import METHODS, REFERENCE_METHODS
from ..planning.pomdp import DEFAULT_PRESET

DEMO_MAP = "simple"
#: the corrective human of the demo's setting (:mod:`pathpref.episode.corrective`)
DEMO_PUSH_RULE = "corrective delay=1 miss=0.2"
DEMO_DELTA_T = 1
#: the periodic human of the MuJoCo episodes (the corrective one is grid-only)
FILM_DELTA_T = 10
#: grid-world runs per method behind the demo's rates, over DEMO_INSTANCES instances
DEMO_RUNS = 30
#: the rendered instance's preferred route is at least this long (a short one shows nothing)
FILM_MIN_STEPS = 8
DEMO_INSTANCES = 5
OUTCOMES = ("by the preferred route", "by another route", "not at all")
#: the stored sweep the demo's statement quotes (in a source checkout)
SWEEP_JSON = Path(__file__).resolve().parents[2] / "docs" / "results" / "demo_sweep.json"


def demo_specs(method: str, runs: int = DEMO_RUNS, seed: int = 0,
               preset: str = DEFAULT_PRESET) -> list[EpisodeSpec]:
    """The demo's grid episodes of ``method``: the first ``runs`` of the sweep
    ``scripts/demo_sweep.sh`` runs in the corrective setting (instance-major, 5 instances)."""
    per = math.ceil(runs / DEMO_INSTANCES)
    specs = sweep_specs(DEMO_MAP, [method], [DEMO_DELTA_T], instances=DEMO_INSTANCES, runs=per,
                        seed=seed, preset=preset, push_rule=DEMO_PUSH_RULE)
    return specs[:runs]


def film_index(specs: list[EpisodeSpec], oracle: list[EpisodeResult]) -> int:
    """Which demo episode is rendered: the first run 0 of an instance whose preferred route
    (the oracle's path) takes at least :data:`FILM_MIN_STEPS` steps, else the first episode.
    The choice reads the route's length only, never a method's outcome."""
    for k, (s, r) in enumerate(zip(specs, oracle, strict=True)):
        if s.run == 0 and r.steps >= FILM_MIN_STEPS:
            return k
    return 0


def film_spec(spec: EpisodeSpec, sim: str) -> EpisodeSpec:
    """The rendered version of a demo episode: in MuJoCo the periodic human every
    :data:`FILM_DELTA_T` steps on the same instance and run (default physics); in the grid the
    episode itself."""
    if sim == "grid":
        return spec
    return replace(spec, sim="mujoco", delta_t=FILM_DELTA_T, push_rule="", physics=None)


def sweep_statement(path: Path = SWEEP_JSON) -> list[str]:
    """Lines comparing path preference with goal only, compliant and the oracle in every
    setting of the stored sweep, each rate with its Wilson interval, and whether the
    preference's interval lies above both others' ("matters") or not."""
    if not path.exists():
        return [f"(the stored sweep {path} is not here: run scripts/demo_sweep.sh)"]
    cells = json.loads(path.read_text())["cells"]
    out = []
    for setting in dict.fromkeys(c["setting"] for c in cells):
        by = {c["method"]: c for c in cells if c["setting"] == setting}
        if not {"path_preference", "goal_only", "compliant"} <= set(by):
            continue

        pp = by["path_preference"]["success_ci"][0]
        rivals = max(by[m]["success_ci"][1] for m in ("goal_only", "compliant"))
        verdict = ("inferring the preference MATTERS" if pp > rivals else
                   "no measurable gain over goal only / compliant at this n")
        def cell(m: str, c: dict = by) -> str:
            lo, hi = c[m]["success_ci"]
            return f"{m} {c[m]['success']}/{c[m]['n']} [{lo:.2f}, {hi:.2f}]"

        refs = "".join(f"; {cell(m)} ({what})" for m, what in (
            ("goal_known", "told the goal"), ("oracle", "knows the preference")) if m in by)
        out.append(f"- {setting}: {cell('path_preference')}; {cell('goal_only')}; "
                   f"{cell('compliant')}{refs} -> {verdict}")
    return out


def outcome(r: EpisodeResult) -> str:
    """Which of :data:`OUTCOMES` an episode had."""
    return OUTCOMES[0] if r.success else OUTCOMES[1] if r.goal_reached else OUTCOMES[2]


def run_demo(out: Path, seed: int = 0, sim: str = "mujoco", runs: int = DEMO_RUNS,
             preset: str = DEFAULT_PRESET) -> list[EpisodeResult]:
    """Run the demo, write videos, figures and tables (see module docstring)."""
    from ..viz.episodes import belief_figure, trajectories_figure
    from ..viz.mapdraw import save_map_figure
    from ..viz.plots import success_pushes_figure

    out.mkdir(parents=True, exist_ok=True)
    world = cached_world(DEMO_MAP)
    print(f"pathpref demo: where inferring the path preference matters (stored sweep "
          f"{SWEEP_JSON.name}, 30 grid episodes per cell, success [95% Wilson CI]):\n", flush=True)
    for line in sweep_statement():
        print(line, flush=True)
    print(f"\nRe-running the setting: {DEMO_MAP}, human '{DEMO_PUSH_RULE}' (ΔT = {DEMO_DELTA_T}), "
          f"{runs} grid runs per method (preset {preset})", flush=True)
    rates, specs_of, res_of = [], {}, {}
    for m in METHODS:
        specs = demo_specs(m, runs, seed, preset)
        res = [run_episode(s) for s in specs]
        specs_of[m], res_of[m] = specs, res
        kinds = Counter(outcome(r) for r in res)
        wins = kinds[OUTCOMES[0]]
        lo, hi = wilson(wins, runs)
        rates.append({"method": m, "runs": runs, "success": wins / runs, "ci_low": round(lo, 3),
                      "ci_high": round(hi, 3), "other_route": kinds[OUTCOMES[1]],
                      "not_reached": kinds[OUTCOMES[2]],
                      "homotopy_success": sum(r.homotopy_success for r in res),
                      "pushes_per_episode": round(sum(r.inputs for r in res) / runs, 3)})
        print(f"  {m}: success {wins}/{runs}", flush=True)
    k = film_index(specs_of["oracle"], res_of["oracle"])
    results = []
    for m in (m for m in METHODS if m not in REFERENCE_METHODS):
        spec = film_spec(specs_of[m][k], sim)
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
    if SWEEP_JSON.exists():
        success_pushes_figure(json.loads(SWEEP_JSON.read_text())["cells"],
                              out / "success_vs_pushes.png")
    rows = [{"method": r.spec.method, "success": r.success, "goal_reached": r.goal_reached,
             "preference_followed": r.pref_followed, "homotopy_success": r.homotopy_success,
             "steps": r.steps, "inputs": r.inputs,
             "p_true_goal_end": round(r.log[-1].p_true_goal, 3)} for r in results]
    with open(out / "summary.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    with open(out / "rates.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rates[0]))
        w.writeheader()
        w.writerows(rates)
    print(f"\nOver {runs} grid runs per method, corrective human (success rate, 95% Wilson "
          "interval):\n")
    for r in rates:
        print(f"- {r['method']}: reached the goal by the preferred route in "
              f"{round(r['success'] * runs)}/{runs} runs ({r['success']:.2f} "
              f"[{r['ci_low']:.2f}, {r['ci_high']:.2f}]), by another route in "
              f"{r['other_route']}, not at all in {r['not_reached']}; "
              f"{r['pushes_per_episode']:.2f} pushes per episode")
    human = (f"the periodic human every ΔT = {FILM_DELTA_T} steps (the corrective human is "
             "grid-only)" if sim == "mujoco" else f"human '{DEMO_PUSH_RULE}'")
    print(f"\nRendered episodes ({sim}; instance {specs_of['oracle'][k].instance}, run 0 of every "
          f"method: the first instance whose preferred route takes >= {FILM_MIN_STEPS} steps, "
          f"not picked for an outcome; {human}):\n")
    print("| method | success | goal reached | preference followed | homotopy-level success "
          "| pushes | steps | P(true goal) |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['method']} | {r['success']} | {r['goal_reached']} | "
              f"{r['preference_followed']} | {r['homotopy_success']} | {r['inputs']} | "
              f"{r['steps']} | {r['p_true_goal_end']} |")
    videos = ", rollout_*.mp4, rollout_path_preference.rrd" if sim == "mujoco" else ""
    print(f"\nwrote {out}/map_simple.png, trajectories.png, belief.png, success_vs_pushes.png, "
          f"rates.csv, summary.csv{videos}")
    return results
