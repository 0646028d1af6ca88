"""Physical interaction that matters: pushes at any time, two pushes are
two cues, the human who pushes like a person, the physical parameters of an episode."""

from __future__ import annotations

import json
import math
import os
from dataclasses import replace

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

import pathpref.sim  # noqa: E402,F401 - registers the MuJoCo body
from pathpref.episode import EpisodeSpec, Physics, run_episode  # noqa: E402
from pathpref.episode.physics import QUIET_DEFAULTS, Drive, HumanModel  # noqa: E402
from pathpref.errors import ConfigError  # noqa: E402
from pathpref.sim.body import scene_for  # noqa: E402
from pathpref.sim.cue_detector import CueDetector  # noqa: E402
from pathpref.sim.force_cue import HumanPush, PushProfile  # noqa: E402
from pathpref.sim.mobile_base import MobileBase  # noqa: E402
from pathpref.sim.pushing_human import sample_profile  # noqa: E402
from pathpref.sim.sensing import SensorModel  # noqa: E402


def _driving_base(world, sensor_model=None, split=True):
    base = MobileBase(scene_for(world), sensor_model=sensor_model,
                      rng=np.random.default_rng(5))
    base.enable_pushes_any_time()
    base.sensing.detector.split = split
    base.reset(world.cell((3, 3)))
    return base


def _half_sine(t, t0, peak, dur):
    return peak * np.sin(np.pi * (t - t0) / dur) if t0 <= t <= t0 + dur else 0.0


def test_detector_splits_two_pushes_20ms_apart():
    """The detector alone on an exact force trace: east 30 N for 0.3 s, 20 ms of nothing,
    north 30 N for 0.3 s. Split: two cues at 0 and 90 degrees (each impulse is a symmetric
    half-sine along one axis). Unsplit: one cue at 45 degrees (equal impulses)."""
    dt = 0.002
    ts = np.arange(0.0, 1.0, dt)
    f = [np.array([_half_sine(t, 0.1, 30, 0.3), _half_sine(t, 0.42, 30, 0.3)]) for t in ts]
    for split, want in ((True, [0.0, 90.0]), (False, [45.0])):
        det = CueDetector(dt, split=split)
        angles = [np.degrees(c.angle) for c in map(det.update, f) if c is not None]
        assert np.allclose(angles, want, atol=1.5), (split, angles)


def test_detector_splits_an_overlapping_turn():
    """East 30 N from 0.1 s to 0.7 s, north 30 N from 0.4 s to 1.0 s (constant forces, no
    dip). A force sensor feels only the sum: (30, 30) during the overlap, exactly 45 degrees
    from the east impulse, not past the turn threshold, so the overlap stays in the first cue:
    impulse (30 x 0.6, 30 x 0.3) = (18, 9) N s. At 0.7 s the force is north, 63 degrees from
    (18, 9): after 25 ms the first cue ends and the second (pure north) begins."""
    dt = 0.002
    ts = np.arange(0.0, 1.3, dt)
    f = [np.array([30.0 * (0.1 <= t < 0.7), 30.0 * (0.4 <= t < 1.0)]) for t in ts]
    det = CueDetector(dt, split=True)
    cues = [c for c in map(det.update, f) if c is not None]
    assert len(cues) == 2 and det.splits == 1
    assert np.allclose(cues[0].impulse, [18.0, 9.0], atol=0.07)
    assert np.degrees(cues[1].angle) == pytest.approx(90.0)
    assert cues[1].impulse[1] == pytest.approx(30.0 * 0.3, abs=0.07)


@pytest.mark.parametrize("model", [None, SensorModel.realistic()])
def test_two_pushes_while_driving_are_two_cues(simple, model):
    base = _driving_base(simple, model)
    base.stop_on_cue = False
    base.target = base.scene.cell_centre(simple.cell((5, 3)))
    prof = PushProfile()
    base.pushes = [HumanPush(0.0, 0.3, prof, 2), HumanPush(np.pi / 2, 0.62, prof, 0)]
    while base.data.time < 1.5:
        base.substep()
    angles = [np.degrees(f.angle) for f in base.felt]
    assert len(angles) == 2 and abs(angles[0]) < 8 and abs(angles[1] - 90) < 8, angles
    assert [f.heading for f in base.felt] == [2, 0]  # E, N
    # felt within 80 ms of the onset (30 N half-sine: 8 N after 26 ms; 100 Hz filtered sensor)
    assert 0.3 <= base.felt[0].t_felt <= 0.3 + 0.08


