"""``carry``: deliver a tray held by the Jaco arm on the base to the unknown goal, by the
human's preferred path; the human pushes the tray (end-effector), as people pushed the arm
in Bajcsy et al.

Everything of :mod:`navigate` (actions, observations, termination, seeding), with the arm
driven by whole-body mink IK (:mod:`pathpref.sim.arm`), plus: the reward subtracts
``TILT_PENALTY * tilt^2`` (tilt in radians, RMS over the step's physics steps) and the
observation adds the tray's tilt (degrees) and position (m).
"""

from __future__ import annotations

import collections

import numpy as np
from dm_env import specs

from .navigate import Navigate, Physics, environment

TILT_PENALTY = 50.0


class Carry(Navigate):
    """The ``carry`` task (module docstring)."""

    def __init__(self, **kwargs):
        super().__init__(task="carry", **kwargs)

    def before_step(self, action, physics: Physics) -> None:
        """The navigate step, minus the tilt penalty over its physics steps."""
        base = self.runner.body.base
        start = len(base.tilts)
        super().before_step(action, physics)
        tilts = np.radians(base.tilts[start:]) if len(base.tilts) > start else np.zeros(1)
        self._reward -= TILT_PENALTY * float(np.mean(np.square(tilts)))

    def observation_spec(self, physics: Physics) -> collections.OrderedDict:
        """Navigate's observations plus the tray's tilt and position."""
        obs = super().observation_spec(physics)
        obs["tray_tilt"] = specs.Array(shape=(1,), dtype=np.float64, name="tray_tilt")
        obs["tray_position"] = specs.Array(shape=(3,), dtype=np.float64, name="tray_position")
        return obs

    def get_observation(self, physics: Physics) -> collections.OrderedDict:
        """Navigate's observations plus the tray's tilt (degrees) and position (m)."""
        obs = super().get_observation(physics)
        base = self.runner.body.base
        from pathpref.sim.arm import tilt_deg

        obs["tray_tilt"] = np.array([tilt_deg(base.data, base.tray)])
        obs["tray_position"] = base.data.xpos[base.tray].copy()
        return obs


def load(map: str = "simple", method: str = "path_preference", delta_t: int = 5, seed: int = 0,
         **kwargs):
    """The ``carry`` environment (see module docstring)."""
    return environment(Carry(map=map, method=method, delta_t=delta_t, seed=seed, **kwargs))
