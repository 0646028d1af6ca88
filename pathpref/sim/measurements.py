"""What a physical episode measures of its base, one physics step at a time.

* ``base_peak_accel``: the largest planar acceleration ``|v_t - v_{t-1}| / (t - t_prev)``
  (m/s^2) over steps with no push acting (within 0.1 s after one) and the base not yielding:
  the controller's own; ``base_peak_accel_pushed``: over every step;
* ``peak_push_estimate_n``: the largest push estimate ``|F_hat|`` the detector was fed;
* contact safety with the static world (obstacles and walls, geoms named ``obstacle_*`` and
  ``wall_*``): ``collisions`` (contacts begun: a step with one after a step without),
  ``contact_impact_speed`` (m/s, the base's planar speed at the step before a contact
  began, the largest), ``contact_peak_force_n`` (the largest normal force of a contact, N, from
  ``mj_contactForce``) and ``contact_penetration_mm`` (the deepest penetration, ``-dist`` of a
  contact, mm).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import mujoco
import numba as nb
import numpy as np

from .kernel_parts import Slot
from .native import hypot


@nb.njit(cache=True)
def planar_accel(vx, vy, vpx, vpy, t, t_prev, dt):
    """The base's planar acceleration ``|v - v_prev| / max(t - t_prev, dt)`` (m/s^2) over the
    time since the last measurement (a caller, e.g. dm_control's environment step, may step
    the physics without the base's substep). The one arithmetic of both drivers."""
    span = t - t_prev
    if dt > span:
        span = dt
    return hypot(vx - vpx, vy - vpy) / span


#: slots of :attr:`Measurements.rec`, the scalars a step updates (the velocity and time of the
#: step before, the peaks, whether the base touches the static world, the sequence number of
#: the push estimate measured last, -1: none), which both drivers read and write in place
(M_VX, M_VY, M_T, M_PEAK, M_PEAK_PUSHED, M_PEAK_FORCE, M_TOUCHING, M_ESTIMATE,
 N_MREC) = range(9)


class Measurements:
    """The measurements of one base (module docstring); :meth:`update` after each physics
    step, :meth:`metrics` at the end of the episode."""

    def __init__(self, model: mujoco.MjModel, dt: float):
        self.model, self.dt = model, dt
        #: the scalars a step updates (slots ``M_*``)
        self.rec = np.zeros(N_MREC)
        self._static = np.array([model.geom(i).name.startswith(("obstacle_", "wall_"))
                                 for i in range(model.ngeom)], dtype=bool)
        self._wrench = np.zeros(6)
        self._data: mujoco.MjData | None = None
        self.reset(0.0)

    #: the peaks (m/s^2, N) and whether the base touches the static world, in :attr:`rec`
    peak_accel = Slot(M_PEAK)
    peak_accel_pushed = Slot(M_PEAK_PUSHED)
    peak_force = Slot(M_PEAK_FORCE)
    _touching = Slot(M_TOUCHING, boolean=True)

    #: the compiled move runs these measurements of a step nothing pushes
    #: (:func:`planar_accel`, the peaks, the contact count; :mod:`.kernel_parts`)
    KERNEL_RUNS = True

    def kernel_ready(self) -> bool:
        """Every step (whether the estimate is the one measured is the base's: :meth:`holds`)."""
        return True

    def holds(self, estimate: int) -> bool:
        """Whether the push estimate numbered ``estimate`` (its sequence number,
        :attr:`~.sensing_chain.SensingChain.estimates`) is the one measured last (the kernel
        measures a new estimate only)."""
        return self.rec.item(M_ESTIMATE) == estimate

    def reset(self, t: float) -> None:
        """Start measuring at simulated time ``t`` with the base at rest."""
        self.rec[M_VX], self.rec[M_VY], self.rec[M_T] = 0.0, 0.0, float(t)
        self.peak_accel = 0.0
        self.peak_accel_pushed = 0.0
        self.peak_force = 0.0
        self.rec[M_ESTIMATE] = -1.0
        self.collisions = 0
        self._touching = False
        self.impact_speed = 0.0
        self.contact_force = 0.0
        self.penetration = 0.0

    def update(self, data: mujoco.MjData, vxy_adr: tuple[int, int],
               pushed: Callable[[], bool], force: np.ndarray, estimate: int) -> None:
        """One physics step: the base's planar velocity at ``vxy_adr`` in ``qvel``, whether a
        push acts (or the base yields: its acceleration is then not the controller's; asked
        only when the step's acceleration is a new peak) and the push estimate ``force``,
        numbered ``estimate`` (measured when the number is new: the estimator holds its
        estimate between samples)."""
        if data is not self._data:  # MjData's qvel, bound once (its buffer stays put)
            self._data, self._qvel = data, data.qvel
        t, qvel, rec = data.time, self._qvel, self.rec
        vx, vy = qvel.item(vxy_adr[0]), qvel.item(vxy_adr[1])
        v_prev = rec.item(M_VX), rec.item(M_VY)  # the velocity a contact begun now met
        a = planar_accel(vx, vy, v_prev[0], v_prev[1], t, rec.item(M_T), self.dt)
        rec[M_VX], rec[M_VY], rec[M_T] = vx, vy, t
        if a > self.peak_accel_pushed:
            self.peak_accel_pushed = a
        if a > self.peak_accel and not pushed():
            self.peak_accel = a
        if estimate != rec.item(M_ESTIMATE):  # a new estimate (held between samples)
            rec[M_ESTIMATE] = estimate
            self.peak_force = max(self.peak_force, math.hypot(force[0], force[1]))
        self.measure_contacts(data, v_prev)

    def measure_contacts(self, data: mujoco.MjData, v_prev: tuple[float, float]) -> None:
        """The contact part of :meth:`update`: contacts with the static world this step,
        ``v_prev`` the base's velocity at the step before (the compiled move hands a step
        with a contact back here, :mod:`.coasting`)."""
        n = data.ncon
        touching = False
        if n > 0:
            geoms = data.contact.geom[:n]
            hits = np.flatnonzero(self._static[geoms].any(axis=1))
            if len(hits):
                touching = True
                for i in hits:
                    i = int(i)
                    mujoco.mj_contactForce(self.model, data, i, self._wrench)
                    self.contact_force = max(self.contact_force, abs(float(self._wrench[0])))
                    self.penetration = max(self.penetration,
                                           -1000.0 * float(data.contact.dist[i]))
        if touching and not self._touching:
            self.collisions += 1
            self.impact_speed = max(self.impact_speed, math.hypot(*v_prev))
        self._touching = touching

    def metrics(self) -> dict[str, float]:
        """The episode's measurements by name (module docstring)."""
        return {"base_peak_accel": self.peak_accel,
                "base_peak_accel_pushed": self.peak_accel_pushed,
                "peak_push_estimate_n": self.peak_force,
                "collisions": float(self.collisions),
                "contact_impact_speed": self.impact_speed,
                "contact_peak_force_n": self.contact_force,
                "contact_penetration_mm": self.penetration}
