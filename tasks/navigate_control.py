"""``navigate_control``: the ``navigate`` task at control rate, for agents that drive the base
themselves (reinforcement learning, a learned controller).

The agent commands the base's planar velocity ``(vx, vy)`` in m/s (world frame, each within
``+-v_max``, 0.8 m/s in the legacy physics) every ``control_timestep`` (0.02 s by default,
i.e. 50 Hz; any multiple of the 2 ms physics step from 0.02 to 0.1 s through
``environment_kwargs``); the base's
velocity actuators hold the command over the control step (a zero-order hold; the yaw is held
at zero by ``wz = -3 yaw``). The simulated human pushes the handle every ``push_period_s``
of simulated time (``delta_t`` decisions of ``decision_s``: the cadence of :mod:`.navigate`),
starting at once, from the cell the base is in, with a heading drawn from the human model; the
push acts in the physics while the agent drives, and the robot's detector, fed by the force
sensor at every physics step, reports the cue when it ends; the belief is updated then.

Observations: those of :mod:`.navigate` (``heading`` is the last detected cue, kept until the
next push starts; ``force`` and ``detector_active`` change within a push) plus the base's
velocity (m/s). Reward: at every cell change, :func:`pathpref.planning.pomdp.transition_reward`
of the grid move between the two cells (no move cost when they are not grid neighbours);
otherwise 0. The episode ends at the goal (discount 0), after ``T_max`` cell changes or at the
time limit, ``T_max * decision_s`` seconds by default (discount 1).

With ``physics`` (see :mod:`.navigate`) the base is the ``--sim mujoco`` body's and its drive
follows the agent's velocity within ``a_max`` (:class:`CommandedVelocity`), the action bound
is ``v_max``; ``timing`` other than ``decision`` pushes on the human's own clock instead of
every ``push_period_s`` (each cue reaches the belief in the next physics step; the corrective
human judges each cell change).

``env.task.policy_action()`` drives toward the cell the loaded method chooses (re-planned at
every cell change and cue) with the base's tracking law, so the task runs end to end.
"""

from __future__ import annotations

import collections
from dataclasses import dataclass, field
from typing import Any, ClassVar

import mujoco
import numpy as np
from dm_env import specs

from pathpref.episode.spec import check_number
from pathpref.errors import ConfigError, EpisodeError
from pathpref.geometry.grid import STAY
from pathpref.sim.body import build_base
from pathpref.sim.controller import ProfiledController, TrackingController
from pathpref.sim.mobile_base import MobileBase

from .navigate import PUSH, Navigate
from .stage import Physics, PushPhase

#: control steps the task accepts (s): 10 to 50 Hz
CONTROL_TIMESTEPS = (0.02, 0.1)
CONTROL_TIMESTEP = 0.02


class VelocityCommand:
    """The base's onboard loop at control rate: the agent's ``(vx, vy)`` held, the yaw
    regulated to zero (``wz = -k_yaw yaw``). It stands in for the tracking controller of
    :class:`~pathpref.sim.mobile_base.MobileBase` (the same ``command`` signature)."""

    def __init__(self, v_max: float, k_yaw: float = 3.0):
        self.v_max, self.k_yaw = v_max, k_yaw
        self.u = np.zeros(3)

    def hold(self, v: np.ndarray) -> None:
        """Hold ``v = (vx, vy)`` (m/s) until the next call."""
        self.u[:2] = v

    def command(self, pos: np.ndarray, yaw: float, target: np.ndarray) -> np.ndarray:
        """Actuator controls ``(vx, vy, wz)`` of this physics step."""
        self.u[2] = -self.k_yaw * yaw
        return self.u


@dataclass(frozen=True)
class CommandedVelocity(ProfiledController):
    """The agent's velocity as the drive of a physical base follows it (the task's physics
    set): the held command ``u[:2]`` is the goal velocity, reached within ``a_max`` by the
    profiled controller's ramp (``|dv| <= a_max dt`` per physics step), the yaw regulated to
    zero; the differential-drive base turns toward it, the physical arm's base follows it."""

    #: the held command (vx, vy, unused); state, updated in place
    u: np.ndarray = field(default_factory=lambda: np.zeros(3), compare=False)
    #: the agent's velocity, not a target: the diff-drive base turns toward it everywhere
    tracks_target: ClassVar[bool] = False

    def hold(self, v: np.ndarray) -> None:
        """Hold ``v = (vx, vy)`` (m/s) until the next call."""
        self.u[:2] = v

    def goal_xy(self, px: float, py: float, tx: float, ty: float) -> tuple[float, float]:
        """The held command (the position and target play no part)."""
        return float(self.u[0]), float(self.u[1])


