"""The Gymnasium conventions of every registered id: string entry points (``to_json``),
``max_episode_steps`` covering every built-in map's horizon, and the ``info`` keys other
libraries read (``is_success``, ``is_intervention``, ``intervention_heading``) at every step."""

from __future__ import annotations

import json

import gymnasium as gym
import pathpref_tasks
import pytest
from pathpref_tasks.gym import ENTRY_POINT, IDS

from pathpref.geometry.maps import load_map


@pytest.mark.parametrize("env_id", sorted(IDS))
def test_every_id_has_a_string_entry_point_and_a_horizon(env_id):
    spec = gym.spec(env_id)
    assert spec.entry_point == ENTRY_POINT
    assert json.loads(spec.to_json())["id"] == env_id
    # classroom's T_max (60 decisions) is the longest built-in horizon: never cut short
    assert load_map("classroom").t_max == 60
    control_rate = not pathpref_tasks.registry.BUILTIN_TASKS[IDS[env_id]].decides
    assert spec.max_episode_steps == (10200 if control_rate else 60)


def test_info_has_the_shared_keys_every_step():
    env = gym.make("pathpref/Navigate-v0", map="simple", delta_t=1)
    _, info = env.reset(seed=0)
    # the human's first push is played in reset (delta_t=1: one push per decision)
    assert info["is_intervention"] is True and 0 <= info["intervention_heading"] <= 7
    for _ in range(3):
        _, _, terminated, truncated, info = env.step(8)  # stay: the human pushes again
        assert info["is_success"] == info["success"]
        assert isinstance(info["is_intervention"], bool)
        assert (info["intervention_heading"] >= 0) == info["is_intervention"]
        if terminated or truncated:
            break
    env.close()


@pytest.mark.parametrize("map_name", ["simple", "office", "classroom"])
def test_candidates_keep_the_minimum_distance_over_many_seeds(map_name):
    """300 draws per map: every candidate at least GYM_MIN_GOAL_DISTANCE grid cells from the
    start; min_distance 0 draws exactly the paper's instances."""
    import numpy as np
    from pathpref_tasks.gym import GYM_MIN_GOAL_DISTANCE

    from pathpref.episode.instances import sample_instance
    from pathpref.geometry.world import load_world

    world = load_world(map_name)
    for seed in range(300):
        inst = sample_instance(world, seed, 10, min_distance=GYM_MIN_GOAL_DISTANCE)
        d = world.motion.distances_from(np.array([inst.start]))[0]
        assert min(d[g] for g in inst.goals) >= GYM_MIN_GOAL_DISTANCE
        if seed < 30:
            assert sample_instance(world, seed, 10, min_distance=0.0) == \
                sample_instance(world, seed, 10)


def test_seed_3_starts_far_from_every_candidate():
    """Navigate-v0 on seed 3 drew a goal beside the start (the episode ended after one step);
    now every candidate is at least 4 grid cells from the start."""
    import numpy as np

    env = gym.make("pathpref/Navigate-v0")
    env.reset(seed=3)
    task = env.unwrapped._env.task
    inst = task.runner.instance
    d = task.world.motion.distances_from(np.array([inst.start]))[0]
    assert min(d[g] for g in inst.goals) >= 4.0
    env.close()
