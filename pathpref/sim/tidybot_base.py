"""The Stanford TidyBot as the ``navigate`` body (``--robot-model tidybot``): Menagerie's robot
(``mjcf/stanford_tidybot/``, :mod:`.tidybot`) in place of ``navigate.xml``'s 12 kg cylinder, so
the same base, controller, sensing chain and compiled steps drive it.

**The model** (:func:`navigation_spec`): ``navigate.xml`` (floor, light, cameras, materials,
the ``contact_count`` sensor) with its cylinder removed and the TidyBot attached under the
prefix ``tidybot/``. What the base's code addresses by name is renamed to ``navigate.xml``'s
names: the planar joints ``joint_x``, ``joint_y``, ``joint_th`` become ``slide_x``,
``slide_y``, ``yaw``; Menagerie's stiff base position servos (``kp`` 1e6) are replaced by the
velocity servos ``vx``, ``vy``, ``wz`` the project's controller commands (the base must yield
to a push; a position servo of 1e6 N/m would not). Added: a push handle (a 0.2 kg post,
``handle``, at the base's rear, its top at 0.935 m, a cart handle's height) with the force
sensor ``handle_force`` at ``handle_site`` where the hand is, as on the cylinder.

* **mass**: Menagerie's (the 60 kg base, the Gen3 arm and gripper, the handle; 69.29 kg,
  :func:`navigation_mass_kg`); the drive's ``mass_kg`` sets the mass of the base link's
  ``body`` mesh (the one base geom with mass, Menagerie's ``mass="60"``) so the whole robot
  weighs it, its inertia scaled with it (its default is Menagerie's,
  :data:`~pathpref.episode.physics.ROBOT_MODELS`);
* **drive**: ``vx``, ``vy`` velocity servos of gain ``mass / DRIVE_TAU_S`` (the same 45 ms
  time constant as the Ridgeback's drive, ``BaseParams.kv``), force limited to the drive's
  ``force_limit_n``; ``wz`` a 20 ms yaw servo for the robot's own yaw inertia at ``rest``,
  read from the model (:func:`navigation_yaw_inertia`, 1.98 kg m^2 at Menagerie's mass: the
  base link's 1.90 from its mesh, as Menagerie's pull request #281 derives it, and 0.08 of the
  retracted arm, gripper and handle; with the placeholder 0.001 kg m^2 the file had before,
  the whole robot had 0.08 kg m^2, so the servo was then sized on a solid cylinder of the
  robot's mass and plan radius, 2.79 kg m^2);
* **arm**: held at Menagerie's ``retract`` posture by its own position servos (the posture
  TidyBot++'s simulator resets the arm to), gravity compensated as the Gen3's controller does;
  the model's keyframe ``rest`` holds it, and a base's reset starts there
  (:meth:`~.mobile_base.MobileBase.reset`);
* **footprint**: the largest horizontal distance from the base's centre to a vertex of any of
  the robot's collision meshes at ``rest`` (:func:`navigation_radius_m`, 0.284 m: the
  bumper's corner), which fits the maps' 0.3-cell footprint at 1 m per cell;
* the options of Menagerie's file (elliptic friction cones, ``impratio`` 10).
"""

from __future__ import annotations

from functools import lru_cache

import mujoco
import numpy as np

from ..episode.physics import ROBOT_MODELS, check_body_drive
from ..errors import ConfigError
from .arm import ArmModel
from .reach import plan_reach_m
from .scene import BaseParams, RobotBody, floor_friction, holonomic_servos, mjcf_path, yaw_servo
from .tidybot import ARM_JOINTS, ARM_SPEED, BASE_JOINTS, below, tidybot_xml

PREFIX = "tidybot/"
#: the planar joints' names in ``navigate.xml`` (what :class:`~.mobile_base.MobileBase` reads)
NAV_JOINTS = ("slide_x", "slide_y", "yaw")
#: the arm's posture while the base navigates: Menagerie's ``retract`` keyframe (joints 1-7)
RETRACT = (0.0, -0.34906585, 3.14159265, -2.54818071, 0.0, -0.87266463, 1.57079633)
#: the drive servos' time constant (s): the Ridgeback drive's (``BaseParams.kv`` 3000 N s/m on
#: 135 kg)
DRIVE_TAU_S = 0.045
#: the push handle: a post at the base's rear (m, in the base's frame) and its length
HANDLE_POS = (-0.2, 0.0, 0.335)
HANDLE_LENGTH = 0.6
HANDLE_MASS = 0.2


