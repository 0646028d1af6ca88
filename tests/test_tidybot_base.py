"""The Stanford TidyBot as the ``navigate`` body (``robot_model = tidybot``,
:mod:`pathpref.sim.tidybot_base`): its scene, its figures read back from the model, its
physics defaults, episodes end to end through every door, and the compiled steps equal to the
Python steps on it."""

from __future__ import annotations

import json
import os

os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

import pathpref.sim  # noqa: E402,F401 - registers the MuJoCo body
from pathpref.episode import EpisodeSpec, Physics  # noqa: E402
from pathpref.episode.physics import ROBOT_MODELS  # noqa: E402
from pathpref.episode.runner import EpisodeRunner  # noqa: E402
from pathpref.errors import ConfigError  # noqa: E402
from pathpref.geometry.world import load_world  # noqa: E402
from pathpref.sim import native, tidybot_base  # noqa: E402
from pathpref.sim.body import MujocoBody, base_params, scene_for  # noqa: E402

TIDY = {"robot_model": "tidybot"}


@pytest.fixture(scope="module")
def world():
    return load_world("simple")


@pytest.fixture(scope="module")
def scene(world):
    p = Physics.of(**TIDY)
    return scene_for(world, p.cell_size_m, "navigate", base_params(p), "tidybot")


def test_the_physics_takes_the_tidybots_own_drive_and_scale():
    """``robot_model`` tidybot: 1 m per cell, TidyBot++'s 0.5 m/s and 0.5 m/s^2, Menagerie's
    mass; a flag given wins; the disk's JSON (and so every stored key) is unchanged; a
    TidyBot's JSON names every field and reads back equal."""
    p = Physics.of(**TIDY)
    d = p.drive
    assert (p.cell_size_m, d.v_max, d.a_max, d.mass_kg) == (1.0, 0.5, 0.5, 69.29)
    assert Physics.of(robot_model="tidybot", v_max=0.3).drive.v_max == 0.3
    assert "robot_model" not in Physics().to_json()
    assert Physics.of(robot_model="disk").to_json() == Physics().to_json()
    raw = json.loads(p.to_json())
    assert raw["robot_model"] == "tidybot" and raw["mass_kg"] == 69.29
    assert Physics.from_json(p.to_json()) == p
    # the one step rule at the body's scale: d = sqrt(2) m, d / v + v / a + 0.5 + 1.0 = 5.33
    assert p.step_s() == pytest.approx(5.4)
    assert Physics().step_s() == pytest.approx(3.4)  # the disk's, as before
    with pytest.raises(ConfigError, match="robot_model"):
        Physics.of(robot_model="pr2")


def test_the_scene_carries_menageries_robot(scene):
    """The model's figures read back: the mass the physics states (Menagerie's), the plan
    radius the servo is sized with, the handle's force sensor, the velocity servos the base
    code drives, Menagerie's contact options, and the arm at ``retract`` after a reset with no
    contact."""
    m = scene.model
    root = m.body("tidybot/base_link").id
    assert m.body_subtreemass[root] == pytest.approx(ROBOT_MODELS["tidybot"].drive["mass_kg"],
                                                     abs=0.01)
    assert tidybot_base.navigation_mass_kg() == pytest.approx(69.29, abs=0.01)
    r = tidybot_base.navigation_radius_m(m)
    assert r == pytest.approx(tidybot_base.TIDYBOT_RADIUS_M, abs=1e-3)
    assert r <= 0.3 * scene.cell_size  # fits the maps' 0.3-cell footprint at 1 m per cell
    assert m.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC and m.opt.impratio == 10.0
    for a in ("vx", "vy", "wz"):
        assert m.actuator(a).biastype == mujoco.mjtBias.mjBIAS_AFFINE  # velocity servos
    assert m.actuator("vx").gainprm[0] == pytest.approx(69.29 / 0.045, rel=1e-3)
    # the yaw servo's 20 ms on the robot's own yaw inertia at rest: the joint-space inertia's
    # yaw entry of the compiled scene (1.98 kg m^2: the base link's mesh 1.90, the arm 0.08)
    d0 = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d0, m.key("rest").id)
    mujoco.mj_forward(m, d0)
    full = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d0, full)
    spin = full[m.joint("yaw").dofadr[0], m.joint("yaw").dofadr[0]]
    assert spin == pytest.approx(1.98, abs=0.01)
    assert m.actuator("wz").gainprm[0] == pytest.approx(spin / 0.02, rel=1e-3)
    assert m.sensor("handle_force").objid == m.site("handle_site").id
    body = MujocoBody(load_world("simple"), EpisodeSpec.single(
        "simple", "path_preference", 5, seed=0, sim="mujoco",
        physics=Physics.of(**TIDY).to_json()), np.random.default_rng(0))
    body.reset(3)
    d = body.base.data
    arm = [d.qpos[m.joint(f"tidybot/joint_{k}").qposadr[0]] for k in range(1, 8)]
    assert arm == pytest.approx(tidybot_base.RETRACT)
    assert np.allclose(body.base.position, body.scene.cell_centre(3))
    for _ in range(500):
        mujoco.mj_step(m, d)
    assert d.ncon == 0
    assert np.allclose(arm, [d.qpos[m.joint(f"tidybot/joint_{k}").qposadr[0]]
                             for k in range(1, 8)], atol=2e-3)  # the servos hold it


