"""dm_control's own suite checks (``dm_control/suite/suite_test.py``) on every task of the one
registry, the Gymnasium ids derived from it, and a package of tasks and maps that registers
itself through entry points (a dist-info with ``entry_points.txt`` on ``sys.path``)."""

from __future__ import annotations

import os
import sys

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from dm_control.rl import control  # noqa: E402
from dm_env import specs  # noqa: E402
from pathpref_tasks import TASKS, all_tasks, gym_id, load  # noqa: E402

from pathpref.errors import ConfigError  # noqa: E402

from .plugin_helpers import install_package  # noqa: E402

#: small episodes: the suite's checks, not the planner, are under test
SMALL = {"map": "simple", "method": "compliant", "delta_t": 1, "queries": 20, "t_max": 3}
#: the model's object kinds and their counts, as suite_test.test_components_have_names
KINDS = [("body", "nbody"), ("joint", "njnt"), ("geom", "ngeom"), ("site", "nsite"),
         ("camera", "ncam"), ("light", "nlight"), ("mesh", "nmesh"), ("hfield", "nhfield"),
         ("texture", "ntex"), ("material", "nmat"), ("equality", "neq"),
         ("tendon", "ntendon"), ("actuator", "nu"), ("sensor", "nsensor"),
         ("numeric", "nnumeric"), ("text", "ntext"), ("tuple", "ntuple")]


def random_policy(spec, seed: int):
    """suite_test's uniform random policy; a discrete spec draws whole actions."""
    rng = np.random.RandomState(seed)
    if isinstance(spec, specs.DiscreteArray):
        return lambda ts: np.int32(rng.randint(0, spec.num_values))
    return lambda ts: rng.uniform(spec.minimum, spec.maximum)


def trajectory(env, policy, episodes: int, steps: int):
    """suite_test's step_environment: ``episodes`` of at most ``steps`` steps."""
    for _ in range(episodes):
        ts = env.reset()
        yield ts
        n = 0
        while not ts.last() and n < steps:
            ts = env.step(policy(ts))
            n += 1
            yield ts


def suite_checks(make, steps: int = 3) -> None:
    """suite_test's checks on the environments ``make(**environment_kwargs)`` builds:
    every model object named, at least two cameras, time steps conforming to the specs
    (shapes, dtypes, finite observations, no extra arrays, discounts in [0, 1], the reward
    None on the first step and a float after), identical trajectories from identical seeds
    and actions, ``flat_observation`` passed through, consecutive observations sharing no
    memory, two consecutive initial states differing. (Not applied: the benchmark's reward in
    [0, 1] and actions in [-1, 1], which bind only the suite's BENCHMARKING tasks; constant
    observation elements, which are constant here by design, e.g. ``goal_cells`` within an
    episode.)"""
    env = make()
    model = env.physics.model
    for kind, count in KINDS:
        for i in range(getattr(model, count)):
            assert model.id2name(i, kind) not in ("", None), f"unnamed {kind} {i}"
    assert model.ncam >= 2
    obs_spec, act_spec = env.observation_spec(), env.action_spec()
    for ts in trajectory(env, random_policy(act_spec, 0), 2, steps):
        obs = dict(ts.observation)
        for name, spec in obs_spec.items():
            arr = obs.pop(name)
            assert arr.shape == spec.shape and arr.dtype == spec.dtype, name
            assert np.isfinite(arr).all(), name
            spec.validate(arr)  # bounded specs: within their bounds
        assert not obs, f"observations outside the spec: {sorted(obs)}"
        if ts.first():
            assert ts.reward is None and ts.discount is None
        else:
            assert isinstance(ts.reward, float) and np.isfinite(ts.reward)
            assert isinstance(ts.discount, float) and 0.0 <= ts.discount <= 1.0
    runs = [list(trajectory(make(), random_policy(act_spec, 0), 1, steps)) for _ in range(2)]
    assert len(runs[0]) == len(runs[1]) >= 2
    for a, b in zip(*runs):
        assert (a.step_type, a.reward, a.discount) == (b.step_type, b.reward, b.discount)
        for k in a.observation:
            np.testing.assert_array_equal(a.observation[k], b.observation[k], err_msg=k)
    flat = make(flat_observation=True)
    assert set(flat.observation_spec()) == {control.FLAT_OBSERVATION_KEY}
    first = env.reset()
    second = env.step(random_policy(act_spec, 1)(first))
    for name, arr in first.observation.items():
        assert not np.may_share_memory(arr, second.observation[name]), name
    o1, o2 = env.reset().observation, env.reset().observation
    assert not all(np.array_equal(o1[k], o2[k]) for k in o1)


@pytest.mark.parametrize("name", sorted(TASKS))
def test_every_task_passes_the_suite_checks(name):
    """Every built-in task, by suite_test's checks (:func:`suite_checks`)."""
    control_rate = name.endswith("_control")
    limit = 0.5 if control_rate else None
    suite_checks(lambda **env_kw: load(name, task_kwargs={**SMALL, "seed": 4},
                                       environment_kwargs=env_kw or None, time_limit=limit),
                 steps=10 if control_rate else 2)


