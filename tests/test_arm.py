"""The arm-on-base variant: mink IK convergence, a level tray under pushes, detection through
the end-effector, no penetration, the carry task, IK failures recorded."""

from __future__ import annotations

import os
import unittest

os.environ.setdefault("MUJOCO_GL", "egl")

import mink  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from dm_env import test_utils  # noqa: E402
from pathpref_tasks import load  # noqa: E402

from pathpref.episode import EpisodeRunner, EpisodeSpec  # noqa: E402
from pathpref.episode.instances import seed_for  # noqa: E402
from pathpref.sim.arm import TRAY_OFFSET, ArmBase, build_arm_scene  # noqa: E402
from pathpref.sim.force_cue import HumanPush, PushProfile  # noqa: E402


@pytest.fixture(scope="module")
def arm(worlds):
    return ArmBase(build_arm_scene(worlds["simple"]))


def carry_spec(seed, **kw):
    d = dict(map="simple", method="path_preference", delta_t=3, instance=0, run=0,
             instance_seed=seed_for(seed, 0), run_seed=seed_for(seed, 0, 0), sim="mujoco",
             robot="carry", queries=1000)
    d.update(kw)
    return EpisodeSpec(**d)


def test_ik_converges_and_follows_the_base(worlds, arm):
    w = worlds["simple"]
    arm.reset(w.cell((2, 2)))
    arm.data.qpos[arm.arm_qpos] += 0.1  # start away from the solution (inside the limits)
    for _ in range(1500):  # 3 s; the joints' friction leaves a ~5 mm dead band
        arm.substep()
    base = arm.data.xpos[arm.model.body("base").id]
    assert np.linalg.norm(arm.data.xpos[arm.tray] - (base + TRAY_OFFSET)) < 0.01
    assert arm.move_to(w.cell((3, 3))) == w.cell((3, 3))
    base = arm.data.xpos[arm.model.body("base").id]
    assert np.linalg.norm(arm.data.xpos[arm.tray] - (base + TRAY_OFFSET)) < 0.02


def test_detection_through_the_arm_and_tilt(worlds, arm):
    w = worlds["simple"]
    rng = np.random.default_rng(4)
    arm.reset(w.cell((3, 3)))
    hits, n = 0, 60
    for _ in range(n):
        h = int(rng.integers(8))
        cue = arm.receive_push(HumanPush.sample(h, 0.0, PushProfile(), rng))
        hits += cue is not None and cue.heading == h
        arm.move_to(arm.cell)
    assert hits / n >= 0.9
    assert arm.tilt_rms() <= 3.0


def test_arm_yields_and_recovers(worlds, arm):
    """The legacy arm (soft servos, no impedance) under the default 30 N, 0.3 s push east,
    along its weak plane at the carrying posture (18.9 mm measured; north 7.9 mm, the weak
    plane of the earlier posture, where north gave 16.0 mm): it gives way by more than 10 mm
    and is back within 20 mm 2 s later."""
    w = worlds["simple"]
    arm.reset(w.cell((3, 3)))
    for _ in range(300):
        arm.substep()
    p0 = arm.data.xpos[arm.tray].copy()
    push = HumanPush(angle=0.0, t0=float(arm.data.time), profile=PushProfile(),
                     intended_heading=2)
    moved = 0.0
    for _ in range(200):
        arm.substep(push)
        moved = max(moved, np.linalg.norm(arm.data.xpos[arm.tray] - p0))
    for _ in range(1000):
        arm.substep()
    assert moved > 0.01  # compliant during the push
    assert np.linalg.norm(arm.data.xpos[arm.tray] - p0) < 0.02  # and back afterwards


@pytest.mark.parametrize("seed", [1, 2])
def test_carry_episode_level_and_no_penetration(seed):
    r = EpisodeRunner(carry_spec(seed))
    r.begin()
    while not r.done:
        r.step()
    m = r.result.metrics
    assert m["tilt_rms_deg"] <= 3.0 and m["max_penetration_mm"] <= 5.0
    assert r.result.inputs >= 1


def test_ik_failure_and_nan_are_recorded(monkeypatch):
    from pathpref.experiments.backends import safe_run

    def no_solution(*a, **k):
        raise mink.NoSolutionFound("daqp")

    monkeypatch.setattr(mink, "solve_ik", no_solution)
    res = safe_run(carry_spec(1))
    assert res.status == "failed" and "IK found no solution" in res.reason
    monkeypatch.setattr(mink, "solve_ik", lambda *a, **k: np.full(9, np.nan))
    res = safe_run(carry_spec(1))
    assert res.status == "failed" and "non-finite" in res.reason


class CarryConformance(test_utils.EnvironmentTestMixin, unittest.TestCase):
    def make_object_under_test(self):
        return load("carry", map="simple", method="goal_only", delta_t=3, seed=0, queries=200,
                    t_max=5)


