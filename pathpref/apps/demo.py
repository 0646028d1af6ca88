"""``pathpref demo`` (``make demo``): what inferring the human's path preference is for.

The setting (found by ``scripts/demo_sweep.sh``, 1260 grid episodes stored with the command
and the preset that made them in :data:`SWEEP_JSON`, package data shipped in the wheel; every
cell in ``docs/results.md``): map ``simple``, random instances (start, 10 goal candidates, true
goal), a *corrective* human who pushes only when the robot leaves the preferred route
(reaction delay 1 step, misses 20% of needs; ΔT = 1). The demo prints the stored sweep's
verdict per setting ("MATTERS" only where path preference's 95% Wilson interval lies above
both goal only's and compliant's), naming the sweep's preset and saying so when it is not the
preset the demo runs with.

Then, all with one preset (``--preset``, default :data:`~pathpref.planning.pomdp.DEFAULT_PRESET`):

1. ``--runs`` grid runs per method in the corrective setting (the paper's four and the
   references ``goal_known`` and ``oracle``; the first 30 are the sweep's episodes of that
   cell, so with the sweep's preset and ``--runs 30`` the counts are the sweep's);
2. the filmed setting's success rate: path preference in that setting, ``k/n`` with its 95%
   Wilson interval over those ``n = --runs`` grid episodes, computed now (never stored);
3. how often path preference and goal only differ over those grid episodes, and the pair
   (:data:`FILM_PAIR`) filmed on one episode where path preference succeeds strictly and goal
   only does not (:data:`FILM_RULE`, :meth:`GridRates.film`: computed when the demo runs, the
   route rule of :func:`worth_filming` preferring among them), rendered in MuJoCo with force
   cues and the same corrective human (its push rule on the base, physics timing
   ``decision``; ``--sim grid``: the grid episodes, no video).

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
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from ..episode import EpisodeResult, EpisodeSpec, Physics, cached_world, run_episode
from ..experiments.report import wilson
from ..experiments.sweep import sweep_specs
from ..planning.policies import resolve_methods
from ..planning.pomdp import DEFAULT_PRESET

#: the demo's methods, the stored sweep's (``--methods all reference``, scripts/demo_sweep.sh):
#: the paper's four and the two reference methods
DEMO_METHODS = tuple(resolve_methods(["all", "reference"]))

DEMO_MAP = "simple"
#: the corrective human of the demo's setting (:mod:`pathpref.episode.corrective`), in the
#: grid and in the videos alike
DEMO_PUSH_RULE = "corrective delay=1 miss=0.2"
DEMO_DELTA_T = 1
#: the body the demo films (``robot_model``): the Stanford TidyBot
FILM_ROBOT = "tidybot"
#: grid-world runs per method behind the demo's rates, over DEMO_INSTANCES instances
DEMO_RUNS = 30
DEMO_INSTANCES = 5
#: the method whose filmed setting's success rate the demo states
FILM_METHOD = "path_preference"
#: the pair the demo films on one instance: the method, and the same robot told nothing of the
#: route (goal only)
FILM_PAIR = (FILM_METHOD, "goal_only")
#: how many of the rule's candidates the demo films at most before it stops looking for one
#: whose MuJoCo pair differs as its grid pair does
FILM_TRIES = 3
#: the filmed instance's preferred route (the oracle's path) takes at least this many steps...
FILM_MIN_STEPS = 8
#: ... crosses at least this many polytope boundaries (the preference decides them) ...
FILM_MIN_CROSSINGS = 2
#: ... and leaves at least this many of the episode's T_max steps spare (time for pushes)
FILM_MIN_SLACK = 10
OUTCOMES = ("by the preferred route", "by another route", "not at all")
#: the stored sweep (package data, shipped in the wheel; written by scripts/results.py from
#: the database of scripts/demo_sweep.sh, with the command and the preset that made it)
SWEEP_JSON = Path(__file__).resolve().with_name("demo_sweep.json")
#: the sweep's cell of the demo's setting
SWEEP_SETTING = {"map": DEMO_MAP, "sim": "grid", "human": "map", "push_rule": DEMO_PUSH_RULE,
                 "delta_t": DEMO_DELTA_T}


def demo_specs(method: str, runs: int = DEMO_RUNS, seed: int = 0,
               preset: str = DEFAULT_PRESET) -> list[EpisodeSpec]:
    """The demo's grid episodes of ``method``: the first ``runs`` of the sweep
    ``scripts/demo_sweep.sh`` runs in the corrective setting (instance-major, 5 instances)."""
    per = math.ceil(runs / DEMO_INSTANCES)
    specs = sweep_specs(DEMO_MAP, [method], [DEMO_DELTA_T], instances=DEMO_INSTANCES, runs=per,
                        seed=seed, preset=preset, push_rule=DEMO_PUSH_RULE)
    return specs[:runs]


def route_crossings(result: EpisodeResult) -> int:
    """How many polytope boundaries an episode's logged path crosses (cell to cell)."""
    world = cached_world(result.spec.map)
    poly = [int(world.cell_polytope[world.cell((s.x, s.y))]) for s in result.log]
    return sum(a != b for a, b in zip(poly, poly[1:], strict=False))