def _robot_spec() -> mujoco.MjSpec:
    """Menagerie's TidyBot as the navigate body: joints renamed, base servos removed, the handle
    added, the arm gravity compensated (module docstring)."""
    tb = mujoco.MjSpec.from_file(str(tidybot_xml()))
    for old, new in zip(BASE_JOINTS, NAV_JOINTS, strict=True):
        tb.delete(tb.actuator(old))
        tb.joint(old).name = new
    for key in list(tb.keys):  # its keyframes name the removed servos' controls
        tb.delete(key)
    base = tb.body("base_link")
    handle = base.add_body(name="handle", pos=list(HANDLE_POS))
    handle.add_geom(name="handle_geom", type=mujoco.mjtGeom.mjGEOM_CAPSULE,
                    fromto=[0.0, 0.0, 0.0, 0.0, 0.0, HANDLE_LENGTH], size=[0.02, 0.0, 0.0],
                    mass=HANDLE_MASS, contype=0, conaffinity=0, rgba=[0.95, 0.6, 0.1, 1.0])
    handle.add_site(name="handle_site", pos=[0.0, 0.0, HANDLE_LENGTH], size=[0.02, 0.0, 0.0],
                    rgba=[1.0, 0.3, 0.1, 1.0])
    arm = tb.body("gen3/base_link")
    for b in tb.bodies:
        if below(b, arm):
            b.gravcomp = 1.0
    return tb


@lru_cache(maxsize=1)
def _masses() -> tuple[float, float]:
    """The whole robot's mass in Menagerie's model and its mass beyond the base link (arm,
    gripper, handle), kg, read from the compiled model."""
    m = _robot_spec().compile()
    base = m.body("base_link").id
    return float(m.body_subtreemass[base]), float(m.body_subtreemass[base] - m.body_mass[base])


def base_mass_geom(body: mujoco.MjsBody) -> mujoco.MjsGeom:
    """The base link's one geom with mass (Menagerie's ``body`` mesh, ``mass="60"``; the other
    base geoms have ``mass="0"`` from their class, pull request #281); a ConfigError of one line
    when the file has not exactly one."""
    heavy = [g for g in body.geoms if g.mass > 0.0]
    if len(heavy) != 1:
        raise ConfigError(f"the TidyBot's base_link in {tidybot_xml()} must have exactly one "
                          f"geom with mass (Menagerie's body mesh), has {len(heavy)}; "
                          "reinstall pathpref")
    return heavy[0]


@lru_cache(maxsize=1)
def _yaw_inertias() -> tuple[float, float, float]:
    """The yaw inertia (kg m^2) about the base's centre at ``rest`` (the arm at
    :data:`RETRACT`) of the base link and of everything else (arm, gripper, handle), and the
    base link's mass (kg), in Menagerie's model: the base link's share is its inertia rotated
    to the world, ``(R I R^T)_zz``, plus ``m (x_c^2 + y_c^2)`` for its centre of mass; the
    rest is the joint-space inertia ``M[yaw, yaw]`` less that."""
    m = _robot_spec().compile()
    d = mujoco.MjData(m)
    for j, q in zip(ARM_JOINTS, RETRACT, strict=True):
        d.qpos[m.joint(j).qposadr[0]] = q
    mujoco.mj_forward(m, d)
    full = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, full)
    yaw = m.joint(NAV_JOINTS[2]).dofadr[0]
    b = m.body("base_link").id
    r = d.ximat[b].reshape(3, 3)
    own = float((r @ np.diag(m.body_inertia[b]) @ r.T)[2, 2]
                + m.body_mass[b] * np.sum((d.xipos[b, :2] - d.xpos[b, :2]) ** 2))
    return own, float(full[yaw, yaw]) - own, float(m.body_mass[b])


def navigation_yaw_inertia(mass_kg: float | None = None) -> float:
    """The whole robot's yaw inertia about the base's centre at ``rest`` (kg m^2) when it weighs
    ``mass_kg`` (None: Menagerie's): the base link's share scales with its mass (the drive's
    ``mass_kg`` sets it, :func:`navigation_spec`), the arm's, gripper's and handle's do not."""
    own, others, base_kg = _yaw_inertias()
    if mass_kg is None:
        return own + others
    return own * (mass_kg - _masses()[1]) / base_kg + others


