"""Write tests/data/physics_traces.json: what a few physical episodes did, step by step, so that
a change to the physics step's Python (the per-step path of :mod:`pathpref.sim`) that changes an
outcome fails a test on any machine. Per episode: every decision step's cell, action and
heading, every cue the base felt (cell, heading, times, peak, impulse), the metrics and the
base's final ``qpos``; per control-rate task run: every reward and the base's final state.
Discrete values compare exactly, floats to ``tests/close.py``'s ``REL_PHYSICS``. Run it only
to re-pin after an intended change of results."""

from __future__ import annotations

import json
import os
import sys

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402

import pathpref.sim  # noqa: E402,F401 - registers the MuJoCo body
from pathpref.episode import EpisodeSpec, Physics  # noqa: E402
from pathpref.episode.runner import EpisodeRunner  # noqa: E402

#: the planner the traces were recorded with (the default preset then)
TRACE_PRESET = "robust"
#: (label, map, task, seed, instance, t_max, physics as JSON, "" legacy)
EPISODES = [
    ("navigate realistic", "simple", "navigate", 11, 0, 10, Physics().to_json()),
    ("navigate legacy", "simple", "navigate", 3, 1, 10, ""),
    ("navigate any time", "simple", "navigate", 5, 2, 10,
     Physics.of(timing="interval").to_json()),
    ("navigate ideal sensor", "simple", "navigate", 7, 0, 8,
     Physics.of(sensor="ideal").to_json()),
    ("navigate diffdrive", "simple", "navigate", 2, 1, 6,
     Physics.of(base="diffdrive", timing="interval").to_json()),
    ("carry realistic", "simple", "carry", 4, 0, 5, Physics().to_json()),
]
#: (label, task, load kwargs, control steps)
TASKS = [
    ("navigate_control realistic", "navigate_control",
     {"map": "simple", "method": "path_preference", "delta_t": 1, "seed": 3, "queries": 20,
      "preset": TRACE_PRESET, "physics": None}, 150),
    ("navigate_control legacy", "navigate_control",
     {"map": "simple", "method": "path_preference", "delta_t": 1, "seed": 4, "queries": 20,
      "preset": TRACE_PRESET, "physics": "legacy"}, 150),
]


def episode(row) -> dict:
    """One physical episode's trace (module docstring)."""
    label, world, task, seed, instance, t_max, physics = row
    spec = EpisodeSpec.single(world, "path_preference", 5, seed=seed, instance=instance,
                              sim="mujoco", t_max=t_max, physics=physics, robot=task,
                              preset=TRACE_PRESET)
    runner = EpisodeRunner(spec)
    while not runner.done:
        runner.step()
    res, base = runner.result, runner.body.base
    return {"label": label,
            "steps": [[s.t, s.x, s.y, s.action, s.heading] for s in res.log],
            "felt": [[f.cell, f.heading, f.t_felt, f.t_cue, f.peak_n, list(f.impulse)]
                     for f in base.felt],
            "metrics": {k: float(v) for k, v in sorted(res.metrics.items())},
            "qpos": np.asarray(base.data.qpos, float).tolist()}


def task_run(row) -> dict:
    """A control-rate task driven by its own policy for a number of control steps."""
    from pathpref_tasks import load

    label, name, kwargs, steps = row
    env = load(name, **kwargs)
    ts = env.reset()
    rewards, cells = [], []
    for _ in range(steps):
        if ts.last():
            break
        ts = env.step(env.task.policy_action())
        rewards.append(float(ts.reward))
        cells.append(np.asarray(ts.observation["cell"], float).tolist())
    base = env.task.base
    return {"label": label, "rewards": rewards, "cells": cells,
            "felt": [[f.cell, f.heading, f.t_felt, f.t_cue] for f in base.felt],
            "qpos": np.asarray(base.data.qpos, float).tolist(),
            "time": float(base.data.time)}


def traces() -> dict:
    """Every episode's and task run's trace, by label."""
    return {**{r[0]: episode(r) for r in EPISODES}, **{r[0]: task_run(r) for r in TASKS}}


def main(path: str) -> None:
    with open(path, "w") as f:
        json.dump(traces(), f)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "tests/data/physics_traces.json")
