"""The tasks' ``human`` argument (as ``pathpref evaluate --human``), through the Gymnasium
ids' kwargs: with ``"consistent"`` the person's route leads to the true goal, with ``"map"``
(the default, the paper's protocol) a generated plan's route often does not. Judged by the
route-following oracle on the grid (``pathpref_tasks.oracles.grid_rollout``) from the
episode's own start, goal and preference."""

from __future__ import annotations

import gymnasium as gym
import pathpref_tasks  # noqa: F401  # registers the ids
import pytest
from pathpref_tasks.oracles import grid_rollout

from pathpref.errors import ConfigError
from pathpref.geometry.generate import floor_plan


def first_episode(human: str | None) -> dict:
    """The route oracle's grid episode on the first ``Navigate-v1`` episode of plan 0, seed 5."""
    extra = {} if human is None else {"human": human}
    env = gym.make("pathpref/Navigate-v1", map=floor_plan(0, name="plan0"), seed=5,
                   delta_t=1, **extra)
    env.reset()
    task = env.unwrapped._env.task
    r = task.runner
    out = grid_rollout(task.world, r.instance.start, r.instance.goal_cell, r.pref, "route",
                       task.gamma, r.spec.t_max)
    out["human"] = r.spec.human
    env.close()
    return out


def test_consistent_human_route_reaches_the_goal():
    # worked out beforehand: this episode's map route misses the true goal (the oracle runs
    # out its 72 decisions), the consistent person's leads there
    default, by_map, consistent = (first_episode(h) for h in (None, "map", "consistent"))
    assert default["human"] == "map" and consistent["human"] == "consistent"
    assert not by_map["success"] and not default["success"]
    assert consistent["success"] and consistent["return"] >= 50.0 - 1e-9


def test_unknown_human_is_one_config_error():
    with pytest.raises(ConfigError, match="human"):
        gym.make("pathpref/Navigate-v1", map="simple", human="stubborn")
