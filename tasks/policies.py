"""Trained agents as policies of a dm_env time step (what ``pathpref render --policy`` films):
a stable-baselines3 checkpoint (``agent.zip`` of ``examples/train_ppo.py``) reads the time
step through the Gymnasium observation (:func:`pathpref_tasks.gym.gym_observation`: bounds,
the learner's features), restricted to the keys the agent was trained on.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from pathpref.errors import ConfigError

#: the observations ``examples/train_ppo.py``'s agent reads: the detected push, the belief,
#: the goals seen from the base and the polytope (:func:`pathpref_tasks.gym.learner_features`)
AGENT_KEYS = ("heading", "detector_active", "goal_belief", "goal_vectors", "goal_direction",
              "polytope_onehot")


def agent_observation(observation: Mapping[str, Any], keys=AGENT_KEYS) -> dict[str, Any]:
    """The agent's ``keys`` of a Gymnasium observation."""
    return {k: observation[k] for k in keys}


def checkpoint_policy(path: str | Path, task: str = "navigate",
                      task_kwargs: dict | None = None) -> Callable[[Any], Any]:
    """The stable-baselines3 agent saved at ``path`` (PPO, else any algorithm
    ``stable_baselines3`` names in the file's ``data``) as a policy of a dm_env time step of
    ``task`` with ``task_kwargs``: deterministic actions on the Gymnasium observations it was
    trained on (the keys of its observation space). A one-line ConfigError when
    stable-baselines3 is missing or the file is no agent for this task's observations."""
    try:
        import stable_baselines3 as sb3
    except ImportError as e:
        raise ConfigError("a checkpoint policy needs stable-baselines3 (pip install "
                          "'pathpref[rl]')") from e
    from .gym import PathprefEnv, gym_observation

    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"no agent checkpoint at {path}")
    model = None
    for algo in (sb3.PPO, sb3.A2C, sb3.DQN, sb3.SAC, sb3.TD3):
        try:
            model = algo.load(path, device="cpu")
            break
        except (ValueError, KeyError, TypeError, RuntimeError, AssertionError):
            continue
    if model is None:
        raise ConfigError(f"{path} is not a stable-baselines3 agent (PPO, A2C, DQN, SAC, TD3)")
    env = PathprefEnv(task, **(task_kwargs or {}))
    space = env.observation_space
    env.close()
    keys = tuple(getattr(model.observation_space, "spaces", {}))
    missing = [k for k in keys if k not in space.spaces]
    if not keys or missing:
        raise ConfigError(f"{path} was trained on observations {list(keys)}; task {task!r} "
                          f"lacks {missing or 'a dict of them'}")

    def act(time_step):
        obs = agent_observation(gym_observation(space, time_step.observation), keys)
        return model.predict(obs, deterministic=True)[0]

    return act