def test_push_while_driving_stops_the_move_and_yields(simple):
    """Driving east from (3, 3) to (5, 3) (one metre), a 40 N push north 0.3 s into the
    move: the move ends on the cue (not at the target), the cue is north and was felt in the
    cell the base was in at the push's onset; the base moved north (it yielded)."""
    base = _driving_base(simple)
    start_y = float(base.position[1])
    base.pushes = [HumanPush(np.pi / 2, 0.3, PushProfile(peak_n=40.0), 0)]
    base.move_to(simple.cell((5, 3)))
    assert len(base.felt) == 1 and base.felt[0].heading == 0
    assert base.data.time < 1.0  # well before the move would have settled
    assert not np.allclose(base.position, base.scene.cell_centre(simple.cell((5, 3))),
                           atol=0.05)
    assert base.position[1] - start_y > 0.02  # yielded with the push


def test_pushes_at_any_time_reach_the_belief():
    ph = Physics.of(timing="interval", sensor="ideal").to_json()
    spec = EpisodeSpec.single("simple", "path_preference", 3, seed=3, instance=1,
                              sim="mujoco", physics=ph)
    res = run_episode(spec)
    assert res.inputs > 0
    heads = [s.heading for s in res.log if s.heading >= 0]
    assert heads, "felt cues reach the policy as the step's heading"
    again = run_episode(spec)
    assert [(s.x, s.y, s.heading, s.p_true_goal) for s in again.log] == \
        [(s.x, s.y, s.heading, s.p_true_goal) for s in res.log]  # deterministic


def test_legacy_spec_key_has_no_physics_field():
    """The legacy physics only by name (its key keeps no physics field, as the rows stored
    before the field); a physical body's default is ``Physics()``, in its key."""
    spec = EpisodeSpec.single("simple", "path_preference", 5, seed=1, sim="mujoco",
                              physics="legacy")
    assert spec.physics == "" and "physics" not in spec.key()
    ph = EpisodeSpec.single("simple", "path_preference", 5, seed=1, sim="mujoco")
    assert ph.physics == Physics().to_json()
    assert "physics=" in ph.key() and ph.key() != spec.key()
    assert EpisodeSpec.single("simple", "path_preference", 5).physics == ""  # the grid


def test_push_distributions():
    """Log-normal strength and duration: the medians are the settings (to sampling error of
    2000 draws), the clips hold."""
    p = Physics().human
    rng = np.random.default_rng(0)
    prof = [sample_profile(p, rng) for _ in range(2000)]
    peaks = np.array([q.peak_n for q in prof])
    durs = np.array([q.duration_s for q in prof])
    assert abs(np.median(peaks) - p.peak_n) < 1.5 and abs(np.median(durs) - p.duration_s) < 0.02
    assert peaks.min() >= p.peak_min_n and peaks.max() <= p.peak_max_n
    assert durs.min() >= 0.1 and durs.max() <= p.duration_max_s
    bell = PushProfile(peak_n=20.0, duration_s=0.4, shape="bell")
    assert bell.magnitude(0.2) == pytest.approx(20.0) and bell.magnitude(0.1) == \
        pytest.approx(16 * 20 * 0.25**2 * 0.75**2)


