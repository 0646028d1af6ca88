"""The physical robot: a planar base in a MuJoCo scene, driven cell to cell, pushed by a human.

The decision step's phases (push, move, hold) are the one machine of :mod:`.decision`;
:meth:`MobileBase.receive_push`, :meth:`MobileBase.move_to` and :meth:`MobileBase.hold` run one
phase to completion on it (the blocking callers), the dm_control tasks advance the same
machine from their Environment's physics steps. A base's physics step is :meth:`substep`:
controller, the pushes acting, ``mj_step``, sensing, cue detection, measurements and the
``on_substep`` hooks (renderers, loggers; ``pre_substep`` hooks run before it: the simulated
human of :mod:`.pushing_human` starts its pushes there).

**One cue stream** (:mod:`.cue_stream`): every cue the detector gives, in any phase, becomes
one :class:`~pathpref.episode.body.Felt` record, appended to :attr:`MobileBase.felt` and handed
to the base's one listener (:attr:`MobileBase.listener`: the episode runner's door, connected
by the body).

**Pushes at any time** (:meth:`MobileBase.enable_pushes_any_time`): pushes in :attr:`pushes`
act whenever their time comes (driving, braking or standing), the detector splits two pushes
into two cues (:mod:`.cue_detector`), the base yields while a cue is under way (the
admittance of :mod:`.admittance`), and a cue ends a move or a hold (:attr:`stop_on_cue`) so that
the planner replans from the new belief instead of finishing the move.

**Guidance** (:meth:`MobileBase.enable_guidance`; :mod:`.guidance`): pushes act at any time
and deform the base's motion; the belief is updated while a push lasts.

The base is three parts: the base itself (its joints, controller, decision step, pushes and
cue stream: this module), its sensing chain (:class:`~.sensing_chain.SensingChain`: sensor,
faults, estimator, detector; :attr:`MobileBase.sensing`) and its measurements
(:class:`~.measurements.Measurements`, on when :attr:`MobileBase.measure`).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import mujoco
import numpy as np

from ..episode.body import Felt
from ..errors import EpisodeError
from .admittance import yield_velocity
from .coasting import CONTACT_SENSOR, Coaster
from .coasting import enabled as compiled_steps_enabled
from .controller import ProfiledController, TrackingController
from .cue_detector import Cue
from .cue_stream import track_cue
from .decision import DecisionStep
from .estimator import EstimatorConfig
from .force_cue import HumanPush, PushProfile, apply_force
from .guidance import Guidance
from .keep_clear import keep_clear, keep_clear_xy
from .measurements import Measurements
from .scene import Scene
from .sensing import SensorModel
from .sensing_chain import SensingChain


class MobileBase:
    """The base in ``scene``: its joints (``slide_x``, ``slide_y``, ``yaw``) and velocity
    actuators (``vx``, ``vy``, ``wz``) addressed by name; the pushed body is the ``handle``.

    ``sensor_model`` (default: the ideal raw sensor) with ``rng`` (required when the model has
    faults), ``estimator`` and ``detector`` settings make its sensing chain
    (:class:`~.sensing_chain.SensingChain`)."""

    #: the base's actuators, in the order of :meth:`_base_command`'s result
    ACTUATORS = ("vx", "vy", "wz")

    def __init__(self, scene: Scene, controller: TrackingController | None = None,
                 profile: PushProfile | None = None, data: mujoco.MjData | None = None,
                 sensor_model: SensorModel | None = None,
                 rng: np.random.Generator | None = None,
                 estimator: EstimatorConfig | None = None, detector: dict | None = None):
        self.scene = scene
        self.model = scene.model
        self.data = data if data is not None else mujoco.MjData(self.model)
        self.controller = controller or TrackingController()
        self.profile = profile or PushProfile()
        m = self.model
        self.xy = np.array([m.joint(j).qposadr[0] for j in ("slide_x", "slide_y")])
        self.yaw = int(m.joint("yaw").qposadr[0])
        self.vxy = np.array([m.joint(j).dofadr[0] for j in ("slide_x", "slide_y")])
        self._vxy_adr = (int(self.vxy[0]), int(self.vxy[1]))
        self.actuators = np.array([m.actuator(a).id for a in self.ACTUATORS])
        #: the planar drive's force limit (N; the first actuator's range)
        self.force_limit = float(m.actuator_forcerange[self.actuators[0], 1])
        self._zero_q, self._zero_v = np.zeros(m.nq), np.zeros(m.nv)
        self._rest = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_KEY, "rest")
        #: the compiled steps may run for this base (:mod:`.coasting`: on, read from
        #: ``PATHPREF_COMPILED_STEPS`` when the base is built, and the scene has the
        #: contact-count sensor they read)
        self.compiled_steps = compiled_steps_enabled() and mujoco.mj_name2id(
            m, mujoco.mjtObj.mjOBJ_SENSOR, CONTACT_SENSOR) >= 0
        # MjData's arrays, bound once (its buffers stay put; an attribute read makes a new one)
        self._qpos, self._qvel, self._ctrl_view = self.data.qpos, self.data.qvel, self.data.ctrl
        a = self.actuators  # a slice when the actuators are adjacent (no index array per step)
        self._act = slice(int(a[0]), int(a[0]) + len(a)) \
            if list(a) == list(range(int(a[0]), int(a[0]) + len(a))) else a
        q, v = self.xy, self.vxy
        self._xy = slice(int(q[0]), int(q[0]) + 2) if q[1] == q[0] + 1 else q
        self._v = slice(int(v[0]), int(v[0]) + 2) if v[1] == v[0] + 1 else v
        self._wrench_of: int | None = None
        self._step_push: HumanPush | None = None
        self._float_for: TrackingController | None = None  # the controller _can_float judged
        self._float_control = False
        #: the body a human pushes and the sensor feels (the handle; the arm's tray)
        self.pushed_body = int(self.model.body("handle").id)
        self.dt = float(self.model.opt.timestep)
        #: sensor -> (faults, estimator) -> detector
        self.sensing = SensingChain(m, self.dt, sensor_model, rng, estimator, detector)
        self.on_substep: list[Callable[[MobileBase, HumanPush | None], None]] = []
        self.pre_substep: list[Callable[[MobileBase], None]] = []
        #: pushes that act when their time comes (pushes at any time); expired ones are dropped
        self.pushes: list[HumanPush] = []
        #: every cue felt since the last reset, as records (module docstring)
        self.felt: list[Felt] = []
        #: the one listener of the cue stream (the episode runner's door; None: nobody)
        self.listener: Callable[[Felt], None] | None = None
        #: the decision step's phases (:mod:`.decision`)
        self.decision = DecisionStep(self)
        #: admittance damping (N s/m) while a cue is under way; None: track the target
        self.admittance_b: float | None = None
        #: end a move or a hold as soon as a cue is felt (the planner replans)
        self.stop_on_cue = False
        #: the guidance admittance and its state (:meth:`enable_guidance`; None: off)
        self.guidance: Guidance | None = None
        #: the safety filter on every command of the motion under way (:mod:`.keep_clear`):
        #: set by :meth:`.decision.DecisionStep.move` for a move that starts off its cell's
        #: centre or still moving (after a tap stopped a move, a yield, guidance), whose path
        #: is not the grid's straight clear move; always on under guidance
        self.keep_clear = False
        self._onset: tuple[float, int] | None = None
        self._anchor: np.ndarray | None = None
        #: measure the base (:mod:`.measurements`; episodes with physical parameters)
        self.measure = False
        self.measurements = Measurements(m, self.dt)
        self.target = np.zeros(2)
        #: leave xfrc_applied to someone else (the viewer's mouse perturbation) when no
        #: simulated push is active
        self.external_forces = False
        self._coaster: Coaster | None = None

    @property
    def coaster(self) -> Coaster | None:
        """The compiled steps of a move with nothing pushing (:mod:`.coasting`) when they
        apply to this base as it is set up now, else None (a subclass steps otherwise)."""
        if not (self.compiled_steps and Coaster.applies(self)):
            return None
        if self._coaster is None:
            self._coaster = Coaster(self)
        return self._coaster

    #: the compiled move runs this kind of base's step (:mod:`.kernel_parts`: a subclass
    #: that steps otherwise declares nothing and keeps the Python path, as the differential
    #: drive does; the physical carry arm declares its own)
    KERNEL_RUNS = True

    def kernel_ready(self) -> bool:
        """Whether the compiled move may take the next step as far as this base's own state
        goes (:meth:`.coasting.Coaster.ready`): its float control path for its controller
        (:meth:`_can_float`, judged when the controller changed) and, when it measures, the
        estimate held already measured (the kernel measures a new one only)."""
        return (self._float_for is self.controller and self._float_control
                and (not self.measure
                     or self.measurements.holds(self.sensing.estimates)))

    def kernel_prepare(self) -> None:
        """What this base does before the compiled move's steps: no yield's anchor (its steps
        do not yield, as :meth:`_control`'s float path) and, unless someone else owns it
        (:attr:`external_forces`), the pushed body's wrench cleared (:meth:`pushed_wrench`;
        the kernel writes a push phase's force into it); the physical carry arm first runs an
        IK solve that is due."""
        self._anchor = None
        if not self.external_forces:
            self.pushed_wrench().fill(0.0)

    def kernel_finish(self, steps: int) -> None:
        """What this base does after the compiled move took ``steps`` physics steps (the
        plain base: nothing; the physical carry arm: its step count and tilt record)."""

    def kernel_addresses(self) -> tuple[int, ...]:
        """The addresses the compiled move (:mod:`.coasting`) reads and writes: ``x``, ``y``
        and ``yaw`` in ``qpos`` and the three actuators in ``ctrl`` of :meth:`_control`'s
        float path (once :meth:`kernel_ready`), then the planar velocity's ``x`` and ``y`` in
        ``qvel``."""
        return (*self._float_adr, *self._float_act, *self._vxy_adr)

    @property
    def cue_open(self) -> bool:
        """Whether the cue stream (:mod:`.cue_stream`) holds a cue under way, felt and not yet
        given (where and when it was first felt)."""
        return self._onset is not None

    def compiled_arm(self) -> tuple | None:
        """The physical carry arm's arrays for the compiled move (None: no arm)."""
        return None

    def enable_pushes_any_time(self, admittance_b: float = 80.0) -> None:
        """Pushes at any time (module docstring): the splitting detector, admittance ``b``
        (N s/m: a 30 N push moves the yielding base at 0.375 m/s), stop on a cue."""
        self.sensing.split_pushes()
        self.admittance_b = float(admittance_b)
        self.stop_on_cue = True

    def enable_guidance(self, mass: float, damping: float) -> None:
        """Guidance (module docstring): pushes at any time, the splitting detector, the
        admittance ``M dv/dt + b v = F_hat`` (``mass`` kg, ``damping`` N s/m) added to the
        tracking command, the belief updated while a push lasts; a push's end stops the
        move (the planner revises the plan at the step's end, :mod:`.decision`)."""
        self.sensing.split_pushes()
        self.guidance = Guidance(mass, damping)
        self.stop_on_cue = True

    # --- state ---------------------------------------------------------------------------
    def reset(self, cell: int) -> None:
        """Reset the physics with the base at the centre of ``cell`` (from the model's ``rest``
        keyframe when it has one: a robot's standing posture, e.g. the TidyBot's arm)."""
        if self._rest >= 0:
            mujoco.mj_resetDataKeyframe(self.model, self.data, self._rest)
        else:
            mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[self.xy] = self.scene.cell_centre(cell)
        self.target = self.scene.cell_centre(cell)
        mujoco.mj_forward(self.model, self.data)
        self._reset_sensing()
        self._reset_control()

    def _reset_sensing(self) -> None:
        """Forget the pushes and cues, reset the sensing chain (zeroing a faulty sensor at
        rest) and the measurements."""
        self.pushes, self.felt, self._onset = [], [], None
        self.sensing.reset(self.data, self.pushed_body)
        self.measurements.reset(float(self.data.time))

    @property
    def position(self) -> np.ndarray:
        """The base's planar position (m; a new array)."""
        return self._qpos[self._xy].copy()

    @property
    def velocity(self) -> np.ndarray:
        """The base's planar velocity (m/s; a new array)."""
        return self._qvel[self._v].copy()

    @property
    def cell(self) -> int:
        """The grid cell under the base."""
        return self.scene.cell_at(self._qpos[self._xy])

    @property
    def end_effector(self) -> np.ndarray | None:
        """Position (m) of what the robot carries; None for the plain base."""
        return None

    def metrics(self) -> dict[str, float]:
        """Per-episode measurements of this base (none for the plain base)."""
        return {}

    # --- stepping ------------------------------------------------------------------------
    def substep(self, push: HumanPush | None = None) -> Cue | None:
        """One physics step: controller, optional push, sensing and detection."""
        d = self.data
        if self.pre_substep:
            for hook in self.pre_substep:
                hook(self)
        self._control()
        if self.pushes:
            self._apply_pushes(push)
        elif push is not None and push.active(d.time):
            push.apply(d, self.pushed_body)
        elif not self.external_forces:
            self.pushed_wrench().fill(0.0)
        mujoco.mj_step(self.model, d)
        # x . 0 is NaN exactly when x holds a NaN or an infinity, and so is the sum of two
        if not math.isfinite(self._qpos.dot(self._zero_q) + self._qvel.dot(self._zero_v)):
            raise EpisodeError(f"simulation diverged at t = {d.time:.3f} s (non-finite state)")
        return self.after_read(self.sensing.read(d), push)

    def after_read(self, cue: Cue | None, push: HumanPush | None) -> Cue | None:
        """The rest of :meth:`substep` once the sensing chain gave ``cue`` (``push``: the push
        the step applied): the cue stream, the measurements and the ``on_substep`` hooks; the
        compiled move hands a step back here after its detector's step (:mod:`.coasting`)."""
        d, sensing = self.data, self.sensing
        if cue is not None or self._onset is not None or self.guidance is not None or \
                sensing.under_way:
            track_cue(self, cue)
        if self.measure:
            self._step_push = push
            self.measurements.update(d, self._vxy_adr, self._pushed_now,
                                     sensing.force_estimate, sensing.estimates)
        self.run_hooks(push)
        return cue

    def run_hooks(self, push: HumanPush | None) -> None:
        """The ``on_substep`` hooks after a physics step (``push``: the push it applied)."""
        for hook in self.on_substep:
            hook(self, push)

    def pushed_wrench(self) -> np.ndarray:
        """A view of the pushed body's row of ``xfrc_applied`` (bound once per pushed body)."""
        if self._wrench_of != self.pushed_body:
            self._wrench_of = self.pushed_body
            self._wrench_view = self.data.xfrc_applied[self.pushed_body]
        return self._wrench_view

    def _pushed_now(self) -> bool:
        """Whether the base's motion in the physics step under way is not its controller's
        own: it yields, or a push acts (or ended less than 0.1 s ago)."""
        t, push = self.data.time, self._step_push
        return self.yielding() or any(
            p.t0 <= t <= p.t0 + p.profile.duration_s + 0.1
            for p in [*self.pushes, *([push] if push is not None else [])])

    def physical_metrics(self) -> dict[str, float]:
        """The base's measurements (:mod:`.measurements`; empty unless :attr:`measure`)."""
        return self.measurements.metrics() if self.measure else {}

    def _apply_pushes(self, push: HumanPush | None) -> None:
        """The sum of the active pushes (and ``push``) on the pushed body; expired pushes are
        dropped."""
        t = float(self.data.time)
        self.pushes = [p for p in self.pushes if t <= p.t0 + p.profile.duration_s]
        total = np.zeros(3)
        for p in [*self.pushes, *([push] if push is not None else [])]:
            if p.active(t):
                total += p.force(t)
        apply_force(self.data, self.pushed_body, total)

    def yielding(self) -> bool:
        """Whether the base yields to a push now (admittance on and a cue under way)."""
        return self.admittance_b is not None and self.sensing.under_way

    def _control(self) -> None:
        """Actuator commands for this physics step (the base's tracking controller). A
        :class:`~.controller.ProfiledController` on this class's own command law, not
        yielding, is evaluated on floats and written per actuator: the same numbers as
        :meth:`_base_command` without its arrays (it runs at every physics step)."""
        c = self.controller
        if self._float_for is not c:
            self._float_control = self._can_float()
        if self.guidance is not None:  # a person may move the base: the safety filter
            self.guidance.admit(self)
            self._ctrl_view[self._act] = self._base_command()
            return
        if self._float_control and (self.admittance_b is None or not self.yielding()):
            self._anchor = None
            q, (ix, iy, iyaw), (a0, a1, a2) = self._qpos, self._float_adr, self._float_act
            tx, ty = self.target.tolist()
            vx, vy = c.ramp_xy(*c.goal_xy(q.item(ix), q.item(iy), tx, ty), c.dt)
            if self.keep_clear:  # a motion off the grid's clear moves: the safety filter
                sc = self.scene
                vx, vy = keep_clear_xy(q.item(ix), q.item(iy), vx, vy, sc.cell_size,
                                       sc.radius_m, 0.5 * c.a_max, sc.clearance.arrays,
                                       sc.clearance.near_rows)
            ctrl = self._ctrl_view
            ctrl[a0], ctrl[a1], ctrl[a2] = vx, vy, -c.k_yaw * q.item(iyaw)
            return
        self._ctrl_view[self._act] = self._base_command()

    def _can_float(self) -> bool:
        """Whether :meth:`_control` may take its float path (its docstring): a
        :class:`~.controller.ProfiledController` whose ``command`` is the profiled law, and
        this class's own ``_base_command``. Decided again when the controller is replaced."""
        c = self._float_for = self.controller
        ok = (isinstance(c, ProfiledController) and type(c).command is ProfiledController.command
              and type(self)._base_command is MobileBase._base_command)
        if ok:
            self._float_adr = (int(self.xy[0]), int(self.xy[1]), self.yaw)
            self._float_act = tuple(int(a) for a in self.actuators)
        return ok

    def _base_command(self) -> np.ndarray:
        """The base's velocity command ``(vx, vy, wz)``: the controller's, or while yielding
        :meth:`admittance_velocity`, which a profiled controller ramps to within its
        acceleration limit. Where a
        person moves the base (guidance, or a yield), the command passes the safety filter
        :func:`.keep_clear.keep_clear` (braking at half ``a_max``: a push may oppose the
        drive), and so does every command of a motion off the grid's clear moves
        (:attr:`keep_clear`)."""
        d = self.data
        pos = self._qpos[self._xy].copy()
        a_brake = 0.5 * self.controller.a_max
        if not self.yielding():
            self._anchor = None
            command = self.controller.command(pos, d.qpos[self.yaw], self.target)
            if self.guidance is not None:
                if self.guidance.moving:  # the push's velocity as feedforward, within v_max
                    command[:2] += self.guidance.v
                    speed = math.hypot(command[0], command[1])
                    if speed > self.controller.v_max:
                        command[:2] *= self.controller.v_max / speed
                keep_clear(self.scene, pos, command, a_brake)  # a push may act unadmitted
            elif self.keep_clear:  # a motion off the grid's clear moves (:attr:`keep_clear`)
                keep_clear(self.scene, pos, command, a_brake)
            return command
        v = self.controller.ramp(keep_clear(self.scene, pos, self.admittance_velocity(),
                                            a_brake))
        return np.array([v[0], v[1], -self.controller.k_yaw * d.qpos[self.yaw]])

    def admittance_velocity(self) -> np.ndarray:
        """The yield's velocity (m/s, world x-y; :func:`.admittance.yield_velocity`) from where
        the yield began (noted now when it begins)."""
        pos = self.data.qpos[self.xy]
        if self._anchor is None:
            self._anchor = pos.copy()
        return yield_velocity(self.sensing.force_estimate, pos, self._anchor,
                              self.admittance_b, self.controller.kp, self.force_limit)

    def _reset_control(self) -> None:
        """A standing base: no yield under way, the controller's state cleared."""
        self._anchor = None
        self.keep_clear = False
        if self.guidance is not None:
            self.guidance.reset()
        self.controller.reset()

    def receive_push(self, push: HumanPush) -> Cue | None:
        """Hold the current cell while ``push`` acts (the push phase, :mod:`.decision`, run to
        completion); the detected cue or None."""
        return self.decision.push(push).run().cue

    def move_to(self, cell: int, min_s: float = 0.0) -> int:
        """Drive to the centre of ``cell`` for at least ``min_s`` simulated seconds (the move
        phase run to completion, within the controller's time limit); the cell the base ends
        in."""
        self.decision.move(cell, self.controller.time_limit_s, min_s).run()
        return self.cell

    def hold(self, seconds: float) -> int:
        """Stand at the current cell's centre for ``seconds`` of simulated time (the hold
        phase run to completion; with :attr:`stop_on_cue` a cue ends it); the cell the base
        is in at the end."""
        self.decision.hold(seconds).run()
        return self.cell
