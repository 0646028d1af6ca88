"""``pathpref_tasks.load(..., physics=...)``: the dm_control and Gymnasium tasks with the physical
parameters of ``--sim mujoco`` (sensor faults, detector, pushes drawn from the human model,
pushes at any time, the physical and the differential-drive base); without ``physics`` the
legacy physics, unchanged bit for bit."""

from __future__ import annotations

import json
import os
import unittest

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from dm_env import test_utils  # noqa: E402
from pathpref_tasks import load  # noqa: E402

from pathpref.episode import Physics  # noqa: E402
from pathpref.errors import ConfigError  # noqa: E402
from pathpref.sim.cue_detector import FilteredCueDetector  # noqa: E402
from pathpref.sim.diffdrive import DiffDriveBase  # noqa: E402

SMALL = {"map": "simple", "method": "goal_only", "queries": 20}


class NavigatePhysicsConformance(test_utils.EnvironmentTestMixin, unittest.TestCase):
    """dm_env's conformance with pushes at any time on the diff-drive base."""

    def make_object_under_test(self):
        return load("navigate", delta_t=2, seed=0, t_max=6, **SMALL,
                    physics={"timing": "interval", "base": "diffdrive"})


class NavigateControlPhysicsConformance(test_utils.EnvironmentTestMixin, unittest.TestCase):
    """dm_env's conformance at control rate with realistic sensing and the physical drive."""

    def make_object_under_test(self):
        return load("navigate_control", delta_t=1, seed=0, time_limit=2.0, **SMALL,
                    physics={"sensor": "realistic", "timing": "rate"})


@pytest.mark.cross_cpu
@pytest.mark.parametrize("case", range(2))
def test_legacy_default_is_unchanged(case):
    """With ``physics="legacy"`` the tasks run the legacy physics unchanged: every observation,
    reward and action of the task's own policy equals ``tests/data/task_traces.json`` (written by
    ``scripts/task_traces.py``), actions and discrete observations exactly, floats to
    ``tests/close.py``'s tolerance (floats compared with a tolerance, not by their bits, which
    differ between CPU classes: README, "Replays exactly")."""
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    sys.path.insert(0, str(root / "scripts"))
    from task_traces import trace

    from tests.close import assert_same

    want = json.loads((root / "tests/data/task_traces.json").read_text())[case]
    env = load(want["task"], **want["kwargs"])
    assert env.task.template.physics == "" and env.task.physics is None
    assert env.task.base is None or env.task.base.sensing.sensor_model is None
    got = trace(want["task"], want["kwargs"], want["steps"])
    # observations added since the traces were taken (the step's interaction) are pinned by
    # tests/test_tasks_interaction.py; every stored one must be unchanged
    stored = set(want["obs"][0])
    assert stored <= set(got["obs"][0])
    got["obs"] = [{k: o[k] for k in sorted(stored)} for o in got["obs"]]
    if want["task"] == "navigate":  # decision steps: the moves are discrete
        assert got["action"] == want["action"]
    assert_same(got, {k: want[k] for k in ("obs", "reward", "action")}, want["task"])


