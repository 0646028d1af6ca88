"""Film any policy on any task (``pathpref render --policy module:function``): one episode of
a :mod:`pathpref_tasks` environment driven by ``policy(time_step) -> action`` (the dm_control
viewer's convention; a trained agent's wrapper, e.g. ``examples/train_ppo.py``'s), recorded
from the drawn top view (:mod:`pathpref_tasks.drawing`: goals by belief, polytopes, the
preferred route, pushes and cues).

The first frame is the state after ``reset``; then a frame is rendered every
``speed / VIDEO_FPS`` s of simulated time (a hook on every physics step of the base), so a
decision step of 4.1 s is 2.05 s of video at ``speed`` 2 and a push is seen as it happens.
"""

from __future__ import annotations

import importlib
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..errors import ConfigError
from .rollout import VIDEO_FPS

#: a module name ``--policy`` imports: dotted Python identifiers (never a path)
MODULE_RE = re.compile(r"[A-Za-z_]\w*(\.[A-Za-z_]\w*)*")
#: the most environment steps filmed (a control-rate episode's default time limit is far less)
MAX_STEPS = 100_000


def load_policy(text: str) -> Callable[[Any], Any]:
    """The callable ``module:function`` names (``module`` importable, dotted names allowed
    after the colon); a one-line ConfigError otherwise, naming the module: a path given as
    the module, an import that fails or raises anything (``SystemExit`` included)."""
    mod, sep, name = str(text).partition(":")
    if not (sep and mod and name):
        raise ConfigError(f"--policy must be module:function (a callable of a dm_env "
                          f"TimeStep returning an action), got {str(text)[:60]!r}")
    if not MODULE_RE.fullmatch(mod) or mod.endswith(".py"):
        raise ConfigError(f"--policy: {mod[:60]!r} is not a module name (dotted Python "
                          "identifiers, not a file path); put its folder on PYTHONPATH and "
                          "give module:function, e.g. my_policies:act")
    try:
        obj: Any = importlib.import_module(mod)
    except ImportError as e:
        raise ConfigError(f"--policy: cannot import module {mod!r} ({e}); put it on "
                          f"PYTHONPATH") from None
    except (Exception, SystemExit) as e:  # noqa: BLE001 - the module's own code failed
        text = " ".join(str(e).split())[:200]
        raise ConfigError(f"--policy: module {mod!r} failed on import: "
                          f"{type(e).__name__}: {text}; fix the module") from None
    for part in name.split("."):
        try:
            obj = getattr(obj, part, None)
        except (Exception, SystemExit):  # noqa: BLE001 - a module's __getattr__ failed
            obj = None
        if obj is None:
            raise ConfigError(f"--policy: module {mod!r} has no {name!r}")
    if not callable(obj):
        raise ConfigError(f"--policy: {text!r} is not callable")
    return obj


def film_policy(task: str, policy: Callable[[Any], Any], out: str | Path, width: int,
                height: int, task_kwargs: dict, speed: float = 2.0,
                max_steps: int = MAX_STEPS, environment_kwargs: dict | None = None,
                time_limit: float | None = None) -> tuple[dict, int]:
    """Run one episode of ``task`` (``pathpref_tasks.load(task, task_kwargs,
    environment_kwargs, time_limit)``) with ``policy`` and write its video to ``out``; the
    episode's metrics (``env.episode_metrics``) and the number of frames."""
    from pathpref_tasks import load  # imports MuJoCo: MUJOCO_GL is set by then

    from ..sim.render import VideoWriter

    env = load(task, task_kwargs=task_kwargs, environment_kwargs=environment_kwargs,
               time_limit=time_limit)
    physics = env.physics
    vis = physics.model.vis.global_
    vis.offwidth, vis.offheight = max(vis.offwidth, width), max(vis.offheight, height)
    writer = VideoWriter(out, VIDEO_FPS)
    state = {"k": 0}
    every = max(1, int(round(speed / VIDEO_FPS / physics.timestep())))

    def film(b, push) -> None:
        state["k"] += 1
        if state["k"] % every == 0:
            writer.append(physics.render(height, width, camera_id="top"))

    try:
        ts = env.reset()
        writer.append(physics.render(height, width, camera_id="top"))
        env.task.base.on_substep.append(film)
        for _ in range(max_steps):  # bounded: every task ends by its own limits first
            if ts.last():
                break
            ts = env.step(policy(ts))
        metrics = env.episode_metrics
    except BaseException:
        writer._abandon()
        Path(out).unlink(missing_ok=True)
        raise
    finally:
        env.close()
    writer.close()
    return metrics, writer.frames