def worth_filming(spec: EpisodeSpec, oracle: EpisodeResult) -> bool:
    """The film rule on one episode: its preferred route (the oracle's path, ``L`` steps) has
    ``L >= FILM_MIN_STEPS``, crosses at least :data:`FILM_MIN_CROSSINGS` polytope boundaries
    and leaves ``T_max - L >=`` :data:`FILM_MIN_SLACK` steps spare. It reads the route's
    geometry only, never a filmed method's outcome."""
    return (oracle.steps >= FILM_MIN_STEPS and spec.t_max - oracle.steps >= FILM_MIN_SLACK
            and route_crossings(oracle) >= FILM_MIN_CROSSINGS)


def film_index(specs: list[EpisodeSpec], oracle: list[EpisodeResult]) -> int:
    """Which demo episode is filmed: the first run 0 of an instance
    :func:`worth_filming`; else the first episode."""
    for k, (s, r) in enumerate(zip(specs, oracle, strict=True)):
        if s.run == 0 and worth_filming(s, r):
            return k
    return 0


def wins_alone(a: EpisodeResult, b: EpisodeResult) -> bool:
    """Whether ``a`` is a strict success (the goal by the preferred route) and ``b`` is not."""
    return bool(a.success) and not b.success


def film_candidates(specs: list[EpisodeSpec], oracle: list[EpisodeResult],
                    pp: list[EpisodeResult], go: list[EpisodeResult]) -> list[int]:
    """The demo's episodes the film may show, in the order the rule prefers them: those where
    path preference (``pp``) is a strict success and goal only (``go``) is not, first the ones
    whose route is :func:`worth_filming` (each group in the sweep's instance-major order).
    Empty when the two never so differ. It reads outcomes of the two filmed methods on the
    demo's grid episodes, all of them, so it is a rule on where they differ, computed when
    the demo runs."""
    differ = [k for k in range(len(specs)) if wins_alone(pp[k], go[k])]
    good = [k for k in differ if worth_filming(specs[k], oracle[k])]
    return good + [k for k in differ if k not in good]


def differ_counts(pp: list[EpisodeResult], go: list[EpisodeResult]) -> tuple[int, int]:
    """Over paired episodes: in how many path preference alone succeeds strictly, in how many
    goal only alone."""
    return (sum(wins_alone(a, b) for a, b in zip(pp, go, strict=True)),
            sum(wins_alone(b, a) for a, b in zip(pp, go, strict=True)))


def tour_spec(seed: int, method: str = FILM_METHOD, preset: str = DEFAULT_PRESET,
              sim: str = "grid") -> EpisodeSpec:
    """The episode ``pathpref render --map simple --method METHOD --delta-t 1 --push-rule
    DEMO_PUSH_RULE --seed SEED`` shows (instance 0, run 0 of ``seed``), in ``sim``."""
    return EpisodeSpec.single(DEMO_MAP, method, DEMO_DELTA_T, seed=seed, sim=sim,
                              push_rule=DEMO_PUSH_RULE, preset=preset)


def tour_ok(seed: int, preset: str = DEFAULT_PRESET) -> bool:
    """Whether ``--seed`` ``seed`` may be the README picture's and the tour's episode: its
    preferred route is :func:`worth_filming` and its path preference episode in the grid is a
    strict success (the goal by the person's route)."""
    spec = tour_spec(seed, "oracle", preset)
    return (worth_filming(spec, run_episode(spec))
            and bool(run_episode(tour_spec(seed, FILM_METHOD, preset)).success))


