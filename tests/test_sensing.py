"""Realistic force sensing (docs/sensing.md): the ideal default is unchanged bit for bit, the
raw sensor already holds the handle's inertia, the estimator tracks the bias at rest and removes
the inertia of the robot's own motion, the filtered detector finds pushes under noise and bias
and gives no false cue while the base drives hard, the mj_inverse residual recovers a push."""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from pathpref.apps.benchmarks.physics import false_cues_realistic  # noqa: E402
from pathpref.errors import ConfigError  # noqa: E402
from pathpref.geometry.grid import ACTION_ANGLES  # noqa: E402
from pathpref.sim.cue_detector import FilteredCueDetector  # noqa: E402
from pathpref.sim.estimator import EstimatorConfig, ResidualEstimator  # noqa: E402
from pathpref.sim.force_cue import HumanPush, PushProfile  # noqa: E402
from pathpref.sim.mobile_base import MobileBase  # noqa: E402
from pathpref.sim.scene import build_scene  # noqa: E402
from pathpref.sim.sensing import SensorModel  # noqa: E402

# A 30 N, 0.3 s push at 0.7 rad on the base at cell (3, 3) of simple, sensed by the ideal
# sensor; computed with the code of main before realistic sensing existed (commit 2361fac)
PINNED_IMPULSE = (4.295599242675679, 3.618133329790661)
PINNED_PEAK = 29.838398020425547
PINNED_DURATION = 0.3120000000000002
PINNED_TIME = 0.34000000000000025


@pytest.fixture(scope="module")
def scene(worlds):
    return build_scene(worlds["simple"])


def _push(angle: float, peak: float = 30.0, duration: float = 0.3) -> HumanPush:
    return HumanPush(angle, 0.0, PushProfile(peak_n=peak, duration_s=duration), 0)


def _rest(base: MobileBase, seconds: float) -> None:
    t_end = base.data.time + seconds
    while base.data.time < t_end:
        base.substep()


@pytest.mark.cross_cpu
@pytest.mark.parametrize("sensor_model", [None, SensorModel.ideal(), SensorModel()])
def test_ideal_default_is_unchanged(worlds, scene, sensor_model):
    """The default (and an explicit ideal model) gives the cue of the old code: its heading
    exactly, its floats to ``tests/close.py``'s physical tolerance (README, "Replays
    exactly")."""
    from tests.close import REL_PHYSICS, assert_same

    base = MobileBase(scene, sensor_model=sensor_model)
    assert base.sensor_model is None and base.estimator is None
    base.reset(worlds["simple"].cell((3, 3)))
    cue = base.receive_push(_push(0.7))
    assert cue.heading == 1
    assert_same([*cue.impulse.tolist(), cue.peak_n, cue.duration_s, base.data.time],
                [*PINNED_IMPULSE, PINNED_PEAK, PINNED_DURATION, PINNED_TIME], "cue",
                rel=REL_PHYSICS)


def test_raw_sensor_reads_the_handle_inertia(worlds, scene):
    """MuJoCo's force sensor already holds the inertial effect: driving off hard with no push,
    the raw reading is -m_handle * a_base (0.2 kg), about 1.6 N at the start."""
    w = worlds["simple"]
    base = MobileBase(scene)
    base.reset(w.cell((1, 1)))
    base.target = base.position + np.array([1.0, 0.0])
    f, a = [], []
    for _ in range(200):
        base.substep()
        f.append(base.sensor.force_xy(base.data)[0])
        a.append(base.data.qacc[base.vxy[0]])
    f, a = np.array(f), np.array(a)
    mass = -np.dot(f, a) / np.dot(a, a)
    assert mass == pytest.approx(0.2, abs=1e-6)
    assert 1.5 < np.abs(f).max() < 1.7


def test_sensor_model_checks_and_needs_a_generator(scene):
    with pytest.raises(ConfigError, match="noise_n"):
        SensorModel(noise_n=-1.0)
    with pytest.raises(ConfigError, match="rate_hz"):
        SensorModel(rate_hz=0.0)
    with pytest.raises(ConfigError, match="Generator"):
        MobileBase(scene, sensor_model=SensorModel.realistic())
    assert SensorModel.ideal().is_ideal and not SensorModel.realistic().is_ideal


def test_faults_are_reproducible_and_leave_the_body_rng_alone(worlds, scene):
    """Same seed, same cue; the sensor draws from a spawned child, not the body's stream."""
    cues = []
    for seed in (3, 3, 4):
        rng = np.random.default_rng(seed)
        base = MobileBase(scene, sensor_model=SensorModel.realistic(), rng=rng)
        assert rng.random() == np.random.default_rng(seed).random()
        base.reset(worlds["simple"].cell((3, 3)))
        cues.append(base.receive_push(_push(0.7)).impulse)
    assert np.array_equal(cues[0], cues[1]) and not np.array_equal(cues[0], cues[2])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_bias_is_tracked_at_rest(worlds, scene, seed):
    """Not zeroed at start (tare off), a 6 N bias is tracked to within 0.4 N after 10 s at
    rest (measured 0.09-0.14 N), and stays frozen while a push acts."""
    base = MobileBase(scene, sensor_model=SensorModel.realistic(),
                      rng=np.random.default_rng(seed), estimator=EstimatorConfig(tare_s=0.0))
    base.reset(worlds["simple"].cell((3, 3)))
    assert np.linalg.norm(base.estimator.bias[:2] - base.faulty.bias[:2]) > 5.0
    _rest(base, 10.0)
    assert np.linalg.norm(base.estimator.bias[:2] - base.faulty.bias[:2]) < 0.4
    before = base.estimator.bias.copy()
    push = _push(0.7, peak=60.0, duration=0.5)
    push.t0 = float(base.data.time)
    while base.data.time < push.t0 + 0.5:
        base.substep(push)
    # frozen during the push: only samples from before it may still enter (a leak of the
    # push's 60 N samples would move it by newtons)
    assert np.linalg.norm(base.estimator.bias - before) < 0.05


