"""dm_control tasks of pathpref, installed as the package ``pathpref_tasks``; loaded the
way ``dm_control.suite.load`` loads the suite's::

    from pathpref_tasks import load
    env = load("navigate", task_kwargs={"map": "simple", "method": "path_preference",
                                        "delta_t": 5, "seed": 0})
    ts = env.reset()
    while not ts.last():
        ts = env.step(env.task.policy_action())   # or any agent's action

Tasks (:data:`TASKS`; with other packages' tasks :func:`all_tasks`, :mod:`.registry`):
``navigate`` (one step = one decision of ``decision_s`` physics seconds; actions 0..8),
``navigate_control`` (control rate, 50 Hz by default; the agent commands the base's velocity
while the simulated human pushes), ``carry`` (a Jaco arm on the base carries a tray; pushes on
the tray; decision steps) and ``carry_control`` (the arm at control rate). ``task_kwargs`` go to
the task (map, method, delta_t, seed, preset, queries, t_max, n_goals, coupling, force,
decision_s, physics; push_period_s at control rate), ``environment_kwargs`` to
``control.Environment`` (``control_timestep`` at control rate, ``flat_observation``),
``time_limit`` (s) caps an episode. Task arguments may also be given as keywords
(``load("navigate", map="office")``). Unknown names and bad values are one-line
:class:`~pathpref.errors.ConfigError` s (a ``ValueError``).

``physics`` sets every physical parameter (:class:`pathpref.episode.Physics`, a dict of its
fields or its JSON; ``docs/physics.md`` section 7): ``load("navigate", physics={"sensor":
"realistic", "timing": "interval", "base": "diffdrive"})`` builds the base as ``--sim mujoco``
does (:func:`pathpref.sim.body.build_base`) and stores the value with every episode's spec.
Without it (None) the tasks run the default physics, ``Physics()``, as every door does;
``"legacy"`` (or ``""``) runs the legacy physics (ideal sensor, a fixed 30 N / 0.3 s push, the
original base and controllers), exactly as before the argument.
"""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")

from .environment import ENVIRONMENT_KWARGS, Environment, load  # noqa: E402
from .registry import BUILTIN_TASKS, all_tasks, gym_id, task_names  # noqa: E402

#: the built-in tasks, name -> task class (every task, other packages' too: :func:`all_tasks`)
TASKS = BUILTIN_TASKS

try:  # Gymnasium is optional for the dm_control tasks; with it, the ids are registered
    from .gym import register_envs
    from .gym_v1 import register_envs_v1
except ImportError:  # pragma: no cover - gymnasium not installed
    pass
else:
    register_envs()
    register_envs_v1()

__all__ = ["ENVIRONMENT_KWARGS", "TASKS", "Environment", "all_tasks", "gym_id", "load",
           "task_names"]