def tour_seeds(preset: str = DEFAULT_PRESET, start: int = 0, limit: int = 1000):
    """The seeds :func:`tour_ok` accepts, ``start``, ``start + 1``, ... below ``limit``."""
    for seed in range(start, limit):
        if tour_ok(seed, preset):
            yield seed


def tour_seed(preset: str = DEFAULT_PRESET, limit: int = 1000) -> int:
    """The README picture's and the tour's episode: the first ``--seed`` 0, 1, 2, ... that
    :func:`tour_ok` accepts (``scripts/video_grid.py`` then films it, and the next one if
    the MuJoCo episode is not a strict success)."""
    for seed in tour_seeds(preset, 0, limit):
        return seed
    raise ValueError(f"no seed below {limit} has a route worth filming and a strict success")


FILM_RULE = (f"the first of the grid episodes above where path preference succeeds strictly "
             f"and goal only does not, among those whose preferred route (the oracle's path) "
             f"takes >= {FILM_MIN_STEPS} steps, crosses >= {FILM_MIN_CROSSINGS} polytope "
             f"boundaries and leaves >= {FILM_MIN_SLACK} of T_max steps spare (else the first "
             f"such episode); in MuJoCo the next such episode when the filmed pair does not "
             f"differ there, at most {FILM_TRIES} tried")


def film_spec(spec: EpisodeSpec, sim: str) -> EpisodeSpec:
    """The rendered version of a demo episode: in MuJoCo the same instance, run, preset and
    corrective human (its pushes at decision steps, the default physics) on MuJoCo
    Menagerie's Stanford TidyBot (:data:`FILM_ROBOT`); in the grid the episode itself."""
    if sim == "grid":
        return spec
    return replace(spec, sim="mujoco", physics=Physics.of(robot_model=FILM_ROBOT).to_json())


def load_sweep(path: Path = SWEEP_JSON) -> dict[str, Any] | None:
    """The stored sweep (command, preset, cells), None when the file is not here."""
    return json.loads(path.read_text()) if path.exists() else None


def sweep_preset(sweep: dict[str, Any]) -> str:
    """The preset that made the stored sweep (its cells' presets, joined when several)."""
    return sweep.get("preset") or " ".join(sorted({c["preset"] for c in sweep["cells"]}))


def sweep_cell(sweep: dict[str, Any], method: str) -> dict[str, Any] | None:
    """The stored sweep's cell of ``method`` in the demo's setting (:data:`SWEEP_SETTING`)."""
    for c in sweep["cells"]:
        if c["method"] == method and all(c.get(k) == v for k, v in SWEEP_SETTING.items()):
            return c
    return None


def sweep_statement(path: Path = SWEEP_JSON) -> list[str]:
    """Lines comparing path preference with goal only, compliant and the oracle in every
    setting of the stored sweep, each rate with its Wilson interval, and whether the
    preference's interval lies above both others' ("matters") or not."""
    if not path.exists():
        return [f"(the stored sweep {path} is missing: reinstall pathpref, whose wheel ships "
                "it as package data)"]
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
            ("hindsight", "hindsight optimisation, from outside the paper"),
            ("goal_known", "told the goal"), ("oracle", "knows the preference")) if m in by)
        out.append(f"- {setting}: {cell('path_preference')}; {cell('goal_only')}; "
                   f"{cell('compliant')}{refs} -> {verdict}")
    return out


def sweep_header(sweep: dict[str, Any] | None, preset: str) -> list[str]:
    """Where the stored sweep comes from (file, episodes, preset, command), and a note when its
    preset is not the one the demo runs with."""
    if sweep is None:
        return []
    n = sweep.get("episodes") or sum(c["n"] for c in sweep["cells"])
    per = sorted({c["n"] for c in sweep["cells"]})
    made = sweep_preset(sweep)
    lines = [f"stored sweep {SWEEP_JSON.name} (shipped with pathpref): {n} grid episodes, "
             f"{'/'.join(map(str, per))} per cell, preset {made}, made by `{sweep['command']}`"]
    if made != preset:
        lines.append(f"NOTE: the stored sweep was made with preset {made}; this demo runs "
                     f"preset {preset}, so its counts below need not match the sweep's")
    return lines


