"""Snapshots of an episode (:mod:`pathpref_tasks.snapshot`): run some steps, snapshot, run
more recording every observation, restore, replay the same actions: the same observations,
rewards and metrics bit for bit (one process, so exact equality is the contract), in the
environment the snapshot came from and in one freshly loaded with the same arguments."""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from pathpref_tasks import load  # noqa: E402

from pathpref.errors import ConfigError  # noqa: E402


def _run(env, actions):
    """Step ``actions``: each step's observation (copied) and reward."""
    out = []
    for a in actions:
        ts = env.step(a)
        out.append(({k: np.array(v, copy=True) for k, v in ts.observation.items()},
                    ts.reward))
    return out


def _same(a, b) -> bool:
    return len(a) == len(b) and all(
        ra == rb and oa.keys() == ob.keys() and all(np.array_equal(oa[k], ob[k]) for k in oa)
        for (oa, ra), (ob, rb) in zip(a, b, strict=True))


def _drive(env, n: int) -> list:
    """``n`` velocity commands of the task's own policy from here (stepped)."""
    actions = []
    for _ in range(n):
        a = env.task.policy_action()
        actions.append(a)
        env.step(a)
    return actions


@pytest.mark.parametrize("compiled", ["1", "0"])
def test_control_rate_episode_restores_bit_for_bit(monkeypatch, compiled):
    """``navigate_control`` with the default physics (faulty sensor, estimator, detector, the
    human pushing from the start): 20 steps, snapshot, 60 more (a push and its cue), restore,
    the same 60: equal; again from the same snapshot; and in a fresh environment."""
    monkeypatch.setenv("PATHPREF_COMPILED_STEPS", compiled)
    kw = {"map": "simple", "seed": 3}
    env = load("navigate_control", **kw)
    env.reset()
    _drive(env, 20)
    snap = env.snapshot()
    actions = []
    for _ in range(60):
        actions.append(env.task.policy_action())
        env.step(actions[-1])
    metrics = env.episode_metrics
    env.restore(snap)
    first = _run(env, actions)
    assert env.episode_metrics == metrics
    assert env.task.base.felt, "the replay read no cue: the test would miss the detector"
    env.restore(snap)
    assert _same(_run(env, actions), first)
    fresh = load("navigate_control", **kw)
    fresh.restore(snap)
    assert _same(_run(fresh, actions), first)
    assert fresh.episode_metrics == metrics


def test_restoring_the_physics_alone_is_not_enough():
    """The parts' state is beside MuJoCo's (docs/tasks.md): ``physics.set_state`` of the
    state at the snapshot leaves the sensor, estimator, detector and task where they were,
    and the same commands end elsewhere; the snapshot puts them back."""
    env = load("navigate_control", map="simple", seed=3)
    env.reset()
    _drive(env, 20)
    snap, state = env.snapshot(), env.physics.get_state().copy()
    actions = [env.task.policy_action() for _ in range(40)]
    reference = _run(env, actions)
    env.physics.set_state(state)
    assert not _same(_run(env, actions), reference)
    env.restore(snap)
    assert _same(_run(env, actions), reference)


def test_decision_task_restores_with_its_planner():
    """``navigate`` (one decision a step, the planner's search and its random stream, the
    belief, the runner): after one decision, snapshot, two more of the planner's choices,
    restore into a fresh environment: the planner chooses the same and the observations are
    equal."""
    kw = {"map": "simple", "seed": 0, "decision_s": 2.0}
    env = load("navigate", **kw)
    env.reset()
    env.step(env.task.policy_action())
    snap = env.snapshot()
    chosen, reference = [], []
    for _ in range(2):
        chosen.append(env.task.policy_action())
        reference += _run(env, chosen[-1:])
    fresh = load("navigate", **kw)
    fresh.restore(snap)
    again = []
    for a in chosen:
        assert fresh.task.policy_action() == a
        again += _run(fresh, [a])
    assert _same(again, reference)


def test_gym_env_restores():
    """The Gymnasium env's ``snapshot`` / ``restore`` (through ``unwrapped``): the same
    observations, rewards, terminations and infos."""
    gym = pytest.importorskip("gymnasium")
    env = gym.make("pathpref_tasks:pathpref/NavigateControl-v0", map="simple")
    env.reset(seed=1)
    for _ in range(10):
        env.step(np.array([0.3, 0.1], np.float32))
    snap = env.unwrapped.snapshot()
    actions = [np.array([0.2 * (i % 3) - 0.2, 0.25], np.float32) for i in range(30)]

    def run():
        out = []
        for a in actions:
            obs, r, term, trunc, info = env.step(a)
            out.append(({k: v.copy() for k, v in obs.items()}, (r, term, trunc, info)))
        return out

    reference = run()
    env.unwrapped.restore(snap)
    again = run()
    assert [x[1] for x in again] == [x[1] for x in reference]
    assert _same([(o, 0.0) for o, _ in again], [(o, 0.0) for o, _ in reference])
    with pytest.raises(ConfigError, match="restore takes a snapshot"):
        env.unwrapped.restore({"bad": 1})


def test_a_snapshot_of_another_task_is_refused():
    """A snapshot fits only an environment of the same task and model: one line."""
    env = load("navigate_control", map="simple", seed=0)
    env.reset()
    snap = env.snapshot()
    other = load("navigate", map="simple", seed=0)
    with pytest.raises(ConfigError, match="same task and arguments"):
        other.restore(snap)
    with pytest.raises(ConfigError, match="takes a snapshot"):
        other.restore(None)
