"""The arm-on-base variant: a Kinova Jaco (dm_control's offline assets) on the planar base,
carrying a tray (``mjcf/carry_tool.xml``), driven by whole-body differential IK with mink.

Model: ``mjcf/navigate.xml`` + the map (``scene.build_spec``) + ``jaco_arm.xml`` attached to a
site on the base + the tray attached to the arm's last link. The arm's bodies are gravity
compensated and its six joints have position servos (stiff enough to hold the tray, soft
enough to yield to a push and recover after it).

IK (mink, solver named explicitly: ``daqp``), every ``ik_period`` seconds (by default 10 ms
in legacy mode, 50 ms in physical mode: "IK rate" below), over all nine joints (base x, y,
yaw + arm)::

    tray task     FrameTask(tool/tray): a level pose at a fixed offset from the base
                  (``TRAY_OFFSET``), in the base's commanded heading (position cost 1,
                  orientation cost 5)
    base task     FrameTask(base): the planner's cell centre (cost 1, z ignored), yaw 0
                  (cost 10)
    posture       PostureTask: the arm's home posture ``ARM_HOME``, the carrying posture
                  within the disk's footprint (cost 1e-2)
    limits        ConfigurationLimit, VelocityLimit (base 0.8 m/s, 1 rad/s; shoulder and
                  elbow 2 rad/s, wrist 6 rad/s),
                  CollisionAvoidanceLimit (arm and base geoms vs obstacles and walls)

**Physical mode** (``physical=True``, episodes with physical parameters): the tray task is a
``RelativeFrameTask`` (the tray relative to the base), so moving the base never serves the tray
task. (The legacy task, a world-frame target re-anchored at the measured base every solve, drives
the base *against* a sustained tray push without end: the pushed tray is ahead of its target,
the IK moves the base back to pull it in, the target moves back with the base; 136 mm in 3 s at
30 N, ``carry_drift_legacy_mm``.) The base follows the base's own profiled controller
(:class:`.controller.ProfiledController`: speed and acceleration limits, braking margin, no
overshoot) instead of the IK's base velocity, yields by admittance while a cue is under way,
and the penetration is measured at every physics step.

**Compliant arm** (physical mode). As in mink's mobile examples (``examples/mobile_tidybot.py``:
``configuration.integrate_inplace(vel, dt)``, the actuators get ``configuration.q``), the IK
integrates a *kinematic* configuration ``q_kin`` (its base joints set to the measured base at
each solve; a ``DampingTask`` on them, cost 100, and no posture cost, so the IK moves the arm
only), and never restarts from the measured joints: a push cannot carry the target along. From
``q_kin`` comes the tray's desired pose relative to the base, ``T_rel``; at every physics step
the arm applies an impedance at the tray about ``T_d = T_base T_rel`` (measured base)::

    F   = K (p_d - p) - D v          (K = ``stiffness``, 1000 N/m; D 40 N s/m)
    M   = K_r e_r - D_r w            (e_r = 1/2 sum_i r_i x r_d,i; K_r 60 N m/rad; D_r 2)
    tau = J_p^T F + J_r^T M + k_0 (q_kin - q)      (arm joints; k_0 = 2 N m/rad)

with ``v``, ``w`` the tray's velocity due to the arm's joints (``J q_dot_arm``). The servos
realise ``tau`` with ``ctrl = q + tau / kp`` (servo force ``kp (ctrl - q) - kv q_dot = tau -
kv q_dot``: their ``kv`` stays as joint damping, integrated implicitly), within their 60 N m.
The static deflection under a push ``F`` is at most ``F / K`` plus the base's own yield
(30 + 2.5 mm at 30 N; the joints' friction carries part: 24.6 mm measured), back within
10 mm 0.23 s after release (``pathpref bench``'s ``arm.tray_*`` keys). **Sharing the push**:
the arm takes it through ``K``; the base holds its cell with its own controller (rigid in
the decision protocol) and, with pushes at any time, yields by its admittance
(``MobileBase``) while a cue is under way; under guidance the base's guidance admittance
(:mod:`.guidance`) follows the push the tray's sensor feels, so a person leads the whole robot
by its tray (25 N for 2 s: 0.62 m, as the plain base). The tray's plate collides with walls,
obstacles and the base (``contype`` 1, ``conaffinity`` 0: not with the arm that holds it).

**Compiled steps** (physical mode): between two IK solves the arm's step is one compiled
function (:func:`~.arm_step.arm_step`: the tray's Jacobian, the impedance, the servo
targets), which the Python step and the compiled move of :mod:`.coasting` both call, so a
carry episode's quiet steps run there as the plain base's do, the same numbers.

**IK rate** (physical mode: ``PHYSICAL_IK_PERIOD_S``, 50 ms, 20 Hz). Here the IK never meets a
push (the impedance does, at every physics step): it only keeps the kinematic tray at its
constant offset from the base and the arm clear of obstacles, so its solution is nearly still
(over two moves on ``simple``, the fastest joint's speed of median 4e-14 rad/s; 9e-4 rad/s at
the first solve, which settles the home posture). Between two solves the base moves at most
``v_max`` x 50 ms = 50 mm (1 m/s), under half the 0.12 m band in which the collision limit acts
(detection 0.15 m, kept 0.03 m). The tray's push figures, tilts, overshoot and penetration of
``pathpref bench``'s ``arm`` section are the same at 10 ms and 50 ms to four digits; each solve
costs about 20 physics steps of bare MuJoCo, so at 10 ms it was most of the carry episode's
cost.

**Legacy mode** (no physical parameters). The base velocity actuators receive the IK's base
velocities; the arm servos receive ``q + v dt`` from the measured ``q``, so the IK itself
corrects the tray's orientation when a push deflects the soft shoulder (solved at 100 Hz;
with 50 Hz and equal costs the tray tilted up to 15 degrees under a 30 N push, now about 5).
Pushes are applied to the tray; the robot senses them with the force sensor between the tray
and the arm (``tool/tool_force``), through the same detector as the handle.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import mink
import mujoco
import numpy as np

from ..episode.physics import CELL_SIZE_M, QUIET_DEFAULTS
from ..errors import EpisodeError
from ..geometry.world import World
from .arm_step import arm_step, tilt_from
from .mobile_base import MobileBase
from .native import addresses, entry_point
from .reach import posture_reach_m
from .scene import BaseParams, Scene, build_spec, check_footprint, mjcf_path
from .sensing import HandleSensor

#: the arm's home (carrying) posture: of the IK solutions holding the tray level at
#: TRAY_OFFSET, the one with the widest margin from the joint limits (0.49 rad) among those
#: whose plan reach below the obstacles stays within the disk's 0.15 m footprint at the
#: posture and within 0.1 rad of it on every joint (:func:`~.reach.carry_reach_m`: the
#: cylinder's 0.15 m; the arm's own 0.118 m), found by random restarts
#: (``scripts/carry_posture.py``)
ARM_HOME = np.array([0.4265, 3.6691, 5.4628, -0.8080, 2.2500, -1.2345])
#: tray position relative to the base body (m): over the base (0.1 m ahead of its centre, within
#: the cylinder's 0.15 m), 0.8 m up (0.9 m above the floor, above the obstacles' 0.6 m). At the
#: earlier (0.05, 0, 0.75) no posture kept the arm's lower links within the footprint (0.16 m
#: at best, 0.195 m within 0.1 rad); 0.1 m ahead does at the same height with 0.28 rad from the
#: joint limits, 0.05 m higher with 0.49 rad (``scripts/carry_posture.py``)
TRAY_OFFSET = np.array([0.10, 0.0, 0.80])
ARM_JOINTS = [f"jaco/joint_{k}" for k in range(1, 7)]
#: servo gains (kp, kv) per joint: a soft shoulder and elbow let the tray yield to a push, a
#: stiff wrist keeps it level while it does
ARM_GAINS = [(120.0, 10.0)] * 3 + [(250.0, 12.0)] * 3
#: the physical arm's end-effector impedance (module docstring, "Compliant arm"): translational
#: stiffness (N/m: 30 N deflects the tray 30 mm), rotational stiffness (N m/rad), and the
#: dampings (N s/m, N m s/rad) added to the servos' joint damping
TRAY_STIFFNESS = QUIET_DEFAULTS["arm_stiffness"]  # the Physics field arm_stiffness
TRAY_ROT_STIFFNESS = 60.0
TRAY_DAMPING = 40.0
TRAY_ROT_DAMPING = 2.0
#: the IK's period (s): legacy mode, where the IK itself levels a pushed tray, and physical
#: mode, where it only holds the tray's offset from the base (module docstring, "IK rate")
IK_PERIOD_S = 0.01
PHYSICAL_IK_PERIOD_S = 0.05
#: the weak joint spring toward the kinematic configuration (N m/rad) that keeps the arm's
#: posture where the tray's six constraints leave it free (near a singularity)
POSTURE_STIFFNESS = 2.0


@dataclass(frozen=True)
class ArmModel:
    """The arm an :class:`ArmBase` drives, by the names in its scene: its joints and position
    servos (the servos' ``kp`` are read from the model), the home posture (the IK solution
    holding the tray level at ``tray_offset`` from ``base_body``), the IK's joint speed limits
    (rad/s), the prefixes of the bodies whose geoms are the robot's in the collision limit
    (with ``base_geoms``), ``support_m`` the radius of the base's support against tipping
    (None: the ``base_geom`` cylinder's), and ``ik_period_s`` the physical mode's IK period
    (module docstring, "IK rate": the base moves at most 50 mm between two solves at its
    drive's speed)."""

    joints: tuple[str, ...]
    servos: tuple[str, ...]
    home: tuple[float, ...]
    tray_offset: tuple[float, float, float]
    speeds: tuple[float, ...]
    base_body: str
    prefixes: tuple[str, ...]
    base_geoms: tuple[str, ...] = ()
    support_m: float | None = None
    ik_period_s: float = PHYSICAL_IK_PERIOD_S


#: the Jaco on the disk base (module docstring)
JACO = ArmModel(joints=tuple(ARM_JOINTS),
                servos=tuple(f"servo_{j.split('/')[1]}" for j in ARM_JOINTS),
                home=tuple(ARM_HOME), tray_offset=tuple(TRAY_OFFSET),
                speeds=(2.0, 2.0, 2.0, 6.0, 6.0, 6.0), base_body="base",
                prefixes=("jaco/", "tool/"), base_geoms=("base_geom",))


def jaco_xml() -> Path:
    """Path of the Kinova Jaco MJCF that ships with dm_control (``third_party/kinova``)."""
    import dm_control

    path = Path(dm_control.__file__).parent / "third_party" / "kinova" / "jaco_arm.xml"
    if not path.exists():
        from ..errors import ConfigError

        raise ConfigError(f"dm_control's Kinova Jaco assets are missing ({path}); reinstall "
                          "dm-control==1.0.50")
    return path


def build_arm_scene(world: World, cell_size: float = CELL_SIZE_M, base: BaseParams | None = None,
                    arm: ArmModel = JACO) -> Scene:
    """Compile the arm-on-base scene of ``world`` (see module docstring); ``base`` a
    physical base. A ConfigError (:func:`~.scene.check_footprint`) when the carrying body
    reaches farther than the footprint the world's moves were made for: the plan reach of
    ``arm`` at its carrying posture and within 0.1 rad of it (:func:`~.reach.posture_reach_m`,
    as :func:`~.reach.carry_reach_m` measures it)."""
    spec = build_spec(world, cell_size, base)
    mount = spec.body("base").add_site(name="arm_mount", pos=[0.0, 0.0, 0.08])
    spec.attach(mujoco.MjSpec.from_file(str(jaco_xml())), prefix="jaco/", site=mount)
    flange = spec.body("jaco/b_6").add_site(name="flange", pos=[0.0, 0.0, 0.0])
    spec.attach(mujoco.MjSpec.from_file(str(mjcf_path("carry_tool.xml"))), prefix="tool/",
                site=flange)
    for b in spec.bodies:
        if b.name.startswith(("jaco/", "tool/")):
            b.gravcomp = 1.0
    for j, (kp, kv) in zip(ARM_JOINTS, ARM_GAINS, strict=True):
        a = spec.add_actuator(name=f"servo_{j.split('/')[1]}", target=j,
                              trntype=mujoco.mjtTrn.mjTRN_JOINT)
        a.set_to_position(kp=kp, kv=kv)
        a.forcerange = [-60.0, 60.0]
        a.forcelimited = 1
    model = spec.compile()
    reach = posture_reach_m(model, mujoco.MjData(model), arm, np.array(arm.home))
    check_footprint(world, cell_size, reach, "the Jaco carrying the tray on the disk",
                    fix="choose a carrying posture within it (scripts/carry_posture.py "
                    "finds them)")
    return Scene(world=world, model=model, cell_size=cell_size)


def tilt_deg(data: mujoco.MjData, body: int) -> float:
    """Angle between the tray's normal and the vertical (degrees): ``acos(R_zz)``, ``R`` the
    body's orientation (``xmat`` row-major, so ``R_zz`` is its last entry)."""
    return tilt_from(float(data.xmat[body, 8]))



class ArmBase(MobileBase):
    """A :class:`MobileBase` whose base and arm follow whole-body IK (module docstring)."""

    def __init__(self, scene: Scene, ik_period: float | None = None, physical: bool = False,
                 stiffness: float = TRAY_STIFFNESS, arm: ArmModel = JACO, **kwargs):
        super().__init__(scene, **kwargs)
        m = self.model
        self.physical = physical
        #: the arm (:class:`ArmModel`: the Jaco on the disk, or the TidyBot's Gen3)
        self.arm = arm
        self.home = np.array(arm.home)
        self.tray_offset = np.array(arm.tray_offset)
        if not (np.isfinite(stiffness) and stiffness > 0):
            from ..errors import ConfigError

            raise ConfigError(f"arm stiffness must be a positive number of N/m, got {stiffness}")
        #: the impedance's gains (K, D, K_r, D_r, k_0; :func:`~.arm_step.tray_impedance_into`)
        self._gains = np.array([float(stiffness), TRAY_DAMPING, TRAY_ROT_STIFFNESS,
                                TRAY_ROT_DAMPING, POSTURE_STIFFNESS])
        self.sensing.sensor = HandleSensor(m, sensor="tool/tool_force", site="tool/tool_site")
        self.tray = int(m.body("tool/tray").id)
        self.pushed_body = self.tray  # people push the tray
        self.arm_qpos = np.array([m.joint(j).qposadr[0] for j in arm.joints])
        self.arm_ctrl = np.array([m.actuator(a).id for a in arm.servos])
        if ik_period is None:
            ik_period = arm.ik_period_s if physical else IK_PERIOD_S
        self.ik_every = max(1, int(round(ik_period / self.dt)))
        self.ik_dt = self.ik_every * self.dt
        self.cfg = mink.Configuration(m)
        if physical:
            self.tray_task = mink.RelativeFrameTask("tool/tray", "body", arm.base_body, "body",
                                                    position_cost=1.0, orientation_cost=5.0)
            self.tray_task.set_target(mink.SE3.from_rotation_and_translation(
                mink.SO3.identity(), self.tray_offset))
        else:
            self.tray_task = mink.FrameTask("tool/tray", "body", position_cost=1.0,
                                            orientation_cost=5.0)
        self.base_task = mink.FrameTask(arm.base_body, "body", position_cost=[1.0, 1.0, 0.0],
                                        orientation_cost=[0.0, 0.0, 10.0])
        self.arm_dofs = np.array([m.joint(j).dofadr[0] for j in arm.joints])
        base_dofs = np.array([m.joint(j).dofadr[0] for j in ("slide_x", "slide_y", "yaw")])
        self.base_qpos = np.array([m.joint(j).qposadr[0] for j in ("slide_x", "slide_y",
                                                                   "yaw")])
        posture_cost = np.full(m.nv, 1e-2)
        if physical:
            posture_cost[base_dofs] = 0.0  # the posture never pulls on the base
            cost = np.zeros(m.nv)
            cost[base_dofs] = 100.0
            self.base_damping = mink.DampingTask(m, cost)
        self.posture = mink.PostureTask(m, cost=posture_cost)
        self._jac = np.zeros((6, m.nv))  # the tray's Jacobian: translation over rotation
        self._base_body = int(m.body(arm.base_body).id)
        self._bodies = np.array([self._base_body, self.tray])
        self._rel = np.hstack([np.eye(3), self.tray_offset[:, None]])  # [R_rel | p_rel]
        self.q_kin = self.home.copy()
        home = np.zeros(m.nq)
        home[self.arm_qpos] = self.home
        self.posture.set_target(home)
        arm_geoms = [i for i in range(m.ngeom)
                     if m.geom(i).name.startswith(arm.prefixes)
                     or m.body(m.geom_bodyid[i]).name.startswith(arm.prefixes)]
        arm_geoms = [g for g in arm_geoms if m.geom_contype[g] or m.geom_conaffinity[g]]
        # the base too: arm/base vs obstacles
        arm_geoms += [int(m.geom(g).id) for g in arm.base_geoms]
        self.obstacle_geoms = [i for i in range(m.ngeom) if m.geom(i).name.startswith(
            ("obstacle_", "wall_"))]
        self.arm_geoms = arm_geoms
        #: per geom: whether it is the arm's (or the base's) and whether an obstacle's
        self._is_arm = np.isin(np.arange(m.ngeom), arm_geoms)
        self._is_obstacle = np.isin(np.arange(m.ngeom), self.obstacle_geoms)
        vel = {"slide_x": [0.8], "slide_y": [0.8], "yaw": [1.0]}
        vel.update({j: [v] for j, v in zip(arm.joints, arm.speeds, strict=True)})
        self.limits = [
            mink.ConfigurationLimit(m),
            mink.VelocityLimit(m, vel),
            mink.CollisionAvoidanceLimit(m, geom_pairs=[(arm_geoms, self.obstacle_geoms)],
                                         minimum_distance_from_collisions=0.03,
                                         collision_detection_distance=0.15),
        ]
        self._kp = m.actuator_gainprm[self.arm_ctrl, 0].copy()  # the servos' kp
        #: :func:`arm_step`'s scratch (the rotation R_d, the force and moment) and torques
        self._Rd, self._f3, self._m3 = np.zeros((3, 3)), np.zeros(3), np.zeros(3)
        self._tau = np.zeros(len(arm.joints))
        self._arm_entry = None  # arm_step's compiled overload (entry_point, resolved once)
        #: the compiled move's tilt record (degrees per step, at most one IK period;
        #: :meth:`compiled_arm`)
        self._tilt_deg = np.zeros(self.ik_every)
        #: the kernel's (steps since the reset, IK period in steps, the step whose IK ran)
        self._ak = np.array([0, self.ik_every, -1], dtype=np.int64)
        self._ik_at = -1  # the step (self._k) whose IK solve ran
        self._k = 0
        self.tilts: list[float] = []
        self.ik_solves = 0
        self.deepest = 0.0  # deepest arm/obstacle penetration at the end of a move (m)

    @property
    def stiffness(self) -> float:
        """The tray's translational stiffness (N/m; physical mode, module docstring)."""
        return float(self._gains[0])

    @stiffness.setter
    def stiffness(self, value: float) -> None:
        self._gains[0] = float(value)

    def reset(self, cell: int) -> None:
        """Reset the physics with the base at ``cell``, the arm at home and the tray level."""
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[self.xy] = self.scene.cell_centre(cell)
        self.data.qpos[self.arm_qpos] = self.home
        self.data.ctrl[self.arm_ctrl] = self.home
        self.target = self.scene.cell_centre(cell)
        mujoco.mj_forward(self.model, self.data)
        self._reset_sensing()
        self._reset_control()
        self._k, self._ik_at = 0, -1
        self.tilts = []
        self.deepest = 0.0
        self.cfg.update(self.data.qpos.copy())  # the kinematic configuration starts at home
        self.q_kin = self.cfg.q[self.arm_qpos].copy()
        self._relative_target()

    def _relative_target(self) -> None:
        """The tray's pose relative to the base in the kinematic configuration (``T_rel``)."""
        T = self.cfg.get_transform("tool/tray", "body", self.arm.base_body, "body")
        self._rel[:, 3] = T.translation()
        self._rel[:, :3] = T.rotation().as_matrix()

    def tray_target(self) -> mink.SE3:
        """Level, at the arm's tray offset from the base's measured position, in the base's
        *commanded* heading (yaw 0). Using the measured yaw closes a loop: where the collision
        limit keeps the tray from its target, the IK turns the base, which turns the target."""
        base = self.data.xpos[self._base_body]
        return mink.SE3.from_rotation_and_translation(mink.SO3.identity(),
                                                      base + self.tray_offset)

    def solve_ik(self) -> np.ndarray:
        """One whole-body IK solve from the measured state; returns joint velocities."""
        d = self.data
        tasks = [self.tray_task, self.base_task, self.posture]
        if self.physical:  # the kinematic configuration, its base at the measured base
            q = self.cfg.q.copy()
            q[self.base_qpos] = d.qpos[self.base_qpos]
            self.cfg.update(q)
            tasks = [self.tray_task, self.posture, self.base_damping]
        else:
            self.cfg.update(d.qpos.copy())
            self.tray_task.set_target(self.tray_target())
        self.base_task.set_target(mink.SE3.from_rotation_and_translation(
            mink.SO3.identity(), np.array([self.target[0], self.target[1], 0.1])))
        try:
            v = mink.solve_ik(self.cfg, tasks, self.ik_dt, solver="daqp", damping=1e-3,
                              limits=self.limits)
        except mink.NoSolutionFound as e:
            raise EpisodeError(f"IK found no solution at t = {d.time:.2f} s: {e}") from None
        if not np.isfinite(v).all():
            raise EpisodeError(f"IK returned a non-finite velocity at t = {d.time:.2f} s")
        self.ik_solves += 1
        return v

    def _control(self) -> None:
        if self.physical:
            self._control_physical()
            return
        d = self.data
        if self._k % self.ik_every == 0:
            v = self.solve_ik()
            d.ctrl[self.actuators] = np.clip(v[:3], [-1, -1, -2], [1, 1, 2])
            d.ctrl[self.arm_ctrl] = d.qpos[self.arm_qpos] + v[3:9] * self.ik_dt
        self._k += 1
        self.tilts.append(tilt_deg(d, self.tray))

    def _control_physical(self) -> None:
        """Physical mode (module docstring, "Compliant arm"): the IK integrates the kinematic
        configuration every ``ik_period``; every physics step the impedance at the tray about
        the pose it gives, and the base's own command."""
        d = self.data
        self._ik_if_due()
        self._k += 1
        args = self.arm_args()
        if self._arm_entry is None:
            self._arm_entry = entry_point(arm_step, args)
        self._arm_entry(*args)
        self.tilts.append(tilt_deg(d, self.tray))
        super()._control()  # the base's command (under guidance it complies to the push)
        self.deepest = max(self.deepest, self.max_penetration())

    def arm_args(self) -> tuple:
        """:func:`arm_step`'s arguments now (the kinematic configuration's arm joints are a
        new array after each IK solve)."""
        d = self.data
        return (addresses(self.model, d), (d.xpos, d.xmat, d.qvel, d.qpos, d.ctrl),
                (self._bodies, self._rel, self._jac, self.arm_dofs, self.arm_qpos, self.q_kin,
                 self._gains, self._kp, self.arm_ctrl), (self._Rd, self._f3, self._m3, self._tau))

    #: the compiled move runs the physical arm's step (:func:`~.arm_step.arm_step` between
    #: IK solves: :mod:`.kernel_parts`)
    KERNEL_RUNS = True

    def kernel_setup(self) -> bool:
        """The physical arm's step is the kernel's; the legacy arm's (its IK drives the base
        at 100 Hz) is not."""
        return self.physical

    def kernel_ready(self) -> bool:
        """The compiled move may take the next step (:meth:`.coasting.Coaster.ready`): nothing
        in contact (whose penetration the Python step measures) and the base's own state
        (:meth:`MobileBase.kernel_ready`)."""
        return self.data.ncon == 0 and super().kernel_ready()

    def kernel_prepare(self) -> None:
        """Before the compiled move's steps: the IK solve of the coming step when one is due
        (:meth:`_ik_if_due`; each step hands back when the next one is due), then the base's
        (:meth:`MobileBase.kernel_prepare`)."""
        self._ik_if_due()
        super().kernel_prepare()

    def kernel_finish(self, steps: int) -> None:
        """After the compiled move's ``steps`` steps: the arm's step count (the kernel's,
        :meth:`compiled_arm`) and the tilts it recorded."""
        self._k = int(self._ak[0])
        self.record_tilts(self._tilt_deg[:steps])

    def _ik_if_due(self) -> None:
        """The IK solve of the coming step when one is due and has not run (every
        ``ik_period``: the kinematic configuration integrated, the tray's pose relative to
        the base in it), the first part of :meth:`_control_physical`."""
        if self._k % self.ik_every == 0 and self._ik_at != self._k:
            v = self.solve_ik()
            self.cfg.integrate_inplace(v, self.ik_dt)
            self.q_kin = self.cfg.q[self.arm_qpos].copy()
            self._relative_target()
            self._ik_at = self._k

    def compiled_arm(self) -> tuple:
        """The arm record of :func:`.coasting._coast`: :meth:`arm_args`, the tilt record of
        one IK period (the tray's tilt per step, :func:`~.arm_step.tilt_from`) and ``(steps
        since the reset, IK period in steps, the step whose IK ran)``, which the kernel
        advances."""
        self._ak[0], self._ak[2] = self._k, self._ik_at
        return self.arm_args(), self._tilt_deg, self._ak

    def record_tilts(self, tilts: np.ndarray) -> None:
        """The tilts (degrees) of steps the compiled move took."""
        self.tilts.extend(tilts.tolist())

    def move_to(self, cell: int, min_s: float = 0.0) -> int:
        """Drive to ``cell`` for at least ``min_s`` (:meth:`MobileBase.move_to`), then record
        the penetration."""
        reached = super().move_to(cell, min_s)
        if not self.physical:  # physical mode measures at every physics step
            self.deepest = max(self.deepest, self.max_penetration())
        return reached

    @property
    def end_effector(self) -> np.ndarray:
        """The tray's position (m)."""
        return self.data.xpos[self.tray].copy()

    def metrics(self) -> dict[str, float]:
        """Tray tilt (RMS and max over physics steps), deepest penetration, IK solves."""
        out = {"tilt_rms_deg": self.tilt_rms(),
               "tilt_max_deg": float(max(self.tilts, default=0.0)),
               "max_penetration_mm": 1e3 * self.deepest,
               "ik_solves": float(self.ik_solves)}
        if self.physical:
            tip = self.tip_force_n()
            out.update(tip_force_n=tip, tip_margin=tip / max(self.measurements.peak_force, 1e-9))
        return out

    def tip_force_n(self) -> float:
        """The horizontal push on the tray that would tip the robot over the edge of its base
        (N): the moments about the base's rim, ``F h = M g r`` with ``M`` the robot's mass,
        ``r`` the base's radius (its support polygon, the centre of mass over the base's
        centre; the arm's ``support_m``) and ``h`` the tray's height above the floor. The
        model's slide joints cannot tip, so this is the check."""
        m = self.model
        mass = float(m.body_subtreemass[m.body_rootid[self._base_body]])
        r = float(m.geom("base_geom").size[0]) if self.arm.support_m is None else \
            self.arm.support_m
        h = float(self.data.xpos[self.tray][2])
        return mass * 9.81 * r / h

    def tilt_rms(self) -> float:
        """RMS tray tilt over the physics steps since reset (degrees)."""
        return float(np.sqrt(np.mean(np.square(self.tilts)))) if self.tilts else 0.0

    def max_penetration(self) -> float:
        """Deepest current contact between arm/tray geoms and obstacles (m, >= 0): the largest
        ``-dist`` of the contacts with an arm geom and an obstacle geom among their two."""
        d = self.data
        if d.ncon == 0:
            return 0.0
        g = d.contact.geom
        a, o = self._is_arm[g], self._is_obstacle[g]
        hit = (a[:, 0] | a[:, 1]) & (o[:, 0] | o[:, 1])
        return max(0.0, float(-d.contact.dist[hit].min())) if hit.any() else 0.0