@dataclass
class GridRates:
    """The demo's grid runs in the corrective setting: per method its specs, results and a row
    of ``rates.csv``."""

    runs: int
    preset: str
    specs: dict[str, list[EpisodeSpec]]
    results: dict[str, list[EpisodeResult]]
    rows: list[dict[str, Any]]

    def row(self, method: str) -> dict[str, Any]:
        """The ``rates.csv`` row of ``method``."""
        return next(r for r in self.rows if r["method"] == method)

    def film_candidates(self) -> list[int]:
        """The episodes the film may show, preferred first (:func:`film_candidates`)."""
        return film_candidates(self.specs["oracle"], self.results["oracle"],
                               self.results[FILM_PAIR[0]], self.results[FILM_PAIR[1]])

    def differ_line(self) -> str:
        """How often the filmed pair's outcomes differ over these episodes."""
        a, b = differ_counts(self.results[FILM_PAIR[0]], self.results[FILM_PAIR[1]])
        return (f"Path preference and goal only differ in {a + b}/{self.runs} of these "
                f"episodes: path preference succeeds strictly and goal only does not in {a}, "
                f"the reverse in {b}")

    def film(self, sim: str, play=None) -> tuple[int, list[EpisodeResult], int]:
        """Film the pair (:data:`FILM_PAIR`) on the rule's episode (:data:`FILM_RULE`): the
        preferred candidate first; in MuJoCo the next one while the filmed path preference
        is not a strict success where goal only is not, at most :data:`FILM_TRIES`.
        ``play(spec) -> EpisodeResult`` runs (or records) one episode (default
        :func:`run_episode`). Returns the index filmed, the pair's results and how many
        candidates were filmed. No candidate (the two never so differ): the route rule's
        episode (:func:`film_index`)."""
        play = play or run_episode
        order = self.film_candidates() or [film_index(self.specs["oracle"],
                                                      self.results["oracle"])]
        tried = 0
        for k in order[:FILM_TRIES if sim == "mujoco" else 1]:
            tried += 1
            pair = [play(film_spec(self.specs[m][k], sim)) for m in FILM_PAIR]
            if wins_alone(*pair):
                break
        return k, pair, tried


def outcome(r: EpisodeResult) -> str:
    """Which of :data:`OUTCOMES` an episode had."""
    return OUTCOMES[0] if r.success else OUTCOMES[1] if r.goal_reached else OUTCOMES[2]


def grid_rates(runs: int = DEMO_RUNS, seed: int = 0, preset: str = DEFAULT_PRESET,
               log=None) -> GridRates:
    """Run ``runs`` grid episodes per method in the demo's setting (:func:`demo_specs`) and
    count their outcomes; ``log(line)`` hears one line per method."""
    specs_of, res_of, rows = {}, {}, []
    for m in DEMO_METHODS:
        specs = demo_specs(m, runs, seed, preset)
        res = [run_episode(s) for s in specs]
        specs_of[m], res_of[m] = specs, res
        kinds = Counter(outcome(r) for r in res)
        wins = kinds[OUTCOMES[0]]
        lo, hi = wilson(wins, runs)
        rows.append({"method": m, "runs": runs, "success": wins / runs, "ci_low": round(lo, 3),
                     "ci_high": round(hi, 3), "other_route": kinds[OUTCOMES[1]],
                     "not_reached": kinds[OUTCOMES[2]],
                     "homotopy_success": sum(r.homotopy_success for r in res),
                     "pushes_per_episode": round(sum(r.inputs for r in res) / runs, 3)})
        if log is not None:
            log(f"  {m}: success {wins}/{runs}")
    return GridRates(runs, preset, specs_of, res_of, rows)


def rate_line(method: str, k: int, n: int, other: int, not_reached: int,
              pushes: float) -> str:
    """One method's outcome counts over ``n`` runs, success with its 95% Wilson interval."""
    lo, hi = wilson(k, n)
    return (f"- {method}: reached the goal by the preferred route in {k}/{n} runs "
            f"({k / n:.2f} [{lo:.2f}, {hi:.2f}]), by another route in {other}, not at all in "
            f"{not_reached}; {pushes:.2f} pushes per episode")


