"""The dm_control environment of a task (:func:`load`, re-exported by :mod:`pathpref_tasks`,
whose docstring describes the arguments) and :class:`Environment`, dm_control's
``control.Environment`` with the task's action check, ``episode_metrics``, bounds of a flat
observation and snapshots of an episode (:meth:`Environment.snapshot`, :meth:`Environment.restore`:
:mod:`.snapshot`)."""

from __future__ import annotations

import collections
import inspect
import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from dm_control.mujoco.wrapper import core
from dm_control.rl import control
from dm_env import specs

from pathpref.episode.spec import check_number
from pathpref.errors import ConfigError

from . import snapshot as snapshots
from .navigate_control import CONTROL_TIMESTEP, CONTROL_TIMESTEPS
from .registry import task_class, task_names
from .stage import Physics

#: environment_kwargs the tasks accept
ENVIRONMENT_KWARGS = ("control_timestep", "flat_observation", "legacy_step")


class Environment(control.Environment):
    """dm_control's ``control.Environment``; an action outside the spec is refused before
    dm_control runs (a one-line ConfigError raised from here, not from inside dm_control);
    each step's reward is added to the task's ``episode_return``."""

    def step(self, action):
        """Check ``action`` against the task's spec, then dm_control's ``step`` with the
        checked action (which the task's ``before_step`` knows as checked: one check a
        step)."""
        if not self._reset_next_step:
            action = self._task.checked_action = self._task.check_action(action)
        ts = super().step(action)
        if ts.reward is not None:  # None on the first step of a new episode
            self._task.episode_return += float(ts.reward)
        return ts

    def observation_spec(self):
        """The task's specs; with ``flat_observation`` the one flat array's, its bounds the
        task's bounds concatenated in observation order (dm_control returns the task's
        unflattened specs then, which the flat observations do not match)."""
        spec = super().observation_spec()
        if not self._flat_observation:
            return spec
        lo = [np.broadcast_to(getattr(s, "minimum", -np.inf), s.shape).ravel()
              for s in spec.values()]
        hi = [np.broadcast_to(getattr(s, "maximum", np.inf), s.shape).ravel()
              for s in spec.values()]
        n = sum(int(np.prod(s.shape)) for s in spec.values())
        key = control.FLAT_OBSERVATION_KEY
        return collections.OrderedDict([(key, specs.BoundedArray(
            (n,), np.float64, np.concatenate(lo), np.concatenate(hi), name=key))])

    def snapshot(self) -> snapshots.Snapshot:
        """The episode now: the physics (the whole ``MjData``), every part's state and the
        task's (belief, runner, planner, random generators) and the step count
        (:mod:`.snapshot`). :meth:`restore` it, replay the same actions: the same
        observations, rewards and metrics, bit for bit."""
        return snapshots.take(self)

    def restore(self, snapshot: snapshots.Snapshot) -> None:
        """Put the episode of ``snapshot`` (:meth:`snapshot`; of this environment or of one
        loaded with the same arguments) back; the next ``step`` continues it."""
        snapshots.put(self, snapshot)

    @property
    def episode_metrics(self) -> dict[str, float | bool]:
        """The current episode's metrics (``task.episode_metrics()``: ``success``, ``pushes``,
        ``violations``, ``return``, ...); final once a time step is ``last()``."""
        return self._task.episode_metrics()


def _task_args(cls) -> list[str]:
    names = []
    for c in cls.__mro__:  # the task classes' own (not dm_control's base.Task's)
        if c.__init__ is object.__init__ or c.__module__.startswith("dm_control"):
            continue
        names += [p for p in inspect.signature(c.__init__).parameters
                  if p not in ("self", "kwargs", "task") and p not in names]
    return names


def load(name: str, task_kwargs: dict | None = None, environment_kwargs: dict | None = None,
         time_limit: float | None = None, **kwargs: Any) -> control.Environment:
    """The dm_control environment of task ``name`` (module docstring)."""
    names = task_names()
    if name not in names:
        raise ConfigError(f"unknown task {name!r}; choose one of {', '.join(names)}")
    cls = task_class(name)
    for what, given in (("task_kwargs", task_kwargs), ("environment_kwargs",
                                                        environment_kwargs)):
        if given is not None and not isinstance(given, Mapping):
            raise ConfigError(f"{what} must be a dict of argument names to values (or None), "
                              f"got {type(given).__name__}")
        if given is not None and not all(isinstance(k, str) for k in given):
            raise ConfigError(f"{what} must have argument names (strings) as keys")
    args = {**(task_kwargs or {}), **kwargs}
    allowed = _task_args(cls)
    for k in args:
        if k not in allowed:
            raise ConfigError(f"unknown argument {k!r} of task {name!r}; choose from "
                              f"{', '.join(allowed)}")
    env_args = dict(environment_kwargs or {})
    for k in env_args:
        if k not in ENVIRONMENT_KWARGS:
            raise ConfigError(f"unknown environment_kwargs {k!r}; choose from "
                              f"{', '.join(ENVIRONMENT_KWARGS)}")
    task = cls(**args)
    timestep = task.dt
    if cls.decides:
        if "control_timestep" in env_args:
            raise ConfigError(f"task {name!r} steps one decision: set task_kwargs "
                              "{'decision_s': ...}, not environment_kwargs control_timestep")
        n_sub_steps = task.n_sub_steps
    else:
        lo, hi = CONTROL_TIMESTEPS
        dt = check_number("control_timestep", env_args.pop("control_timestep",
                                                           CONTROL_TIMESTEP), lo, hi,
                          integer=False)
        n_sub_steps = int(round(dt / timestep))
        if abs(n_sub_steps * timestep - dt) > 1e-9:
            raise ConfigError(f"control_timestep must be a multiple of the physics step "
                              f"{timestep:g} s in [{lo:g}, {hi:g}], got {dt:g}")
    if time_limit is None:
        time_limit = getattr(task, "time_limit_s", math.inf)
    elif time_limit != math.inf:
        time_limit = check_number("time_limit", time_limit, 0.01, 1e7, integer=False)
    # dm_control wraps the compiled mujoco.MjModel; the wrapper copies nothing
    physics = Physics.from_model(core.MjModel(task.scene.model))
    return Environment(physics, task, time_limit=time_limit, n_sub_steps=n_sub_steps,
                       **env_args)