@pytest.mark.parametrize("given,msg", [
    ({"sensor_noise_n": -2.0}, r"sensor_noise_n \(--sensor-noise-n\) must be a number in 0..50"),
    ({"base": "tank"}, r"base \(--base\) must be one of holonomic, diffdrive"),
    ({"force_limit_n": 5.0, "mass_kg": 20.0, "a_max": 0.2},
     "force_limit_n must be above the detector's on_n"),
    ({"timing": "sometimes"}, r"timing \(--timing\) must be one of decision, interval"),
    ({"v_max": 3.0}, r"v_max \(--v-max\) must be a number in 0.05..1.5"),
    ({"nonsense": 1}, "unknown field 'nonsense'"),
    # the drive cannot deliver the planned acceleration: 120 N on 135 kg is 0.889 m/s^2
    ({"a_max": 10.0}, r"a_max \(--a-max\) must be at most 0.889 m/s\^2"),
    ({"a_max": 0.8, "friction_n": 30.0}, r"at most 0.667 m/s\^2"),  # (120 - 30) / 135
    ({"a_max": 0.8, "mass_kg": 200.0}, r"at most 0.6 m/s\^2"),
    ({"friction_n": 130.0}, "friction_n must be below force_limit_n"),
])
def test_bad_physics(given, msg):
    with pytest.raises(ConfigError, match=msg):
        Physics.of(**given)


def test_physics_groups_and_stable_json():
    """The three typed groups hold every flat field once; the canonical JSON of the defaults
    is the one stored keys hold (the fields added later, mass and friction, appear only when
    set), and it parses back to the same value."""
    p = Physics()
    flat = p.flat()
    assert set(flat) == set(json.loads(p.to_json())) | set(QUIET_DEFAULTS)
    assert Physics(sensor="ideal", base="diffdrive") == Physics.of(sensor="ideal",
                                                                   base="diffdrive")
    assert Physics(drive=Drive(v_max=0.5), a_max=0.3).drive == Drive(v_max=0.5, a_max=0.3)
    assert p.drive.kind == flat["base"] == "holonomic" and p.human.gamma_h == 1.5
    assert Physics.from_json(p.to_json()) == p
    heavy = Physics.of(mass_kg=200.0, a_max=0.5)
    assert json.loads(heavy.to_json())["mass_kg"] == 200.0
    assert Physics.from_json(heavy.to_json()) == heavy


def test_grid_episodes_take_the_human_model():
    """A grid episode's human has a rationality of its own (``gamma_h``): the spec keeps
    only the human's settings, the default human leaves the key as before, and physical
    settings are refused with the fix."""
    base = EpisodeSpec.single("simple", "path_preference", 5, seed=1)
    assert base.physics == "" and base.human_model.gamma_h == 1.5 and base.physical is None
    same = EpisodeSpec.single("simple", "path_preference", 5, seed=1,
                              physics={"gamma_h": 1.5})
    assert same.physics == "" and same.key() == base.key()
    wild = EpisodeSpec.single("simple", "path_preference", 5, seed=1,
                              physics={"gamma_h": 0.2})
    wild.validate()
    assert wild.human_model.gamma_h == 0.2 and wild.key() != base.key()
    assert set(json.loads(wild.physics)) == set(json.loads(HumanModel().to_json()))
    with pytest.raises(ConfigError, match=r"sensor \(--sensor\) needs a physical body"):
        EpisodeSpec.single("simple", "path_preference", 5, seed=1,
                           physics={"sensor": "ideal"}).validate()
    # the human's rationality reaches the grid human: P(h) ~ exp(-gamma Delta_h) with Delta
    # at most a few cells, so at gamma 0.01 every heading is within a factor exp(0.01 * 8)
    # of any other; the default human (1.5) prefers some by far more
    from pathpref.episode.runner import EpisodeRunner

    def spread(spec):
        r = EpisodeRunner(spec)
        q = r.human.probs(r.cell)
        return q.max() / q[q > 0].min()

    assert spread(replace(wild, physics=HumanModel(gamma_h=0.01).to_json())) < math.exp(0.08)
    assert spread(base) > 2.0