def test_realistic_sensing_noisy_at_rest_and_cue_detected():
    """``{"sensor": "realistic"}``: the sensor carries a 6 N bias, the force observation at
    rest is noise (the legacy ideal sensor reads zero there), and the first push is still
    detected in the heading it was given (angle noise 0, so the sector is exact)."""
    passed = {"sensor": "realistic", "noise_deg": 0}
    env = load("navigate", delta_t=4, t_max=5, seed=2, physics=passed, **SMALL)
    legacy = load("navigate", delta_t=4, t_max=5, seed=2, physics="legacy", **SMALL)
    assert env.task.template.physics == Physics.of(**passed).to_json()
    ts = env.reset()
    legacy.reset()
    b = env.task.base
    assert env.task.runner.spec.physics == Physics.of(**passed).to_json()  # stored with the row
    assert isinstance(b.sensing.detector, FilteredCueDetector)
    assert np.hypot(*b.sensing.faulty.bias[:2]) == pytest.approx(6.0, abs=0.05)
    push = env.task.body.last_push
    assert ts.observation["heading"].sum() == 1.0
    assert int(np.argmax(ts.observation["heading"])) == push.intended_heading
    assert 10.0 <= push.profile.peak_n <= 60.0  # drawn from the human model
    forces, forces0 = [], []
    for _ in range(3):  # no push is due: the base stands
        forces.append(env.step(8).observation["force"].copy())
        forces0.append(legacy.step(8).observation["force"].copy())
    mags = np.hypot(*np.array(forces).T)
    assert (mags > 0.05).all() and (mags < 4.0).all() and len({tuple(f) for f in forces}) == 3
    assert np.abs(forces0).max() < 1e-3


def test_diffdrive_base_turns_and_drives_without_sliding():
    """``{"base": "diffdrive"}``: the base turns toward a move north (90 degrees from its
    heading), drives the cell (0.5 m) and never slides sideways (the wheels' grip)."""
    env = load("navigate", delta_t=5, t_max=4, seed=0, physics={"base": "diffdrive"}, **SMALL)
    env.reset()
    task = env.task
    b = task.base
    assert isinstance(b, DiffDriveBase)
    cell = task.runner.cell
    north = [a for a in (0, 4) if task.world.motion.next_cell[cell, a] != cell][0]
    side = []
    b.on_substep.append(lambda base, push: side.append(abs(
        -np.sin(base.data.qpos[base.yaw]) * base.velocity[0]
        + np.cos(base.data.qpos[base.yaw]) * base.velocity[1])))
    p0 = b.position.copy()
    env.step(north)
    assert abs(abs(float(b.data.qpos[b.yaw])) - np.pi / 2) < 0.15
    assert np.linalg.norm(b.position - p0) == pytest.approx(0.5, abs=0.03)
    assert max(side) < 0.02  # m/s across the wheels


@pytest.mark.parametrize("name,physics,extra,msg", [
    ("navigate", {"sensor_noise_n": -3}, {}, "physics sensor_noise_n"),
    ("navigate", {"base": "tracked"}, {}, "physics base .* must be one of holonomic, diffdrive"),
    ("navigate", {"bogus": 1}, {}, "unknown field 'bogus'"),
    ("navigate", 7, {}, "physics must be a Physics"),
    ("navigate", '{"sensor":', {}, "physics must be JSON"),
    ("carry", {"base": "diffdrive"}, {}, "diffdrive runs the navigate task only"),
    ("navigate", {"duration_max_s": 2.0}, {"decision_s": 2.5}, "decision_s must leave"),
    ("navigate_control", {"timing": "rate"}, {"push_period_s": 2.0}, "push_period_s sets"),
])
def test_bad_physics_is_one_line_naming_the_field(name, physics, extra, msg):
    with pytest.raises(ConfigError, match=msg) as e:
        load(name, physics=physics, **extra, **SMALL)
    assert "\n" not in str(e.value) and isinstance(e.value, ValueError)


def test_physics_forms_store_the_same_json():
    """A ``Physics``, a dict of its fields and its JSON give the same stored string; "" and
    "legacy" the legacy physics; nothing given, the defaults (as every door's)."""
    ph = Physics.of(sensor="ft300s", base="diffdrive", peak_n=30.0)
    given = [ph, {"sensor": "ft300s", "base": "diffdrive", "peak_n": 30.0}, ph.to_json()]
    assert {load("navigate", physics=g, **SMALL).task.template.physics
            for g in given} == {ph.to_json()}
    assert {load("navigate", physics=g, **SMALL).task.template.physics
            for g in ("", "legacy")} == {""}  # the legacy physics only by name
    assert load("navigate", **SMALL).task.template.physics == Physics().to_json()


