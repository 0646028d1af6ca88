"""Rendering and logging: a short headless render with non-blank frames, rerun files, the
render command, a clear error without a GL backend."""

from __future__ import annotations

import os
import subprocess
import sys

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from pathpref.apps.rollout import record_rollout  # noqa: E402
from pathpref.episode import EpisodeSpec  # noqa: E402
from pathpref.episode.instances import seed_for  # noqa: E402
from pathpref.errors import ConfigError  # noqa: E402
from pathpref.sim.render import RolloutRenderer, write_video  # noqa: E402
from pathpref.sim.scene import build_scene  # noqa: E402


def test_frames_are_not_blank_and_show_overlays(worlds):
    import mujoco

    sc = build_scene(worlds["simple"])
    d = mujoco.MjData(sc.model)
    d.qpos[:2] = sc.cell_centre(0)
    mujoco.mj_forward(sc.model, d)
    r = RolloutRenderer(sc, 160, 120)
    plain = r.frame(d, goal_cells=np.zeros((0, 2)), belief=np.ones(1), true_goal=-1,
                    polygon=None, push_origin=None, push_force=None)
    pushed = r.frame(d, goal_cells=np.array([[1, 8], [5, 8]]), belief=np.array([0.9, 0.1]),
                     true_goal=0, polygon=worlds["simple"].arrangement.polygons[0],
                     push_origin=np.array([0.25, 0.25, 0.35]), push_force=np.array([30, 0, 0]))
    r.close()
    assert plain.shape == (120, 320, 3) and plain.std() > 10
    red = (pushed[..., 0] > 180) & (pushed[..., 1] < 80) & (pushed[..., 2] < 80)
    assert red.sum() > 20 and np.abs(pushed.astype(int) - plain).sum() > 0


def test_short_rollout_video_and_rerun(tmp_path):
    spec = EpisodeSpec(map="simple", method="compliant", delta_t=2, instance=0, run=0,
                       instance_seed=seed_for(5, 0), run_seed=seed_for(5, 0, 0), sim="mujoco",
                       t_max=6)
    rec = record_rollout(spec, video=tmp_path / "r.mp4", rerun=tmp_path / "r.rrd", width=160,
                         height=120)
    assert rec.frames > 10 and (tmp_path / "r.mp4").stat().st_size > 2000
    assert (tmp_path / "r.rrd").stat().st_size > 2000
    import imageio.v2 as iio

    frame = iio.get_reader(str(tmp_path / "r.mp4")).get_data(rec.frames // 2)
    assert frame.std() > 10


def test_blank_video_is_refused(tmp_path):
    with pytest.raises(ConfigError, match="blank"):
        write_video([np.zeros((16, 16, 3), np.uint8)] * 5, tmp_path / "b.mp4")
    assert not (tmp_path / "b.mp4").exists()


def test_render_command_and_missing_gl(tmp_path):
    out = tmp_path / "v.mp4"
    base = [sys.executable, "-m", "pathpref", "render", "--map", "simple", "--method",
            "compliant", "--delta-t", "2", "--t-max", "4", "--width", "160", "--height", "120"]
    p = subprocess.run([*base, "--out", str(out)], capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    assert out.stat().st_size > 1000
    env = dict(os.environ, MUJOCO_GL="osmesa", PYOPENGL_PLATFORM="osmesa")
    out2 = tmp_path / "nogl.mp4"
    p = subprocess.run([*base, "--out", str(out2)], capture_output=True, text=True, env=env,
                       timeout=300)
    if p.returncode == 0:  # this machine happens to have OSMesa too: nothing to check
        return
    assert p.returncode == 2
    assert "pathpref: error:" in p.stderr and "libosmesa6" in p.stderr
    assert "Traceback" not in p.stderr and not out2.exists()