@pytest.mark.parametrize("given,move,step", [
    # 2 sqrt(d / a), d = 0.5 sqrt(2): the default drive never reaches v_max within a cell
    ({}, 2 * math.sqrt(0.5 * math.sqrt(2) / 0.8), 3.4),          # 1.880 + 0.5 + 0.6 + 0.4
    ({"v_max": 0.5, "a_max": 0.3}, 2 * math.sqrt(0.5 * math.sqrt(2) / 0.3), 4.6),  # 3.070
    # v^2 / a = 0.1125 < d: cruise at v, d / v + v / a = 2.357 + 0.375
    ({"v_max": 0.3}, 0.5 * math.sqrt(2) / 0.3 + 0.3 / 0.8, 4.3),
    ({"duration_max_s": 3.0, "duration_s": 2.0}, 2 * math.sqrt(0.5 * math.sqrt(2) / 0.8), 5.8),
])
def test_one_rule_for_the_decision_step(given, move, step):
    """The step every door uses (``Physics.step_s``): the drive's diagonal move, the settle
    allowance and the longest push with its release window, rounded up to 0.1 s; the move
    limit is the step less the push window."""
    p = Physics.of(**given)
    assert p.move_s() == pytest.approx(move, rel=1e-12)
    assert p.step_s() == pytest.approx(step, abs=1e-12)
    assert p.move_limit_s() == pytest.approx(step - p.human.duration_max_s - 0.4, abs=1e-12)


def test_a_slow_drive_gets_the_time_its_move_needs():
    """A 0.5 m/s, 0.3 m/s^2 drive needs 3.07 s for a diagonal cell: its move limit (3.6 s,
    the one rule) lets it settle on the target (the fixed 3 s limit cut it short)."""
    from pathpref.episode.cache import cached_world
    from pathpref.sim.body import MujocoBody

    spec = EpisodeSpec.single("simple", "compliant", 5, sim="mujoco",
                              physics=Physics.of(v_max=0.5, a_max=0.3, sensor="ideal"))
    world = cached_world("simple")
    body = MujocoBody(world, spec, np.random.default_rng(0))
    where = {tuple(c): i for i, c in enumerate(world.cells.tolist())}
    start, target = next((i, where[(x + 1, y + 1)]) for (x, y), i in where.items()
                         if (x + 1, y + 1) in where)
    body.reset(start)
    assert body.base.move_to(target) == target
    took = float(body.base.data.time)
    centre = body.base.scene.cell_centre(target)
    assert np.hypot(*(body.base.position - centre)) < 0.02  # settled (tol_m)
    assert 3.0 < took < spec.physical.move_limit_s()


def test_schema3_database_upgrades_with_legacy_physics(tmp_path):
    """The saved schema-3 sweep upgrades to schema 5 in place: same keys, ``physics`` empty
    (NULL: the legacy physics, as :func:`row_spec` reads it)."""
    import shutil
    import sqlite3

    from pathpref.experiments.migrate import upgrade_database
    from pathpref.experiments.store import ResultStore, row_spec

    db = tmp_path / "old.sqlite"
    shutil.copy("tests/data/saved_sweep.sqlite", db)
    old_keys = {r[0] for r in sqlite3.connect(db).execute("SELECT key FROM episodes")}
    out = upgrade_database(db)
    assert (out["from"], out["to"], out["merged"]) == (3, 5, 0)
    with ResultStore(db) as st:
        rows = st.episodes()
    assert {r["key"] for r in rows} == old_keys and {r["physics"] for r in rows} == {None}
    assert all(row_spec(r).physics == "" and row_spec(r).key() == r["key"] for r in rows)


def test_carry_sustained_push_moves_with_it_or_holds():
    """30 N for 3 s on the tray, north and south: the legacy carry drives against the push
    (hundreds of mm); the physical one never does (<= 5 mm)."""
    from pathpref.apps.benchmarks.physics import carry_drift

    assert carry_drift(physical=True)["carry_drift_mm"] <= 5.0
    assert carry_drift(physical=False)["carry_drift_mm"] > 100.0


def test_physical_moves_settle_without_overshoot_within_limits():
    from pathpref.apps.benchmarks.physics import carry_moves

    out = carry_moves(6, seed=1)
    assert out["carry_overshoot_max_mm"] <= 10.0
    assert out["carry_base_peak_accel"] <= 1.0 + 1e-6  # the Ridgeback's 1.0 m/s^2


def test_push_above_the_actuator_limit_does_not_run_away():
    """130 N for 3 s against a 120 N drive: the legacy 12 kg base is carried metres away; the
    physical 135 kg base braces (net 10 N: 0.5 * 10/135 * 3^2 = 0.33 m plus the yield before
    the brace) and comes back to its cell."""
    from pathpref.apps.benchmarks.physics import runaway

    phys = runaway(physical=True, any_time=True)
    assert phys["runaway_m"] <= 0.5 and phys["runaway_recovered_m"] < 0.05
    assert runaway(physical=False)["runaway_m"] > 1.0


