"""The robot's estimate of the human's push from a faulty force sensor and its own motion.

:class:`ForceEstimator` removes what the robot can know (``docs/sensing.md``):

* **inertia and weight** of what hangs on the sensor: the sensor reads
  ``s = R^T (m (a - g) - F) + b + noise``, so the estimate is
  ``F_hat = -(R (s - b_hat - R^T m_hat (a_hat - g)))_xy``; ``m_hat`` is the tool-side mass the
  robot knows (its handle or tray and the sensor's tool plate), ``a_hat`` the acceleration of
  that body's centre of mass from the robot's *own* state: ``J_com(q) (qvel_now -
  qvel_then) / T``, the body's Jacobian (kinematics) times the finite difference of the
  measured joint velocities over the sensor's averaging window ``T`` (so a 100 Hz sensor that
  averages 10 ms is compensated with the mean acceleration of the same 10 ms). It never
  reads ``xfrc_applied``, ``cacc`` or ``qacc``.
* **the bias**: a zero (tare) from the mean of ``tare_s`` of readings at rest when the robot
  starts, then an exponential average of the residual with a slow time constant
  (``bias_tau_s``), updated only while the robot is at rest (no cue under way, the sensed
  body slower than ``still_mps`` and accelerating less than ``still_mps2``) and frozen
  otherwise. A sample enters the average only ``quiet_s`` after it was taken, if the robot
  stayed at rest meanwhile: the first newtons of a push (before the detector goes active or
  the base yields) are dropped, not averaged in.

:class:`ResidualEstimator` is the alternative without a sensor (PHRI_NOTES 2.2 (b)):
``mj_inverse`` with ``qacc = dqvel/dt`` gives ``qfrc_inverse``; minus the robot's own
actuator forces, the residual on the base's slide joints is the horizontal external force.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import mujoco
import numba as nb
import numpy as np

from ..errors import ConfigError
from .kernel_parts import Slot
from .native import addresses, matTvec, matvec, mj_jacBodyCom, norm

GRAVITY_UP = np.array([0.0, 0.0, 9.81])
#: :func:`estimate_step`'s constants, in this order in :attr:`ForceEstimator.params`
MASS, BIAS_TAU, STILL_MPS, STILL_MPS2, QUIET_S, COMPENSATE = range(6)
#: slots of :attr:`ForceEstimator.rec`, the estimator's scalar state (the rest timer
#: ``quiet`` in s, ``at_rest``, 1.0 or 0.0, and how many estimates it made: the sequence
#: number of the estimate it holds, by which both drivers tell a new one), which both drivers
#: read and write in place
E_QUIET, E_AT_REST, E_ESTIMATES, N_EREC = range(4)
#: the bias queue's rows beyond ``quiet_s / dt + 1`` (the most it holds)
QUEUE_SLACK = 4


@nb.njit(cache=True)
def estimate_step(mp, dp, body, reading, R, qvel, window, cue_idle, params, rec, st):
    """One fresh sensor sample ``reading`` (averaged over ``window`` s) through
    :class:`ForceEstimator` (module docstring), on plain arrays: ``a = J_com (qvel - mark) /
    window`` (``mark`` then set to ``qvel``), the residual ``r = s - R^T m (a + g)`` (``a``
    zero without inertial compensation), at rest (``cue_idle``, ``|J_com qvel| < still_mps``,
    ``|a| < still_mps2``) ``r`` queued and ``quiet += window``, else the queue dropped; queued
    residuals older than ``quiet_s`` enter ``bias += w (r - bias)``, ``w = min(1, window /
    (tau + window))``; the estimate ``-(R (r - bias))_xy``. ``mp``, ``dp``: the ``MjModel``'s
    and ``MjData``'s addresses; ``rec`` the estimator's record (slots ``E_*``: ``quiet`` read
    and written, ``at_rest`` written, the estimates counted, ``+1``); ``st`` the arrays
    ``(mark, jac, dv, acc, bias, ring, queue, force, tmp3, res, vel)``, updated in place
    (``acc``, ``force`` receive the acceleration and the estimate). The one arithmetic of
    the Python step and the compiled move (:mod:`.coasting`): MuJoCo's ``mj_jacBodyCom``
    and NumPy's BLAS kernels (:mod:`.native`)."""
    mark, jac, dv, acc, bias, ring, queue, force, tmp3, res, vel = st
    quiet = rec[E_QUIET]
    nv = qvel.shape[0]
    mj_jacBodyCom(mp, dp, jac.ctypes.data, 0, body)
    for i in range(nv):
        dv[i] = qvel[i] - mark[i]
    for i in range(nv):
        dv[i] = dv[i] / window
    for i in range(nv):
        mark[i] = qvel[i]
    matvec(jac, dv, acc)
    for i in range(3):  # ForceEstimator.expected: R^T m (a + g)
        ai = acc[i] if params[COMPENSATE] != 0.0 else 0.0
        tmp3[i] = params[MASS] * (ai + (GRAVITY_UP[i]))
    matTvec(R, tmp3, res)
    for i in range(3):
        res[i] = reading[i] - res[i]
    still = False
    if cue_idle:
        matvec(jac, qvel, vel)
        still = norm(vel) < params[STILL_MPS] and norm(acc) < params[STILL_MPS2]
    cap = ring.shape[0]
    if still:
        quiet += window
        j = (queue[0] + queue[1]) % cap
        ring[j, 0], ring[j, 1], ring[j, 2] = res[0], res[1], res[2]
        queue[1] += 1
    else:
        quiet = 0.0  # the samples just before a push or a start never count
        queue[0], queue[1] = 0, 0
    at_rest = quiet >= params[QUIET_S] - 1e-12
    w = window / (params[BIAS_TAU] + window)
    if not w < 1.0:
        w = 1.0
    while queue[1] * window > params[QUIET_S] + 1e-12:
        j = queue[0]
        for i in range(3):
            bias[i] += w * (ring[j, i] - bias[i])
        queue[0] = (j + 1) % cap
        queue[1] -= 1
    for i in range(3):
        tmp3[i] = res[i] - bias[i]
    matvec(R, tmp3, res)
    force[0], force[1] = -res[0], -res[1]
    rec[E_QUIET], rec[E_AT_REST] = quiet, 1.0 if at_rest else 0.0
    rec[E_ESTIMATES] += 1.0


