"""``maps`` section: per map, setup (arrangement, cost tables), belief updates and POMCP
decisions (paper and robust search), next to the paper's Table II."""

from __future__ import annotations

import os
import platform
import time
from dataclasses import replace
from statistics import median
from typing import Any

import numpy as np

from ...episode.runner import EpisodeRunner
from ...episode.spec import EpisodeSpec
from ...experiments import paper
from ...geometry.maps import load_map
from ...geometry.world import World
from ...inference.belief import GoalBelief, PreferenceBelief
from ...inference.human import ObservationModel
from ...inference.priors import PriorInputs, make_belief
from ...inference.routes import RouteBelief
from ...planning.crossing import check_crossing
from ...planning.pomcp import POMCP
from ...planning.pomdp import DEFAULT_PRESET, get_preset


# --- maps: setup, belief, POMCP ------------------------------------------------------------
def _timeit(fn, repeat: int) -> list[float]:
    """Wall times (s) of ``repeat`` calls of ``fn`` (``time.perf_counter``)."""
    out = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t)
    return out


def bench_map(name: str, quick: bool = False, seed: int = 0) -> dict[str, Any]:
    """Build, table and belief-update timings for one map (10 goal candidates): wall clock
    for the setup (``arrangement_build_s``, ``cost_tables_s``, ``setup_s``) and the belief
    updates (``belief_update_ms``, ``_p99_ms``, ``goal_belief_update_ms``); CPU time for the
    route prior's update, the default preset's first decisions and its decision steps."""
    rng = np.random.default_rng(seed)
    spec = load_map(name)
    reps = 3 if quick else 7
    build = _timeit(lambda: World.from_spec(spec), reps)
    world = World.from_spec(spec)
    goals = rng.choice(world.n_cells, size=min(10, world.n_cells), replace=False)

    def tables():
        m = ObservationModel.build(world, goals)
        return m.cell_likelihood, m.goal_likelihood

    tab = _timeit(tables, reps)
    model = ObservationModel.build(world, goals)
    n_upd = 200 if quick else 1000
    cells = rng.integers(0, world.n_cells, size=n_upd)
    heads = rng.integers(0, 8, size=n_upd)
    pb, gb = PreferenceBelief(model), GoalBelief(model)
    pb.update(0, 0)
    gb.update(0, 0)  # warm the cached tables
    t_pref, t_goal = [], []
    for c, h in zip(cells.tolist(), heads.tolist(), strict=True):
        t = time.perf_counter()
        pb.update(c, h)
        t_pref.append(time.perf_counter() - t)
        t = time.perf_counter()
        gb.update(c, h)
        t_goal.append(time.perf_counter() - t)
    planning = bench_pomcp(world, name, quick=quick, seed=seed)
    first = bench_first_decisions(name, instances=5 if quick else 20, seed=seed)
    routes = bench_route_update(model, pushes=20 if quick else 40, seed=seed)
    decisions = bench_default_decisions(name, episodes=2 if quick else 6, seed=seed)
    return {
        "polytopes": world.n_polytopes,
        "edges": world.graph.n_edges,
        "free_cells": world.n_cells,
        "arrangement_build_s": median(build),
        "cost_tables_s": median(tab),
        "setup_s": median(build) + median(tab),
        "belief_update_ms": 1e3 * median(t_pref),
        "belief_update_p99_ms": 1e3 * float(np.percentile(t_pref, 99)),
        "goal_belief_update_ms": 1e3 * median(t_goal),
        "belief_updates": n_upd,
        "paper_belief_update_ms": paper.update_ms(name),
        **planning,
        **first,
        **decisions,
        **routes,
    }


def bench_route_update(model: ObservationModel, pushes: int = 40, seed: int = 0
                       ) -> dict[str, Any]:
    """The route prior's update: CPU time of one push (``update``) and the goal marginal
    after it, median and mean over ``pushes`` pushes at random cells with random headings
    (almost every one in a polytope not yet observed, the case that grows the observed set;
    the belief of every candidate is solved after each)."""
    rng = np.random.default_rng(seed + 2)
    world = model.world
    belief = RouteBelief(model)
    belief.goal_marginal()
    out = []
    for c, h in zip(rng.integers(0, world.n_cells, size=pushes).tolist(),
                    rng.integers(0, 8, size=pushes).tolist(), strict=True):
        t = time.process_time()
        belief.update(c, h)
        belief.goal_marginal()
        out.append(time.process_time() - t)
    return {"route_update_ms": 1e3 * median(out),
            "route_update_mean_ms": 1e3 * float(np.mean(out)),
            "route_update_pushes": pushes,
            "route_update_observed_polytopes": len(belief.observed_polytopes())}


def bench_first_decisions(name: str, instances: int = 20, seed: int = 0) -> dict[str, Any]:
    """``robust_decision_ms`` and ``robust_goal_only_decision_ms``: the median CPU time (ms) of
    the first decision step of an episode under the default preset
    (:data:`~pathpref.planning.pomdp.DEFAULT_PRESET`), path preference and goal only, ΔT = 5,
    the preset's queries, over ``instances`` instances (the sweeps' rule, ``seed``) after one
    warm-up instance that compiles or loads the kernels. The step is the whole decision as an
    episode runs it: the human's first push and the belief's update, the search from that
    belief (the route posterior's solve and the root pool included), the crossing check and
    the wait budget. ``robust_decision_preset`` names the preset."""
    out: dict[str, list[float]] = {"path_preference": [], "goal_only": []}
    for method, times in out.items():
        for i in range(instances + 1):
            spec = EpisodeSpec.single(name, method, 5, seed=seed, instance=i,
                                      preset=DEFAULT_PRESET)
            runner = EpisodeRunner(spec)
            t = time.process_time()
            runner.step()
            if i > 0:
                times.append(time.process_time() - t)
    return {"robust_decision_preset": DEFAULT_PRESET,
            "robust_decision_ms": 1e3 * median(out["path_preference"]),
            "robust_goal_only_decision_ms": 1e3 * median(out["goal_only"]),
            "robust_decisions": instances}