def test_pushes_at_any_time_update_the_belief_at_once():
    """``{"timing": "interval"}``: the human pushes on their own clock, also while the base
    drives; each cue reaches the runner's door in the physics step it is read (the one cue
    stream), a cue while driving ends the move, and every cue has the heading of the push
    that caused it."""
    env = load("navigate", delta_t=2, t_max=4, seed=1, method="path_preference",
               physics={"timing": "interval", "interval_s": 1.0},
               **{k: v for k, v in SMALL.items() if k != "method"})
    ts = env.reset()
    task = env.task
    b, body = task.base, task.body
    observed = []
    door = body.observe
    body.connect(lambda felt: (observed.append(felt), door(felt)))
    seen: list[tuple[int, int, float, tuple, tuple]] = []
    b.on_substep.append(lambda base, push: seen.append(
        (len(base.felt), len(observed), float(np.hypot(*base.velocity)), tuple(base.target),
         tuple(task.scene.cell_centre(base.cell)))))
    steps = 0
    while not ts.last() and steps < 3:
        ts, steps = env.step(task.policy_action()), steps + 1
    felt = len(b.felt)
    # the runner counts the pushes begun until its last cue or step; later ones are not felt
    assert felt >= 4 and body.inputs_given() >= task.runner.result.inputs >= felt
    # the runner's door is told in the very physics step a cue is read
    assert all(cur[1] == cur[0] for cur in seen)
    assert body.cue_metrics()["cue_hits"] >= felt - 1
    moving = [i for i in range(1, len(seen) - 1) if seen[i][0] > seen[i - 1][0]
              and seen[i - 1][2] > 0.1]
    assert moving  # at least one cue felt while the base drove ...
    # ... which ended the move: the base holds the centre of the cell it was in
    assert all(seen[i + 1][3] == seen[i][4] for i in moving)


def test_control_rate_physical_base_and_gym_pass_physics():
    """At control rate the physical base follows the agent's velocity within its
    acceleration limit (0.8 m/s^2) and its speed limit sets the action bounds; the Gymnasium
    id passes ``physics`` through to the task."""
    gym = pytest.importorskip("gymnasium")
    env = load("navigate_control", delta_t=1, seed=1, physics={"sensor": "realistic"},
               time_limit=1.5, **SMALL)
    assert np.all(env.action_spec().maximum == 1.0)
    ts, n = env.reset(), 0
    while not ts.last():
        ts, n = env.step(np.array([1.0, 0.0]) if n < 40 else np.array([-1.0, 0.0])), n + 1
    b = env.task.base
    m = b.measurements
    assert 0.5 < m.peak_accel_pushed <= 0.8 + 1e-3 and m.peak_accel <= 0.8 + 1e-3
    g = gym.make("pathpref/NavigateControl-v0", physics={"v_max": 0.5}, time_limit=0.2,
                 **SMALL)
    assert g.action_space == gym.spaces.Box(-0.5, 0.5, (2,), np.float32)
    assert g.unwrapped._env.task.template.physics == Physics.of(v_max=0.5).to_json()
    g.close()


def test_control_rate_diffdrive_turns_toward_the_command():
    """At control rate the differential-drive base turns toward the agent's velocity and then
    drives along it (an agent's command has no target to settle on): 0.6 m/s north for 3 s
    from a standstill facing east."""
    env = load("navigate_control", delta_t=5, seed=1, physics={"base": "diffdrive"},
               time_limit=3.5, **SMALL)
    env.reset()
    b = env.task.base
    p0 = b.position.copy()
    for _ in range(150):
        env.step(np.array([0.0, 0.6]))
    assert float(b.data.qpos[b.yaw]) == pytest.approx(np.pi / 2, abs=0.05)
    assert b.position[1] - p0[1] > 0.8 and abs(b.position[0] - p0[0]) < 0.05
