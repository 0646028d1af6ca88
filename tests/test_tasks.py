"""The dm_control task: dm_env conformance, seeding, termination and reward."""

from __future__ import annotations

import os
import unittest

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from dm_env import test_utils  # noqa: E402
from pathpref_tasks import load  # noqa: E402

from pathpref.errors import ConfigError  # noqa: E402


class NavigateConformance(test_utils.EnvironmentTestMixin, unittest.TestCase):
    def make_object_under_test(self):
        return load("navigate", map="simple", method="goal_only", delta_t=3, seed=0,
                    queries=200, t_max=8)


def run(env):
    ts, total, cells = env.reset(), 0.0, []
    while not ts.last():
        ts = env.step(env.task.policy_action())
        total += ts.reward
        cells.append(tuple(ts.observation["cell"]))
    return ts, total, cells


def test_seeded_and_terminates():
    a = run(load("navigate", map="simple", method="path_preference", delta_t=5, seed=3,
                 queries=500))
    b = run(load("navigate", map="simple", method="path_preference", delta_t=5, seed=3,
                 queries=500))
    assert a[2] == b[2] and a[1] == pytest.approx(b[1])
    ts = a[0]
    assert ts.discount in (0.0, 1.0)
    assert len(a[2]) <= 30


def test_goal_gives_goal_reward_and_zero_discount():
    env = load("navigate", map="simple", method="compliant", delta_t=1, seed=0, queries=200)
    for _ in range(6):
        ts, total, _ = run(env)
        if env.task.runner.result.goal_reached:
            assert ts.discount == 0.0 and ts.reward >= 50.0 - 1.5 - 18.0
            return
    pytest.fail("compliant with input every step never reached a goal in 6 episodes")


def test_bad_actions_are_clear_errors():
    env = load("navigate", map="simple", method="compliant", delta_t=5, seed=0, t_max=3)
    env.reset()
    for bad in (np.nan, 9, -1):
        with pytest.raises(ConfigError, match="action must be"):
            env.step(bad)


def test_unknown_task():
    with pytest.raises(ConfigError, match="unknown task"):
        load("fly")


def test_observation_belief_is_a_distribution():
    env = load("navigate", map="office", method="path_preference", delta_t=2, seed=1,
               queries=300)
    ts = env.reset()
    for _ in range(4):
        p = ts.observation["goal_belief"]
        assert abs(p.sum() - 1) < 1e-9 and (p >= 0).all()
        if ts.last():
            break
        ts = env.step(env.task.policy_action())
    assert np.isfinite(ts.observation["position"]).all()


def test_action_spec_is_discrete():
    """A DiscreteArray of 9 values (so wrappers such as shimmy map it to Discrete(9))."""
    from dm_env import specs

    env = load("navigate", map="simple", method="compliant", delta_t=5, seed=0, queries=20,
               t_max=3)
    spec = env.action_spec()
    assert isinstance(spec, specs.DiscreteArray) and spec.num_values == 9
    spec.validate(np.int32(8))


@pytest.mark.parametrize("env_id", ["pathpref/Navigate-v0", "pathpref/Carry-v0"])
def test_gymnasium_env_passes_check_env(env_id):
    """Registered ids, Discrete(9) actions, the env checker (seeding determinism included)."""
    gym = pytest.importorskip("gymnasium")
    from gymnasium.utils.env_checker import check_env

    env = gym.make(f"pathpref_tasks:{env_id}", map="simple", method="compliant", delta_t=2,
                   queries=20, t_max=4, render_mode="rgb_array", width=64, height=48)
    assert env.action_space == gym.spaces.Discrete(9)
    check_env(env.unwrapped, skip_render_check=False)
    a, _ = env.reset(seed=3)
    b, _ = env.reset(seed=3)
    assert all(np.array_equal(a[k], b[k]) for k in a)
    frame = env.render()
    assert frame.shape == (48, 64, 3)
    done = False
    while not done:
        _, r, term, trunc, info = env.step(8)
        done = term or trunc
    assert trunc or info["goal_reached"]
    env.close()