def test_a_push_on_the_handle_is_what_the_sensor_reads(scene):
    """A steady 30 N push east on the handle of the standing robot: the handle's sensor (in the
    world frame) feels 30 N east within 1 N, and the base yields east (its velocity servo gives
    way at ``F / kv``, 19 mm/s, less what the tracking controller takes back)."""
    body = MujocoBody(load_world("simple"), EpisodeSpec.single(
        "simple", "path_preference", 5, seed=0, sim="mujoco",
        physics=Physics.of(sensor="ideal", **TIDY).to_json()), np.random.default_rng(0))
    body.reset(3)
    b = body.base
    x0 = b.position.copy()
    b.data.xfrc_applied[b.pushed_body, :3] = (30.0, 0.0, 0.0)
    b.external_forces = True
    for _ in range(250):
        b.substep(None)
    f = b.sensing.sensor.force_xy(b.data)
    assert f == pytest.approx((30.0, 0.0), abs=1.0)
    assert b.position[0] - x0[0] > 0.002 and abs(b.position[1] - x0[1]) < 1e-3


def test_the_mass_flag_sets_the_robots_mass(world):
    """``--mass-kg`` on the TidyBot is the whole robot's mass (a payload on its base)."""
    p = Physics.of(mass_kg=100.0, **TIDY)
    m = scene_for(world, 1.0, "navigate", base_params(p), "tidybot").model
    assert m.body_subtreemass[m.body("tidybot/base_link").id] == pytest.approx(100.0)
    # the base link's mesh inertia scales with its mass: 1.903 (100 - 9.29) / 60 + 0.080
    assert m.actuator("wz").gainprm[0] * 0.02 == pytest.approx(
        1.903 * (100.0 - 9.29) / 60.0 + 0.080, abs=0.01)


def test_what_the_tidybot_cannot_be_is_one_line(world):
    """The differential drive is refused, naming the fix; an unknown body names the known."""
    with pytest.raises(ConfigError, match="holonomic"):
        scene_for(world, 1.0, "navigate", base_params(Physics.of(base="diffdrive", **TIDY)),
                  "tidybot")
    with pytest.raises(ConfigError, match="disk, tidybot"):
        scene_for(world, 1.0, "navigate", None, "pr2")


def _carry_body(timing: str = "decision", instance: int = 0, map_name: str = "simple"):
    spec = EpisodeSpec.single(map_name, "path_preference", 5, seed=3, instance=instance,
                              sim="mujoco", t_max=20, robot="carry",
                              physics=Physics.of(timing=timing, **TIDY).to_json())
    return EpisodeRunner(spec)


def test_the_carrying_posture_holds_the_tray_level_where_it_says():
    """``carry`` on the TidyBot: after a reset the Gen3 stands at ``CARRY_HOME``, the tray
    level (within 0.01 degrees) at ``CARRY_TRAY_OFFSET`` from the base link (within 1 mm),
    above the maps' 0.6 m obstacles, every arm joint 0.4 rad or more inside its limits, and
    nothing touching; the servos are Menagerie's (``kp`` 2000 / 500)."""
    runner = _carry_body()
    runner.body.reset(runner.instance.start)
    b = runner.body.base
    m, d = b.model, b.data
    assert b.arm is tidybot_base.TIDYBOT_ARM
    assert d.qpos[b.arm_qpos] == pytest.approx(tidybot_base.CARRY_HOME)
    rel = d.xpos[b.tray] - d.xpos[m.body("tidybot/base_link").id]
    assert rel == pytest.approx(tidybot_base.CARRY_TRAY_OFFSET, abs=1e-3)
    assert np.degrees(np.arccos(min(1.0, d.xmat[b.tray][8]))) < 0.01
    assert d.xpos[b.tray][2] > 0.6
    for j in b.arm.joints:
        jid = m.joint(j).id
        if m.jnt_limited[jid]:
            q = d.qpos[m.jnt_qposadr[jid]]
            assert min(q - m.jnt_range[jid, 0], m.jnt_range[jid, 1] - q) > 0.4
    assert list(b._kp) == [2000.0] * 4 + [500.0] * 3
    mujoco.mj_forward(m, d)
    assert d.ncon == 0