def test_gymnasium_ids_derive_from_the_one_registry():
    """The Gymnasium ids are the registry's names, capitalised; each is registered."""
    gym = pytest.importorskip("gymnasium")
    from pathpref_tasks.gym import IDS

    assert IDS == {"pathpref/Navigate-v0": "navigate",
                   "pathpref/NavigateControl-v0": "navigate_control",
                   "pathpref/Carry-v0": "carry", "pathpref/CarryControl-v0": "carry_control"}
    assert {gym_id(n) for n in TASKS} <= set(gym.registry)


PACKAGE = '''
"""An example package of pathpref tasks and maps (tests/test_tasks_suite.py)."""
from pathpref_tasks.navigate import Navigate


class Patrol(Navigate):
    """``navigate`` with an argument of its own: ``hurry`` scales every reward."""

    def __init__(self, hurry: float = 2.0, **kwargs):
        super().__init__(**kwargs)
        self.hurry = float(hurry)

    def get_reward(self, physics):
        return self.hurry * super().get_reward(physics)


def corridor():
    """An 8 x 6 map with a 1 x 2 pillar; the human circles it counter-clockwise."""
    return {"name": "corridor", "width": 8, "height": 6,
            "obstacles": [{"cells": {"lower_left": [4, 3], "size": [1, 2]}}],
            "preference": {"route": [[2, 2], [7, 2], [7, 5], [2, 5]], "closed": True}}


NOT_A_TASK = 3
'''


@pytest.fixture
def example_package(tmp_path, monkeypatch):
    """``pathpref_example_tasks`` installed the venv-less way: its module and a dist-info
    whose ``entry_points.txt`` declares a task, a map, and (``broken``) a bad task."""
    yield install_package(tmp_path, monkeypatch, "pathpref_example_tasks", PACKAGE, """\
        [pathpref.tasks]
        patrol = pathpref_example_tasks:Patrol

        [pathpref.maps]
        corridor = pathpref_example_tasks:corridor
        """)
    sys.modules.pop("pathpref_example_tasks", None)


def test_a_package_registers_a_task_and_a_map(example_package):
    """The package's task loads by name with its own argument, on the package's map; it
    passes the suite checks and Gymnasium's ``check_env`` under its derived id; its reward
    is ``hurry`` times navigate's, step by step on the same seed."""
    assert "patrol" in all_tasks() and "patrol" not in TASKS
    kw = {**SMALL, "map": "corridor", "seed": 1}
    env = load("patrol", hurry=3.0, **kw)
    assert env.task.world.spec.name == "corridor" and env.task.world.spec.width == 8
    assert env.task.template.map == "dict:corridor"
    suite_checks(lambda **e: load("patrol", task_kwargs=kw, environment_kwargs=e or None))
    plain = load("navigate", **kw)
    env.reset(), plain.reset()
    for _ in range(2):
        a = plain.task.policy_action()
        got, want = env.step(a), plain.step(a)
        assert got.reward == 3.0 * want.reward
    gym = pytest.importorskip("gymnasium")
    from gymnasium.utils.env_checker import check_env
    from pathpref_tasks.gym import register_envs

    register_envs()
    assert gym_id("patrol") == "pathpref/Patrol-v0"
    genv = gym.make("pathpref/Patrol-v0", **kw)
    check_env(genv.unwrapped)
    genv.close()


def test_bad_entry_points_are_one_line_errors(example_package):
    """A task entry point naming something that is not a task (refused when it is loaded,
    not when another task is), or clashing with a built-in name, and a map failing to load:
    one line naming the entry point; a map clashing with a built-in one is not used."""
    gym = pytest.importorskip("gymnasium")
    from pathpref_tasks.gym import register_envs

    ep = example_package / "entry_points.txt"
    ep.write_text("[pathpref.tasks]\nbroken = pathpref_example_tasks:NOT_A_TASK\n")
    with pytest.raises(ConfigError, match=r"entry point 'broken' .* subclass of") as e:
        load("broken", **SMALL)
    assert "\n" not in str(e.value)
    assert load("navigate", **SMALL).task.world.spec.name == "simple"  # others still load
    register_envs()  # the id is registered without importing the package's task
    assert "pathpref/Broken-v0" in gym.registry
    ep.write_text("[pathpref.tasks]\nnavigate = pathpref_example_tasks:Patrol\n")
    with pytest.raises(ConfigError, match="clashes with a built-in task"):
        all_tasks()
    ep.write_text("[pathpref.maps]\nsimple = pathpref_example_tasks:corridor\n"
                  "gone = pathpref_example_tasks:missing\n")
    assert load("navigate", **SMALL).task.world.spec.name == "simple"  # built-in first
    with pytest.raises(ConfigError, match="entry point 'gone' .* failed to load"):
        load("navigate", **{**SMALL, "map": "gone"})
