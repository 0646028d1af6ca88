"""The ``-v1`` ids' observations (``pathpref_tasks.gym_v1``): the same spaces on every map, so
an agent made on one map runs on another; stable-baselines3's env checker passes;
Gymnasium's ``RecordVideo`` records (moviepy, the ``rl`` extra); the ``-v0`` ids stay as
they were."""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pathpref_tasks  # noqa: F401  # registers the ids
import pytest
from pathpref_tasks.gym_v1 import MAX_GOALS, OCCUPANCY_RADIUS, PathprefEnvV1
from pathpref_tasks.route_reward import DISCOUNT

from pathpref.errors import ConfigError, MapError
from pathpref.geometry.generate import floor_plan

MAPS = ("simple", "office", "classroom")


def make(map_, env_id="pathpref/Navigate-v1", **kw):
    return gym.make(env_id, map=map_, seed=0, delta_t=1, **kw)


@pytest.mark.parametrize("env_id", ["pathpref/Navigate-v1", "pathpref/NavigateControl-v1"])
def test_spaces_identical_on_every_map(env_id):
    spaces = []
    for m in (*MAPS, floor_plan(21)):
        env = make(m, env_id)
        obs, _ = env.reset()
        assert env.observation_space.contains(obs)
        spaces.append(env.observation_space)
        env.close()
    assert all(s == spaces[0] for s in spaces[1:])
    assert all(len(s.shape) == 1 for s in spaces[0].spaces.values())  # flat, as SB3 asks


def test_v0_kept_as_it_was():
    sizes = {}
    for m in ("simple", "office"):
        env = make(m, "pathpref/Navigate-v0")
        sizes[m] = env.observation_space["polytope_onehot"].shape[0]
        assert env.unwrapped.task_kwargs["reward"] == "potential"
        env.close()
    assert sizes == {"simple": 8, "office": 56}  # the map-dependent one-hot of the issue


def test_features_worked_out(simple):
    env = make("simple")
    obs, _ = env.reset()
    task = env.unwrapped._env.task
    assert task.reward == "route" and task.gamma == DISCOUNT
    r = task.runner
    G = len(r.instance.goals)
    assert obs["goal_mask"].sum() == G and obs["goal_belief"][G:].sum() == 0.0
    assert obs["goal_belief"].sum() == pytest.approx(1.0, abs=1e-9)
    # the occupancy: 1 exactly where (x + dx, y + dy) is no free cell of the map
    R = OCCUPANCY_RADIUS
    x, y = (int(c) for c in simple.cells[r.cell])
    occ = obs["local_occupancy"].reshape(2 * R + 1, 2 * R + 1)
    for dy in range(-R, R + 1):
        for dx in range(-R, R + 1):
            try:
                simple.cell((x + dx, y + dy))
                free = True
            except MapError:
                free = False
            assert occ[dy + R, dx + R] == (0.0 if free else 1.0), (dx, dy)
    p = obs["exit_probs"]
    assert np.all(np.diff(p) <= 1e-12) and p.sum() <= 1.0 + 1e-9 and p[0] > 0.0
    ev = obs["exit_vectors"].reshape(-1, 3)
    assert np.hypot(*ev[0, :2]) == pytest.approx(1.0, abs=1e-9)
    assert obs["time_left"][0] == 1.0  # no decision taken yet
    obs, *_ = env.step(8)  # stay: one decision of T_max
    assert obs["time_left"][0] == pytest.approx(1.0 - 1.0 / r.spec.t_max)
    env.close()


def test_too_many_goals_is_one_line():
    with pytest.raises(ConfigError, match="n_goals must be at most 16"):
        PathprefEnvV1("navigate", map="simple", n_goals=MAX_GOALS + 1)


def test_sb3_check_env_and_an_agent_runs_on_other_maps():
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_checker import check_env

    env = make("simple")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no warning of the checker either
        check_env(env.unwrapped)
    model = PPO("MultiInputPolicy", env, n_steps=16, batch_size=16, device="cpu", seed=0)
    env.close()
    for m in ("office", floor_plan(21)):  # an agent made on one map acts on another
        other = make(m)
        obs, _ = other.reset()
        a, _ = model.predict(obs, deterministic=True)
        assert other.action_space.contains(int(a))
        other.close()


def test_record_video(tmp_path):
    pytest.importorskip("moviepy")
    from gymnasium.wrappers import RecordVideo

    env = RecordVideo(make("simple", render_mode="rgb_array", width=96, height=64),
                      str(tmp_path), episode_trigger=lambda k: k == 0, disable_logger=True)
    env.reset()
    for _ in range(2):
        env.step(8)
    env.close()
    videos = list(tmp_path.glob("*.mp4"))
    assert len(videos) == 1 and videos[0].stat().st_size > 0
