"""``carry``: deliver a tray held by the Jaco arm on the base to the unknown goal, by the
human's preferred path; the human pushes the tray (end-effector), as people pushed the arm
in Bajcsy et al.

Everything of :mod:`.navigate` (decision steps of ``decision_s`` physics seconds, actions,
observations, termination, seeding), with the arm driven by whole-body mink IK
(:mod:`pathpref.sim.arm`), plus: the reward subtracts ``TILT_PENALTY * mean(tilt^2)`` (tilt in
radians over the step's physics steps) and the observation adds the tray's tilt (degrees) and
position (m).
"""

from __future__ import annotations

import collections

import numpy as np
from dm_env import specs

from pathpref.sim.arm import ArmBase, tilt_deg

from .navigate import Navigate
from .navigate_control import NavigateControl, VelocityCommand
from .stage import Physics

TILT_PENALTY = 50.0


class Carry(Navigate):
    """The ``carry`` task (module docstring)."""

    def __init__(self, **kwargs):
        super().__init__(task="carry", **kwargs)

    def before_step(self, action, physics: Physics) -> None:
        """The navigate step's target; remember where this step's tilt samples start."""
        super().before_step(action, physics)
        self._tilt_start = len(self.base.tilts)

    def get_reward(self, physics: Physics) -> float:
        """The navigate reward minus the tilt penalty over the step's physics steps."""
        tilts = np.radians(self.base.tilts[self._tilt_start:])
        penalty = TILT_PENALTY * float(np.mean(np.square(tilts))) if len(tilts) else 0.0
        return super().get_reward(physics) - penalty

    def observation_spec(self, physics: Physics) -> collections.OrderedDict:
        """Navigate's observations plus the tray's tilt (0..180 degrees) and position."""
        obs = super().observation_spec(physics)
        obs["tray_tilt"] = specs.BoundedArray(shape=(1,), dtype=np.float64, minimum=0.0,
                                              maximum=180.0, name="tray_tilt")
        obs["tray_position"] = specs.Array(shape=(3,), dtype=np.float64, name="tray_position")
        return obs

    def get_observation(self, physics: Physics) -> collections.OrderedDict:
        """Navigate's observations plus the tray's tilt (degrees) and position (m)."""
        obs = super().get_observation(physics)
        b = self.base
        obs["tray_tilt"] = np.array([tilt_deg(b.data, b.tray)])
        obs["tray_position"] = b.data.xpos[b.tray].copy()
        return obs


class CarryControl(Carry, NavigateControl):
    """``carry_control``: :mod:`.navigate_control`'s control rate with the arm of ``carry``.
    The agent's velocity ``(vx, vy)`` becomes the whole-body IK's base target, led by one IK
    period (``target = p + v * ik_dt``: the IK's base velocity toward it is ``v``, within the
    base's 0.8 m/s limit); rewards and observations as ``navigate_control`` plus the tilt
    penalty and the tray's tilt and position of ``carry``."""

    def make_base(self, data, rng: np.random.Generator) -> ArmBase:
        """The arm base; the agent's command is held for the IK target (with physics the
        physical arm's base also follows it, :class:`.navigate_control.CommandedVelocity`)."""
        if self.physics is None:
            self.command = VelocityCommand(v_max=self.v_max)
            return ArmBase(self.scene, data=data)
        return NavigateControl.make_base(self, data, rng)

    def substep(self) -> None:
        """Lead the IK's base target by the commanded velocity, then the physics step."""
        b = self.base
        b.target = b.position + self.command.u[:2] * b.ik_dt
        super().substep()
