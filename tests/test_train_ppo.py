"""examples/train_ppo.py (stable-baselines3's PPO on pathpref/Navigate-v0) runs end to end for
256 steps: curve, agent, summary with the held-out evaluation; the saved agent loads as a
checkpoint policy and acts on a dm_env time step. Skipped without the ``rl`` extra. Training
runs in a subprocess: torch is imported there before any MuJoCo context (the script's
docstring)."""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.skipif(
    importlib.util.find_spec("stable_baselines3") is None
    or importlib.util.find_spec("torch") is None,
    reason="the rl extra (stable-baselines3, torch) is not installed")


def test_train_ppo_runs_saves_and_loads(tmp_path):
    env = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
    p = subprocess.run([sys.executable, str(ROOT / "examples" / "train_ppo.py"), "--out",
                        str(tmp_path), "--steps", "256", "--eval", "2", "--video-size", "0x0"],
                       capture_output=True, text=True, env=env, timeout=600, cwd=tmp_path)
    assert p.returncode == 0, p.stderr[-2000:]
    summary = json.loads((tmp_path / "summary.json").read_text())
    eps = json.loads((tmp_path / "episodes.json").read_text())
    assert summary["steps"] == 256 and summary["episodes"] == len(eps)
    # an episode lasts at most 60 decisions (simple's T_max): at least 4 end in 256 steps
    assert len(eps) >= 4 and all(e["steps"] <= 60 for e in eps)
    assert summary["eval_n"] == 2 and 0 <= summary["eval_successes"] <= 2
    lo, hi = summary["eval_success_wilson95"]
    assert 0.0 <= lo <= summary["eval_success"] <= hi <= 1.0
    assert (tmp_path / "curve.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    check = subprocess.run(
        [sys.executable, "-c",
         "import sys, pathpref_tasks; from pathpref_tasks.policies import checkpoint_policy;"
         "kw = dict(map='simple', method='path_preference', delta_t=1, reward='potential',"
         " min_goal_distance=4.0);"
         "act = checkpoint_policy(sys.argv[1], 'navigate', kw);"
         "env = pathpref_tasks.load('navigate', task_kwargs=kw); ts = env.reset();"
         "a = int(act(ts)); ts = env.step(a); print(a)",
         str(tmp_path / "agent.zip")], capture_output=True, text=True, timeout=300, env=env)
    assert check.returncode == 0, check.stderr[-2000:]
    assert 0 <= int(check.stdout.split()[-1]) <= 8
