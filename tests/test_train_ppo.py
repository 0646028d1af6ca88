"""examples/train_ppo.py (stable-baselines3's PPO on pathpref/Navigate-v1 over generated plans)
runs end to end on a tiny budget: it stops at the step budget, writes the curve, the agent and
the summary with the held-out and unseen-map evaluations (Wilson intervals). Skipped without
the ``rl`` extra. Training runs in a subprocess: torch is imported there before any MuJoCo
context (the script's docstring)."""

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


def test_train_ppo_runs_to_its_step_budget(tmp_path):
    env = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])
    p = subprocess.run([sys.executable, str(ROOT / "examples" / "train_ppo.py"), "--out",
                        str(tmp_path), "--steps", "64", "--n-steps", "64", "--plans", "1",
                        "--eval", "1", "--maps", "simple", "--video-size", "0x0"],
                       capture_output=True, text=True, env=env, timeout=900, cwd=tmp_path)
    assert p.returncode == 0, p.stderr[-2000:]
    summary = json.loads((tmp_path / "summary.json").read_text())
    eps = json.loads((tmp_path / "episodes.json").read_text())
    assert summary["steps"] == 64 and summary["episodes"] == len(eps)
    assert summary["env"] == "pathpref/Navigate-v1" and summary["train_plans"] == ["plan0"]
    assert all(e["steps"] <= 72 for e in eps)  # a generated plan's T_max
    for key in ("held_out_plans", "simple"):
        ev = summary["eval"][key]
        assert ev["n"] == 1 and 0 <= ev["successes"] <= 1
        lo, hi = ev["success_wilson95"]
        assert 0.0 <= lo <= ev["success"] <= hi <= 1.0
    assert (tmp_path / "curve.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (tmp_path / "agent.zip").is_file()