@pytest.mark.parametrize("heading", range(8))
def test_known_push_under_noise_and_bias(worlds, scene, heading):
    """A 30 N push and a weak 12 N, 0.15 s push toward each sector, under 2 N noise, 6 N
    drifting bias and inertia: the right sector each time."""
    base = MobileBase(scene, sensor_model=SensorModel.realistic(),
                      rng=np.random.default_rng(heading))
    base.reset(worlds["simple"].cell((3, 3)))
    for peak, duration in ((30.0, 0.3), (12.0, 0.15)):
        _rest(base, 0.3)
        cue = base.receive_push(_push(float(ACTION_ANGLES[heading]), peak, duration))
        assert cue is not None and cue.heading == heading
        base.move_to(worlds["simple"].cell((3, 3)))


def test_inertial_compensation_removes_the_acceleration_reading():
    """Hard driving with no push, 0.6 kg sensed, no noise or bias: uncompensated the estimate
    peaks above 6 N (the inertia), compensated it stays below 5 % of that (measured 2 %)."""
    inertia_only = SensorModel(extra_mass_kg=0.4)
    _, _, raw = false_cues_realistic(10.0, sensor_model=inertia_only,
                                     estimator=EstimatorConfig(compensate_inertia=False))
    _, _, residual = false_cues_realistic(10.0, sensor_model=inertia_only)
    assert raw > 6.0
    assert residual < 0.05 * raw


def test_no_false_cue_while_driving_hard():
    """60 s of hard random driving and braking on office with realistic sensing: no cue.
    Without the inertial compensation the same drive gives false cues."""
    n, seconds, _ = false_cues_realistic(60.0)
    assert seconds >= 60.0 and n == 0
    n_unc, _, _ = false_cues_realistic(60.0,
                                       estimator=EstimatorConfig(compensate_inertia=False))
    assert n_unc > 0


def test_filtered_detector_raises_its_thresholds_with_the_noise():
    """At rest, a 6 N per-axis noise lifts the on/off thresholds above 8/4 N; pure noise gives
    no cue; a clear push still does."""
    det = FilteredCueDetector(0.002)
    rng = np.random.default_rng(0)
    for _ in range(5000):
        assert det.update(6.0 * rng.standard_normal(2), at_rest=True) is None
    assert det.on_n > 8.0 and det.off_n > 4.0
    cue = None
    for k in range(400):
        f = 40.0 * np.sin(np.pi * k / 150) if k < 150 else 0.0
        cue = cue or det.update(np.array([0.0, f]) + 6.0 * rng.standard_normal(2))
    assert cue is not None and cue.heading == 0  # north


def test_residual_estimator_recovers_the_push_while_driving(worlds, scene):
    """mj_inverse with the measured velocity difference: the push to 1e-9 N while the base
    drives off (the sensor is off by the handle's inertia, 1.6 N)."""
    w = worlds["simple"]
    base = MobileBase(scene)
    base.reset(w.cell((3, 3)))
    res = ResidualEstimator(base.model, base.vxy)
    push = _push(0.7)
    base.target = base.scene.cell_centre(w.cell((4, 3)))
    worst = 0.0
    for _ in range(200):
        q0, v0, t = base.data.qpos.copy(), base.data.qvel.copy(), float(base.data.time)
        base.substep(push)
        worst = max(worst, float(np.linalg.norm(res.estimate(q0, v0, base.data)
                                                - push.force(t)[:2])))
    assert worst < 1e-9
    assert mujoco.__version__.startswith("3.")


def test_tray_sensor_of_the_arm_with_realistic_faults(worlds):
    """The arm's tray sensor goes through the same chain (sensor, estimator and detector are
    built for the tray at reset): four pushes, the right sector each."""
    from pathpref.sim.arm import ArmBase
    from pathpref.sim.body import scene_for

    w = worlds["simple"]
    arm = ArmBase(scene_for(w, 0.5, "carry"), sensor_model=SensorModel.realistic(),
                  rng=np.random.default_rng(0))
    arm.reset(w.cell((3, 3)))
    assert arm.faulty.sensor is arm.sensor and arm.estimator.body == arm.tray
    for heading in (0, 3, 4, 6):
        cue = arm.receive_push(_push(float(ACTION_ANGLES[heading])))
        assert cue is not None and cue.heading == heading
        arm.move_to(arm.cell)
