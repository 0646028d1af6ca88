"""The dm_control task: dm_env conformance, seeding, termination and reward."""

from __future__ import annotations

import os
import unittest

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from dm_env import test_utils  # noqa: E402
from pathpref_tasks import TASKS, gym_id, load  # noqa: E402

from pathpref.episode import Physics  # noqa: E402
from pathpref.errors import ConfigError  # noqa: E402


class NavigateConformance(test_utils.EnvironmentTestMixin, unittest.TestCase):
    def make_object_under_test(self):
        return load("navigate", map="simple", method="goal_only", delta_t=3, seed=0,
                    queries=200, t_max=8)


class NavigateControlConformance(test_utils.EnvironmentTestMixin, unittest.TestCase):
    def make_object_under_test(self):
        return load("navigate_control", task_kwargs={"map": "simple", "method": "goal_only",
                                                     "delta_t": 1, "seed": 0, "queries": 50},
                    time_limit=3.0)


class CarryControlConformance(test_utils.EnvironmentTestMixin, unittest.TestCase):
    def make_object_under_test(self):
        return load("carry_control", task_kwargs={"map": "simple", "method": "compliant",
                                                  "delta_t": 1, "seed": 0, "queries": 20},
                    time_limit=2.0)


def test_carry_control_reaches_the_goal_with_the_tray_level():
    """The arm at control rate: the method's own velocities reach the goal; the tray stays
    within 10 degrees of level and the reward carries the tilt penalty."""
    env = load("carry_control", map="simple", method="compliant", delta_t=1, seed=0,
               queries=20)
    ts, tilt, n = env.reset(), 0.0, 0
    while not ts.last() and n < 600:
        ts, n = env.step(env.task.policy_action()), n + 1
        tilt = max(tilt, float(ts.observation["tray_tilt"][0]))
    assert env.task.runner.result.goal_reached and ts.discount == 0.0
    assert tilt < 10.0 and env.control_timestep() == pytest.approx(0.02)


class CarryConformance(test_utils.EnvironmentTestMixin, unittest.TestCase):
    def make_object_under_test(self):
        return load("carry", task_kwargs={"map": "simple", "method": "compliant",
                                          "delta_t": 2, "seed": 0, "queries": 20, "t_max": 3,
                                          "decision_s": 1.5, "physics": "legacy"})


@pytest.mark.parametrize("name,kwargs,sub", [
    ("navigate", {"delta_t": 1, "t_max": 4, "physics": "legacy"}, 1250),  # 2.5 s steps
    ("navigate", {"delta_t": 1, "t_max": 4}, 1700),  # the default physics: Physics.step_s 3.4 s
    ("navigate_control", {"delta_t": 1}, 10),
])
def test_time_is_honest(name, kwargs, sub):
    """One env step advances exactly control_timestep() of physics, all of it through the
    substeps the hooks see (no extra hidden step): the last hook's time is the physics time."""
    env = load(name, task_kwargs={"map": "simple", "method": "compliant", "seed": 2,
                                  "queries": 20, **kwargs})
    assert env.control_timestep() == pytest.approx(sub * 0.002)
    ts = env.reset()
    seen = []
    env.task.base.on_substep.append(lambda b, push: seen.append(float(b.data.time)))
    for _ in range(3):
        t0, n0 = env.physics.time(), len(seen)
        ts = env.step(8 if name == "navigate" else np.array([0.3, 0.0]))
        assert env.physics.time() - t0 == pytest.approx(env.control_timestep(), abs=1e-9)
        assert len(seen) - n0 == sub and seen[-1] == env.physics.time()
        if ts.last():
            break


def _random_actions(env, rng):
    spec = env.action_spec()
    if hasattr(spec, "num_values"):
        return int(rng.integers(spec.num_values))
    return rng.uniform(spec.minimum, spec.maximum, size=spec.shape)


@pytest.mark.parametrize("name,kwargs", [
    ("navigate", {"delta_t": 2, "t_max": 5, "physics": "legacy"}),  # 2.5 s steps: 4 in 4 s
    ("navigate_control", {"delta_t": 1, "push_period_s": 1.0}),
])
def test_same_seed_same_episodes_step_by_step(name, kwargs):
    """Two fresh environments with one seed give identical observations and rewards at every
    step, over two episodes (so across reset); another seed gives another episode."""
    def trace(seed):
        env = load(name, task_kwargs={"map": "simple", "method": "path_preference",
                                      "seed": seed, "queries": 50, **kwargs}, time_limit=4.0)
        rng, out = np.random.default_rng(0), []
        for _ in range(2):
            ts = env.reset()
            out.append({k: v.copy() for k, v in ts.observation.items()})
            while not ts.last():
                ts = env.step(_random_actions(env, rng))
                out.append((ts.reward, {k: v.copy() for k, v in ts.observation.items()}))
        return out

    a, b, c = trace(4), trace(4), trace(5)
    assert len(a) == len(b) > 4

    def same(x, y):
        if isinstance(x, tuple):
            return x[0] == y[0] and same(x[1], y[1])
        return x.keys() == y.keys() and all(np.array_equal(x[k], y[k]) for k in x)

    assert all(same(x, y) for x, y in zip(a, b, strict=True))
    assert not (len(a) == len(c) and all(same(x, y) for x, y in zip(a, c, strict=True)))


