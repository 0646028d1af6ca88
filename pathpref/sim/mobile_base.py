"""The physical robot: a planar base in a MuJoCo scene, driven cell to cell, pushed by a human.

Two operations make up a decision step:

* :meth:`MobileBase.receive_push`: the base holds its cell while the simulated human pushes the
  handle; the robot's :class:`~pathpref.sim.cue_detector.CueDetector`, fed only by the handle
  force sensor, returns the detected cue (or None when nothing was detected);
* :meth:`MobileBase.move_to`: the tracking controller drives to a cell centre at physics rate
  until the base settles or the time limit passes; collisions are MuJoCo contacts.

Hooks (``on_substep``) see every physics step, e.g. a renderer or a logger.

Sensing: by default the detector reads the raw force sensor (:class:`HandleSensor`, ideal: no
noise, no bias; the handle's own inertia is in it, as MuJoCo computes it). With a
``sensor_model`` that is not ideal (:class:`~pathpref.sim.sensing.SensorModel`) the sensor has
faults drawn from a child of the ``rng`` given (the body's generator: ``rng.spawn`` draws
nothing from it), the robot zeroes it at every :meth:`MobileBase.reset` and estimates the push
with :class:`~pathpref.sim.estimator.ForceEstimator` (bias tracking at rest, inertial
compensation from its own joint velocities), and detects with
:class:`~pathpref.sim.cue_detector.FilteredCueDetector`. ``docs/sensing.md`` has the figures.
"""

from __future__ import annotations

from collections.abc import Callable

import mujoco
import numpy as np

from ..errors import ConfigError, EpisodeError
from .controller import TrackingController
from .cue_detector import Cue, CueDetector, FilteredCueDetector
from .estimator import EstimatorConfig, ForceEstimator
from .force_cue import HumanPush, PushProfile
from .scene import Scene
from .sensing import FaultySensor, HandleSensor, SensorModel

RELEASE_WINDOW_S = 0.4  # how long after a push ends the detector may still release