class HeldCommandBase(MobileBase):
    """The planar base of the legacy physics at control rate: the actuator commands are set
    once per control step (:meth:`hold`, a zero-order hold of the agent's velocity and the yaw
    regulation) and a physics step is the push, ``mj_step``, the ideal sensor's force and the
    detector, and the hooks; a non-finite state is checked once per control step
    (:meth:`check_finite`). With physics the task's base is :func:`~pathpref.sim.body.
    build_base`'s, driven by :class:`CommandedVelocity`."""

    def __init__(self, scene, v_max: float, **kwargs: Any):
        self.command = VelocityCommand(v_max)
        super().__init__(scene, controller=self.command, **kwargs)
        d = self.data
        # views into MjData (its buffers stay put): the sensor's rotation and reading
        self._R = d.site_xmat[self.sensor.site].reshape(3, 3)[:2]
        self._reading = d.sensordata[self.sensor.adr:self.sensor.adr + 3]
        self._pushed = False

    def hold(self, v: np.ndarray) -> None:
        """Command ``v = (vx, vy)`` (m/s) and ``wz = -k_yaw yaw`` until the next call."""
        self.command.hold(v)
        self.data.ctrl[self.actuators] = self.command.command(None, float(
            self.data.qpos[self.yaw]), None)

    def substep(self, push=None):
        """One physics step (class docstring); the detected cue or None."""
        d = self.data
        if push is not None and push.active(float(d.time)):
            push.apply(d, self.pushed_body)
            self._pushed = True
        elif self._pushed and not self.external_forces:
            d.xfrc_applied[self.pushed_body, :] = 0.0
            self._pushed = False
        mujoco.mj_step(self.model, d)
        self.force_estimate = -(self._R @ self._reading)
        cue = self.detector.update(self.force_estimate)
        for hook in self.on_substep:
            hook(self, push)
        return cue

    def check_finite(self) -> None:
        """An EpisodeError when the simulation diverged (as ``MobileBase.substep`` checks)."""
        d = self.data
        if not (np.isfinite(d.qpos).all() and np.isfinite(d.qvel).all()):
            raise EpisodeError(f"simulation diverged at t = {d.time:.3f} s (non-finite state)")