def bench_default_decisions(name: str, episodes: int = 6, seed: int = 0) -> dict[str, Any]:
    """CPU time of every decision step of ``episodes`` grid episodes of ``path_preference``
    under the default preset (:data:`~pathpref.planning.pomdp.DEFAULT_PRESET`: search, crossing
    check, wait budget and the belief update of the step's push), the consistent human, a
    push every 5 steps: median, 95th percentile and maximum in ms. The first episode also
    compiles or loads the kernels: it is run once before the timed ones."""
    out: list[float] = []
    for i in range(episodes + 1):
        spec = EpisodeSpec.single(name, "path_preference", 5, seed=seed, instance=i,
                                  human="consistent", preset=DEFAULT_PRESET)
        runner = EpisodeRunner(spec)
        while not runner.done:
            t = time.process_time()
            runner.step()
            if i > 0:
                out.append(time.process_time() - t)
    return {"default_preset": DEFAULT_PRESET,
            "default_decision_ms": 1e3 * median(out),
            "default_decision_p95_ms": 1e3 * float(np.percentile(out, 95)),
            "default_decision_max_ms": 1e3 * max(out),
            "default_decisions": len(out)}


def _check_times(planner: POMCP, belief, model: ObservationModel, res, start: int,
                 depth: int) -> list[float]:
    """Seconds of the crossing check (:func:`~pathpref.planning.crossing.check_crossing`,
    the default preset's) of every move from ``start`` into another polytope, as if the search
    ``res`` had chosen it, a push expected every step."""
    m, cp = planner.world.motion, planner.cell_poly
    out = []
    for a in range(8):
        if m.blocked[start, a] or cp[m.next_cell[start, a]] == cp[start]:
            continue
        t = time.perf_counter()
        check_crossing(planner, belief, model.cell_likelihood, replace(res, action=a), start,
                       depth, (1, 1))
        out.append(time.perf_counter() - t)
    return out


def bench_pomcp(world: World, name: str, quick: bool = False, seed: int = 0) -> dict[str, Any]:
    """First-decision POMCP time, wall clock: 5000 queries at depth T_max, median over random
    instances, of one search each (no episode around it). ``pomcp_decision_ms`` and
    ``pomcp_goal_only_decision_ms``: the paper preset. ``preset_robust_decision_ms`` and
    ``preset_robust_goal_only_decision_ms``: the ``robust`` preset's search (what
    ``robust_decision_ms`` timed before it timed the default preset,
    :func:`bench_first_decisions`), from the robust preset's belief after one push (the route
    prior: the posterior's solve and the Wilson particles, :meth:`POMCP.pool_size`, are in the
    time); after it, the crossing check (the default preset's) of each move from the start into
    another polytope (``crossing_check_ms``; None where no start had one)."""
    preset = get_preset("paper")
    robust = get_preset("robust")
    depth = world.spec.t_max
    n = 5 if quick else 20
    rng = np.random.default_rng(seed + 1)
    t_pp, t_go, t_rb, t_rb_go, t_ck = [], [], [], [], []
    for i in range(n + 1):
        goals = rng.choice(world.n_cells, size=10, replace=False)
        start = int(rng.integers(world.n_cells))
        model = ObservationModel.build(world, goals)
        # the robust preset's belief (route prior), one push: the start polytope is known
        pushed = make_belief(robust.prior, PriorInputs(model, start, coupling=robust.coupling))
        pushed.update(start, int(rng.integers(8)))
        for planner, belief, out in (
            (POMCP(world, goals, preset.path_preference), PreferenceBelief(model), t_pp),
            (POMCP(world, goals, preset.goal_only), GoalBelief(model), t_go),
            (POMCP(world, goals, robust.path_preference.for_mission(depth),
                   tables=model.tables), pushed, t_rb),
            (POMCP(world, goals, robust.goal_only.for_mission(depth), tables=model.tables),
             GoalBelief(model), t_rb_go),
        ):
            t = time.perf_counter()
            res = planner.search(start, belief, depth, seed=i)
            if i > 0:  # the first search compiles or loads the kernel
                out.append(time.perf_counter() - t)
            if out is t_rb:  # the first decision's checks compile route_steps: not counted
                checks = _check_times(planner, belief, model, res, start, depth)
                t_ck += checks if i > 0 else []
    return {
        "pomcp_queries": preset.queries,
        "pomcp_depth": depth,
        "pomcp_decision_ms": 1e3 * median(t_pp),
        "pomcp_goal_only_decision_ms": 1e3 * median(t_go),
        "pomcp_queries_per_s": preset.queries / median(t_pp),
        "pomcp_decisions": n,
        "paper_pomcp_decision_ms": paper.solve_ms(name),
        "preset_robust_decision_ms": 1e3 * median(t_rb),
        "preset_robust_goal_only_decision_ms": 1e3 * median(t_rb_go),
        "crossing_check_ms": 1e3 * median(t_ck) if t_ck else None,
    }


def machine_info() -> dict[str, Any]:
    """Python version, CPU count and platform of this machine."""
    return {
        "python": platform.python_version(),
        "cpu_count": os.cpu_count(),
        "platform": platform.platform(),
    }


