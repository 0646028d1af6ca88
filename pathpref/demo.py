"""The main job (``make demo``): one episode per method on the paper's Fig. 4 instance, in
MuJoCo with force cues (``--sim grid`` for the grid world only).

Writes to the output folder:

* ``rollout_<method>.mp4`` (MuJoCo): top-down and perspective views, belief-tinted goals, pushes;
* ``rollout_path_preference.rrd``: a rerun recording (open with ``rerun FILE``);
* ``map_simple.png``: the map with polytopes, graph and the human's preference;
* ``trajectories.png``: the path of each method, with the human's pushes as arrows;
* ``belief.png``: P(true goal) and goal entropy along each episode;
* ``summary.csv`` and a table on stdout: success, goal reached, preference followed, steps.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

from .experiments.episode import EpisodeResult, EpisodeSpec, cached_world, run_episode
from .experiments.instances import FIG4, seed_for
from .planning.policies import METHODS

DEMO_DELTA_T = 3


def demo_spec(method: str, seed: int = 0, delta_t: int = DEMO_DELTA_T,
              sim: str = "mujoco") -> EpisodeSpec:
    fixed = json.dumps({"start": list(FIG4["start"]), "goals": [list(g) for g in FIG4["goals"]],
                        "true_goal": FIG4["true_goal"], "free_goal_polytope": True},
                       sort_keys=True)
    return EpisodeSpec(map="simple", method=method, delta_t=delta_t, instance=0, run=seed,
                       instance_seed=seed_for(seed, 0), run_seed=seed_for(seed, 0, 0),
                       fixed=fixed, sim=sim)


def run_demo(out: Path, seed: int = 0, sim: str = "mujoco") -> list[EpisodeResult]:
    """Run the demo episodes, write videos, figures and the table (see module docstring)."""
    from .viz.episodes import belief_figure, trajectories_figure
    from .viz.mapdraw import save_map_figure

    out.mkdir(parents=True, exist_ok=True)
    world = cached_world("simple")
    results = []
    for m in METHODS:
        spec = demo_spec(m, seed, sim=sim)
        if sim == "mujoco":
            from .sim.rollout import record_rollout

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
    print(f"\npathpref demo ({sim}): map 'simple', start (1,1), 10 candidates on row 8, true goal "
          f"(1,8), human push every {DEMO_DELTA_T} steps (seed {seed})\n")
    print("| method | success | goal reached | preference followed | steps | P(true goal) |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['method']} | {r['success']} | {r['goal_reached']} | "
              f"{r['preference_followed']} | {r['steps']} | {r['p_true_goal_end']} |")
    videos = ", rollout_*.mp4, rollout_path_preference.rrd" if sim == "mujoco" else ""
    print(f"\nwrote {out}/map_simple.png, trajectories.png, belief.png, summary.csv{videos}")
    return results