class MobileBase:
    """The base in ``scene``: its joints (``slide_x``, ``slide_y``, ``yaw``) and velocity
    actuators (``vx``, ``vy``, ``wz``) addressed by name; the pushed body is the ``handle``.

    ``sensor_model`` (default: the ideal raw sensor) with ``rng`` (required when the model has
    faults) and ``estimator`` settings choose how the robot senses (module docstring)."""

    def __init__(self, scene: Scene, controller: TrackingController | None = None,
                 profile: PushProfile | None = None, data: mujoco.MjData | None = None,
                 sensor_model: SensorModel | None = None,
                 rng: np.random.Generator | None = None,
                 estimator: EstimatorConfig | None = None):
        self.scene = scene
        self.model = scene.model
        self.data = data if data is not None else mujoco.MjData(self.model)
        self.controller = controller or TrackingController()
        self.profile = profile or PushProfile()
        m = self.model
        self.xy = np.array([m.joint(j).qposadr[0] for j in ("slide_x", "slide_y")])
        self.yaw = int(m.joint("yaw").qposadr[0])
        self.vxy = np.array([m.joint(j).dofadr[0] for j in ("slide_x", "slide_y")])
        self.actuators = np.array([m.actuator(a).id for a in ("vx", "vy", "wz")])
        self.sensor = HandleSensor(self.model)
        #: the body a human pushes and the sensor feels (the handle; the arm's tray)
        self.pushed_body = int(self.model.body("handle").id)
        self.dt = float(self.model.opt.timestep)
        self.detector = CueDetector(self.dt)
        self.on_substep: list[Callable[[MobileBase, HumanPush | None], None]] = []
        #: called with each cue detected while driving (study mode feeds it to the belief)
        self.on_cue: list[Callable[[MobileBase, Cue], None]] = []
        self.target = np.zeros(2)
        #: cues detected while driving (no simulated push is given then: a person pushing
        #: live in study mode, or a false cue in a simulated episode)
        self.cues_while_driving: list[Cue] = []
        #: leave xfrc_applied to someone else (the viewer's mouse perturbation) when no
        #: simulated push is active
        self.external_forces = False
        self.last_onset_s: float | None = None
        #: the sensor's faults; None (or ideal) reads the raw sensor exactly as before
        self.sensor_model = None if sensor_model is None or sensor_model.is_ideal \
            else sensor_model
        self.estimator_config = estimator or EstimatorConfig()
        self.faulty: FaultySensor | None = None
        self.estimator: ForceEstimator | None = None
        #: the push estimate the detector was last fed (N, world frame)
        self.force_estimate = np.zeros(2)
        if self.sensor_model is not None:
            if not isinstance(rng, np.random.Generator):
                raise ConfigError("a sensor model with faults needs the body's numpy "
                                  "Generator (rng=...)")
            self._sensor_rng = rng.spawn(1)[0]
            self.detector = FilteredCueDetector(self.dt)

    # --- state ---------------------------------------------------------------------------
    def reset(self, cell: int) -> None:
        """Reset the physics with the base at the centre of ``cell``."""
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[self.xy] = self.scene.cell_centre(cell)
        self.target = self.scene.cell_centre(cell)
        mujoco.mj_forward(self.model, self.data)
        self._reset_sensing()

    def _reset_sensing(self) -> None:
        """Reset the detector; with a faulty sensor, (re)build the sensing chain for the
        current sensor and pushed body and zero the sensor at rest (``tare_s`` of readings)."""
        self.detector.reset()
        if self.sensor_model is None:
            return
        if self.faulty is None or self.faulty.sensor is not self.sensor:
            self.faulty = FaultySensor(self.model, self.sensor, self.pushed_body,
                                       self.sensor_model, self._sensor_rng)
            mass = self.faulty.mass + self.sensor_model.extra_mass_kg
            self.estimator = ForceEstimator(self.model, self.pushed_body, mass,
                                            self.estimator_config)
        self.faulty.restart()
        self.estimator.quiet = 0.0
        self.estimator.mark(self.data)
        n = int(round(self.estimator_config.tare_s / self.faulty.period))
        if n > 0:
            readings = [self.faulty.read_still(self.data) for _ in range(n)]
            self.estimator.tare(readings, self.sensor.rotation(self.data))
        self.faulty.restart()

    def sense(self) -> np.ndarray:
        """The push estimate of this physics step (N, world frame): the raw sensor by
        default, else the faulty sensor through the estimator."""
        d = self.data
        if self.sensor_model is None:
            self.force_estimate = self.sensor.force_xy(d)
            return self.force_estimate
        if self.faulty is None:
            self._reset_sensing()
        idle = not self.detector.active and self.detector._above == 0.0
        reading = self.faulty.read(d)
        self.force_estimate = self.estimator.update(
            reading, self.sensor.rotation(d), d, idle, self.faulty.fresh, self.faulty.window_s)
        return self.force_estimate

    @property
    def position(self) -> np.ndarray:
        """The base's planar position (m)."""
        return self.data.qpos[self.xy]

    @property
    def velocity(self) -> np.ndarray:
        """The base's planar velocity (m/s)."""
        return self.data.qvel[self.vxy]

    @property
    def cell(self) -> int:
        """The grid cell under the base."""
        return self.scene.cell_at(self.position)

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
        self._control()
        if push is not None and push.active(float(d.time)):
            push.apply(d, self.pushed_body)
        elif not self.external_forces:
            d.xfrc_applied[self.pushed_body, :] = 0.0
        mujoco.mj_step(self.model, d)
        if not np.isfinite(d.qpos).all() or not np.isfinite(d.qvel).all():
            raise EpisodeError(f"simulation diverged at t = {d.time:.3f} s (non-finite state)")
        if self.sensor_model is None:
            cue = self.detector.update(self.sensor.force_xy(d))
        else:
            cue = self.detector.update(self.sense(), at_rest=self.estimator.at_rest)
        for hook in self.on_substep:
            hook(self, push)
        return cue

    def _control(self) -> None:
        """Actuator commands for this physics step (the base's tracking controller)."""
        d = self.data
        d.ctrl[self.actuators] = self.controller.command(d.qpos[self.xy], d.qpos[self.yaw],
                                                         self.target)

    def receive_push(self, push: HumanPush) -> Cue | None:
        """Hold the current cell while ``push`` acts; return the detected cue or None."""
        self.target = self.scene.cell_centre(self.cell)
        push.t0 = float(self.data.time)
        end = push.t0 + push.profile.duration_s + RELEASE_WINDOW_S
        cue = None
        #: seconds from the push's onset to the detector going active (None: it did not)
        self.last_onset_s = None
        while self.data.time < end and cue is None:
            cue = self.substep(push)
            if self.last_onset_s is None and self.detector.active:
                self.last_onset_s = float(self.data.time) - push.t0
        self.detector.reset()
        return cue

    def move_to(self, cell: int, min_s: float = 0.0) -> int:
        """Drive to the centre of ``cell`` (for at least ``min_s`` simulated seconds, holding
        it once there); return the cell the base ends in. A cue detected on the way is kept
        in ``cues_while_driving`` and given to every ``on_cue`` hook at once."""
        self.target = self.scene.cell_centre(cell)
        t0 = self.data.time
        t_end = t0 + max(self.controller.time_limit_s, min_s)
        while self.data.time < t_end:
            cue = self.substep()
            if cue is not None:
                self.cues_while_driving.append(cue)
                for hook in self.on_cue:
                    hook(self, cue)
            if self.data.time - t0 >= min_s and self.controller.settled(
                    self.position, self.velocity, self.target):
                break
        return self.cell