def test_carry_observes_the_tray():
    env = load("carry", map="simple", method="compliant", delta_t=2, seed=1, t_max=4)
    ts = env.reset()
    assert ts.observation["tray_tilt"].shape == (1,) and ts.observation["tray_tilt"][0] < 5
    assert ts.observation["tray_position"][2] > 0.5


def test_compliant_tray_under_a_sustained_push():
    """The physical arm's tray impedance (``arm.TRAY_STIFFNESS`` 1000 N/m): a 30 N push on the
    tray for 3 s, north, east, south and west. Statically the tray gives way at most ``F / K``
    = 30 mm plus the base's own yield (2.5 mm, ``carry_yield_mm``); the joints' friction
    carries part of the push (24.6 mm measured, west), far inside the 60 mm target
    (the IK that restarted from the measured joints gave 565 mm), tilts less than 6 degrees
    (2.6 measured; 29 before) and is back within 10 mm in under 2 s (0.23 s measured; never
    within 4 s before)."""
    from pathpref.apps.benchmarks.physics import tray_push

    r = tray_push(30.0, 3.0)
    assert 10.0 < r["deviation_mm"] <= 30.0 + 3.0
    assert r["tilt_deg"] < 6.0 and r["recovery_s"] <= 2.0


def test_largest_human_push_on_the_tray():
    """The default human's largest push (60 N half-sine, 0.6 s): within the 60 mm target
    (``F / K`` = 60 mm at the peak, not reached in 0.6 s: 47.2 measured; 145 before), back
    within 10 mm in under 2 s (0.38 s measured)."""
    from pathpref.apps.benchmarks.physics import tray_push

    r = tray_push(60.0, 0.6, shape="half_sine")
    assert r["deviation_mm"] <= 60.0 and r["recovery_s"] <= 2.0 and r["tilt_deg"] < 10.0


def test_stiffness_is_a_parameter():
    """Halving the stiffness deepens the deflection under 30 N east (the arm's weak plane at
    its carrying posture), doubling it makes it shallower (37.6 / 24.2 / 15.4 mm at 500 /
    1000 / 2000 N/m), each within ``F / K`` plus the base's 2.5 mm yield; a stiffness that is
    not a positive number is refused with one line naming it."""
    from pathpref.apps.benchmarks.physics import tray_push
    from pathpref.errors import ConfigError

    soft = tray_push(30.0, 3.0, headings=(2,), stiffness=500.0)["deviation_mm"]
    stiff = tray_push(30.0, 3.0, headings=(2,), stiffness=2000.0)["deviation_mm"]
    assert stiff + 10.0 < soft <= 60.0 + 3.0 and stiff <= 15.0 + 3.0
    with pytest.raises(ConfigError, match="arm stiffness"):
        ArmBase(build_arm_scene_cached(), physical=True, stiffness=-1.0)


def build_arm_scene_cached():
    from pathpref.episode import cached_world
    from pathpref.sim.body import scene_for

    return scene_for(cached_world("simple"), 0.5, "carry")


def test_tray_collides_with_walls_and_base_not_with_its_arm():
    """MuJoCo's contact rule ``(contype_a & conaffinity_b) | (contype_b & conaffinity_a)``:
    the tray plate against every wall, obstacle and the base geom is nonzero, against every
    arm link zero."""
    m = build_arm_scene_cached().model
    plate = m.geom("tool/tray_plate").id

    def collide(a, b):
        return bool((m.geom_contype[a] & m.geom_conaffinity[b])
                    | (m.geom_contype[b] & m.geom_conaffinity[a]))

    names = [m.geom(i).name for i in range(m.ngeom)]
    walls = [i for i, n in enumerate(names) if n.startswith(("wall_", "obstacle_"))]
    links = [i for i in range(m.ngeom) if m.body(m.geom_bodyid[i]).name.startswith("jaco/")]
    assert walls and links
    assert all(collide(plate, g) for g in [*walls, m.geom("base_geom").id])
    assert not any(collide(plate, g) for g in links)


def test_carry_with_pushes_at_any_time_runs():
    """A physical carry episode whose human pushes on a clock of its own (``timing``
    ``interval``): the body's decision step asks the arm for a move of at least
    ``Physics.step_s`` (``move_to(cell, min_s=...)``, which the arm refused before); pushes
    are felt and the tray stays level."""
    from pathpref.episode import Physics, run_episode

    spec = EpisodeSpec.single("simple", "path_preference", 3, seed=13, instance=0,
                              sim="mujoco", robot="carry", t_max=4,
                              physics=Physics(timing="interval").to_json())
    res = run_episode(spec)
    assert res.inputs > 0 and res.metrics["tilt_max_deg"] < 10.0


