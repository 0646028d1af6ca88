"""The task drawn in every standard render (``physics.render``, Gymnasium ``rgb_array``, the
dm_control viewer's scene camera): goals, polytopes, the preferred route, the push while it
acts and the cue read."""

from __future__ import annotations

import os
import sys

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from pathpref_tasks import load  # noqa: E402
from pathpref_tasks import viewer as task_viewer  # noqa: E402

KW = {"map": "simple", "method": "path_preference", "delta_t": 1, "seed": 5, "queries": 20}


def red(img: np.ndarray) -> int:
    """Pixels of the push arrow's red (0.95, 0.1, 0.1): nothing else in the scene is."""
    r, g, b = (img[..., k].astype(int) for k in range(3))
    return int(((r > 180) & (g < 70) & (b < 70)).sum())


def green(img: np.ndarray) -> int:
    """Pixels of the cue arrow's green (0.1, 0.85, 0.3)."""
    r, g, b = (img[..., k].astype(int) for k in range(3))
    return int(((g > 150) & (r < 90) & (b < 130)).sum())


def _until(env, cond, limit: int = 400):
    for _ in range(limit):  # bounded: the first push starts at t = 0 and lasts < 2 s
        env.step(env.task.policy_action())
        if cond():
            return
    raise AssertionError("condition not reached")


def test_physics_render_draws_the_push_and_the_cue():
    """While the human's push acts the top view has the red arrow, and without the drawing
    it has none; after the cue is read (within 2 s) the green arrow; the drawn frame differs
    from the plain one (goal discs, outlines, arrows)."""
    env = load("navigate_control", **KW)
    env.reset()
    task = env.task
    _until(env, lambda: task.body.last_push is not None
           and task.body.last_push.active(float(task.base.data.time))
           and np.linalg.norm(task.body.last_push.force(float(task.base.data.time))) > 15)
    drawn = env.physics.render(240, 240, camera_id="top")
    drawing, env.physics.drawing = env.physics.drawing, None
    plain = env.physics.render(240, 240, camera_id="top")
    env.physics.drawing = drawing
    assert red(drawn) > 20 and red(plain) == 0
    assert green(plain) == 0
    assert np.abs(drawn.astype(int) - plain.astype(int)).sum(axis=2).astype(bool).mean() > 0.02
    _until(env, lambda: bool(task.base.felt))
    assert green(env.physics.render(240, 240, camera_id="top")) > 20
    # depth images are the physics' only (no overlay geoms in them)
    assert env.physics.render(48, 48, camera_id="top", depth=True).shape == (48, 48)


def test_gymnasium_rgb_array_is_the_drawn_view():
    """``render()`` of ``rgb_array`` is the drawn top view, pixel for pixel."""
    gym = pytest.importorskip("gymnasium")
    env = gym.make("pathpref_tasks:pathpref/Navigate-v0", render_mode="rgb_array", width=160,
                   height=120, **{**KW, "t_max": 3})
    env.reset(seed=5)
    frame = env.render()
    physics = env.unwrapped._env.physics
    assert np.array_equal(frame, physics.render(120, 160, camera_id="top"))
    physics.drawing = None
    assert not np.array_equal(frame, physics.render(120, 160, camera_id="top"))
    env.close()


def test_viewer_scene_camera_gets_the_task_geoms():
    """The dm_control viewer's scene camera with :func:`pathpref_tasks.viewer.scene_callback`
    (no window: the scene is built, not shown) has at least one geom per goal and per
    preferred transition more than without it."""
    from dm_control.viewer import renderer

    env = load("navigate", **{**KW, "t_max": 3})
    env.reset()
    cams = [renderer.SceneCamera(env.physics.model, env.physics.data,
                                 renderer.RenderSettings(), scene_callback=cb)
            for cb in (None, task_viewer.scene_callback(lambda: env))]
    plain, drawn = (c.render().ngeom for c in cams)
    r = env.task.runner
    assert drawn - plain >= len(r.instance.goals) + int((r.pref >= 0).sum())


POLICIES = '''
import numpy as np

CALLS = []


def east(time_step):
    """Drive east at 0.3 m/s; note each time step's position."""
    CALLS.append(np.asarray(time_step.observation["position"]).copy())
    return np.array([0.3, 0.0])


NOT_CALLABLE = 3
'''


