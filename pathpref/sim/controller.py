"""Tracking a target cell at physics rate with the base's velocity actuators.

A saturated proportional law on position, ``v = clip(k_p (p* - p), v_max)`` (norm-clipped), and
yaw held at zero. A decision step ends when the base has settled (position error below
``tol_m`` and speed below ``still_mps``) or after ``time_limit_s``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class TrackingController:
    """Proportional velocity tracking of a cell centre, saturated at ``v_max``; yaw held at 0.

    A move ends when the base is within ``tol_m`` of the target and slower than ``still_mps``,
    or after ``time_limit_s``."""
    kp: float = 4.0
    v_max: float = 0.8
    k_yaw: float = 3.0
    tol_m: float = 0.02
    still_mps: float = 0.05
    time_limit_s: float = 3.0

    def command(self, pos: np.ndarray, yaw: float, target: np.ndarray) -> np.ndarray:
        """Actuator controls ``(vx, vy, wz)``."""
        v = self.kp * (np.asarray(target) - pos)
        n = np.linalg.norm(v)
        if n > self.v_max:
            v *= self.v_max / n
        return np.array([v[0], v[1], -self.k_yaw * yaw])

    def settled(self, pos: np.ndarray, vel: np.ndarray, target: np.ndarray) -> bool:
        """Within ``tol_m`` of ``target`` and slower than ``still_mps``."""
        return (np.linalg.norm(np.asarray(target) - pos) < self.tol_m
                and np.linalg.norm(vel) < self.still_mps)