@dataclass(frozen=True)
class EstimatorConfig:
    """Settings of :class:`ForceEstimator` (see the module docstring)."""

    bias_tau_s: float = 2.0
    tare_s: float = 0.2
    still_mps: float = 0.02
    still_mps2: float = 0.3
    quiet_s: float = 0.15
    compensate_inertia: bool = True

    def __post_init__(self):
        for name in ("bias_tau_s", "tare_s", "still_mps", "still_mps2", "quiet_s"):
            v = getattr(self, name)
            if not np.isfinite(v) or v < 0 or (name == "bias_tau_s" and v == 0):
                raise ConfigError(f"estimator {name} must be a finite number >= 0, got {v}")


class ForceEstimator:
    """Bias tracking and inertial compensation for the force sensed at ``body``.

    Call :meth:`update` once per physics step with the sensor's output and the site's
    rotation; it returns the horizontal push estimate."""

    def __init__(self, model: mujoco.MjModel, body: int, mass_kg: float,
                 config: EstimatorConfig | None = None):
        self.model, self.body, self.mass = model, int(body), float(mass_kg)
        #: the scalar state (slots ``E_*``: :attr:`quiet`, :attr:`at_rest`, :attr:`estimates`)
        self.rec = np.zeros(N_EREC)
        #: the body's acceleration and the push estimate of the last sample (:meth:`update`),
        #: written in place at every sample (:attr:`estimates` numbers them)
        self.acc, self.force = np.zeros(3), np.zeros(2)
        self.config = config or EstimatorConfig()
        self.dt = float(model.opt.timestep)
        self._jac = np.zeros((3, model.nv))
        self._dv = np.zeros(model.nv)
        c = self.config
        #: :func:`estimate_step`'s constants (its ``params``)
        self.params = np.array([self.mass, c.bias_tau_s, c.still_mps, c.still_mps2, c.quiet_s,
                                float(c.compensate_inertia)])
        self._ring = np.zeros((int(c.quiet_s / self.dt) + 1 + QUEUE_SLACK, 3))
        self._scratch = (np.zeros(3), np.zeros(3), np.zeros(3))
        self.reset()

    #: how long the base has been still (s) and whether it is at rest (:attr:`rec`)
    quiet = Slot(E_QUIET)
    at_rest = Slot(E_AT_REST, boolean=True)

    @property
    def estimates(self) -> int:
        """How many estimates the estimator has made since it was built (counted by
        :func:`estimate_step` in both drivers): the number of the estimate :attr:`force`
        holds; a new number is a new estimate."""
        return int(self.rec.item(E_ESTIMATES))

    #: the compiled move runs this estimator's step (:mod:`.kernel_parts`)
    KERNEL_RUNS = True

    def kernel_ready(self) -> bool:
        """The compiled move runs the next update: the estimator has started (its first
        sample, which marks the velocities, is Python's)."""
        return self._qvel_mark is not None

    def reset(self) -> None:
        """Forget the bias estimate and the rest timer (a new robot, not yet zeroed)."""
        self.bias = np.zeros(3)
        self.quiet = 0.0
        self.at_rest = False
        self.acc[:] = 0.0
        self.force[:] = 0.0
        self._qvel_mark: np.ndarray | None = None
        # the bias queue: a ring of residual rows and its (head, length)
        self._queue = np.zeros(2, dtype=np.int64)

    def pending(self) -> np.ndarray:
        """The queued residuals (N, sensor frame), oldest first (a new array)."""
        head, n = self._queue.tolist()
        return self._ring[(head + np.arange(n)) % len(self._ring)]

    def mark(self, data) -> None:
        """Start a sensor window at the current joint velocities (after a reset)."""
        self._qvel_mark = data.qvel.copy()

    def expected(self, R: np.ndarray, acc: np.ndarray) -> np.ndarray:
        """What the sensor reads without a push and without faults (N, sensor frame): the
        known mass's inertia and weight, ``R^T m (a - g)``."""
        a = acc if self.config.compensate_inertia else np.zeros(3)
        return R.T.dot(self.mass * (a + GRAVITY_UP))

    def tare(self, readings: list[np.ndarray], R: np.ndarray) -> None:
        """Zero the sensor from readings taken at rest (the mean residual becomes the bias)."""
        if readings:
            r = np.mean(readings, axis=0) - self.expected(R, np.zeros(3))
            self.bias = np.asarray(r, float).copy()

    def update(self, reading: np.ndarray, R: np.ndarray, data, cue_idle: bool,
               fresh: bool = True, window_s: float | None = None) -> np.ndarray:
        """The horizontal push estimate (N, world frame) after one physics step. On a
        ``fresh`` sensor sample (averaged over ``window_s``, one step by default) the estimate
        is recomputed and, at rest with ``cue_idle`` (the detector has nothing under way), the
        bias tracked; between samples the last estimate is held. The array returned is
        :attr:`force`, written in place at every sample (:attr:`estimates` numbers it)."""
        if not fresh:
            if not cue_idle:
                self.quiet, self.at_rest = 0.0, False
                self._queue[:] = 0
            return self.force
        window = self.dt if window_s is None else window_s
        if self._qvel_mark is None:
            self._qvel_mark = data.qvel.copy()
        mp, dp = addresses(self.model, data)
        estimate_step(mp, dp, self.body, reading, R, data.qvel, window, cue_idle, self.params,
                      self.rec, self.step_arrays())
        return self.force

    def step_arrays(self) -> tuple:
        """:func:`estimate_step`'s state arrays (its ``st``; :attr:`acc` and :attr:`force`
        receive the acceleration and the estimate in place): what :meth:`update` and the
        compiled move (:mod:`.coasting`) both pass."""
        return (self._qvel_mark, self._jac, self._dv, self.acc, self.bias, self._ring,
                self._queue, self.force, *self._scratch)


