"""Guidance (Bajcsy et al. 2017): a push deforms the base's motion while it lasts.

The admittance velocity ``v`` of ``M dv/dt + b v = F_hat`` moves the base's target
(``dp_target/dt = v``: the base keeps the deformation, it does not spring back) and is added
to the tracking command as its feedforward; ``v`` decays (time constant ``M / b``) once the
push is released. Every ``GUIDANCE_PERIOD_S`` of a cue under way a *partial*
:class:`~pathpref.episode.body.Felt` carries the direction of the force felt over that period
and its share of one observation (``period / GUIDANCE_EVIDENCE_S``, at most
``GUIDANCE_MAX_EVIDENCE`` per cue); the cue's final record carries the rest
(:mod:`pathpref.episode.physics`, "Guidance").
"""

from __future__ import annotations

import math

import numpy as np

from ..episode.body import Felt
from ..episode.physics import GUIDANCE_EVIDENCE_S, GUIDANCE_MAX_EVIDENCE, GUIDANCE_PERIOD_S
from ..geometry.grid import heading_to_action


class Guidance:
    """The guidance admittance ``(mass, damping)`` of one base and its state: the admittance
    velocity :attr:`v` and the evidence gathered since the last record."""

    def __init__(self, mass: float, damping: float):
        self.mass, self.damping = float(mass), float(damping)
        self.v = np.zeros(2)
        self.evidence = np.zeros(2)  # the impulse since the last evidence record (N s)
        self.evidence_s = 0.0  # its duration (s)
        self.given = 0.0  # the evidence the cue under way has given (observations)

    def reset(self) -> None:
        """A standing base: no admittance velocity, no evidence."""
        self.v[:] = 0.0
        self.evidence[:], self.evidence_s, self.given = 0.0, 0.0, 0.0

    def admit(self, base) -> None:
        """One step of ``v += dt (F_hat - b v) / M`` (explicit Euler; stable for
        ``dt < 2 M / b``: 0.5 s for the defaults against the 2 ms step) and of the target it
        deforms, ``p_target += dt v``. Safety: ``|v|`` is capped at the controller's
        ``v_max``; where the base would not fit (:meth:`.scene.Scene.fits`) within its
        stopping distance ahead, ``|v|^2 / a_max`` (braking at half ``a_max``: a push may
        oppose the drive), the admittance brakes at ``a_max``; the target never moves where
        the base does not fit, so a push cannot drive the base into an obstacle or a wall."""
        c, dt, fits = base.controller, base.dt, base.scene.fits
        v, a_max = self.v, c.a_max
        v += dt * (base.sensing.force_estimate - self.damping * v) / self.mass
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
        else:
            v[:] = 0.0

    def feel(self, force: np.ndarray, dt: float) -> bool:
        """Add one step's force to the evidence; whether a period is full."""
        self.evidence += force * dt
        self.evidence_s += dt
        return self.evidence_s >= GUIDANCE_PERIOD_S - 1e-9

    def take(self) -> tuple[float, float]:
        """The direction of the force felt since the last evidence record and its weight
        (module docstring); starts the next period (a cue's total is capped)."""
        e = self.evidence
        weight = min(self.evidence_s / GUIDANCE_EVIDENCE_S, GUIDANCE_MAX_EVIDENCE - self.given)
        angle = math.atan2(float(e[1]), float(e[0]))
        self.given += max(weight, 0.0)
        self.evidence[:], self.evidence_s = 0.0, 0.0
        return angle, max(weight, 0.0)

    def partial(self, cell: int, t0: float, t: float) -> Felt:
        """A partial record of the cue under way at ``cell`` (felt since ``t0``, now ``t``):
        not a cue, its evidence so far."""
        e = (float(self.evidence[0]), float(self.evidence[1]))
        angle, weight = self.take()
        return Felt(cell, heading_to_action(angle), t0, t, None, e, t - t0,
                    evidence=(angle, weight), partial=True)