def test_arm_stiffness_is_a_physical_parameter():
    """``arm_stiffness`` reaches the physical arm through the body; the default leaves the
    stored JSON (and so every key) as before."""
    import json

    import numpy as np

    from pathpref.episode import Physics
    from pathpref.episode.cache import cached_world
    from pathpref.sim.body import MujocoBody

    assert "arm_stiffness" not in json.loads(Physics().to_json())
    spec = carry_spec(0, physics=Physics(arm_stiffness=2500.0, sensor="ideal").to_json())
    body = MujocoBody(cached_world("simple"), spec, np.random.default_rng(0))
    assert body.base.stiffness == 2500.0


def test_tray_impedance_is_the_formula(worlds):
    """The compiled arm step (:func:`~pathpref.sim.arm_step.arm_step`, which the Python step
    and the compiled move both call: the Jacobian from MuJoCo, the impedance, the servo
    targets) against the module docstring's formula written with matrices and ``np.cross``,
    on a deflected, moving arm whose kinematic target is rotated and offset (every term
    nonzero): the torques within 1e-9 relative, the servo targets ``q + tau / kp``."""
    import mujoco

    from pathpref.sim import arm as arm_module
    from pathpref.sim.arm_step import arm_step

    arm = ArmBase(build_arm_scene_cached(), physical=True, stiffness=1300.0)
    m, d = arm.model, arm.data
    arm.reset(worlds["simple"].cell((3, 3)))
    rng = np.random.default_rng(3)
    d.qpos[arm.arm_qpos] += rng.uniform(-0.2, 0.2, 6)
    d.qpos[arm.base_qpos[2]] = 0.4  # a turned base: R_b is not the identity
    d.qvel[:] = rng.uniform(-0.5, 0.5, m.nv)
    mujoco.mj_forward(m, d)
    arm.q_kin = arm.q_kin + rng.uniform(-0.1, 0.1, 6)
    rel_R = mink.SO3.exp(np.array([0.05, -0.08, 0.1])).as_matrix()
    rel_p = np.array([0.07, -0.02, 0.71])
    arm._rel[:, :3], arm._rel[:, 3] = rel_R, rel_p

    base, tray = m.body("base").id, arm.tray
    Rb, R = d.xmat[base].reshape(3, 3), d.xmat[tray].reshape(3, 3)
    p_d, R_d = d.xpos[base] + Rb @ rel_p, Rb @ rel_R
    jacp, jacr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
    mujoco.mj_jacBody(m, d, jacp, jacr, tray)
    Jp, Jr = jacp[:, arm.arm_dofs], jacr[:, arm.arm_dofs]
    qd = d.qvel[arm.arm_dofs]
    e_r = 0.5 * sum(np.cross(R[:, i], R_d[:, i]) for i in range(3))
    a = arm_module
    f = 1300.0 * (p_d - d.xpos[tray]) - a.TRAY_DAMPING * (Jp @ qd)
    moment = a.TRAY_ROT_STIFFNESS * e_r - a.TRAY_ROT_DAMPING * (Jr @ qd)
    want = Jp.T @ f + Jr.T @ moment + a.POSTURE_STIFFNESS * (arm.q_kin - d.qpos[arm.arm_qpos])
    assert np.abs(want).min() > 1e-3
    arm_step(*arm.arm_args())
    np.testing.assert_allclose(arm._tau, want, rtol=1e-9, atol=1e-12)
    kp = m.actuator_gainprm[arm.arm_ctrl, 0]
    np.testing.assert_allclose(d.ctrl[arm.arm_ctrl], d.qpos[arm.arm_qpos] + want / kp,
                               rtol=1e-9, atol=1e-12)


def test_penetration_is_the_deepest_arm_obstacle_contact(worlds):
    """``max_penetration`` against a loop over MuJoCo's contacts: the base driven into a
    wall until the tray's plate presses into it; the deepest contact between an arm (or the
    base's) geom and an obstacle geom, 0 while there is none."""
    import mujoco

    arm = ArmBase(build_arm_scene_cached(), physical=True)
    m, d = arm.model, arm.data
    arm.reset(worlds["simple"].cell((3, 3)))
    x0 = float(d.qpos[arm.base_qpos[0]])
    assert arm.max_penetration() == 0.0
    arm_g, obs = set(arm.arm_geoms), set(arm.obstacle_geoms)

    def loop():
        worst = 0.0
        for c in d.contact[: d.ncon]:
            pair = {int(c.geom1), int(c.geom2)}
            if pair & arm_g and pair & obs:
                worst = max(worst, -float(c.dist))
        return worst

    seen = 0
    for x in np.linspace(x0, -0.3, 60):  # teleported west, through the outer wall
        d.qpos[arm.base_qpos[0]] = x
        mujoco.mj_forward(m, d)
        want = loop()
        seen += want > 0.0
        assert arm.max_penetration() == want
    assert seen > 0