def navigation_mass_kg() -> float:
    """The whole robot's mass in Menagerie's model (kg)."""
    return _masses()[0]


def navigation_spec(base: BaseParams | None) -> mujoco.MjSpec:
    """``navigate.xml`` with the TidyBot for its base (module docstring); ``base`` sets the
    mass, the drive's force limit and the floor's friction (None: Menagerie's mass and the
    drive's defaults)."""
    if base is None:
        base = BaseParams(mass_kg=navigation_mass_kg())
    check_body_drive("tidybot", base.kind)
    try:
        spec = mujoco.MjSpec.from_file(str(mjcf_path("navigate.xml")))
    except ValueError as e:
        raise ConfigError(f"mjcf/navigate.xml does not load: {e}") from None
    for a in list(spec.actuators):
        spec.delete(a)
    spec.delete(spec.sensor("handle_force"))
    spec.delete(spec.body("base_xy"))
    tb = _robot_spec()
    spec.option.cone, spec.option.impratio = tb.option.cone, tb.option.impratio
    spec.attach(tb, prefix=PREFIX, frame=spec.worldbody.add_frame())
    for name in NAV_JOINTS:
        spec.joint(PREFIX + name).name = name
    spec.body(PREFIX + "handle").name = "handle"
    spec.site(PREFIX + "handle_site").name = "handle_site"
    spec.add_sensor(name="handle_force", type=mujoco.mjtSensor.mjSENS_FORCE,
                    objtype=mujoco.mjtObj.mjOBJ_SITE, objname="handle_site")
    mass, others = base.mass_kg, _masses()[1]
    if mass <= others:
        raise ConfigError(f"the TidyBot's mass_kg must exceed its arm's and handle's "
                          f"{others:.2f} kg, got {mass:g}")
    base_mass_geom(spec.body(PREFIX + "base_link")).mass = mass - others
    floor_friction(spec, base.friction_n)
    for name, joint in zip(("vx", "vy", "wz"), NAV_JOINTS, strict=True):  # navigate.xml's
        spec.add_actuator(name=name, target=joint, trntype=mujoco.mjtTrn.mjTRN_JOINT)
    spec.actuator("wz").ctrlrange = [-2.0, 2.0]
    holonomic_servos(spec, mass / DRIVE_TAU_S, base.force_limit_n)
    yaw_servo(spec, navigation_yaw_inertia(mass))  # the model's own, at ``rest``
    return spec


def add_rest(spec: mujoco.MjSpec, model: mujoco.MjModel) -> None:
    """The keyframe ``rest``: the base at the origin, the arm at :data:`RETRACT` with its
    servos' controls there (``model`` the spec compiled once, for the addresses)."""
    qpos = model.qpos0.copy()
    ctrl = np.zeros(model.nu)
    for j, q in zip(ARM_JOINTS, RETRACT, strict=True):
        qpos[model.joint(PREFIX + j).qposadr[0]] = q
        ctrl[model.actuator(PREFIX + j).id] = q
    spec.add_key(name="rest", qpos=qpos.tolist(), ctrl=ctrl.tolist())


def navigation_radius_m(model: mujoco.MjModel) -> float:
    """The plan radius (m): the largest horizontal distance from the base's centre to a vertex
    of the robot's collision meshes (and the handle's capsule), at the ``rest`` keyframe."""
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("rest").id)
    mujoco.mj_forward(model, data)
    root = model.body(PREFIX + "base_link").id
    centre = data.xpos[root, :2]
    far = 0.0
    for g in range(model.ngeom):
        b = int(model.geom_bodyid[g])
        if model.body_rootid[b] != root:
            continue
        if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH:
            if not (model.geom_contype[g] or model.geom_conaffinity[g]):
                continue
            mid = model.geom_dataid[g]
            v = model.mesh_vert[model.mesh_vertadr[mid]:model.mesh_vertadr[mid]
                                + model.mesh_vertnum[mid]]
            w = v @ data.geom_xmat[g].reshape(3, 3).T + data.geom_xpos[g]
            far = max(far, float(np.hypot(*(w[:, :2] - centre).T).max()))
        elif b == model.body("handle").id:
            far = max(far, float(np.hypot(*(data.geom_xpos[g, :2] - centre)))
                      + float(model.geom_size[g, 0]))
    return far


