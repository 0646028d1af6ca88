"""Benchmarks behind ``pathpref bench --json`` and ``scripts/bench.py``.

They report numbers; they assert nothing (tests check behaviour). The JSON keys named in the
issues are a contract: add keys, never rename them. Layout::

    {"machine": {...},
     "maps": {"simple": {"arrangement_build_s": ..., "cost_tables_s": ...,
                         "belief_update_ms": ..., "goal_belief_update_ms": ..., ...}, ...}}
"""

from __future__ import annotations

import os
import platform
import time
from statistics import median
from typing import Any

import numpy as np

from .geometry.maps import load_map
from .geometry.world import World
from .inference.belief import GoalBelief, PreferenceBelief
from .inference.human import ObservationModel

#: the paper's Table II belief-update times (ms) for reference
PAPER_UPDATE_MS = {"simple": 73.5, "office": 28.7, "classroom": 38.3}


def _timeit(fn, repeat: int) -> list[float]:
    out = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t)
    return out


def bench_map(name: str, quick: bool = False, seed: int = 0) -> dict[str, Any]:
    """Build, table and belief-update timings for one map (10 goal candidates)."""
    rng = np.random.default_rng(seed)
    spec = load_map(name)
    reps = 3 if quick else 7
    build = _timeit(lambda: World.from_spec(spec), reps)
    world = World.from_spec(spec)
    goals = rng.choice(world.n_cells, size=min(10, world.n_cells), replace=False)

    def tables():
        m = ObservationModel.build(world, goals)
        return m.likelihood, m.goal_likelihood

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
        "paper_belief_update_ms": PAPER_UPDATE_MS.get(name),
    }


def machine_info() -> dict[str, Any]:
    return {
        "python": platform.python_version(),
        "cpu_count": os.cpu_count(),
        "platform": platform.platform(),
    }


def run_benchmarks(maps: list[str] | None = None, quick: bool = False) -> dict[str, Any]:
    """All benchmarks as one JSON-ready dictionary."""
    maps = maps or ["simple", "office", "classroom"]
    return {"machine": machine_info(), "maps": {m: bench_map(m, quick=quick) for m in maps}}