@pytest.mark.parametrize("timing", ["interval", "guidance"])
def test_tidybot_carry_episodes_keep_the_tray(timing):
    """Carry episodes on the TidyBot with pushes on the tray at any time and under guidance:
    pushes felt through the tray's sensor, the tray within 5 degrees of level, no arm or tray
    in an obstacle, no collision, the IK at 10 Hz."""
    runner = _carry_body(timing, instance=1, map_name="office")
    while not runner.done:
        runner.step()
    met = runner.result.metrics
    assert met["pushes"] >= 1 and met["pushes_missed"] == 0
    assert met["tilt_max_deg"] < 5.0
    assert met["max_penetration_mm"] == 0.0 and met["collisions"] == 0
    assert met["ik_solves"] == pytest.approx(met["sim_time_s"] * 10, rel=0.02)


@pytest.mark.parametrize("timing", ["decision", "interval", "guidance"])
def test_tidybot_episodes_run_without_contact(timing):
    """Episodes on the TidyBot under each human: every decision's cell is the one the base
    stands in, pushes were felt, nothing touched the map."""
    spec = EpisodeSpec.single("office", "path_preference", 5, seed=3, instance=1,
                              sim="mujoco", t_max=20,
                              physics=Physics.of(timing=timing, **TIDY).to_json())
    runner = EpisodeRunner(spec)
    while not runner.done:
        runner.step()
    res = runner.result
    assert runner.body.scene.cell_size == 1.0
    assert res.metrics["collisions"] == 0 and res.metrics["pushes"] >= 1
    last = res.log[-1]
    assert runner.body.base.cell == runner.world.cell((last.x, last.y))


@pytest.mark.skipif(not native.ready(), reason="no compiled path")
def test_the_compiled_steps_drive_the_tidybot_the_same(monkeypatch):
    """Compiled steps on and off on the TidyBot: the same final state and decisions."""
    def run():
        spec = EpisodeSpec.single("simple", "path_preference", 5, seed=11, instance=0,
                                  sim="mujoco", t_max=8,
                                  physics=Physics.of(timing="interval", **TIDY).to_json())
        runner = EpisodeRunner(spec)
        while not runner.done:
            runner.step()
        d = runner.body.base.data
        return (d.time, d.qpos.tobytes(), d.qvel.tobytes(),
                [(s.t, s.x, s.y, s.action) for s in runner.result.log])

    out = []
    for flag in ("0", "1"):
        monkeypatch.setenv("PATHPREF_COMPILED_STEPS", flag)
        out.append(run())
    assert out[0] == out[1]


def test_the_dm_control_task_runs_the_tidybot():
    """``load("navigate", physics={"robot_model": "tidybot"})``: its step is the TidyBot's
    step rule, its positions in metres at 1 m per cell, and a stay keeps the base in its
    cell."""
    from pathpref_tasks import load

    env = load("navigate", map="simple", seed=0, physics=TIDY)
    assert env.control_timestep() == pytest.approx(5.4)
    ts = env.reset()
    cell = np.asarray(ts.observation["cell"])
    assert np.allclose(ts.observation["position"], cell - 0.5, atol=0.05)  # metres, 1 m cells
    ts = env.step(8)  # the task's stay action
    assert np.allclose(ts.observation["cell"], cell)


def test_the_tray_keys_measure_the_episode_body():
    """``tidybot.tray_*`` are measured on the body ``--robot carry --robot-model tidybot``
    runs: a steady 30 N push north for 3 s deflects the tray at least ``F / K`` = 30 mm (the
    arm's tray impedance, 1000 N/m; the stand-alone whole-body model gives 9.7) and at most
    that plus 8 mm (the base's velocity servo yields about 5 mm and its yaw 0.02 rad, which
    the controller takes back); back within 10 mm in under 1 s, within 1 mm no sooner."""
    from pathpref.apps.benchmarks.physics import tray_push

    r = tray_push(30.0, 3.0, headings=(0,), after_s=1.5, robot_model="tidybot")
    assert 30.0 <= r["deviation_mm"] <= 38.0
    assert r["recovery_s"] <= 1.0 and r["recovery_1mm_s"] >= r["recovery_s"]
