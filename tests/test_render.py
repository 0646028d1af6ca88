"""Rendering and logging: a short headless render with non-blank frames, rerun files, the
render command, a clear error without a GL backend."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from pathpref.apps.rollout import record_rollout  # noqa: E402
from pathpref.episode import EpisodeSpec  # noqa: E402
from pathpref.episode.instances import seed_for  # noqa: E402
from pathpref.errors import ConfigError  # noqa: E402
from pathpref.sim.render import Overlay, RolloutRenderer, write_video  # noqa: E402
from pathpref.sim.scene import build_scene  # noqa: E402
from pathpref.viz.video import belief_rgba  # noqa: E402


def test_frames_are_not_blank_and_show_overlays(worlds):
    import mujoco

    sc = build_scene(worlds["simple"])
    d = mujoco.MjData(sc.model)
    d.qpos[:2] = sc.cell_centre(0)
    mujoco.mj_forward(sc.model, d)
    r = RolloutRenderer(sc, 400, 200)
    plain, persp = r.views(d, Overlay())
    o = Overlay(goal_cells=np.array([[1, 8], [5, 8]]), goal_rgba=belief_rgba([0.9, 0.1]),
                true_goal=0, polygons=worlds["simple"].arrangement.polygons, current=0,
                push_origin=np.array([1.5, 0.25, 0.35]), push_force=np.array([30, 0, 0]))
    pushed, _ = r.views(d, o)
    r.close()
    assert plain.shape == (200, 200, 3) and persp.shape == (100, 200, 3) and plain.std() > 10
    red = (pushed[..., 0] > 180) & (pushed[..., 1] < 80) & (pushed[..., 2] < 80)
    assert red.sum() > 20 and np.abs(pushed.astype(int) - plain).sum() > 0


def test_goal_colours_are_absolute_and_shown_as_given(worlds):
    """A uniform belief over 10 goals paints every goal viridis(0.1), dark purple, never
    bright; the disc renders within 30 of the given colour per channel (the scene's light
    is compensated), and p = 1 is yellow."""
    import mujoco

    rgba = belief_rgba(np.full(10, 0.1))
    assert np.allclose(rgba, rgba[0]) and rgba[0, :3].mean() < 0.35
    assert belief_rgba([1.0])[0, 0] > 0.9 and belief_rgba([1.0])[0, 2] < 0.3  # yellow
    sc = build_scene(worlds["simple"])
    d = mujoco.MjData(sc.model)
    mujoco.mj_forward(sc.model, d)
    r = RolloutRenderer(sc, 200, 200)
    img, _ = r.views(d, Overlay(goal_cells=np.array([[3, 3]]), goal_rgba=rgba[:1]))
    r.close()
    # cell (3, 3) is at (1.25, 1.25) m; the top camera looks at the map's centre (2.5, 2.5)
    px = img.reshape(-1, 3).astype(int)
    want = (rgba[0, :3] * 255).astype(int)
    close = np.abs(px - want).max(axis=1) <= 30
    assert close.sum() > 30


def test_info_panel_and_grid():
    """The panel draws bars whose heights follow the absolute probabilities."""
    from pathpref.viz.video import PanelInfo, frame_grid, info_panel

    p = np.array([0.7, 0.2, 0.1])
    img = info_panel(420, 270, PanelInfo(title="m", step=1, t_max=9, sim_time=1.0, belief=p,
                                         true_goal=0, push_n=30.0, cue_heading=2))
    assert img.shape == (270, 420, 3)
    heights = []
    for k in range(3):
        col = (belief_rgba(p[k:k + 1])[0, :3] * 255).astype(int)
        hit = np.abs(img.astype(int) - col).max(axis=2) <= 2
        heights.append(hit.any(axis=1).sum())
    assert heights[0] > heights[1] > heights[2] > 0
    assert heights[0] / heights[1] == pytest.approx(3.5, rel=0.25)
    assert frame_grid([img] * 6, cols=3, scale=0.5).shape == (270, 630, 3)


def test_short_rollout_video_and_rerun(tmp_path):
    spec = EpisodeSpec(map="simple", method="compliant", delta_t=2, instance=0, run=0,
                       instance_seed=seed_for(5, 0), run_seed=seed_for(5, 0, 0), sim="mujoco",
                       t_max=6)
    rec = record_rollout(spec, video=tmp_path / "r.mp4", rerun=tmp_path / "r.rrd")
    assert rec.frames > 10 and (tmp_path / "r.mp4").stat().st_size > 2000
    assert (tmp_path / "r.rrd").stat().st_size > 2000
    import imageio.v2 as iio

    reader = iio.get_reader(str(tmp_path / "r.mp4"))
    frame = reader.get_data(rec.frames // 2)
    assert frame.std() > 10
    # the video ends on the outcome card, held CARD_S s: the same faded frame, a white box
    from pathpref.apps.rollout import CARD_S, VIDEO_FPS

    held = int(round(CARD_S * VIDEO_FPS))
    last, card0 = reader.get_data(rec.frames - 1), reader.get_data(rec.frames - held)
    assert np.abs(last.astype(int) - card0.astype(int)).mean() < 3  # codec noise only
    final_step = reader.get_data(rec.frames - held - 1)  # the frame the card fades
    assert last.mean() > final_step.mean() + 5  # faded towards white (0.45 v + 0.55 * 255)
    assert frame.shape == (540, 960, 3)  # the default size
    # the recording: its entities and the blueprint stored with it (read back with the
    # rerun CLI that rerun-sdk installs next to this Python)
    cli = Path(sys.executable).with_name("rerun")
    if not cli.exists():
        pytest.skip("no rerun CLI next to this Python")
    out = subprocess.run([str(cli), "rrd", "print", "-vvv", str(tmp_path / "r.rrd")],
                         capture_output=True, text=True, timeout=120).stdout
    for entity in ("/map/preference", "/map/goals", "/robot/position", "/belief/goals",
                   "/belief/p/g0", "/belief/p_true_goal", "/force/magnitude",
                   "/detector/active", "/camera"):
        assert entity in out, entity
    for view in ("P(goal) now", "P(goal) over time", "force on the handle (N)",
                 "detector active", "camera"):
        assert view in out, view
    assert "Blueprint" in out


def test_blank_video_is_refused(tmp_path):
    with pytest.raises(ConfigError, match="blank"):
        write_video([np.zeros((16, 16, 3), np.uint8)] * 5, tmp_path / "b.mp4")
    assert not (tmp_path / "b.mp4").exists()


def test_render_command_and_missing_gl(tmp_path):
    out = tmp_path / "v.mp4"
    base = [sys.executable, "-m", "pathpref", "render", "--map", "simple", "--method",
            "compliant", "--delta-t", "2", "--t-max", "4", "--width", "160", "--height", "120"]
    p = subprocess.run(["sh", "-c", 'umask 022 && exec "$@"', "sh", *base, "--out", str(out)],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    assert out.stat().st_size > 1000
    assert "step 1/4: P(true goal) = " in p.stderr  # progress, one line per decision
    assert oct(out.stat().st_mode & 0o777) == oct(0o644)  # the umask's mode, not mkstemp's
    env = dict(os.environ, MUJOCO_GL="osmesa", PYOPENGL_PLATFORM="osmesa")
    out2 = tmp_path / "nogl.mp4"
    p = subprocess.run([*base, "--out", str(out2)], capture_output=True, text=True, env=env,
                       timeout=300)
    if p.returncode == 0:  # this machine happens to have OSMesa too: nothing to check
        return
    assert p.returncode == 2
    assert "pathpref: error:" in p.stderr and "libosmesa6" in p.stderr
    assert "Traceback" not in p.stderr and not out2.exists()


@pytest.mark.parametrize("args,msg", [
    (["--size", "1280"], "--size must be WxH with W and H in 16..4096 (e.g. 960x540 or "
                         "1280x720), got '1280'"),
    (["--size", "axb"], "--size must be WxH"),
    (["--size", "540x960"], "at least as wide as high"),
    (["--method", "all"], "--method must be one method (render shows one episode)"),
])
def test_render_bad_input_is_one_line(tmp_path, capsys, args, msg):
    from pathpref.apps.cli import main

    out = tmp_path / "v.mp4"
    assert main(["render", "--out", str(out), *args]) == 2
    err = capsys.readouterr().err
    assert msg in err and err.count("\n") == 1
    assert not out.exists()


def test_parse_size():
    from pathpref.apps.rollout import DEFAULT_SIZE, parse_size

    assert parse_size("1280x720") == (1280, 720) and parse_size("960X540") == DEFAULT_SIZE


def test_push_arrow_is_one_metre_per_30_newtons(worlds):
    """The push arrow ends at the pushed body and is 1 m long per 30 N (MuJoCo draws an
    arrow geom half as long as its size, which the renderer compensates)."""
    import mujoco

    sc = build_scene(worlds["simple"])
    d = mujoco.MjData(sc.model)
    mujoco.mj_forward(sc.model, d)
    r = RolloutRenderer(sc, 600, 600)
    red_rgba = np.array([[1.0, 0.0, 0.0, 1.0]] * 2)
    discs, _ = r.views(d, Overlay(goal_cells=np.array([[1, 1], [10, 1]]), goal_rgba=red_rgba))
    arrow, _ = r.views(d, Overlay(push_origin=np.array([3.0, 0.75, 0.05]),
                                  push_force=np.array([30.0, 0.0, 0.0])))
    r.close()

    def red_x(img, lo=100):
        m = (img[..., 0] > lo) & (img[..., 1] < 80) & (img[..., 2] < 80)
        xs = np.nonzero(m)[1]
        return xs.min(), xs.max()

    a, b = red_x(discs)
    px_per_m = (b - a) / (4.5 + 0.3)  # centres 4.5 m apart, discs 0.3 m across
    lo, hi = red_x(arrow, 180)
    assert (hi - lo) / px_per_m == pytest.approx(1.0, abs=0.12)


# --- a full disk while encoding -------------------------------------------------------------
def fake_ffmpeg(folder: Path, read_all: bool) -> str:
    """An ``ffmpeg`` for imageio (``IMAGEIO_FFMPEG_EXE``) that fails as on a full disk: it
    writes the start of the file, then (``read_all``) takes every frame and fails on the
    trailer, exit status 1 (what imageio never checked), or dies at once (the pipe breaks)."""
    exe = folder / "ffmpeg"
    exe.write_text("#!/bin/sh\nfor a; do out=$a; done\nprintf '\\000\\000\\000\\040ftypisom' "
                   '> "$out"\n' + ("cat > /dev/null\n" if read_all else "") + "exit 1\n")
    exe.chmod(0o755)
    return str(exe)


@pytest.mark.parametrize("read_all", [True, False])
def test_a_video_the_encoder_could_not_finish_is_removed(tmp_path, monkeypatch, read_all):
    import errno

    from pathpref.sim import render

    monkeypatch.setenv("IMAGEIO_FFMPEG_EXE", fake_ffmpeg(tmp_path, read_all))
    frames = [np.random.default_rng(k).integers(0, 255, (48, 64, 3), np.uint8)
              for k in range(200)]
    out = tmp_path / "v.mp4"
    monkeypatch.setattr(render, "free_bytes", lambda folder: 4096)  # the disk is full
    with pytest.raises(OSError) as e:
        write_video(frames, out)
    assert e.value.errno == errno.ENOSPC and not out.exists()
    monkeypatch.setattr(render, "free_bytes", lambda folder: 2**40)  # it is not
    with pytest.raises(OSError, match="the video encoder") as e:
        write_video(frames, out)
    assert e.value.errno == errno.EIO and "\n" not in str(e.value) and not out.exists()


def test_render_on_a_full_disk_exits_2_and_keeps_no_file(tmp_path, capsys, monkeypatch):
    """`render --out` used to exit 0 and print "wrote" over an unplayable MP4."""
    from pathpref.apps.cli import main
    from pathpref.sim import render

    monkeypatch.setenv("IMAGEIO_FFMPEG_EXE", fake_ffmpeg(tmp_path, read_all=True))
    monkeypatch.setattr(render, "free_bytes", lambda folder: 0)
    (tmp_path / "out").mkdir()
    out = tmp_path / "out" / "v.mp4"
    rc = main(["render", "--map", "simple", "--method", "compliant", "--delta-t", "2",
               "--t-max", "3", "--width", "64", "--height", "48", "--no-progress",
               "--out", str(out)])
    cap = capsys.readouterr()
    assert rc == 2 and "wrote" not in cap.out
    assert cap.err.splitlines() == [f"pathpref: error: cannot write {out}: no space left on "
                                    "device; free some space and run again (no partial file "
                                    "was kept)"]
    assert os.listdir(tmp_path / "out") == []

    def full(self, frame):  # a writer that raises ENOSPC itself
        import errno

        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.delenv("IMAGEIO_FFMPEG_EXE")
    monkeypatch.setattr(render.VideoWriter, "append", full)
    assert main(["render", "--map", "simple", "--method", "compliant", "--delta-t", "2",
                 "--t-max", "3", "--width", "64", "--height", "48", "--no-progress",
                 "--out", str(out)]) == 2
    assert len(capsys.readouterr().err.splitlines()) == 1
    assert os.listdir(tmp_path / "out") == []


# --- every push drawn, the arm close-up -----------------------------------------------------
def test_push_trace_follows_the_applied_force():
    """Onset above 0.5 N, the force now while acting, the peak (alpha 0.7) until ``hold_s``
    after the onset, then nothing; a second rise is a new push."""
    from pathpref.sim.render import PushTrace

    tr = PushTrace(hold_s=1.0)
    assert tr.shown(0.0) is None
    tr.update(0.1, np.array([0.3, 0.0, 0.0]))
    assert tr.shown(0.1) is None  # below 0.5 N
    tr.update(0.2, np.array([0.0, 10.0, 0.0]))
    tr.update(0.3, np.array([0.0, 20.0, 0.0]))
    f, alpha = tr.shown(0.3)
    assert f.tolist() == [0.0, 20.0, 0.0] and alpha == 1.0 and tr.t0 == 0.2
    tr.update(0.4, np.array([0.0, 5.0, 0.0]))
    tr.update(0.5, np.zeros(3))
    f, alpha = tr.shown(1.2)
    assert f.tolist() == [0.0, 20.0, 0.0] and alpha == 0.7
    assert tr.shown(1.21) is None  # 1.0 s after the onset at 0.2
    tr.update(1.5, np.array([-8.0, 0.0, 0.0]))
    assert tr.t0 == 1.5 and tr.shown(1.5)[0].tolist() == [-8.0, 0.0, 0.0]


def test_pushes_at_any_time_are_drawn(worlds):
    """Two pushes on a driving base given through ``base.pushes`` (not the push phase's
    argument, which the video followed before: 0 of 785 frames had the arrow): at every step
    either acts, the trace shows exactly the sum the simulation applied."""
    from pathpref.sim.force_cue import HumanPush, PushProfile
    from pathpref.sim.mobile_base import MobileBase
    from pathpref.sim.render import PushTrace, applied_push

    w = worlds["simple"]
    base = MobileBase(build_scene(w))
    base.enable_pushes_any_time()
    base.stop_on_cue = False
    base.reset(w.cell((3, 3)))
    base.target = base.scene.cell_centre(w.cell((5, 3)))
    pushes = [HumanPush(0.0, 0.3, PushProfile(), 2), HumanPush(np.pi / 2, 0.5, PushProfile(), 0)]
    base.pushes = list(pushes)
    tr = PushTrace(2.0)
    acting = 0
    while base.data.time < 1.2:
        base.substep()
        t = float(base.data.time) - base.dt  # the force of the step just taken
        tr.update(float(base.data.time), applied_push(base.data, base.pushed_body))
        want = sum((p.force(t) for p in pushes if p.active(t)), np.zeros(3))
        if np.hypot(*want[:2]) > 0.5:
            acting += 1
            assert tr.acting and np.allclose(tr.shown(float(base.data.time))[0], want,
                                             atol=1e-9)
    assert acting > 200  # 0.5 s of pushing at 2 ms


def test_carry_video_has_an_arm_closeup(worlds):
    """The carry scene's perspective view holds the close-up inset (white border, bottom
    right) following the tray; a push arrow into the tray shows in it in red."""
    import mujoco

    from pathpref.sim.arm import ArmBase
    from pathpref.sim.body import scene_for
    from pathpref.sim.render import CLOSEUP_SHARE

    sc = scene_for(worlds["simple"], 0.5, "carry")
    arm = ArmBase(sc)
    arm.reset(worlds["simple"].cell((3, 3)))
    mujoco.mj_forward(sc.model, arm.data)
    r = RolloutRenderer(sc, 640, 360)
    assert r.closeup is not None
    _, plain = r.views(arm.data, Overlay())
    _, pushed = r.views(arm.data, Overlay(push_origin=arm.end_effector,
                                          push_force=np.array([0.0, 30.0, 0.0])))
    ch, cw = r.closeup.height, r.closeup.width
    r.close()
    assert ch == round(r.persp_h * CLOSEUP_SHARE)
    corner = plain[-ch:, -cw:]
    assert (corner[0] == 255).all() and (corner[:, 0] == 255).all()  # the border
    assert corner[2:, 2:].std() > 10  # a picture, not blank
    red = (pushed[-ch:, -cw:, 0] > 180) & (pushed[-ch:, -cw:, 1] < 80) & \
        (pushed[-ch:, -cw:, 2] < 80)
    assert red.sum() > 50
    nav = RolloutRenderer(build_scene(worlds["simple"]), 640, 360)
    assert nav.closeup is None  # navigate: no tray
    nav.close()
