"""The scripts that no other test runs still start: each prints its usage for ``--help`` and
exits 0 (their full runs are sweeps and figures, documented in docs/). A script that breaks on
import, or whose arguments no longer parse, fails here."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: scripts with an argument parser that no other test runs
SCRIPTS = ["bench", "budget_figure", "contact_eval", "doc_figures", "episode_speed",
           "errors_doc", "forced_moves", "gamma_sweep", "guidance_eval", "merge_cost",
           "physics_study", "pool_by_plan_size", "pushes_figure", "robust_scale", "root_values",
           "tidybot_frame"]


@pytest.mark.parametrize("name", SCRIPTS)
def test_script_prints_its_usage(name):
    p = subprocess.run([sys.executable, str(ROOT / "scripts" / f"{name}.py"), "--help"],
                       capture_output=True, text=True, timeout=120, cwd=ROOT,
                       env={**os.environ, "MUJOCO_GL": "egl"})
    assert p.returncode == 0, p.stderr
    assert "usage:" in p.stdout


def test_the_motion_rule_figure_is_drawn(tmp_path):
    """scripts/motion_rule_figure.py draws docs/motion_rule.png (it takes the output path)."""
    out = tmp_path / "motion_rule.png"
    p = subprocess.run([sys.executable, str(ROOT / "scripts" / "motion_rule_figure.py"),
                        str(out)], capture_output=True, text=True, timeout=120, cwd=ROOT,
                       env={**os.environ, "MUJOCO_GL": "egl"})
    assert p.returncode == 0, p.stderr
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 10_000
