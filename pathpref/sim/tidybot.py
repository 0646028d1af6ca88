"""The Stanford TidyBot from MuJoCo Menagerie (``mjcf/stanford_tidybot/``, vendored with its
LICENSE and source commit): a holonomic base (planar joints ``joint_x``, ``joint_y``,
``joint_th``) with a Kinova Gen3 arm and a Robotiq 2F-85 gripper, here carrying the project's
tray (``mjcf/carry_tool.xml``) at the gripper's ``pinch_site``, driven by whole-body IK with
mink the way mink's ``examples/mobile_tidybot.py`` does it.

**The model** (:func:`build_tidybot`): Menagerie's ``tidybot.xml`` unmodified, plus a floor,
a light and the tray (its force sensor ``tool/tool_force`` between the tray and the gripper
measures a push; contacts between the plate and the gripper's bodies are excluded, else the
fingers through the plate carry part of the push past the sensor: 22.8 N of 25 N felt). The
arm, gripper and tray are gravity compensated (``gravcomp`` 1, as the Gen3's own controller
compensates gravity), so the servos hold no static load. Its figures,
all read from the model (:func:`physical_figures`): the base's mass 60 kg (Menagerie's
``base_link``, its inertia from its body mesh as Menagerie derives it since its
pull request #281), the whole robot 69.29 kg with the tray; the base's position servos
``kp`` 1e6 N/m, ``kv`` 5e4 N s/m (yaw 5e4 N m/rad, 1e3), the arm's ``kp`` 2000/500 N m/rad
(joints 1-4 / 5-7) within 105/52 N m; the physics step 2 ms (``option timestep`` default).
The base's footprint is a 0.482 m square bumper (0.284 m from the centre to its farthest point,
:func:`footprint_radius_m`): wider than the maps' footprint (0.15 m radius at 0.5 m per cell),
so a world must be built with its own :class:`~pathpref.geometry.footprint.Footprint`
(:func:`footprint`) and :func:`~.scene.check_footprint` refuses the default one.

**Whole-body IK** (:class:`WholeBody`), as in mink's example: one ``mink.Configuration`` over
all joints, base and arm; tasks ``FrameTask(tool/tray)`` (position cost 1, orientation cost 1,
``lm_damping`` 1) and ``PostureTask`` (cost 1e-3 on the arm's joints, 0 on the base's: the
base moves freely, the arm is drawn to its carrying posture); limits ``ConfigurationLimit`` and
``VelocityLimit`` (base 0.5 m/s and 1 rad/s, not sourced; arm joints 1-4 1.3963 rad/s, 5-7
1.2218 rad/s, the Gen3's joint speed limits); ``solve_ik`` (``daqp``) then
``configuration.integrate_inplace(v, dt)`` every physics step, the position servos given
``configuration.q``. Because the posture holds the arm and nothing holds the base, the base
takes a share of every end-effector motion (:func:`base_share`). A push on the tray meets the
arm's joint-space impedance (the servos' ``kp``, ``kv``) and the base's stiff position servos;
the IK integrates its own configuration, so a push never moves the target. Under guidance
(:meth:`WholeBody.enable_guidance`) the base's admittance follows the force the tray's sensor
feels, as the project's guided bases do (:func:`guided_push`).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import mink
import mujoco
import numpy as np

from ..errors import ConfigError
from ..geometry.footprint import Footprint
from .scene import MJCF_DIR, mjcf_path
from .sensing import HandleSensor

#: the vendored model's folder and file
TIDYBOT_DIR = MJCF_DIR / "stanford_tidybot"
TIDYBOT_XML = "tidybot.xml"
BASE_JOINTS = ("joint_x", "joint_y", "joint_th")
ARM_JOINTS = tuple(f"joint_{k}" for k in range(1, 8))
#: the Gen3's joint speed limits (rad/s): 1.3963 (joints 1-4) and 1.2218 (joints 5-7), the
#: ``max_velocity`` of a Kinova Gen3 MoveIt ``joint_limits`` configuration (80 and 70 deg/s)
ARM_SPEED = (1.3963,) * 4 + (1.2218,) * 3
#: the base's speed limit in the IK (m/s, m/s, rad/s): not in the model and not sourced (a
#: walking pace for x, y; chosen, not measured)
BASE_SPEED = (0.5, 0.5, 1.0)
#: the bound on the kinematic IK solves that bring the tray level (:meth:`WholeBody.reset`)
RESET_ITERS = 2000
#: the clearance the base keeps (m), as the maps' default footprint
CLEARANCE_M = 0.05


def tidybot_xml() -> Path:
    """The vendored ``tidybot.xml``; a ConfigError of one line naming the first missing file
    (the XML, or a mesh it names under its ``meshdir``)."""
    path = TIDYBOT_DIR / TIDYBOT_XML
    if not path.exists():
        raise ConfigError(f"TidyBot model file {path} is missing; reinstall pathpref (its "
                          "wheel ships mjcf/stanford_tidybot/)")
    root = ET.parse(path).getroot()
    meshdir = path.parent / (root.find("compiler").get("meshdir", "") or "")
    for mesh in (m for a in root.iter("asset") for m in a.iter("mesh")):
        f = meshdir / mesh.get("file", "")
        if not f.is_file():
            raise ConfigError(f"TidyBot mesh {f} is missing; reinstall pathpref (its wheel "
                              "ships mjcf/stanford_tidybot/assets/)")
    return path


def build_tidybot() -> mujoco.MjModel:
    """Compile the TidyBot on a floor with the tray at ``pinch_site`` (module docstring); a
    failed load is a ConfigError of one line naming the file."""
    path = tidybot_xml()
    try:
        spec = mujoco.MjSpec.from_file(str(path))
        wb = spec.worldbody
        wb.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0.0, 0.0, 0.05],
                    rgba=[0.55, 0.55, 0.52, 1.0])
        wb.add_light(pos=[0.0, 0.0, 3.0], dir=[0.0, 0.0, -1.0],
                     type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL)
        spec.attach(mujoco.MjSpec.from_file(str(mjcf_path("carry_tool.xml"))),
                    prefix="tool/", site=spec.site("pinch_site"))
        arm, hand = spec.body("gen3/base_link"), spec.body("bracelet_link")
        for b in spec.bodies:
            if below(b, arm):
                b.gravcomp = 1.0
            if below(b, hand) and not b.name.startswith("tool/"):
                # the gripper holds the plate: no contact between them, so the whole push
                # passes the tray's force sensor
                spec.add_exclude(bodyname1=b.name, bodyname2="tool/tray")
        return spec.compile()
    except ValueError as e:
        msg = str(e).replace("\n", " ")
        raise ConfigError(f"TidyBot model {path} failed to load: {msg}") from None


def below(body, top) -> bool:
    """Whether ``body`` is ``top`` or in its subtree (bounded by the tree's depth)."""
    b = body
    for _ in range(64):
        if b.name == top.name:
            return True
        parent = b.parent
        if parent is None or parent.name == b.name or parent.name == "world":
            return False
        b = parent
    return False


def robot_model(model: mujoco.MjModel) -> str:
    """The compiled model's name (``tidybot`` for Menagerie's file): MuJoCo stores it first in
    the model's names buffer."""
    return model.names.split(b"\x00", 1)[0].decode()


def footprint_radius_m(model: mujoco.MjModel) -> float:
    """The base's plan radius (m): the largest horizontal distance from the base's centre to a
    vertex of its collision meshes, at the model's rest pose."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    base = model.body("base_link").id
    far = 0.0
    for g in range(model.ngeom):
        if model.geom_bodyid[g] != base or model.geom_type[g] != mujoco.mjtGeom.mjGEOM_MESH \
                or not (model.geom_contype[g] or model.geom_conaffinity[g]):
            continue
        mid = model.geom_dataid[g]
        v = model.mesh_vert[model.mesh_vertadr[mid]:model.mesh_vertadr[mid]
                            + model.mesh_vertnum[mid]]
        w = v @ data.geom_xmat[g].reshape(3, 3).T + data.geom_xpos[g] - data.xpos[base]
        far = max(far, float(np.hypot(w[:, 0], w[:, 1]).max()))
    return far


def footprint(model: mujoco.MjModel, cell_size: float) -> Footprint:
    """The TidyBot's footprint in map units at ``cell_size`` m per cell: its plan radius and
    the maps' clearance (``CLEARANCE_M``)."""
    return Footprint(radius=footprint_radius_m(model) / cell_size,
                     clearance=CLEARANCE_M / cell_size)


def physical_figures(model: mujoco.MjModel) -> dict[str, float]:
    """The figures the module docstring names, read from the compiled model."""
    base = model.body("base_link").id
    act = {model.actuator(i).name: i for i in range(model.nu)}
    return {"base_mass_kg": float(model.body_mass[base]),
            "robot_mass_kg": float(model.body_subtreemass[base]),
            "base_kp": float(model.actuator_gainprm[act["joint_x"], 0]),
            "base_kv": float(-model.actuator_biasprm[act["joint_x"], 2]),
            "arm_kp_large": float(model.actuator_gainprm[act["joint_1"], 0]),
            "arm_kp_small": float(model.actuator_gainprm[act["joint_7"], 0]),
            "timestep_s": float(model.opt.timestep),
            "footprint_radius_m": footprint_radius_m(model)}


class WholeBody:
    """The TidyBot's whole-body IK and physics on one model (module docstring)."""

    def __init__(self, model: mujoco.MjModel, frame: str = "tool/tray"):
        self.model = m = model
        self.data = mujoco.MjData(m)
        self.frame = frame
        self.dt = float(m.opt.timestep)
        self.cfg = mink.Configuration(m)
        self.task = mink.FrameTask(frame, "body", position_cost=1.0, orientation_cost=1.0,
                                   lm_damping=1.0)
        names = (*BASE_JOINTS, *ARM_JOINTS)
        self.dofs = np.array([m.joint(j).dofadr[0] for j in names])
        self.qadr = np.array([m.joint(j).qposadr[0] for j in names])
        self.act = np.array([m.actuator(j).id for j in names])
        cost = np.zeros(m.nv)
        cost[self.dofs[3:]] = 1e-3
        self.posture = mink.PostureTask(m, cost=cost)
        speeds = dict(zip(names, (*BASE_SPEED, *ARM_SPEED), strict=True))
        self.limits = [mink.ConfigurationLimit(m),
                       mink.VelocityLimit(m, {j: [s] for j, s in speeds.items()})]
        self.body = m.body(frame).id
        self.base = m.body("base_link").id
        self._carry_q: np.ndarray | None = None  # the carrying posture (:meth:`reset`)
        self.sensor = HandleSensor(m, sensor="tool/tool_force", site="tool/tool_site")
        #: the base's guidance admittance ``(M, b)`` (:meth:`enable_guidance`; None: off)
        self.admittance: tuple[float, float] | None = None
        self.v_adm = np.zeros(2)

    def enable_guidance(self, mass: float, damping: float) -> None:
        """The base complies to the push the tray's sensor feels, as the project's guided
        bases (:mod:`.guidance`): ``M dv/dt + b v = F`` (``F`` the horizontal force at
        ``tool/tool_site``, world frame) and the deformation ``dp/dt = v`` is added to the
        base's joints in the IK's configuration and to the tray's target, so the whole robot
        follows the push while the arm's servos take its force."""
        self.admittance = (float(mass), float(damping))

    def reset(self) -> None:
        """The carrying posture: from Menagerie's ``home`` keyframe, the arm alone (the base
        held by a ``DampingTask``, cost 100) brings the tray level (its normal vertical) where
        ``home`` holds it, IK iterated kinematically to 1e-6 m and rad (at most
        ``RESET_ITERS`` solves); the robot stands there, the posture task's target is that
        configuration and the tray's target that pose."""
        m, d = self.model, self.data
        mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
        mujoco.mj_forward(m, d)
        if self._carry_q is None:
            self.cfg.update(d.qpos.copy())
            here = self.cfg.get_transform_frame_to_world(self.frame, "body")
            self.task.set_target(mink.SE3.from_rotation_and_translation(
                mink.SO3.identity(), here.translation()))
            cost = np.zeros(m.nv)
            cost[self.dofs[:3]] = 100.0
            hold = mink.DampingTask(m, cost)
            for _ in range(RESET_ITERS):
                v = mink.solve_ik(self.cfg, [self.task, hold], 0.01, solver="daqp",
                                  damping=1e-3, limits=[mink.ConfigurationLimit(m)])
                self.cfg.integrate_inplace(v, 0.01)
                if np.linalg.norm(self.task.compute_error(self.cfg)) < 1e-6:
                    break
            self._carry_q = self.cfg.q.copy()
        self.v_adm[:] = 0.0
        d.qpos[:] = self._carry_q
        d.ctrl[self.act] = self._carry_q[self.qadr]
        mujoco.mj_forward(m, d)
        self.cfg.update(d.qpos.copy())
        self.posture.set_target_from_configuration(self.cfg)
        self.task.set_target(self.cfg.get_transform_frame_to_world(self.frame, "body"))

    def aim(self, offset: np.ndarray) -> None:
        """Move the tray's target by ``offset`` (m, world) from where the target is."""
        T = self.task.transform_target_to_world
        self.task.set_target(mink.SE3.from_rotation_and_translation(
            T.rotation(), T.translation() + np.asarray(offset, float)))

    def step(self) -> None:
        """One physics step: the guidance admittance when on (:meth:`enable_guidance`), one IK
        solve integrated over ``dt``, the servos given the configuration, ``mj_step``."""
        if self.admittance is not None:
            self._admit()
        v = mink.solve_ik(self.cfg, [self.task, self.posture], self.dt, solver="daqp",
                          damping=1e-3, limits=self.limits)
        self.cfg.integrate_inplace(v, self.dt)
        self.data.ctrl[self.act] = self.cfg.q[self.qadr]
        mujoco.mj_step(self.model, self.data)

    def _admit(self) -> None:
        """One explicit Euler step of the admittance and of the deformation it makes."""
        mass, damping = self.admittance
        f = self.sensor.force_xy(self.data)
        self.v_adm += self.dt * (f - damping * self.v_adm) / mass
        step = self.dt * self.v_adm
        q = self.cfg.q.copy()
        q[self.qadr[:2]] += step
        self.cfg.update(q)
        self.aim(np.array([step[0], step[1], 0.0]))

    @property
    def tray(self) -> np.ndarray:
        """The carried frame's position (m)."""
        return self.data.xpos[self.body].copy()

    @property
    def base_xy(self) -> np.ndarray:
        """The base's planar position (m)."""
        return self.data.xpos[self.base][:2].copy()


def base_share(wb: WholeBody, reach_m: float = 0.3, seconds: float = 3.0) -> dict[str, float]:
    """The share of a ``reach_m`` end-effector target (straight ahead, +x) reached by base
    motion: from ``home``, the tray's target moves ``reach_m`` along ``x``; after ``seconds``
    of IK and physics, ``share = (base displacement . x) / reach_m``; also the tray's remaining
    distance from its target (m)."""
    wb.reset()
    settle = int(round(0.5 / wb.dt))
    for _ in range(settle):
        wb.step()
    b0 = wb.base_xy
    wb.aim(np.array([reach_m, 0.0, 0.0]))
    for _ in range(int(round(seconds / wb.dt))):
        wb.step()
    target = np.asarray(wb.task.transform_target_to_world.translation(), float)
    return {"share": float((wb.base_xy - b0)[0] / reach_m),
            "error_m": float(np.linalg.norm(wb.tray - target))}


def tray_push(wb: WholeBody, force_n: float = 30.0, seconds: float = 3.0,
              after_s: float = 2.0, headings: tuple[float, ...] = (0.0, 90.0, 180.0, 270.0)
              ) -> dict[str, float]:
    """A steady horizontal push of ``force_n`` on the standing robot's tray for ``seconds``
    toward each of ``headings`` (degrees): the tray's largest distance from where it stood
    (mm), and the time from the release until it is back within 10 mm (``recovery_s``) and
    within 1 mm (``recovery_1mm_s``) for good (s; ``after_s`` when it never is); the worst
    heading each. This is the stand-alone whole-body model (base servos ``kp`` 1e6), not the
    episode body (``pathpref.apps.benchmarks.physics.tray_push`` measures that)."""
    dev, rec, rec1 = [], [], []
    for h in headings:
        wb.reset()
        for _ in range(int(round(0.5 / wb.dt))):
            wb.step()
        p0, t0 = wb.tray, float(wb.data.time)
        f = force_n * np.array([np.cos(np.radians(h)), np.sin(np.radians(h)), 0.0])
        worst, back = 0.0, {0.010: None, 0.001: None}
        for _ in range(int(round((seconds + after_s) / wb.dt))):
            pushing = float(wb.data.time) < t0 + seconds
            wb.data.xfrc_applied[wb.body, :3] = f if pushing else 0.0
            wb.step()
            e = float(np.linalg.norm(wb.tray - p0))
            worst = max(worst, e)
            if not pushing:
                for r in back:
                    if e > r:
                        back[r] = None
                    elif back[r] is None:
                        back[r] = float(wb.data.time) - t0 - seconds
        wb.data.xfrc_applied[wb.body] = 0.0
        dev.append(1e3 * worst)
        rec.append(after_s if back[0.010] is None else back[0.010])
        rec1.append(after_s if back[0.001] is None else back[0.001])
    return {"deviation_mm": max(dev), "recovery_s": max(rec), "recovery_1mm_s": max(rec1)}


def guided_push(wb: WholeBody, mass: float, damping: float, force_n: float = 25.0,
                seconds: float = 2.0, after_s: float = 1.0) -> float:
    """Guidance on the TidyBot (:meth:`WholeBody.enable_guidance` with ``mass``, ``damping``):
    a steady ``force_n`` push on the tray toward +x for ``seconds``; the base's largest
    displacement (m) until ``after_s`` past the release. Guidance stays on afterwards."""
    wb.enable_guidance(mass, damping)
    wb.reset()
    for _ in range(int(round(0.5 / wb.dt))):
        wb.step()
    b0, t0 = wb.base_xy, float(wb.data.time)
    worst = 0.0
    for _ in range(int(round((seconds + after_s) / wb.dt))):
        pushing = float(wb.data.time) < t0 + seconds
        wb.data.xfrc_applied[wb.body, :3] = (force_n, 0.0, 0.0) if pushing else 0.0
        wb.step()
        worst = max(worst, float(np.linalg.norm(wb.base_xy - b0)))
    wb.data.xfrc_applied[wb.body] = 0.0
    return worst
