"""Computation times at the first decision (the paper's Table II).

For each of ``instances`` random instances: one human heading at the start, the time of the
belief update it causes, and the time of the POMCP search at full depth ``T_max``, for the
goal-only and the path-preference methods. Reported as mean +- 95% CI (``1.96 std / sqrt(n)``).
The likelihood tables are built per instance beforehand (once per map and goal set) and are not
part of the update time.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from ..episode import cached_world, sample_instance, seed_for
from ..inference.belief import GoalBelief, PreferenceBelief
from ..inference.human import ObservationModel, SimulatedHuman
from ..planning.pomcp import POMCP
from ..planning.pomdp import get_preset
from .paper import TABLE_II


def mean_ci(x: list[float]) -> tuple[float, float]:
    """Mean and the half-width of its 95% normal interval (``1.96 s / sqrt(n)``)."""
    a = np.asarray(x, float)
    if len(a) < 2:
        return float(a.mean()), float("nan")
    return float(a.mean()), float(1.96 * a.std(ddof=1) / np.sqrt(len(a)))


def time_map(map_name: str, instances: int = 100, queries: int = 5000, preset: str = "paper",
             seed: int = 0, t_max: int | None = None, progress=None) -> dict[str, Any]:
    """Table II figures for one map (ms)."""
    world = cached_world(map_name)
    pref = world.require_preference()
    p = get_preset(preset)
    depth = t_max or world.spec.t_max
    out: dict[str, list[float]] = {k: [] for k in
                                    ("solve_goal_only", "solve_path_pref", "update_goal_only",
                                     "update_path_pref")}
    for i in range(instances):
        inst = sample_instance(world, seed_for(seed, i, 7))
        goals = np.array(inst.goals)
        model = ObservationModel.build(world, goals)
        _ = (model.cell_likelihood, model.goal_likelihood)  # build the tables outside the timing
        rng = np.random.default_rng(seed_for(seed, i, 8))
        heading = SimulatedHuman(model, inst.true_goal, pref).sample(inst.start, rng)
        for method, belief, rewards in (
            ("goal_only", GoalBelief(model), p.goal_only),
            ("path_pref", PreferenceBelief(model), p.path_preference),
        ):
            t = time.perf_counter()
            belief.update(inst.start, heading)
            out[f"update_{method}"].append(1e3 * (time.perf_counter() - t))
            planner = POMCP(world, goals, rewards, queries=queries, c=p.ucb_c)
            if i == 0:
                planner.search(inst.start, belief, depth, 0)  # compile / warm caches
            t = time.perf_counter()
            planner.search(inst.start, belief, depth, seed_for(seed, i, 9))
            out[f"solve_{method}"].append(1e3 * (time.perf_counter() - t))
        if progress is not None:
            progress.update(1)
    res: dict[str, Any] = {"map": map_name, "instances": instances, "depth": depth,
                           "queries": queries}
    for k, v in out.items():
        res[k + "_ms"], res[k + "_ci_ms"] = mean_ci(v)
    return res


def timing_markdown(results: list[dict[str, Any]]) -> str:
    """Markdown table of :func:`time_map` results with the paper's Table II beside them."""
    lines = ["| map | solve goal only (ms) | solve path pref (ms) | update goal only (ms) | "
             "update path pref (ms) |", "|---|---|---|---|---|"]
    for r in results:
        cells = [f"{r[k + '_ms']:.3g} ± {r[k + '_ci_ms']:.2g}" for k in
                 ("solve_goal_only", "solve_path_pref", "update_goal_only", "update_path_pref")]
        lines.append(f"| {r['map']} | " + " | ".join(cells) + " |")
        if r["map"] in TABLE_II:
            lines.append(f"| {r['map']} (paper) | " + " | ".join(
                f"{v:g}" for v in TABLE_II[r["map"]]) + " |")
    return "\n".join(lines)
