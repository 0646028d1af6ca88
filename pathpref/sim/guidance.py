"""Guidance (Bajcsy et al. 2017): a push deforms the base's motion while it lasts, and the
deformation is the evidence.

The admittance velocity ``v`` of ``M dv/dt + b v = F_hat`` moves the base's target
(``dp_target/dt = v``: the base keeps the deformation, it does not spring back) and is added
to the tracking command as its feedforward; ``v`` decays (time constant ``M / b``) once the
push is released.

**The deformation as evidence.** The target's displacement by the admittance, ``D = sum dt v``
over the steps where it moved, is where the push took the plan relative to where the plan was
going (the plan's own target does not move during a step). Every ``GUIDANCE_PERIOD_S`` of a cue
under way a *partial* :class:`~pathpref.episode.body.Felt` carries the direction ``theta`` of
the period's ``D`` (from the cue's first step) and its weight ``|D| /
DEFORMATION_EVIDENCE_M`` (a push that moves the plan
0.1 m is one observation, as a tap is; at most ``GUIDANCE_MAX_EVIDENCE`` per cue); the cue's final
record carries the rest. The belief takes it with the likelihood ``P(theta | s, g, p) = sum_h
P(h | s, g, p) VM(theta; mu_h, kappa)`` to that power (:mod:`pathpref.episode.physics`,
"Guidance"). A push the base cannot follow (into a wall) moves nothing and tells nothing.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from ..episode.body import Felt
from ..episode.physics import CELL_SIZE_M, GUIDANCE_MAX_EVIDENCE, GUIDANCE_PERIOD_S
from ..geometry.footprint import _clear_at
from ..geometry.grid import heading_to_action
from .kernel_parts import Slot
from .native import hypot

#: below this admittance speed, with no cue under way, the admittance is at rest (m/s): the
#: target's remaining travel ``|v| M / b`` is then under 0.3 mm
V_REST = 1e-3
#: the deformation worth one observation (m): a correction is one choice of heading by the
#: person, as a tap is, and once it has moved the plan this far (a fifth of a cell; a tap
#: moves the yielding base 3 cm) its direction is what the person chose
DEFORMATION_EVIDENCE_M = 0.2 * CELL_SIZE_M


class Guidance:
    """The guidance admittance ``(mass, damping)`` of one base and its state: the admittance
    velocity :attr:`v` and the evidence gathered since the last record."""

    def __init__(self, mass: float, damping: float):
        self.mass, self.damping = float(mass), float(damping)
        self.v = np.zeros(2)
        self.evidence = np.zeros(2)  # the impulse since the last evidence record (N s)
        self.evidence_s = 0.0  # its duration (s)
        self.deformation = np.zeros(2)  # the target's displacement since the last record (m)
        #: the state the compiled move reads and writes in place: ``[moving]``
        self.rec = np.zeros(1)
        self.moving = False
        self.given = 0.0  # the evidence the cue under way has given (observations)
        self._rest = np.zeros(2)  # the force while no cue is under way
        self._params_for = None  # the controller step_params were made for

    #: the admittance moves the target (False: at rest, ``v = 0``), in :attr:`rec`
    moving = Slot(0, boolean=True)

    #: the compiled move runs this admittance's tail (:func:`admit_step` with no cue under
    #: way; :mod:`.kernel_parts`)
    KERNEL_RUNS = True

    def kernel_ready(self) -> bool:
        """Every step with no cue under way (:meth:`.coasting.Coaster.ready` asks that)."""
        return True

    def reset(self) -> None:
        """A standing base: no admittance velocity, no evidence."""
        self.v[:] = 0.0
        self.moving = False
        self.evidence[:], self.evidence_s, self.given = 0.0, 0.0, 0.0
        self.deformation[:] = 0.0

    def admit(self, base) -> bool:
        """One step of ``v += dt (F_hat - b v) / M`` (explicit Euler; stable for
        ``dt < 2 M / b``: 0.5 s for the defaults against the 2 ms step) and of the target it
        deforms, ``p_target += dt v``; whether the admittance moves (:attr:`moving`).
        ``F_hat`` is the force estimate while the detector has a cue under way, else 0 (as
        Bajcsy et al.'s controller zeroes the torques below its threshold: sensor noise does
        not walk the base away); once no cue is under way and ``|v| < V_REST`` the
        admittance is at rest (``v = 0``) and the base tracks its target alone.
        Safety: ``|v|`` is capped at the controller's ``v_max``; where the base would not fit
        (:meth:`.scene.Scene.fits`) within its stopping distance ahead, ``|v|^2 / a_max``
        (braking at half ``a_max``: a push may oppose the drive), the admittance brakes at
        ``a_max``; the target never moves where the base does not fit, so a push cannot drive
        the base into an obstacle or a wall."""
        s = base.sensing
        pushing = s.under_way
        if not (pushing or self.moving):
            return False
        self.moving = admit_step(self.v, base.target, self.deformation,
                                 s.force_estimate if pushing else self._rest, pushing,
                                 self.step_params(base), base.scene.clearance.arrays)
        return self.moving

    def step_params(self, base) -> np.ndarray:
        """:func:`admit_step`'s ``params`` for ``base``: ``(dt, M, b, v_max, a_max, cell size,
        the footprint's reach)``, kept until the base's controller changes."""
        c = base.controller
        if self._params_for is not c:
            sc = base.scene
            self._params = np.array([base.dt, self.mass, self.damping, c.v_max, c.a_max,
                                     sc.cell_size, sc.world.footprint.reach])
            self._params_for = c
        return self._params

    def feel(self, force: np.ndarray, dt: float) -> bool:
        """Add one step's force to the evidence; whether a period is full. A cue's first
        step starts its deformation afresh (the tail of an earlier push's deformation, once
        the detector let it go, is not this cue's evidence)."""
        if self.evidence_s == 0.0 and self.given == 0.0:
            self.deformation[:] = 0.0
        self.evidence += force * dt
        self.evidence_s += dt
        return self.evidence_s >= GUIDANCE_PERIOD_S - 1e-9

    def take(self) -> tuple[float, float]:
        """The direction of the deformation since the last evidence record and its weight
        (module docstring); starts the next period (a cue's total is capped)."""
        d = self.deformation
        size = math.hypot(float(d[0]), float(d[1]))
        weight = max(0.0, min(size / DEFORMATION_EVIDENCE_M, GUIDANCE_MAX_EVIDENCE - self.given))
        angle = math.atan2(float(d[1]), float(d[0]))
        self.given += weight
        self.evidence[:], self.evidence_s = 0.0, 0.0
        self.deformation[:] = 0.0
        return angle, weight

    def partial(self, cell: int, t0: float, t: float) -> Felt:
        """A partial record of the cue under way at ``cell`` (felt since ``t0``, now ``t``):
        not a cue, its evidence so far."""
        e = (float(self.evidence[0]), float(self.evidence[1]))
        angle, weight = self.take()
        return Felt(cell, heading_to_action(angle), t0, t, None, e, t - t0,
                    evidence=(angle, weight), partial=True)


@nb.njit(cache=True)
def admit_step(v, target, deformation, force, pushing, params, clr):
    """One step of :meth:`Guidance.admit` on plain arrays (``v``, ``target`` and
    ``deformation`` updated in place; ``params`` = ``(dt, M, b, v_max, a_max, cell size (m),
    the footprint's reach (cells))``, ``clr`` the map's
    :attr:`~pathpref.geometry.footprint.Clearance.arrays`); whether the admittance moves.
    ``pushing``: ``v += dt (F - b v) / M``; else (moving) ``v += dt (-b v) / M``, at rest below
    ``V_REST``. Called by the Python step and by the compiled steps
    (:mod:`.coasting`, the admittance's tail after a push); allocates nothing."""
    dt, mass, damping, v_max, a_max, cell, reach = (params[0], params[1], params[2],
                                                     params[3], params[4], params[5],
                                                     params[6])
    width, height, A, b, row_starts, e0, e1, _ = clr
    if pushing:
        v[0] += dt * (force[0] - damping * v[0]) / mass
        v[1] += dt * (force[1] - damping * v[1]) / mass
    else:
        v[0] += dt * (-damping * v[0]) / mass
        v[1] += dt * (-damping * v[1]) / mass
        if hypot(v[0], v[1]) < V_REST:
            v[0] = v[1] = 0.0
            return False
    speed = hypot(v[0], v[1])
    if speed > v_max:
        q = v_max / speed
        v[0] *= q
        v[1] *= q
        speed = v_max
    if speed > 1e-9:  # |v|^2 / a_max ahead, along v
        ax, ay = target[0] + v[0] / a_max, target[1] + v[1] / a_max
        if not _clear_at(ax / cell, ay / cell, width, height, reach, A, b, row_starts, e0, e1):
            q = max(0.0, 1.0 - a_max * dt / speed)
            v[0] *= q
            v[1] *= q
    mx, my = target[0] + dt * v[0], target[1] + dt * v[1]
    if _clear_at(mx / cell, my / cell, width, height, reach, A, b, row_starts, e0, e1):
        target[0], target[1] = mx, my
        deformation[0] += dt * v[0]
        deformation[1] += dt * v[1]
    else:
        v[0] = v[1] = 0.0
    return True
