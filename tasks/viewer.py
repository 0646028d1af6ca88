"""MuJoCo's own viewer with the task drawn (goals by belief, polytopes, the preferred route,
pushes and cues: :mod:`.drawing`)::

    from pathpref_tasks import load, viewer
    viewer.launch(lambda: load("navigate_control", map="office"))

dm_control's viewer gives an application no public scene callback, so :func:`launch` runs the
environment in MuJoCo's public passive viewer (``mujoco.viewer.launch_passive``) and draws the
task into the viewer's ``user_scn`` (its public scene for a caller's geoms) after every step.
Needs a display (GLFW).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any


def scene_callback(environment: Callable[[], Any]) -> Callable[[Any, Any, Any], None]:
    """A ``scene_callback(model, data, scene)``: draws the task of the environment
    ``environment()`` returns now (nothing while there is none or its physics has no
    drawing)."""

    def draw(model, data, scn) -> None:
        env = environment()
        drawing = getattr(getattr(env, "physics", None), "drawing", None)
        if drawing is not None:
            drawing(scn)

    return draw


def launch(environment_loader: Callable[[], Any], policy: Callable[[Any], Any] | None = None,
           max_steps: int | None = None) -> None:
    """Run the environment ``environment_loader()`` in MuJoCo's passive viewer until the
    window closes (or ``max_steps`` steps), at most in real time, with the task drawn in
    every frame. ``policy`` maps a dm_env time step to an action (default: the task's own,
    ``env.task.policy_action()``); an episode that ends starts the next."""
    import mujoco.viewer

    env = environment_loader()
    physics = env.physics
    model, data = physics.model.ptr, physics.data.ptr
    draw = scene_callback(lambda: env)
    act = policy or (lambda time_step: env.task.policy_action())
    ts = env.reset()
    limit = 10**12 if max_steps is None else int(max_steps)
    with mujoco.viewer.launch_passive(model, data) as handle:
        for _ in range(limit):  # the window's closing ends it first
            if not handle.is_running():
                break
            started = time.perf_counter()
            ts = env.reset() if ts.last() else env.step(act(ts))
            with handle.lock():
                handle.user_scn.ngeom = 0
                draw(model, data, handle.user_scn)
            handle.sync()
            time.sleep(max(0.0, env.control_timestep() - (time.perf_counter() - started)))
    env.close()
