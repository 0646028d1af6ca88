"""examples/train_ppo.py (stable-baselines3's PPO on pathpref/NavigateControl-v0) runs end to
end for 2048 steps: curve, agent, video, summary. Skipped without the ``rl`` extra. It runs in
a subprocess: torch is imported there before any MuJoCo context (the script's docstring)."""

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


def test_train_ppo_runs_and_writes_curve_agent_video(tmp_path):
    """2048 steps of 0.1 s with episodes of at most 40 s (400 steps): at least 5 episodes
    end, each within 400 steps of the previous; the curve is a PNG, the agent loads and
    acts, the video has a frame per 0.08 s of the filmed episode (25 fps at speed 2)."""
    env = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
    p = subprocess.run([sys.executable, str(ROOT / "examples" / "train_ppo.py"), "--out",
                        str(tmp_path), "--steps", "2048", "--video-size", "160x120"],
                       capture_output=True, text=True, env=env, timeout=600, cwd=tmp_path)
    assert p.returncode == 0, p.stderr[-2000:]
    summary = json.loads((tmp_path / "summary.json").read_text())
    eps = json.loads((tmp_path / "episodes.json").read_text())
    assert summary["episodes"] == len(eps) >= 5
    ends = [0] + [e["at_step"] for e in eps]
    assert all(0 < b - a <= 400 for a, b in zip(ends, ends[1:]))
    assert ends[-1] <= 2048
    assert (tmp_path / "curve.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (tmp_path / "agent.mp4").stat().st_size > 1000
    film = summary["filmed_episode"]
    assert film["steps"] >= 0 and isinstance(film["success"], bool)
    # the video: the first frame and one per 0.08 s of at most 40 s simulated
    assert 2 <= summary["video_frames"] <= 1 + 40.0 / 0.08
    check = subprocess.run(
        [sys.executable, "-c", "import sys, numpy as np; from stable_baselines3 import PPO; "
         "m = PPO.load(sys.argv[1], device='cpu'); "
         "print(m.action_space.shape, float(np.abs(m.action_space.high).max()))",
         str(tmp_path / "agent.zip")], capture_output=True, text=True, timeout=300)
    assert check.returncode == 0, check.stderr[-2000:]
    assert check.stdout.split(")")[0] == "(2,"
