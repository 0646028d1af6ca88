"""A differential-drive base (``--base diffdrive``): it drives along its heading and turns in
place, it cannot move sideways (the scene's lateral grip, :func:`.scene.apply_base`).

Control, per physics step, from the planar velocity ``v`` the holonomic law would command
(:class:`~.controller.ProfiledController`'s goal toward the target, or the admittance while a
cue is under way): the heading error ``e = wrap(atan2(v) - yaw)``, taken to the nearer of
forward and reverse (``|e| > 90`` degrees drives backwards with ``e - 180``); turn rate
``w = clip(k_turn e, min(w_max, a_max / |v_fwd|))`` (the turn's centripetal acceleration
``|v_fwd| w`` stays within ``a_max``); forward speed ``|v| cos(e)`` when ``|e| < 0.25`` rad
(14 degrees), else 0 (turn first), ramped by at most ``a_max dt`` per step. Within
``near_m`` (5 cm) of the target the base no longer turns (the heading of a tiny error is
meaningless) and closes the rest along its heading; a controller that does not track a target
(``tracks_target`` False: an agent's velocity command at control rate) is followed everywhere.
Where a person moves the base (a yield, guidance) and on a move off the grid's clear moves
(:attr:`.mobile_base.MobileBase.keep_clear`), the forward speed passes the safety filter
(:mod:`.keep_clear`) along the heading.
"""

from __future__ import annotations

import math

import numpy as np

from .keep_clear import keep_clear_xy
from .mobile_base import MobileBase


def wrap(angle: float) -> float:
    """``angle`` in ``(-pi, pi]``."""
    return float((angle + np.pi) % (2.0 * np.pi) - np.pi)


class DiffDriveBase(MobileBase):
    """The base of a scene built with ``BaseParams(kind="diffdrive")`` (module docstring);
    ``controller`` should be a :class:`~.controller.ProfiledController` (its ``a_max``)."""

    ACTUATORS = ("drive", "grip", "wz")
    k_turn = 4.0
    w_max = 1.5  # rad/s
    near_m = 0.05  # within this of the target the base stops turning
    drive_within = 0.25  # rad: drive only when the heading error is below this (turn first)

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.forward = 0.0  # the last forward-speed command (m/s)

    def _reset_control(self) -> None:
        super()._reset_control()
        self.forward = 0.0

    def _base_command(self) -> np.ndarray:
        d, c = self.data, self.controller
        pos, yaw = d.qpos[self.xy], float(d.qpos[self.yaw])
        if self.yielding():
            v = self.admittance_velocity()
        else:
            self._anchor = None
            v = c.goal_velocity(pos, self.target)
        speed = math.hypot(v[0], v[1])
        fwd_goal, w = 0.0, 0.0
        near = c.tracks_target and not self.yielding() and \
            math.hypot(self.target[0] - pos[0], self.target[1] - pos[1]) < self.near_m
        if near and speed > 1e-3:  # the last centimetres: along the heading, no turning
            fwd_goal = float(v[0] * math.cos(yaw) + v[1] * math.sin(yaw))
        elif speed > 1e-3:
            e = wrap(math.atan2(v[1], v[0]) - yaw)
            sign = 1.0
            if abs(e) > np.pi / 2:
                e, sign = wrap(e - np.pi), -1.0
            # turning while driving accelerates the base by |v| w: keep it within a_max
            w_lim = min(self.w_max, c.a_max / max(abs(self.forward), 1e-6))
            w = max(-w_lim, min(w_lim, self.k_turn * e))
            if abs(e) < self.drive_within:
                fwd_goal = sign * speed * math.cos(e)
        step = c.a_max * self.dt
        self.forward += max(-step, min(step, fwd_goal - self.forward))
        if self.keep_clear or self.guidance is not None or self.yielding():
            self.forward = self._kept_clear(pos, yaw, c.a_max)
        return np.array([self.forward, 0.0, w])

    def _kept_clear(self, pos, yaw: float, a_max: float) -> float:
        """The forward speed the safety filter allows (:mod:`.keep_clear`, braking at half
        ``a_max`` as the holonomic base): the planar velocity ``forward (cos yaw, sin yaw)``
        filtered, then taken along the heading (the drive cannot move sideways); a speed the
        filter did not lower is kept, one it lowered (or reversed, to back out) is the
        filtered velocity's component along the heading."""
        cy, sy = math.cos(yaw), math.sin(yaw)
        sc = self.scene
        vx, vy = keep_clear_xy(float(pos[0]), float(pos[1]), self.forward * cy,
                               self.forward * sy, sc.cell_size, sc.radius_m, 0.5 * a_max,
                               sc.clearance.arrays, sc.clearance.near_rows)
        along = vx * cy + vy * sy
        return along if abs(along) < abs(self.forward) or along * self.forward < 0.0 \
            else self.forward
