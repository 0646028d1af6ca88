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

import numpy as np

from ..episode.body import Felt
from ..episode.physics import CELL_SIZE_M, GUIDANCE_MAX_EVIDENCE, GUIDANCE_PERIOD_S
from ..geometry.grid import heading_to_action

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
        #: the admittance moves the target (False: at rest, ``v = 0``)
        self.moving = False
        self.given = 0.0  # the evidence the cue under way has given (observations)

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
        c, dt, fits = base.controller, base.dt, base.scene.fits
        v, a_max = self.v, c.a_max
        if base.sensing.under_way:
            v += dt * (base.sensing.force_estimate - self.damping * v) / self.mass
        elif self.moving:
            v += dt * (-self.damping * v) / self.mass
            if math.hypot(v[0], v[1]) < V_REST:
                v[:] = 0.0
                self.moving = False
                return False
        else:
            return False
        self.moving = True
        speed = math.hypot(v[0], v[1])
        if speed > c.v_max:
            v *= c.v_max / speed
            speed = c.v_max
        if speed > 1e-9:
            ahead = base.target + v / a_max  # |v|^2 / a_max ahead, along v
            if not fits(ahead):
                v *= max(0.0, 1.0 - a_max * dt / speed)
        moved = base.target + dt * v
        if fits(moved):
            base.target = moved
            self.deformation += dt * v
        else:
            v[:] = 0.0
        return True

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