def test_diffdrive_turns_and_cannot_slide(simple):
    """Driving from (3, 3) to the cell north of it, the diff-drive base turns to face north
    (yaw +90 degrees: the nearer way from yaw 0) and its velocity is along its heading."""
    from pathpref.apps.benchmarks.physics import physical_base

    base = physical_base(simple, sensor="ideal", kind="diffdrive")
    base.reset(simple.cell((3, 3)))
    lateral = []

    def watch(b, _push):
        yaw = float(b.data.qpos[b.yaw])
        lateral.append(abs(-np.sin(yaw) * b.velocity[0] + np.cos(yaw) * b.velocity[1]))

    base.on_substep.append(watch)
    assert base.move_to(simple.cell((3, 4))) == simple.cell((3, 4))
    assert float(base.data.qpos[base.yaw]) == pytest.approx(np.pi / 2, abs=0.1)
    assert max(lateral) < 0.02


def test_tip_force_of_the_arm_on_base(simple):
    from pathpref.apps.benchmarks.physics import physical_base

    arm = physical_base(simple, task="carry", sensor="ideal")
    arm.reset(simple.cell((3, 3)))
    m = arm.model
    mass = m.body_subtreemass[m.body("base_xy").id]
    h = arm.data.xpos[arm.tray][2]
    assert 138 < mass < 140 and 0.8 < h < 1.0  # 135 kg base + Jaco and tray; tray height
    assert arm.tip_force_n() == pytest.approx(mass * 9.81 * 0.15 / h)
    assert arm.tip_force_n() > 60.0  # above the strongest default push (peak_max_n)


@pytest.mark.parametrize("argv,msg", [
    (["--sim", "mujoco", "--sensor-noise-n", "-2"], "sensor_noise_n (--sensor-noise-n) must be "
                                                     "a number in 0..50"),
    (["--sim", "mujoco", "--base", "tank"], "argument --base: invalid choice: 'tank'"),
    (["--sim", "mujoco", "--force-limit-n", "5", "--mass-kg", "20", "--a-max", "0.2"],
     "force_limit_n must be above the detector"),
    (["--sim", "mujoco", "--v-max", "3", "--a-max", "10"], "v_max (--v-max) must be a number"),
    (["--sim", "mujoco", "--a-max", "10"], "a_max (--a-max) must be at most 0.889"),
    (["--sim", "grid", "--sensor", "ideal"], "--sensor is a physical parameter: it needs --sim"),
    (["--sim", "mujoco", "--robot", "carry", "--base", "diffdrive"],
     "physics base diffdrive runs the navigate task only"),
    (["--sensor", "ideal"], "--sensor is a physical parameter: it needs --sim mujoco"),
    (["--sim", "mujoco", "--physics", "legacy", "--timing", "rate"], "--timing is a physical"),
    (["--sim", "mujoco", "--task", "carry", "--base", "diffdrive"], "diffdrive runs the navigate"),
])
def test_bad_physical_input_on_the_command_line(tmp_path, capsys, argv, msg):
    from tests.test_bad_input import refuse

    refuse(tmp_path, capsys, ["evaluate", "--db", "r.sqlite", "--instances", "1", "--runs",
                              "1", "--delta-t", "5", "--methods", "compliant", *argv], msg)


def test_physical_parameters_are_stored_with_every_row(tmp_path):
    from pathpref.apps.cli import main
    from pathpref.experiments.store import ResultStore, row_spec

    db = tmp_path / "r.sqlite"
    assert main(["evaluate", "--db", str(db), "--sim", "mujoco", "--instances", "1", "--runs",
                 "1", "--delta-t", "5", "--methods", "compliant", "--t-max", "6",
                 "--timing", "interval", "--sensor-noise-n", "1.5", "--base", "diffdrive",
                 "--gamma-h", "2", "--no-progress", "--workers", "1"]) == 0
    with ResultStore(db) as st:
        (row,) = st.episodes()
    ph = Physics.from_json(row["physics"])
    assert (ph.human.timing, ph.sensing.sensor_noise_n, ph.drive.kind, ph.human.gamma_h,
            ph.sensing.sensor) == \
        ("interval", 1.5, "diffdrive", 2.0, "realistic")
    assert run_episode(row_spec(row)).spec.key() == row["key"]