def cell_rate_line(cell: dict[str, Any]) -> str:
    """:func:`rate_line` of a stored sweep cell (what the demo's re-run prints when its preset
    and ``--runs`` are the sweep's)."""
    n, k, reached = cell["n"], cell["success"], cell["goal_reached"]
    return rate_line(cell["method"], k, n, reached - k, n - reached,
                     cell["pushes_per_episode"])


#: the markers of the block of docs/demo.md written by scripts/demo_doc.py
DOC_BEGIN = "<!-- demo-numbers: written by `python scripts/demo_doc.py`; do not edit by hand -->"
DOC_END = "<!-- /demo-numbers -->"


def doc_block(rates: GridRates, k: int, film: list[EpisodeResult],
              tried: int) -> list[str]:
    """The numbers of docs/demo.md (between :data:`DOC_BEGIN` and :data:`DOC_END`): the stored
    sweep's verdicts, the demo's grid rates, how often the filmed pair differs, the filmed
    setting's rate and the filmed episodes (``film``: the pair on episode ``k``, the MuJoCo
    body, no video; ``tried`` candidates filmed, :meth:`GridRates.film`)."""
    sweep = load_sweep()
    lines = [DOC_BEGIN, "", f"Preset `{rates.preset}` (the planner's default when this was "
             "written; `pathpref demo` computes every number below again when it runs, under "
             "its `--preset`).", "", "Where it matters: the "
             + "; ".join(sweep_header(sweep, rates.preset)) + ":", "",
             *sweep_statement(), "",
             f"The demo's re-run (`pathpref demo`, seed 0): n = {rates.runs} grid runs per "
             f"method on `{DEMO_MAP}`, human `{DEMO_PUSH_RULE}` (ΔT = {DEMO_DELTA_T}):", ""]
    for r in rates.rows:
        lines.append(rate_line(r["method"], round(r["success"] * rates.runs), rates.runs,
                               r["other_route"], r["not_reached"], r["pushes_per_episode"]))
    lines += ["", filmed_rate_line(rates) + ".", "", rates.differ_line() + ".", "",
              f"The filmed episode: {filmed_episode(rates, k, tried)}. Its MuJoCo episodes "
              "(the same corrective human pushing the Stanford TidyBot; default physics):", "",
              "| method | success | goal reached | preference followed | pushes | steps |",
              "|---|---|---|---|---|---|"]
    for r in film:
        lines.append(f"| {r.spec.method} | {r.success} | {r.goal_reached} | {r.pref_followed} "
                     f"| {r.inputs} | {r.steps} |")
    return [*lines, "", DOC_END]


def filmed_episode(rates: GridRates, k: int, tried: int) -> str:
    """Which episode the film shows and by which rule."""
    spec = rates.specs["oracle"][k]
    return (f"instance {spec.instance}, run {spec.run} ({FILM_RULE}; "
            f"{tried} filmed)")


def filmed_setting(preset: str) -> str:
    """The filmed setting in words: map, method, human, push rule, preset."""
    return (f"{DEMO_MAP}, {FILM_METHOD}, the map's human, push rule '{DEMO_PUSH_RULE}' "
            f"(ΔT = {DEMO_DELTA_T}), preset {preset}")


def filmed_rate_line(rates: GridRates) -> str:
    """How often the filmed setting succeeds over the demo's grid episodes, with its
    interval."""
    r = rates.row(FILM_METHOD)
    k = round(r["success"] * rates.runs)
    return (f"The filmed setting ({filmed_setting(rates.preset)}) succeeds in {k}/{rates.runs} "
            f"grid episodes, {r['success']:.2f} [95% Wilson {r['ci_low']:.2f}, "
            f"{r['ci_high']:.2f}]")


def rerun_source(runs: int) -> str:
    """Which of the sweep's episodes a re-run of ``runs`` per method is (:func:`demo_specs`)."""
    per = math.ceil(runs / DEMO_INSTANCES)
    if runs == DEMO_RUNS:
        return "exactly the sweep's episodes of that cell"
    return (f"drawn as the sweep draws them: runs 0..{per - 1} of its {DEMO_INSTANCES} "
            f"instances, the first {runs}; --runs {DEMO_RUNS} is exactly the sweep's cell")