class NavigateControl(Navigate):
    """The ``navigate_control`` task (module docstring)."""

    decides = False

    def __init__(self, push_period_s: float | None = None, **kwargs: Any):
        super().__init__(**kwargs)
        ph = self.physics
        self.v_max = TrackingController().v_max if ph is None else ph.v_max
        if push_period_s is not None and ph is not None and ph.timing != "decision":
            raise ConfigError(f"push_period_s sets the pushes of physics timing 'decision'; "
                              f"with timing {ph.timing!r} set physics interval_s")
        period = self.template.delta_t * self.decision_s if push_period_s is None \
            else push_period_s
        self.push_period_s = check_number("push_period_s", period, 1.0, 1000.0, integer=False)

    @property
    def time_limit_s(self) -> float:
        """The default time limit: ``T_max`` decisions' worth of physics."""
        return self.template.t_max * self.decision_s

    def make_base(self, data, rng: np.random.Generator) -> MobileBase:
        """The base with the agent's command held over each control step: the legacy
        :class:`HeldCommandBase`, or with physics the ``--sim mujoco`` body's base
        (:func:`~pathpref.sim.body.build_base`) driven by :class:`CommandedVelocity`."""
        if self.physics is None:
            base = HeldCommandBase(self.scene, self.v_max, data=data)
            self.command = base.command
            return base
        self.command = CommandedVelocity(v_max=self.v_max, a_max=self.physics.a_max)
        return build_base(self.scene, self.template.task, self.physics, rng, data=data,
                          controller=self.command)

    def initialize_episode(self, physics: Physics) -> None:
        """Draw the episode (as ``navigate``); the first push plays during the first steps,
        not in ``reset``."""
        self._next_push = 0.0
        self._plan: int | None = None
        self._plan_cue = None
        super().initialize_episode(physics)

    def _start_push(self, push) -> None:
        """The push plays while the agent keeps driving (no hold)."""
        self.push, self.phase = PushPhase(push, self.base), PUSH

    def substep(self) -> None:
        """One physics step: under the push when one plays, else driving."""
        b = self.base
        if self.push is not None:
            over, cue = self.push.substep(b)
            if over:
                self._end_push(cue)
        else:
            cue = b.substep()
            if cue is not None:
                b.cues_while_driving.append(cue)
                if self.body.human is not None and not self.runner.done:
                    self.runner.read_felt_inputs()  # a push at any time: the belief now
        self.filter.update(b.force_estimate if isinstance(b, HeldCommandBase) else None)

    def check_action(self, action) -> np.ndarray:
        """``action`` as ``(vx, vy)``; a one-line ConfigError naming the shape or the range."""
        if np.iscomplexobj(action) or any(isinstance(v, complex) for v in np.ravel(
                np.asarray(action, dtype=object))):
            raise ConfigError(f"action must be (vx, vy) in m/s, real numbers, got "
                              f"{repr(action)[:40]} (a complex number)")
        try:
            a = None if isinstance(action, str) else np.asarray(action, dtype=float)
        except (TypeError, ValueError):
            a = None
        if a is None or a.shape != (2,):
            shown = repr(action)[:40] if a is None else f"an array of shape {a.shape}"
            raise ConfigError(f"action must be (vx, vy) in m/s, shape (2,), got {shown}")
        if not (np.isfinite(a).all() and (np.abs(a) <= self.v_max + 1e-9).all()):
            raise ConfigError(f"action must be (vx, vy) with each in [-{self.v_max:g}, "
                              f"{self.v_max:g}] m/s, got {np.array2string(a, precision=3)}")
        return a

    def before_step(self, action, physics: Physics) -> None:
        """Hold the commanded velocity; start the human's push when one is due."""
        a = self.check_action(action)
        if isinstance(self.base, HeldCommandBase):
            self.base.hold(a)
        else:  # the arm (carry_control) reads the command for its IK target
            self.command.hold(a)
        self._reward = 0.0
        if (self.push is None and float(self.base.data.time) >= self._next_push - 1e-9
                and not self.runner.done and not self.runner.continuous):
            self._next_push += self.push_period_s
            self.runner.give_input()

    def after_step(self, physics: Physics) -> None:
        """A cell change is a step of the runner (success rule, goal, log) and earns the
        reward of its grid move."""
        if isinstance(self.base, HeldCommandBase):
            self.base.check_finite()
        r, cell = self.runner, self.base.cell
        if cell == r.cell:
            return
        before = r.cell
        hits = np.flatnonzero(self.world.motion.next_cell[before] == cell)
        a = int(hits[0]) if len(hits) and cell != before else STAY
        r.arrive(a, cell, r.pending_heading)
        self.body.cell = cell
        if self.body.human is not None and a != STAY:  # the corrective human judges the move
            self.body.human.robot_moves(before, a)
        self._reward = self._step_reward(before, cell, a)

    def action_spec(self, physics: Physics) -> specs.BoundedArray:
        """The base velocity ``(vx, vy)`` in m/s, each within ``+-v_max``."""
        return specs.BoundedArray(shape=(2,), dtype=np.float64, minimum=-self.v_max,
                                  maximum=self.v_max, name="base_velocity")

    def observation_spec(self, physics: Physics) -> collections.OrderedDict:
        """Navigate's observations plus the base's velocity."""
        obs = super().observation_spec(physics)
        obs["velocity"] = specs.Array((2,), np.float64, name="velocity")
        return obs

    def get_observation(self, physics: Physics) -> collections.OrderedDict:
        """Navigate's observations plus the base's velocity (m/s)."""
        obs = super().get_observation(physics)
        obs["velocity"] = self.base.velocity.copy()
        return obs

    def policy_action(self) -> np.ndarray:
        """Velocity toward the centre of the cell the loaded method chooses: planned again
        when the base reaches it, changes cell or a new cue arrives."""
        r, b = self.runner, self.base
        cue = r.pending_heading
        if self._plan is None or b.cell != self._plan_from or cue != self._plan_cue:
            a = int(r.policy.act(r.t + 1, r.cell, cue))
            self._plan_from, self._plan_cue = b.cell, cue
            self._plan = r.cell if a == STAY else int(self.world.motion.next_cell[r.cell, a])
        u = TrackingController(v_max=self.v_max).command(b.position, 0.0,
                                                         self.scene.cell_centre(self._plan))
        return np.clip(u[:2], -self.v_max, self.v_max)