@pytest.mark.parametrize("kind", ["goal", "preference"])
def test_tempered_update_is_a_power_of_the_likelihood(simple, kind):
    """``update(c, h, w)`` multiplies by ``P(h)^w``: weight 2 is the same update twice,
    weight 0.5 twice is the plain update once."""
    from pathpref.inference.belief import GoalBelief, PreferenceBelief
    from pathpref.inference.human import ObservationModel

    model = ObservationModel.build(simple, np.array([simple.cell((2, 9)), simple.cell((9, 9)),
                                                     simple.cell((9, 2))]))
    make = (lambda: GoalBelief(model)) if kind == "goal" else (lambda: PreferenceBelief(model))
    cell = simple.cell((3, 3))
    a, b, c, d = make(), make(), make(), make()
    a.update(cell, 0, 2.0)
    b.update(cell, 0)
    b.update(cell, 0)
    c.update(cell, 0, 0.5)
    c.update(cell, 0, 0.5)
    d.update(cell, 0)
    assert np.allclose(a.goal_marginal(), b.goal_marginal())
    assert np.allclose(c.goal_marginal(), d.goal_marginal())
    assert not np.allclose(a.goal_marginal(), d.goal_marginal())


def test_corrective_human_reacts_to_wrong_moves_and_withholds_from_a_failing_robot():
    """``corrective``: a wrong move (heading 4 where 0 is the human's best) draws a push after
    the reaction time when the robot has seemed to work; after five wrong moves in a row the
    human has given up correcting (Wang et al. 2025: p_correct scaled by the share of right
    moves seen); a right move with p_needless 0 never draws one."""
    from types import SimpleNamespace

    from pathpref.sim.pushing_human import PushingHuman

    probs = np.array([0.6, 0.1, 0.05, 0.05, 0.05, 0.05, 0.05, 0.05])
    ph = Physics.of(timing="corrective", p_correct=1.0, p_needless=0.0, reaction_s=0.4)
    human = PushingHuman(ph.human, np.random.default_rng(0), 5, lambda c: 0, lambda c: probs)
    base = SimpleNamespace(data=SimpleNamespace(time=10.0), pre_substep=[], cell=0, pushes=[])
    human.attach(base)
    human.robot_moves(0, 0)  # right: nothing (p_needless 0)
    assert human.next_t is None
    human.robot_moves(0, 4)  # wrong, after one right move seen: certain correction
    assert human.next_t is not None and 10.05 <= human.next_t <= 11.0
    base.data.time = human.next_t
    human(base)  # the push begins, toward the human's heading at the base's cell
    assert len(base.pushes) == 1 and base.pushes[0].intended_heading == 0
    for _ in range(5):  # the robot keeps failing (corrections may still come meanwhile)
        human.robot_moves(0, 4)
        if human.next_t is not None:
            base.data.time = human.next_t
            human(base)
    human.robot_moves(0, 4)
    assert human.next_t is None  # the last five moves were wrong: no more corrections


@pytest.mark.parametrize("timing", ["interval", "rate"])
def test_push_timing_not_locked_to_decisions(timing):
    """The first push ``reaction_s`` after the start, then gaps of mean ``interval_s``:
    uniform within +-50 % (interval) or exponential (rate; its spread equals its mean)."""
    from types import SimpleNamespace

    from pathpref.sim.pushing_human import PushingHuman

    ph = Physics.of(timing=timing, interval_s=2.0, jitter=0.5, reaction_s=0.3)
    human = PushingHuman(ph.human, np.random.default_rng(1), 5, lambda c: 0)
    base = SimpleNamespace(data=SimpleNamespace(time=0.0), pre_substep=[], cell=0, pushes=[])
    human.attach(base)
    assert human.next_t == pytest.approx(0.3)
    starts = []
    for _ in range(3000):
        base.data.time = human.next_t
        human(base)
        starts.append(base.pushes[-1].t0)
    gaps = np.diff(starts)
    assert abs(gaps.mean() - 2.0) < 0.1
    if timing == "interval":
        assert gaps.min() >= 1.0 - 1e-9 and gaps.max() <= 3.0 + 1e-9
    else:
        assert abs(gaps.std() - 2.0) < 0.15 and gaps.min() < 0.1


