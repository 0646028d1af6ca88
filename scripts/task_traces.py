"""Write tests/data/task_traces.json: every observation, reward and action of a few steps of
the dm_control tasks driven by their own policy (legacy physics), so that a change to what a
task shows or decides fails a test on any machine (compared to ``tests/close.py``'s tolerance,
not as a digest of float bits). Run it only to re-pin after an intended change."""

from __future__ import annotations

import json
import os
import sys

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402
from pathpref_tasks import load  # noqa: E402

#: (task, load kwargs, steps); recorded with the ``robust`` preset (the default then)
CASES = [
    ("navigate", {"map": "simple", "method": "path_preference", "delta_t": 2, "seed": 5,
                  "queries": 50, "t_max": 6, "physics": "legacy", "preset": "robust"}, 7),
    ("navigate_control", {"map": "simple", "method": "path_preference", "delta_t": 1,
                          "seed": 1, "queries": 20, "physics": "legacy", "preset": "robust"},
     60),
]


def trace(name: str, kwargs: dict, steps: int) -> dict:
    """``{"obs": [...], "reward": [...], "action": [...]}`` of ``steps`` steps of the task's own
    policy (observations as nested lists of floats, keys sorted)."""
    env = load(name, **kwargs)
    ts = env.reset()
    out = {"obs": [], "reward": [], "action": []}
    for _ in range(steps):
        out["obs"].append({k: np.asarray(ts.observation[k], np.float64).tolist()
                           for k in sorted(ts.observation)})
        if ts.last():
            break
        a = env.task.policy_action()
        out["action"].append(np.asarray(a).tolist())
        ts = env.step(a)
        out["reward"].append(float(ts.reward))
    return out


def main(path: str) -> None:
    rows = [{"task": n, "kwargs": kw, "steps": s, **trace(n, kw, s)} for n, kw, s in CASES]
    with open(path, "w") as f:
        json.dump(rows, f)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "tests/data/task_traces.json")