def test_control_rate_push_shows_in_force_and_detector():
    """At control rate the human's first push plays while the agent drives: the filtered
    force exceeds the detector's 8 N threshold, the detector is active for a while, and the
    detected heading arrives as a one-hot when the cue ends, about the push's heading."""
    env = load("navigate_control", map="simple", method="compliant", delta_t=1, seed=1,
               queries=20)
    ts = env.reset()
    assert not ts.observation["heading"].any()
    peak, active = 0.0, 0
    for _ in range(40):  # 0.8 s: the 0.3 s push and its release
        ts = env.step(np.zeros(2))
        peak = max(peak, float(np.hypot(*ts.observation["force"])))
        active += int(ts.observation["detector_active"][0])
        if ts.observation["heading"].any():
            break
    push = env.task.body.last_cue
    assert peak > 8.0 and active >= 3 and push is not None
    assert ts.observation["heading"].sum() == 1.0
    assert int(np.argmax(ts.observation["heading"])) == push.heading
    assert env.task.runner.result.inputs == 1


def test_control_rewards_are_the_rule_at_cell_changes():
    """Reward only at cell changes; each is ``transition_reward`` of the grid move between
    the two cells (checked here from the cells the observations report). The planner is the
    ``robust`` preset, which never stands still waiting for a push, so the episode's first
    400 control steps cross cells (the rule checked is the environment's, whatever the
    planner)."""
    from pathpref.planning.pomdp import get_preset, transition_reward

    env = load("navigate_control", map="simple", method="path_preference", delta_t=2, seed=0,
               queries=200, preset="robust")
    ts, task, changes = env.reset(), env.task, 0
    world, rewards = task.world, get_preset("paper").path_preference
    index = {tuple(c): i for i, c in enumerate(world.cells.tolist())}
    cell = index[tuple(ts.observation["cell"].astype(int).tolist())]
    for _ in range(400):
        ts = env.step(task.policy_action())
        new = index[tuple(ts.observation["cell"].astype(int).tolist())]
        if new == cell:
            assert ts.reward == 0.0
        else:
            changes += 1
            moves = [a for a in range(8) if world.motion.next_cell[cell, a] == new]
            pref = int(task.runner.pref[int(world.cell_polytope[cell])])
            assert moves and ts.reward == transition_reward(
                world, cell, new, moves[0], task.runner.instance.goal_cell, pref, rewards)
        cell = new
        if ts.last():
            break
    assert changes >= 3


def test_suite_style_load_and_time_limit():
    env = load("navigate_control", task_kwargs={"map": "simple", "seed": 0, "queries": 20},
               environment_kwargs={"control_timestep": 0.05}, time_limit=0.5)
    assert env.control_timestep() == pytest.approx(0.05)
    ts, n = env.reset(), 0
    while not ts.last():
        ts, n = env.step(np.zeros(2)), n + 1
    assert n == 10 and ts.discount == 1.0
    env = load("navigate", task_kwargs={"map": "simple", "decision_s": 2.0, "queries": 20})
    assert env.control_timestep() == pytest.approx(2.0)


@pytest.mark.parametrize("kwargs,msg", [
    ({"task_kwargs": {"speed": 1}}, "unknown argument 'speed' of task 'navigate_control'"),
    ({"environment_kwargs": {"n_sub_steps": 3}}, "unknown environment_kwargs 'n_sub_steps'"),
    ({"environment_kwargs": {"control_timestep": 0.5}}, "control_timestep must be"),
    ({"environment_kwargs": {"control_timestep": 0.021}}, "multiple of the physics step"),
    ({"time_limit": -1}, "time_limit must be"),
])
def test_bad_load_arguments_name_the_field(kwargs, msg):
    with pytest.raises(ConfigError, match=msg) as e:
        load("navigate_control", **kwargs)
    assert isinstance(e.value, ValueError) and "\n" not in str(e.value)


@pytest.mark.parametrize("bad", [np.array([np.nan, 0.0]), np.zeros(3), np.array([2.0, 0.0]),
                                 "fast", None])
def test_bad_control_actions_name_the_field(bad):
    import traceback

    env = load("navigate_control", map="simple", seed=0, queries=20)
    env.reset()
    t = env.physics.time()
    with pytest.raises(ConfigError, match="action must be \\(vx, vy\\)") as e:
        env.step(bad)
    assert "\n" not in str(e.value) and env.physics.time() == t  # refused before any step
    frames = traceback.extract_tb(e.value.__traceback__)
    assert not any("dm_control" in f.filename for f in frames)