def test_grid_gamma_h_from_the_command_line_is_stored_and_reported(tmp_path, capsys):
    """``--gamma-h`` on a grid sweep: stored with the row (the human's JSON), replayed with
    the same key, and reported as its own cell (never mixed with the default human)."""
    from pathpref.apps.cli import main
    from pathpref.experiments.store import ResultStore, row_spec

    db = tmp_path / "g.sqlite"
    common = ["evaluate", "--db", str(db), "--instances", "1", "--runs", "1", "--delta-t", "5",
              "--methods", "compliant", "--t-max", "6", "--no-progress", "--workers", "1"]
    assert main(common + ["--gamma-h", "0.5"]) == 0
    assert main(common) == 0
    with ResultStore(db) as st:
        rows = st.episodes()
    humans = sorted(HumanModel().to_json() if not r["physics"] else r["physics"] for r in rows)
    assert [json.loads(h)["gamma_h"] for h in humans] == [0.5, 1.5]
    for r in rows:
        assert run_episode(row_spec(r)).spec.key() == r["key"]
    capsys.readouterr()
    assert main(["report", str(db), "--csv", str(tmp_path / "g.csv")]) == 0
    out = capsys.readouterr().out
    assert "human model gamma_h=0.5" in out


def _pushed_east(guidance: bool) -> float:
    """How far a standing base goes east under a 20 N push held for 2 s (1.5 s after it)."""
    from pathpref.episode.cache import cached_world

    world = cached_world("simple")
    base = MobileBase(scene_for(world))
    if guidance:
        base.enable_guidance(20.0, 80.0)
    else:
        base.enable_pushes_any_time(80.0)
    base.reset(world.cell((2, 2)))
    x0 = float(base.position[0])
    base.pushes.append(HumanPush(0.0, float(base.data.time),
                                 PushProfile(peak_n=20.0, duration_s=2.0, noise_deg=0.0,
                                             shape="plateau"), 2))
    base.decision.hold(3.5, until_cue=False).run()
    return float(base.position[0]) - x0


def test_guidance_deforms_the_motion_and_keeps_it():
    """Guidance (Bajcsy-style): the admittance v = F / b = 20 / 80 = 0.25 m/s carries the
    base's target, so a 2 s push (0.2 s ramps: 1.8 s at full force) moves the base about
    0.25 m/s x 1.8 s = 0.45 m and it stays there; the tap protocol's yielding base springs
    back to where it stood (its admittance has a 400 N/m spring to its anchor)."""
    guided, tapped = _pushed_east(True), _pushed_east(False)
    assert 0.3 < guided < 0.6
    assert abs(tapped) < 0.05


def test_a_guided_base_is_not_pushed_into_a_wall():
    """Guidance moves the base's target only where the base fits: 40 N toward the east wall
    for 3 s from the cell beside it leaves the physical base (Physics() drive, stiff servos)
    off the wall: no contact begun."""
    from pathpref.episode.cache import cached_world
    from pathpref.sim.body import MujocoBody

    world = cached_world("simple")
    spec = EpisodeSpec.single("simple", "compliant", 5, sim="mujoco",
                              physics=Physics(timing="guidance", sensor="ideal"))
    base = MujocoBody(world, spec, np.random.default_rng(0)).base
    base.enable_guidance(20.0, 80.0)
    w = world.spec.width
    start = next(world.cell((w, y)) for y in range(1, world.spec.height + 1)
                 if world.arrangement.cell_index[w - 1, y - 1] >= 0)
    base.reset(start)
    base.pushes.append(HumanPush(0.0, float(base.data.time),
                                 PushProfile(peak_n=40.0, duration_s=3.0, noise_deg=0.0,
                                             shape="plateau"), 2))
    base.decision.hold(3.5, until_cue=False).run()
    m = base.physical_metrics()
    assert m["collisions"] == 0.0
    assert m["contact_impact_speed"] == 0.0