#: the plan radius the yaw servo is sized with (m; the TidyBot's footprint in its record,
#: :data:`~pathpref.episode.physics.ROBOT_MODELS`; :func:`navigation_radius_m` of the model,
#: checked by the tests)
TIDYBOT_RADIUS_M = ROBOT_MODELS["tidybot"].footprint_m

#: the TidyBot as a scene's robot (:func:`~.scene.build_scene`)
TIDYBOT = RobotBody(name="tidybot", spec=navigation_spec, radius_m=navigation_radius_m,
                    finish=add_rest)


def carry_spec(base: BaseParams | None) -> mujoco.MjSpec:
    """:func:`navigation_spec` with the project's tray (``mjcf/carry_tool.xml``, prefix
    ``tool/``) at the gripper's ``pinch_site``, gravity compensated, its plate's contacts with
    the gripper excluded (as :func:`.tidybot.build_tidybot`: else the fingers through the plate
    carry part of a push past the tray's sensor)."""
    spec = navigation_spec(base)
    spec.attach(mujoco.MjSpec.from_file(str(mjcf_path("carry_tool.xml"))), prefix="tool/",
                site=spec.site(PREFIX + "pinch_site"))
    hand = spec.body(PREFIX + "bracelet_link")
    for b in spec.bodies:
        if b.name.startswith("tool/"):
            b.gravcomp = 1.0
        elif below(b, hand):
            spec.add_exclude(bodyname1=b.name, bodyname2="tool/tray")
    return spec


#: the tray's place in ``carry`` (m, relative to the base link): 0.2 m ahead of the base's
#: centre, 0.8 m above the floor (above the maps' 0.6 m obstacles and walls)
CARRY_TRAY_OFFSET = (0.2, 0.0, 0.8)
#: the Gen3's carrying posture (joints 1-7, rad): from ``retract``, the IK solution (the base
#: held) holding the tray level at :data:`CARRY_TRAY_OFFSET`; 0.50 rad from every joint limit,
#: no contact (``retract`` itself folds the gripper onto the shoulder, where the tray's plate
#: would touch the arm); checked against the model by the tests
CARRY_HOME = (0.4782, -0.2878, 2.8365, -1.8291, -0.0854, -1.5876, 0.1835)
#: the base's support radius against tipping (m): the body's half-width, 0.23 m, an upper
#: bound on where its casters stand (the casters' positions are not in the model)
SUPPORT_M = 0.23

#: the TidyBot's Gen3 as :class:`~.arm.ArmBase` drives it in ``carry``: Menagerie's servos
#: (``kp`` 2000 / 500 N m/rad), the Gen3's joint speed limits in the IK, the IK at 10 Hz (the
#: base at its 0.5 m/s moves 50 mm between two solves, as the Jaco's at 1 m/s and 20 Hz)
TIDYBOT_ARM = ArmModel(joints=tuple(PREFIX + j for j in ARM_JOINTS),
                       servos=tuple(PREFIX + j for j in ARM_JOINTS), home=CARRY_HOME,
                       tray_offset=CARRY_TRAY_OFFSET, speeds=ARM_SPEED,
                       base_body=PREFIX + "base_link", prefixes=(PREFIX, "tool/"),
                       support_m=SUPPORT_M, ik_period_s=0.1)

def carry_radius_m(model: mujoco.MjModel) -> float:
    """The carrying TidyBot's plan radius (m): the larger of :func:`navigation_radius_m` (the
    robot at ``rest``, every height) and its plan reach below the obstacles' height with the
    arm at its carrying posture :data:`CARRY_HOME` (:func:`~.reach.plan_reach_m`: the Gen3
    and the tray's plate there stay within the bumper, so it is the bumper's 0.284 m)."""
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("rest").id)
    for j, q in zip(ARM_JOINTS, CARRY_HOME, strict=True):
        data.qpos[model.joint(PREFIX + j).qposadr[0]] = q
    mujoco.mj_forward(model, data)
    return max(navigation_radius_m(model),
               plan_reach_m(model, data, model.body(PREFIX + "base_link").id))


#: the TidyBot carrying the tray, as a scene's robot (:func:`~.scene.build_scene`): its
#: footprint is the carrying body's (:func:`carry_radius_m`)
TIDYBOT_CARRY = RobotBody(name="tidybot", spec=carry_spec, radius_m=carry_radius_m,
                          finish=add_rest)