def run_demo(out: Path, seed: int = 0, sim: str = "mujoco", runs: int = DEMO_RUNS,
             preset: str = DEFAULT_PRESET) -> list[EpisodeResult]:
    """Run the demo, write videos, figures and tables (see module docstring)."""
    from ..viz.episodes import belief_figure, trajectories_figure
    from ..viz.mapdraw import save_map_figure
    from ..viz.plots import success_pushes_figure

    out.mkdir(parents=True, exist_ok=True)
    world = cached_world(DEMO_MAP)
    sweep = load_sweep()
    print(f"pathpref demo (preset {preset}): where inferring the path preference matters "
          "(success [95% Wilson CI]).\n", flush=True)
    for line in [*sweep_header(sweep, preset), "", *sweep_statement()]:
        print(line, flush=True)
    print(f"\nRe-running the setting with preset {preset}: {DEMO_MAP}, human '{DEMO_PUSH_RULE}' "
          f"(ΔT = {DEMO_DELTA_T}), n = {runs} grid runs per method ({rerun_source(runs)})",
          flush=True)
    rates = grid_rates(runs, seed, preset, log=lambda line: print(line, flush=True))
    print(f"{rates.differ_line()}.", flush=True)

    def play(spec: EpisodeSpec) -> EpisodeResult:
        """Record one filmed episode (MuJoCo: video, and a rerun file for path preference)."""
        if sim != "mujoco":
            return run_episode(spec)
        from .rollout import record_rollout

        m = spec.method
        rrd = out / f"rollout_{m}.rrd" if m == FILM_METHOD else None
        rec = record_rollout(spec, video=out / f"rollout_{m}.mp4", rerun=rrd)
        print(f"  {m} (instance {spec.instance}, run {spec.run}): {rec.frames} frames -> "
              f"{out}/rollout_{m}.mp4", flush=True)
        return rec.result

    k, results, tried = rates.film(sim, play)
    save_map_figure(world, out / "map_simple.png")
    trajectories_figure(world, results, out / "trajectories.png")
    belief_figure(results, out / "belief.png")
    figures = "map_simple.png, trajectories.png, belief.png"
    if sweep is not None:
        success_pushes_figure(sweep["cells"], out / "success_vs_pushes.png")
        figures += ", success_vs_pushes.png"
    rows = [{"method": r.spec.method, "success": r.success, "goal_reached": r.goal_reached,
             "preference_followed": r.pref_followed, "homotopy_success": r.homotopy_success,
             "steps": r.steps, "inputs": r.inputs,
             "p_true_goal_end": round(r.log[-1].p_true_goal, 3)} for r in results]
    with open(out / "summary.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    with open(out / "rates.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rates.rows[0]))
        w.writeheader()
        w.writerows(rates.rows)
    print(f"\nOver n = {runs} grid runs per method, corrective human, preset {preset} (success "
          "rate, 95% Wilson interval):\n")
    for r in rates.rows:
        print(rate_line(r["method"], round(r["success"] * runs), runs, r["other_route"],
                        r["not_reached"], r["pushes_per_episode"]))
    print(f"\n{filmed_rate_line(rates)}; the film below is one episode of it.")
    print(f"{rates.differ_line()}.")
    body = ("MuJoCo, the same corrective human pushing the Stanford TidyBot" if sim == "mujoco"
            else "grid")
    print(f"\nRendered episodes ({body}; preset {preset}; {filmed_episode(rates, k, tried)}):\n")
    print("| method | success | goal reached | preference followed | homotopy-level success "
          "| pushes | steps | P(true goal) |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['method']} | {r['success']} | {r['goal_reached']} | "
              f"{r['preference_followed']} | {r['homotopy_success']} | {r['inputs']} | "
              f"{r['steps']} | {r['p_true_goal_end']} |")
    videos = ", rollout_*.mp4, rollout_path_preference.rrd" if sim == "mujoco" else ""
    print(f"\nwrote {out}/{figures}, rates.csv, summary.csv{videos}")
    if not wins_alone(*results):
        print("NOTE: on the filmed episode path preference does not succeed strictly where goal "
              "only fails (none of the candidates tried differs so in MuJoCo)")
    return results
