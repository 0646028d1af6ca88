"""Benchmarks of the dm_control tasks: environment steps per second of ``navigate_control``
(no rendering) and of ``navigate`` (one decision per step)."""

from __future__ import annotations

import time
from typing import Any

import numpy as np


def control_steps_per_s(steps: int = 2000, control_timestep: float = 0.02,
                        seed: int = 0) -> float:
    """``navigate_control`` environment steps per second under random velocity commands
    (uniform in the action spec), resets included, no rendering."""
    from pathpref_tasks import load

    env = load("navigate_control", task_kwargs={"map": "simple", "method": "goal_only",
                                                "seed": seed, "queries": 50},
               environment_kwargs={"control_timestep": control_timestep})
    spec, rng = env.action_spec(), np.random.default_rng(seed)
    actions = rng.uniform(spec.minimum, spec.maximum, size=(steps, *spec.shape))
    env.reset()
    t0 = time.perf_counter()
    for a in actions:
        if env.step(a).last():
            env.reset()
    return steps / (time.perf_counter() - t0)


def decision_steps_per_s(steps: int = 40, seed: int = 0) -> float:
    """``navigate`` environment steps (decisions of 2.5 s physics) per second, random moves."""
    from pathpref_tasks import load

    env = load("navigate", task_kwargs={"map": "simple", "method": "goal_only", "seed": seed,
                                        "queries": 50})
    rng = np.random.default_rng(seed)
    env.reset()
    t0 = time.perf_counter()
    for a in rng.integers(9, size=steps):
        if env.step(int(a)).last():
            env.reset()
    return steps / (time.perf_counter() - t0)


def bench_tasks(quick: bool = False) -> dict[str, Any]:
    """The task benchmarks (keys ``control_steps_per_s`` at 50 Hz, ``control_steps_per_s_20hz``
    and ``decision_steps_per_s``)."""
    n = 500 if quick else 4000
    return {"control_steps_per_s": control_steps_per_s(n, 0.02),
            "control_steps_per_s_20hz": control_steps_per_s(n // 2, 0.05),
            "decision_steps_per_s": decision_steps_per_s(10 if quick else 40)}
