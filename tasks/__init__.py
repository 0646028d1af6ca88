"""dm_control tasks of pathpref, installed as the package ``pathpref_tasks``.

    from pathpref_tasks import load
    env = load("navigate", map="simple", method="path_preference", delta_t=5, seed=0)
    ts = env.reset()
    while not ts.last():
        ts = env.step(env.task.policy_action())   # or any agent's action in 0..7

Tasks: ``navigate`` (the planar base, human force cues through its handle) and ``carry``
(a Jaco arm on the base carries a tray; pushes on the tray; mink IK).

``physics=`` sets every physical parameter (:class:`pathpref.episode.Physics`, a dict of its
fields or its JSON; ``docs/physics.md``): ``load("navigate", physics={"sensor": "realistic",
"timing": "interval", "base": "diffdrive"})``. Without it the task keeps the legacy physics
(ideal sensor, the original base), so environments made before the field behave as before.
"""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")

from pathpref.errors import ConfigError  # noqa: E402

from . import carry, navigate  # noqa: E402

TASKS = {"navigate": navigate.load, "carry": carry.load}


def load(name: str, **kwargs):
    """Build a dm_env environment by task name (see module docstring for the arguments)."""
    if name not in TASKS:
        raise ConfigError(f"unknown task '{name}'; choose one of {', '.join(TASKS)}")
    return TASKS[name](**kwargs)


try:  # Gymnasium is optional for the dm_control tasks; with it, the ids are registered
    from .gym import register_envs
except ImportError:  # pragma: no cover - gymnasium not installed
    pass
else:
    register_envs()

__all__ = ["TASKS", "load"]