@pytest.mark.parametrize("bad", [np.nan, 9, -1, np.zeros(2), "n", None])
def test_bad_moves_are_refused_outside_dm_control(bad):
    import traceback

    env = load("navigate", map="simple", seed=0, queries=20, t_max=3)
    env.reset()
    with pytest.raises(ConfigError, match="action must be 0..8") as e:
        env.step(bad)
    assert not any("dm_control" in f.filename
                   for f in traceback.extract_tb(e.value.__traceback__))


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


@pytest.mark.parametrize("env_id", sorted(gym_id(name) for name in TASKS))
def test_gymnasium_env_passes_check_env(env_id):
    """Registered ids, Discrete(9) or Box(2) actions, every observation a bounded box, the env
    checker silent (its warnings raised as errors; seeding determinism included), rendering,
    a clear error when stepping after the end."""
    import warnings

    gym = pytest.importorskip("gymnasium")
    from gymnasium.utils.env_checker import check_env

    control = "Control" in env_id
    env = gym.make(f"pathpref_tasks:{env_id}", map="simple", method="compliant", delta_t=2,
                   queries=20, t_max=4, render_mode="rgb_array", width=64, height=48,
                   time_limit=1.0 if control else None)
    if control:  # the default physics' base: v_max
        v = Physics().drive.v_max
        assert env.action_space == gym.spaces.Box(-v, v, (2,), np.float32)
    else:
        assert env.action_space == gym.spaces.Discrete(9)
    space = env.observation_space
    assert space["goal_belief"].is_bounded() and space["position"].is_bounded()
    assert space["position"].high[0] == 5.0  # the 10 x 10 map at 0.5 m per cell
    assert all(box.is_bounded() for box in space.values())
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped, skip_render_check=False)
    a, _ = env.reset(seed=3)
    b, _ = env.reset(seed=3)
    assert all(np.array_equal(a[k], b[k]) for k in a)
    frame = env.render()
    assert frame.shape == (48, 64, 3)
    done = False
    while not done:
        _, r, term, trunc, info = env.step(np.zeros(2, np.float32) if control else 8)
        done = term or trunc
    assert trunc or info["goal_reached"]
    with pytest.raises(ConfigError, match="call reset"):
        env.step(np.zeros(2, np.float32) if control else 8)
    env.close()


def test_readme_vector_example_runs():
    """docs/physical.md's ``gymnasium.vector`` example, run as written (shortened to 20
    steps)."""
    pytest.importorskip("gymnasium")
    from pathlib import Path

    text = (Path(__file__).parents[1] / "docs" / "physical.md").read_text()
    block = next(b.split("\n", 1)[1] for b in text.split("```python")[1:]
                 if "gym.vector" in b).split("```")[0]
    assert "range(100)" in block
    scope: dict = {}
    exec(block.replace("range(100)", "range(20)"), scope)
    obs = scope["obs"]
    assert obs["position"].shape == (4, 2) and obs["goal_belief"].shape == (4, 10)
    assert len({tuple(p) for p in obs["goal_cells"][:, 0]}) > 1  # seeds 0..3: other goals


@pytest.mark.parametrize("physics", ["legacy", None])  # 0.8 m/s (float32 above it), 1.0 m/s
@pytest.mark.parametrize("env_id", ["pathpref/NavigateControl-v0", "pathpref/CarryControl-v0"])
def test_control_rate_tasks_accept_their_own_bounds(env_id, physics):
    """The bound as every library writes it is an action: Gymnasium's float32 ``high`` and
    ``low`` (``float32(0.8) > 0.8``: stable-baselines3's PPO clips to it and died on the first
    rollout), the float64 bound of the dm_env spec, and mixed corners, in Gymnasium and
    dm_env; the base is commanded at most ``v_max``; a value one float32 step past the bound
    is refused with one line."""
    gym = pytest.importorskip("gymnasium")
    from pathpref.errors import ConfigError

    env = gym.make(f"pathpref_tasks:{env_id}", map="simple", method="compliant", delta_t=2,
                   queries=20, t_max=4, time_limit=1.0, physics=physics)
    env.reset(seed=0)
    hi, lo = env.action_space.high, env.action_space.low
    task = env.unwrapped._env.task
    v = task.v_max
    assert hi.dtype == np.float32 and float(hi[0]) >= v
    for a in (hi, lo, hi.astype(np.float64), np.array([v, -v]), np.array([hi[0], lo[1]])):
        env.step(a)
        assert np.abs(task.command.u[:2]).max() <= v  # clipped to v_max, not past it
    past = np.nextafter(np.float32(v), np.float32(2 * v))
    with pytest.raises(ConfigError, match="each in"):
        env.step(np.array([past, 0.0], np.float32))
    dm = load(env_id.split("/")[1].replace("-v0", "").replace("NavigateControl",
              "navigate_control").replace("CarryControl", "carry_control"), map="simple",
              method="compliant", delta_t=2, queries=20, t_max=4, time_limit=1.0,
              physics=physics)
    dm.reset()
    spec = dm.action_spec()
    for a in (spec.maximum, spec.minimum, hi, lo):
        dm.step(np.broadcast_to(a, spec.shape))
