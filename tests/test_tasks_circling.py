"""The Gymnasium ids' default reward (the loop-free potential of ``pathpref_tasks.reward``):
a circling policy that never reaches the goal earns a negative return on every built-in map
and every registered id. At decisions: the goal-blind crossing farmer (the move with the best
one-step paper reward, never into the goal cell; the paper's rule pays it for circling on
``office`` and ``classroom``); at control rate: a circle of 1.5 cells' radius around the start
(0.8 v_max, one turn in 2 pi r / v seconds), 30 s of it. The arm's ids (the same reward code,
:class:`~pathpref_tasks.carry.Carry` subclasses navigate) run on ``simple`` only and shorter
(8 decisions, 10 s): a decision of the arm costs seconds."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pathpref_tasks  # noqa: F401  # registers the ids
import pytest
from pathpref_tasks.gym import IDS
from pathpref_tasks.navigate import CELL_SIZE
from pathpref_tasks.registry import BUILTIN_TASKS

from tests.test_tasks_reward import crossing_farmer

MAPS = ("simple", "office", "classroom")
#: simulated seconds of circling at control rate
CIRCLE_S = 30.0


def circle(task, v_max: float, t: float) -> np.ndarray:
    """The velocity of a circle of radius 1.5 cells at 0.8 v_max at time ``t``."""
    v = 0.8 * v_max
    w = v / (1.5 * CELL_SIZE)
    return np.array([v * math.cos(w * t), v * math.sin(w * t)], np.float32)


def drive(env_id: str, map_name: str, short: bool = False) -> tuple[float, dict]:
    """One episode of the circling policy: its return (the sum of the rewards) and last info;
    ``short``: 8 decisions or 10 s."""
    decides = BUILTIN_TASKS[IDS[env_id]].decides
    if decides:
        extra = {"t_max": 8} if short else {}
    else:
        extra = {"environment_kwargs": {"control_timestep": 0.1},
                 "time_limit": 10.0 if short else CIRCLE_S}
    env = gym.make(env_id, map=map_name, seed=0, delta_t=1, **extra)
    env.reset(seed=0)
    task, rng, total = env.unwrapped._env.task, np.random.default_rng(0), 0.0
    high = float(env.action_space.high[0]) if not decides else 0.0
    for k in range(20_000):  # the task's own limits end it first
        a = crossing_farmer(task, rng) if decides else circle(task, high, 0.1 * k)
        _, r, term, trunc, info = env.step(a)
        total += r
        if term or trunc:
            break
    env.close()
    return total, info


CASES = [(i, m) for i in ("pathpref/Navigate-v0", "pathpref/NavigateControl-v0") for m in MAPS]
CASES += [(i, "simple") for i in ("pathpref/Carry-v0", "pathpref/CarryControl-v0")]


def test_every_id_is_covered():
    assert {i for i, _ in CASES} == set(IDS)


@pytest.mark.parametrize(("env_id", "map_name"), CASES)
def test_circling_never_pays(env_id, map_name):
    total, info = drive(env_id, map_name, short="Carry" in env_id)
    assert not info["goal_reached"]
    assert total < 0.0
    assert abs(total - info["return"]) < 1e-9  # the task's own sum of the rewards