def test_render_films_any_policy(tmp_path, monkeypatch, capsys):
    """``pathpref render --policy module:function`` drives a control-rate task with the
    callable (called once per control step with the dm_env time step), writes a video of
    the drawn top view (25 fps at speed 2: one frame per 0.08 s of simulated time, plus the
    first) and prints the episode's metrics; bad policies are one line."""
    import imageio.v2 as imageio

    from pathpref.apps.cli import main

    (tmp_path / "my_policies.py").write_text(POLICIES)
    monkeypatch.syspath_prepend(str(tmp_path))
    out = tmp_path / "east.mp4"
    base = ["render", "--map", "simple", "--method", "compliant", "--delta-t", "1",
            "--t-max", "3", "--width", "160", "--height", "120", "--task",
            "navigate_control", "--out", str(out)]
    assert main([*base, "--policy", "my_policies:east", "--no-progress"]) == 0
    import my_policies

    text = capsys.readouterr().out
    assert "my_policies:east on navigate_control simple: success" in text
    n_steps = len(my_policies.CALLS)
    assert n_steps >= 2 and my_policies.CALLS[-1][0] > my_policies.CALLS[0][0]  # it drove east
    frames = imageio.mimread(out)
    # control steps of 0.02 s: n_steps steps (the last call's step included) = n_steps * 0.02 s
    assert abs(len(frames) - (1 + n_steps * 0.02 / 0.08)) <= 1
    assert frames[0].shape == (120, 160, 3)
    for bad, msg in (("my_policies", "--policy must be module:function"),
                     ("my_policies:missing", "has no 'missing'"),
                     ("my_policies:NOT_CALLABLE", "is not callable"),
                     ("no_such_module_29:f", "cannot import module")):
        out.unlink(missing_ok=True)
        assert main([*base, "--policy", bad]) == 2
        err = capsys.readouterr().err
        assert msg in err and err.count("\n") == 1 and not out.exists()
    sys.modules.pop("my_policies", None)


def test_filming_stops_at_max_steps(tmp_path):
    """The filming loop is bounded: with ``max_steps`` 3 the policy is called 3 times (the
    episode not over), and the video has the first frame and one per 0.08 s of the 3 steps
    (decision steps of ``decision_s``, the default physics')."""
    import imageio.v2 as imageio

    from pathpref.apps.film import film_policy

    calls = []

    def stay(ts):
        calls.append(ts.step_type)
        return 8

    metrics, frames = film_policy("navigate", stay, tmp_path / "v.mp4", 64, 48,
                                  {**KW, "t_max": 10}, max_steps=3)
    assert len(calls) == 3 and metrics["steps"] == 3 and not metrics["goal_reached"]
    assert frames == len(imageio.mimread(tmp_path / "v.mp4"))
    # the first frame (the state after reset), then one per 40 physics steps of 2 ms
    # (0.08 s) of the 3 decision steps (3 * n_sub_steps physics steps)
    task = load("navigate", **{**KW, "t_max": 10}).task
    assert task.dt == 0.002
    assert frames == 1 + 3 * task.n_sub_steps // 40


def test_viewer_draws_the_task_into_the_public_user_scene(monkeypatch):
    """``viewer.launch`` runs in MuJoCo's passive viewer (``launch_passive``, faked here: no
    display) and draws the task into its public ``user_scn`` after each step: the goals and
    the preferred route at least, 3 steps of the task's own policy."""
    import mujoco
    import mujoco.viewer

    seen = {}

    class Handle:
        def __init__(self, model, data):
            self.user_scn = mujoco.MjvScene(model, maxgeom=2000)
            self.steps = 0

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

        def is_running(self):
            return True

        def lock(self):
            import contextlib
            return contextlib.nullcontext()

        def sync(self):
            self.steps += 1
            seen["ngeom"], seen["steps"] = self.user_scn.ngeom, self.steps

    envs = []

    def loader():
        envs.append(load("navigate", **{**KW, "t_max": 5}))
        return envs[-1]

    monkeypatch.setattr(mujoco.viewer, "launch_passive", Handle)
    monkeypatch.setattr("time.sleep", lambda s: None)
    task_viewer.launch(loader, max_steps=3)
    r = envs[0].task.runner
    assert seen["steps"] == 3
    assert seen["ngeom"] >= len(r.instance.goals) + int((r.pref >= 0).sum())
