"""What the robot measures of a push: the handle's force sensor rotated into the world frame,
and, optionally, the faults of a real force/torque sensor (:class:`SensorModel`).

The force sensor at ``handle_site`` reports, in the site frame, the force the base exerts on
the handle (``s = R^T (m (a - g) - F)`` for a push ``F`` on a handle of mass ``m`` with
acceleration ``a``); a push ``F`` on a still handle reads ``-F``. So the horizontal interaction
force in the world frame is ``-(R s)_xy`` with ``R`` the site's rotation (``site_xmat``). The
robot never reads ``xfrc_applied``.

**Inertia is in the raw reading.** MuJoCo computes the sensor from the handle's own dynamics
(``cacc``/``cfrc_int``), so when the base accelerates the raw reading includes ``-m a``:
measured on ``simple``, a base starting towards a target 1 m away (0.8 m/s, 7.9 m/s^2 at
the start) reads 1.57 N on the 0.2 kg handle, which is exactly ``m * qacc`` (fit: 0.200 kg).
The ideal sensor (the default) is that raw reading: no noise, no bias, the model's inertia.

**Faults** (:class:`SensorModel`, applied by :class:`FaultySensor` in the sensor's own frame):
white noise per output sample, an initial constant bias of a given magnitude in a random
horizontal direction, a random-walk drift of that bias, an extra sensed mass (the grip and the
sensor's tool plate, which the MJCF handle does not model) whose inertia the sensor feels, and
an output rate (each sample the mean of the physics steps since the last, held in between).
MuJoCo 3.17 ignores the MJCF sensor ``noise`` attribute, so the faults are drawn here from a
NumPy ``Generator`` the caller passes (reproducible).
See ``docs/sensing.md`` for the figures behind :meth:`SensorModel.realistic`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numba as nb
import numpy as np
from numba.np.random.distributions import random_standard_normal

from ..errors import ConfigError
from .native import (
    OBJ_BODY,
    addresses,
    bit_generator,
    bit_generator_pointers,
    matTvec,
    mj_objectAcceleration,
)

#: the thermal warm-up's time constant (s; :class:`SensorModel` ``thermal_n``)
THERMAL_S = 120.0
INF = float("inf")
#: :attr:`FaultySensor.win`'s slots: the window's sum (sensor frame), the physics steps in it,
#: the next sample's time, the last sample's window (s), whether the last step gave a sample
#: (1.0), that sample's mean and how many samples the sensor gave since its restart (the
#: sequence number of the held sample: both drivers tell a new sample by it)
(W_S0, W_S1, W_S2, W_COUNT, W_NEXT_T, W_WINDOW_S, W_FRESH, W_MEAN, W_SAMPLES, N_WIN) = (
    0, 1, 2, 3, 4, 5, 6, 7, 10, 11)


@nb.njit(cache=True)
def physical_reading(mp, dp, body, reading, R, extra_m, scratch):
    """This physics step's reading before the electronics (N, sensor frame), into
    ``scratch[12:15]``: MuJoCo's ``reading`` plus, for an extra (or removed) mass ``extra_m``
    (kg, 0: none), ``R^T m a`` with ``a`` the world-frame linear acceleration of body ``body``'s
    centre of mass minus gravity (``mj_objectAcceleration``; the simulator's truth: the sensor
    model uses it, the robot's estimator does not) and ``R`` the sensor site's rotation.
    ``mp``, ``dp``: the ``MjModel``'s and ``MjData``'s addresses; ``scratch`` 15 floats
    (acceleration, ``m a``, ``R^T m a``, the result). The C functions of :mod:`.native`: the
    products of ``R.T.dot`` in NumPy."""
    out = scratch[12:15]
    if extra_m == 0.0:
        for i in range(3):
            out[i] = reading[i]
        return out
    acc6, ma, x = scratch[0:6], scratch[6:9], scratch[9:12]
    mj_objectAcceleration(mp, dp, OBJ_BODY, body, acc6.ctypes.data, 0)
    for i in range(3):
        ma[i] = acc6[3 + i] * extra_m
    matTvec(R, ma, x)
    for i in range(3):
        out[i] = reading[i] + x[i]
    return out


@nb.njit(cache=True)
def window_step(mp, dp, body, reading, R, extra_m, scratch, win, t, dt, period):
    """One physics step (time ``t``) into the sensor's averaging window ``win`` (slots
    ``W_*``): the :func:`physical_reading` added to the sum, one more step counted. A sample is
    due when ``t >= next_t - 1e-9`` (``next_t`` starts at the first step's time) or no sample
    was given since the restart (``win[W_SAMPLES] == 0``): then its mean (sum / steps) goes to
    ``win[W_MEAN:W_MEAN + 3]``, its window is ``steps dt``, ``win[W_SAMPLES]`` counts it, the
    sum restarts and ``next_t`` advances by ``period`` until it is past ``t``. Returns
    whether a sample is due. The one arithmetic of :meth:`FaultySensor.read` and the compiled
    move (:mod:`.coasting`)."""
    x = physical_reading(mp, dp, body, reading, R, extra_m, scratch)
    win[W_S0] += x[0]
    win[W_S1] += x[1]
    win[W_S2] += x[2]
    win[W_COUNT] += 1.0
    if win[W_NEXT_T] == -math.inf:
        win[W_NEXT_T] = t
    fresh = t >= win[W_NEXT_T] - 1e-9 or win[W_SAMPLES] == 0.0
    win[W_FRESH] = 1.0 if fresh else 0.0
    if fresh:
        win[W_SAMPLES] += 1.0
        n = win[W_COUNT]
        win[W_WINDOW_S] = n * dt
        for i in range(3):
            win[W_MEAN + i] = win[W_S0 + i] / n
            win[W_S0 + i] = 0.0
        win[W_COUNT] = 0.0
        while win[W_NEXT_T] <= t + 1e-9:
            win[W_NEXT_T] += period
    return fresh


@nb.njit(cache=True)
def emit_step(rng, mean, bias, drift, drift_step, noise_n, out):
    """One output sample of the faulty sensor from its window's ``mean`` (N, sensor frame)
    into ``out``: with ``drift``, the bias's random walk ``bias[:2] += drift_step z`` (two
    normals), then ``out = mean + bias + noise_n z`` (three normals when ``noise_n > 0``),
    the normals drawn from the sensor's ``Generator`` (``rng``: its
    :func:`~.native.bit_generator_pointers`; the draws NumPy's ``standard_normal`` gives).
    The one arithmetic of :meth:`FaultySensor.read` and the compiled move (:mod:`.coasting`;
    the thermal warm-up is Python's, added after)."""
    bitgen = bit_generator(rng)
    if drift:
        z0 = random_standard_normal(bitgen)
        z1 = random_standard_normal(bitgen)
        bias[0] += drift_step * z0
        bias[1] += drift_step * z1
    if noise_n > 0.0:
        n0 = noise_n * random_standard_normal(bitgen)
        n1 = noise_n * random_standard_normal(bitgen)
        n2 = noise_n * random_standard_normal(bitgen)
    else:
        n0 = n1 = n2 = 0.0
    out[0] = mean[0] + bias[0] + n0
    out[1] = mean[1] + bias[1] + n1
    out[2] = mean[2] + bias[2] + n2


class HandleSensor:
    """Reads the horizontal interaction force at a site with a force sensor."""

    def __init__(self, model, sensor: str = "handle_force", site: str = "handle_site"):
        self.adr = int(model.sensor(sensor).adr[0])
        self.site = int(model.site(site).id)

    def force_xy(self, data) -> np.ndarray:
        """The horizontal interaction force (N) in the world frame."""
        f_site = data.sensordata[self.adr:self.adr + 3]
        R = data.site_xmat[self.site].reshape(3, 3)
        return -(R.dot(f_site))[:2]  # the same gemv as ``@``

    def rotation(self, data) -> np.ndarray:
        """The site's rotation (site frame to world frame, 3x3)."""
        return data.site_xmat[self.site].reshape(3, 3).copy()


@dataclass(frozen=True)
class SensorModel:
    """The faults of a force sensor (all zero: the ideal sensor, MuJoCo's raw reading).

    ``noise_n``: white noise per axis per output sample (N, 1 sigma);
    ``bias_n``: magnitude of the initial constant bias (N), in a random horizontal direction
    of the sensor frame;
    ``drift_n_per_sqrt_s``: random-walk drift of the bias per horizontal axis (N after 1 s,
    1 sigma; after ``t`` seconds its spread is ``drift sqrt(t)``);
    ``inertia``: keep the handle's inertia in the reading (physical; MuJoCo computes it); False
    removes it with the simulator's true acceleration (an idealisation, for comparisons);
    ``extra_mass_kg``: mass on the sensor's tool side that the scene does not model (grip,
    tool plate): the sensor also reads ``-m_extra (a - g)``, the dynamics do not change;
    ``rate_hz``: output rate (each sample averages the physics steps since the previous one,
    as an anti-aliasing filter does, and is held until the next); None: every physics step;
    ``thermal_n``: a warm-up offset that grows after the sensor is zeroed, ``thermal_n (1 -
    exp(-t / THERMAL_S))`` in a random horizontal direction (strain gauges warming after
    power-up or a change of load; the time constant is an assumption, no datasheet figure), so
    zeroing at the start does not remove it; 0: none (no random draw either).
    """

    noise_n: float = 0.0
    bias_n: float = 0.0
    drift_n_per_sqrt_s: float = 0.0
    inertia: bool = True
    extra_mass_kg: float = 0.0
    rate_hz: float | None = None
    thermal_n: float = 0.0

    def __post_init__(self):
        for name in ("noise_n", "bias_n", "drift_n_per_sqrt_s", "extra_mass_kg", "thermal_n"):
            v = getattr(self, name)
            if not np.isfinite(v) or v < 0:
                raise ConfigError(f"sensor {name} must be a finite number >= 0, got {v}")
        if self.rate_hz is not None and not (np.isfinite(self.rate_hz) and self.rate_hz > 0):
            raise ConfigError(f"sensor rate_hz must be a positive number, got {self.rate_hz}")

    @classmethod
    def ideal(cls) -> SensorModel:
        """MuJoCo's raw reading: no noise, no bias, no drift, the model's own inertia."""
        return cls()

    @classmethod
    def ft300s(cls) -> SensorModel:
        """The datasheet of a Robotiq FT 300-S on a still bench (figures recalled, not
        verified here; see ``docs/sensing.md``): signal noise 0.1 N (1 sigma, Fx/Fy/Fz) at its
        100 Hz stream rate, offset removed at start (the sensor is zeroed), a slow thermal drift
        of the zero (about 1 N over an hour: 0.02 N/sqrt(s)), a tool side (plate and grip) of
        about 0.3 kg beyond the model's handle."""
        return cls(noise_n=0.1, bias_n=0.0, drift_n_per_sqrt_s=0.02, inertia=True,
                   extra_mass_kg=0.3, rate_hz=100.0)

    @classmethod
    def realistic(cls) -> SensorModel:
        """A handle F/T sensor of the FT 300-S / ATI Mini45 class as mounted on a driving base,
        with margins for what a bench datasheet leaves out: 2 N noise per axis per sample at
        100 Hz (20 times the FT 300-S's 0.1 N: floor and wheel vibration, cable pull), a 6 N
        offset the robot has not zeroed (tool weight and mounting preload, thermal offset) that
        drifts by 0.05 N/sqrt(s) (3 N over an hour), inertia on, and 0.4 kg of grip and tool
        plate beyond the model's 0.2 kg handle (so 0.6 kg sensed: about 6 N at the base's
        10 m/s^2 peak acceleration)."""
        return cls(noise_n=2.0, bias_n=6.0, drift_n_per_sqrt_s=0.05, inertia=True,
                   extra_mass_kg=0.4, rate_hz=100.0)

    @property
    def is_ideal(self) -> bool:
        """Whether this is the raw reading (the default path, bit for bit)."""
        return self == SensorModel()


class FaultySensor:
    """A :class:`HandleSensor` with the faults of a :class:`SensorModel`; its randomness comes
    from ``rng`` only. Call :meth:`read` once per physics step (after ``mj_step``)."""

    def __init__(self, model: mujoco.MjModel, sensor: HandleSensor, body: int,
                 sensor_model: SensorModel, rng: np.random.Generator):
        if not isinstance(rng, np.random.Generator):
            raise ConfigError("a sensor with faults needs a numpy Generator (the body's rng)")
        self.model, self.sensor, self.body = model, sensor, int(body)
        self.spec = sensor_model
        self.rng = rng
        #: the Generator's pointers (:func:`~.native.bit_generator_pointers`; :func:`emit_step`)
        self.rng_pointers = bit_generator_pointers(rng)
        self.mass = float(model.body_subtreemass[self.body])  # the model's sensed mass
        self.dt = float(model.opt.timestep)
        self.period = self.dt if sensor_model.rate_hz is None else 1.0 / sensor_model.rate_hz
        #: the drift's spread per sample, ``drift sqrt(period)`` (N)
        self.drift_step = sensor_model.drift_n_per_sqrt_s * math.sqrt(self.period)
        phi = rng.uniform(0.0, 2.0 * np.pi)
        #: the current bias (N, sensor frame); drifts as a random walk
        self.bias = sensor_model.bias_n * np.array([np.cos(phi), np.sin(phi), 0.0])
        #: the warm-up offset's direction (sensor frame); drawn only when there is one
        self._thermal = np.zeros(3)
        if sensor_model.thermal_n > 0:
            psi = rng.uniform(0.0, 2.0 * np.pi)
            self._thermal = sensor_model.thermal_n * np.array([np.cos(psi), np.sin(psi), 0.0])
        #: the mass whose inertia and weight the reading adds to MuJoCo's (kg; 0: none)
        self.extra_m = 0.0 if sensor_model.extra_mass_kg == 0 and sensor_model.inertia else \
            sensor_model.extra_mass_kg - (0.0 if sensor_model.inertia else self.mass)
        #: :func:`window_step`'s state (slots ``W_*``) and :func:`physical_reading`'s scratch
        self.win = np.zeros(N_WIN)
        #: the last output sample (N, sensor frame; :meth:`read`'s), written in place at every
        #: sample (:attr:`samples` numbers it; zeros before the first)
        self.held = np.zeros(3)
        self._scratch = np.zeros(15)
        self._data = None
        self.restart()

    #: the compiled move runs this sensor's step (:mod:`.kernel_parts`)
    KERNEL_RUNS = True

    def kernel_ready(self) -> bool:
        """The compiled move runs the next sample: no thermal warm-up (its offset is
        Python's) and a sample held (the first one is taken in Python)."""
        return self.spec.thermal_n == 0 and self.samples > 0

    @property
    def samples(self) -> int:
        """How many samples the sensor gave since its :meth:`restart` (``win[W_SAMPLES]``,
        counted by :func:`window_step` in both drivers): :attr:`held` is the sample of this
        number, and a new number is a new sample (0: none held yet)."""
        return int(self.win.item(W_SAMPLES))

    def step_arrays(self) -> tuple:
        """The sensor's arrays as the compiled move (:mod:`.coasting`) takes them: the drift
        bias, :attr:`held` (where a new sample goes, in place), the window
        (:func:`window_step`'s ``win``) and :func:`physical_reading`'s scratch; the arrays
        :meth:`read` passes."""
        return self.bias, self.held, self.win, self._scratch

    def __getstate__(self) -> dict:
        """The sensor's state for a copy (``copy.deepcopy``, a task's snapshot:
        ``pathpref_tasks.snapshot``) without what is bound to addresses: the ``MjData`` views
        and address (bound again at the next read) and the Generator's pointers (taken again
        from the copy's own Generator, :meth:`__setstate__`)."""
        state = dict(self.__dict__)
        for k in ("_mp", "_dp", "_reading", "_R", "rng_pointers"):
            state.pop(k, None)
        state["_data"] = None
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self.rng_pointers = bit_generator_pointers(self.rng)

    @property
    def fresh(self) -> bool:
        """Whether the last :meth:`read` gave a new sample."""
        return self.win[W_FRESH] != 0.0

    @property
    def window_s(self) -> float:
        """Over how long the last sample averaged (s)."""
        return float(self.win[W_WINDOW_S])

    def _bind(self, data) -> None:
        """Views into ``data``'s buffers (they stay put for the life of an ``MjData``): the
        sensor's reading and the site's rotation, read without a copy at every step."""
        self._data = data
        self._mp, self._dp = addresses(self.model, data)
        a = self.sensor.adr
        self._reading = data.sensordata[a:a + 3]
        self._R = data.site_xmat[self.sensor.site].reshape(3, 3)

    def _emit(self, mean: np.ndarray, out: np.ndarray) -> np.ndarray:
        """An output sample from a window's ``mean`` into ``out`` (:func:`emit_step`, then the
        thermal warm-up since the sensor was zeroed, ``out += (1 - exp(-t / THERMAL_S))
        thermal``); returns ``out``."""
        sm = self.spec
        emit_step(self.rng_pointers, mean, self.bias, sm.drift_n_per_sqrt_s > 0,
                  self.drift_step, float(sm.noise_n), out)
        if sm.thermal_n > 0:
            self.warm_s += self.period
            out += (1.0 - np.exp(-self.warm_s / THERMAL_S)) * self._thermal
        return out

    def read(self, data) -> np.ndarray:
        """The sensor's output after this physics step (N, sensor frame, 3 axes). Every
        ``1/rate_hz`` seconds a new sample: the mean of the physical readings since the last
        one (the electronics' anti-aliasing average, :func:`window_step`), plus bias and
        noise; held in between. :attr:`fresh` says whether this step gave a new sample,
        :attr:`window_s` over how long it averaged, :attr:`samples` which sample it is. The
        array returned is :attr:`held`, written in place at every sample (a caller that keeps
        a sample copies it)."""
        if data is not self._data:
            self._bind(data)
        if window_step(self._mp, self._dp, self.body, self._reading, self._R,
                       self.extra_m, self._scratch, self.win, data.time, self.dt,
                       self.period):
            self._emit(self.win[W_MEAN:W_MEAN + 3], self.held)
        return self.held

    def read_still(self, data) -> np.ndarray:
        """A fresh output sample of the current (still) state that advances the sensor's
        clock by one period without physics: what the robot reads while it waits at rest."""
        if data is not self._data:
            self._bind(data)
        return self._emit(physical_reading(self._mp, self._dp, self.body,
                                           self._reading, self._R, self.extra_m,
                                           self._scratch), np.empty(3))

    def restart(self) -> None:
        """Forget the held sample (after a physics reset: :attr:`samples` back to 0); the bias
        stays (same device)."""
        self.held[:] = 0.0
        self.win[:] = 0.0
        self.win[W_NEXT_T], self.win[W_WINDOW_S] = -INF, self.dt
        self.warm_s = 0.0  # seconds of samples since the restart (the thermal warm-up)
