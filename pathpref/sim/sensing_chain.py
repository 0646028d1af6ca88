"""The robot's sensing chain: force sensor -> (faults, estimator) -> push detector.

One physics step's reading is :meth:`SensingChain.read`: the horizontal push estimate
``F_hat`` (N, world frame) fed to the detector, which returns a :class:`~.cue_detector.Cue`
when one ends.

* With the ideal sensor (``model`` None or ideal) ``F_hat`` is MuJoCo's raw reading
  (:class:`~.sensing.HandleSensor`: the handle's own inertia included) and the detector is the
  plain hysteresis :class:`~.cue_detector.CueDetector`.
* With sensor faults (:class:`~.sensing.SensorModel`) the reading passes through
  :class:`~.sensing.FaultySensor` (noise, bias, drift, output rate; drawn from a child of the
  body's generator, ``rng.spawn``, which draws nothing from it) and
  :class:`~.estimator.ForceEstimator` (zeroed over ``tare_s`` at every :meth:`reset`, bias
  tracked at rest, inertia compensated from the robot's own joint velocities), and the detector
  is :class:`~.cue_detector.FilteredCueDetector`. ``docs/sensing.md`` has the figures.

The chain knows nothing of the base's motion or of the episode: the base
(:mod:`.mobile_base`) owns one and asks it for a cue per physics step.
"""

from __future__ import annotations

import mujoco
import numpy as np

from ..errors import ConfigError
from .cue_detector import Cue, CueDetector, FilteredCueDetector
from .estimator import EstimatorConfig, ForceEstimator
from .sensing import FaultySensor, HandleSensor, SensorModel

#: the settings the unfiltered :class:`CueDetector` takes
PLAIN_SETTINGS = ("on_n", "on_s", "off_n", "off_s", "split", "turn_deg")


def make_detector(dt: float, sensor_model: SensorModel | None,
                  settings: dict | None = None) -> CueDetector:
    """The detector of a chain whose sensor is ``sensor_model`` (None or ideal: the plain
    hysteresis :class:`CueDetector` with the :data:`PLAIN_SETTINGS` of ``settings``; with
    faults: the :class:`FilteredCueDetector` with all of them), taking one force sample every
    ``dt`` seconds. The one choice :class:`SensingChain` and a remote robot's chain
    (:mod:`pathpref.ros`, fed a force/torque sensor's messages) make."""
    settings = dict(settings or {})
    if sensor_model is None or sensor_model.is_ideal:
        return CueDetector(dt, **{k: v for k, v in settings.items() if k in PLAIN_SETTINGS})
    return FilteredCueDetector(dt, **settings)


def cue_under_way(detector: CueDetector) -> bool:
    """A cue is under way in ``detector``: it is active or the force is above its onset."""
    return detector.active or detector._above > 0.0


class SensingChain:
    """The sensor, its faults and estimator, and the detector of one base (module
    docstring). ``detector`` holds the detector's settings (thresholds, ``split``)."""

    def __init__(self, model: mujoco.MjModel, dt: float, sensor_model: SensorModel | None = None,
                 rng: np.random.Generator | None = None,
                 estimator: EstimatorConfig | None = None, detector: dict | None = None):
        self.model, self.dt = model, dt
        #: the force sensor read (the handle's; the arm's tool sensor)
        self.sensor = HandleSensor(model)
        self.detector_settings: dict = dict(detector or {})
        #: the sensor's faults; None (or ideal) reads the raw sensor exactly
        self.sensor_model = None if sensor_model is None or sensor_model.is_ideal \
            else sensor_model
        self.estimator_config = estimator or EstimatorConfig()
        self.faulty: FaultySensor | None = None
        self.estimator: ForceEstimator | None = None
        #: the push estimate the detector was last fed (N, world frame; with faults the
        #: estimator's :attr:`~.estimator.ForceEstimator.force`, written in place)
        self.force_estimate = np.zeros(2)
        self._raw_estimates = 0  # the ideal sensor's estimates (one per physics step)
        self.pushed_body: int | None = None
        if self.sensor_model is not None:
            if not isinstance(rng, np.random.Generator):
                raise ConfigError("a sensor model with faults needs the body's numpy "
                                  "Generator (rng=...)")
            self._rng = rng.spawn(1)[0]
        self.detector: CueDetector = make_detector(dt, self.sensor_model,
                                                   self.detector_settings)

    def split_pushes(self) -> None:
        """Two pushes make two cues (pushes at any time; :mod:`.cue_detector`)."""
        self.detector_settings["split"] = True
        self.detector.split = True

    @property
    def under_way(self) -> bool:
        """A cue is under way: the detector is active or the force is above its onset."""
        return cue_under_way(self.detector)

    @property
    def estimates(self) -> int:
        """The sequence number of :attr:`force_estimate`: a new number is a new estimate
        (with faults the estimator's count, :attr:`~.estimator.ForceEstimator.estimates`, a
        new one at each sensor sample; the ideal sensor's: one per :meth:`sense`). What a
        reader that acts once per estimate compares (the measurements' peak estimate)."""
        if self.sensor_model is None:
            return self._raw_estimates
        return 0 if self.estimator is None else self.estimator.estimates

    def reset(self, data: mujoco.MjData, pushed_body: int) -> None:
        """Reset the detector; with a faulty sensor, (re)build the faults and the estimator
        for the current sensor and ``pushed_body`` and zero the sensor at rest (``tare_s`` of
        readings)."""
        self.detector.reset()
        self.pushed_body = int(pushed_body)
        if self.sensor_model is None:
            return
        if self.faulty is None or self.faulty.sensor is not self.sensor:
            self.faulty = FaultySensor(self.model, self.sensor, self.pushed_body,
                                       self.sensor_model, self._rng)
            mass = self.faulty.mass + self.sensor_model.extra_mass_kg
            self.estimator = ForceEstimator(self.model, self.pushed_body, mass,
                                            self.estimator_config)
        self.faulty.restart()
        # a view of the sensor site's rotation (MjData's buffers stay put): no copy per step
        self._rotation = data.site_xmat[self.sensor.site].reshape(3, 3)
        self.estimator.quiet = 0.0
        self.estimator.mark(data)
        n = int(round(self.estimator_config.tare_s / self.faulty.period))
        if n > 0:
            readings = [self.faulty.read_still(data) for _ in range(n)]
            self.estimator.tare(readings, self.sensor.rotation(data))
        self.faulty.restart()

    def sense(self, data: mujoco.MjData) -> np.ndarray:
        """The push estimate of this physics step (N, world frame): the raw sensor with the
        ideal model, else the faulty sensor through the estimator (the estimator tracks the
        bias only while no cue is under way)."""
        if self.sensor_model is None:
            self.force_estimate = self.sensor.force_xy(data)
            self._raw_estimates += 1
            return self.force_estimate
        if self.faulty is None:
            raise ConfigError("the sensing chain reads before its first reset: call the "
                              "base's reset(cell) first")
        faulty, est = self.faulty, self.estimator
        reading = faulty.read(data)
        idle = not self.under_way
        if faulty.fresh or not idle:
            self.force_estimate = est.update(reading, self._rotation, data, idle,
                                             faulty.fresh, faulty.window_s)
        else:  # between samples with no cue under way the estimator holds its estimate
            self.force_estimate = est.force
        return self.force_estimate

    def read(self, data: mujoco.MjData) -> Cue | None:
        """One physics step: :meth:`sense` and detect; the cue that ended, if any."""
        f = self.sense(data)
        if self.sensor_model is None:
            return self.detector.update(f)
        return self.detector.update(f, at_rest=self.estimator.at_rest)