class ResidualEstimator:
    """The push from inverse dynamics, no sensor (PHRI_NOTES 2.2 (b)): with ``qacc`` from the
    finite difference of the measured joint velocities, ``mj_inverse`` gives the generalised
    force the motion needed; minus the robot's own actuator forces, the residual on the base's
    slide joints is the horizontal external force (``J^T`` of the push; contacts are modelled
    by the inverse and so are not in it). Works on a copy of the model with discrete-time
    inverse dynamics (``mjENBL_INVDISCRETE``, consistent with the ``implicitfast`` step, so
    the velocity actuators' implicit damping leaves no residual) and a scratch ``MjData``."""

    def __init__(self, model: mujoco.MjModel, slide_dofs: np.ndarray):
        self.model = copy.deepcopy(model)
        self.model.opt.enableflags |= int(mujoco.mjtEnableBit.mjENBL_INVDISCRETE)
        self.scratch = mujoco.MjData(self.model)
        self.dofs = np.asarray(slide_dofs, int)
        self.dt = float(model.opt.timestep)

    def estimate(self, qpos_before: np.ndarray, qvel_before: np.ndarray, data) -> np.ndarray:
        """The horizontal external force (N, world frame) during the step that led from
        ``(qpos_before, qvel_before)`` to ``data``'s state; ``data.qfrc_actuator`` is the
        actuator force of that step (the robot's own command)."""
        s = self.scratch
        s.qpos[:] = qpos_before
        s.qvel[:] = qvel_before
        s.act[:] = data.act
        s.ctrl[:] = data.ctrl
        s.qacc[:] = (data.qvel - qvel_before) / self.dt
        mujoco.mj_inverse(self.model, s)
        return (s.qfrc_inverse - data.qfrc_actuator)[self.dofs].copy()
