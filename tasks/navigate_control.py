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

import numpy as np
from dm_env import specs

from pathpref.episode.spec import check_number
from pathpref.errors import ConfigError
from pathpref.geometry.grid import STAY
from pathpref.sim.body import build_base
from pathpref.sim.controller import HeldVelocity, TrackingController
from pathpref.sim.decision import PUSH
from pathpref.sim.mobile_base import MobileBase

from .navigate import Navigate
from .stage import Physics

#: control steps the task accepts (s): 10 to 50 Hz
CONTROL_TIMESTEPS = (0.02, 0.1)
CONTROL_TIMESTEP = 0.02


@dataclass(frozen=True)
class VelocityCommand(TrackingController):
    """The legacy base's onboard loop at control rate: a zero-order hold of the whole command
    over a control step, the agent's ``(vx, vy)`` and the yaw regulation ``wz = -k_yaw yaw``
    with the yaw at the step's start. The controller of the task's
    :class:`~pathpref.sim.mobile_base.MobileBase`."""

    #: the held command (vx, vy, wz); state, updated in place
    u: np.ndarray = field(default_factory=lambda: np.zeros(3), compare=False)
    #: the agent's velocity, not a target
    tracks_target: ClassVar[bool] = False

    def hold(self, v: np.ndarray, yaw: float = 0.0) -> None:
        """Hold ``v = (vx, vy)`` (m/s) and ``wz = -k_yaw yaw`` until the next call."""
        self.u[:2] = v
        self.u[2] = -self.k_yaw * yaw

    def command(self, pos: np.ndarray, yaw: float, target: np.ndarray) -> np.ndarray:
        """Actuator controls ``(vx, vy, wz)`` of this physics step: the held ones."""
        return self.u


#: the agent's velocity as the drive of a physical base follows it (the task's physics set;
#: :class:`~pathpref.sim.controller.HeldVelocity`): the differential-drive base turns toward
#: it, the physical arm's base follows it
CommandedVelocity = HeldVelocity


class NavigateControl(Navigate):
    """The ``navigate_control`` task (module docstring)."""

    decides = False

    def __init__(self, push_period_s: float | None = None, **kwargs: Any):
        super().__init__(**kwargs)
        ph = self.physics
        self.v_max = TrackingController().v_max if ph is None else ph.drive.v_max
        if push_period_s is not None and ph is not None and ph.human.timing != "decision":
            raise ConfigError(f"push_period_s sets the pushes of physics timing 'decision'; "
                              f"with timing {ph.human.timing!r} set physics interval_s")
        period = self.template.delta_t * self.decision_s if push_period_s is None \
            else push_period_s
        self.push_period_s = check_number("push_period_s", period, 1.0, 1000.0, integer=False)

    @property
    def time_limit_s(self) -> float:
        """The default time limit: ``T_max`` decisions' worth of physics."""
        return self.template.t_max * self.decision_s

    def make_base(self, data, rng: np.random.Generator) -> MobileBase:
        """The base with the agent's command held over each control step: without physics a
        plain :class:`~pathpref.sim.mobile_base.MobileBase` driven by :class:`VelocityCommand`,
        with physics the ``--sim mujoco`` body's base
        (:func:`~pathpref.sim.body.build_base`) driven by :class:`CommandedVelocity`."""
        if self.physics is None:
            self.command = VelocityCommand(v_max=self.v_max)
            return MobileBase(self.scene, controller=self.command, data=data)
        self.command = CommandedVelocity(v_max=self.v_max, a_max=self.physics.drive.a_max)
        return build_base(self.scene, self.template.robot, self.physics, rng, data=data,
                          controller=self.command)

    def initialize_episode(self, physics: Physics) -> None:
        """Draw the episode (as ``navigate``); the first push plays during the first steps,
        not in ``reset``."""
        self._next_push = 0.0
        self._plan: int | None = None
        self._plan_cue = None
        super().initialize_episode(physics)
        physics.substeps = self.substeps

    def _start_push(self, push) -> None:
        """The push phase of the base's decision step, while the agent keeps driving (the
        cell is not held)."""
        self.base.decision.push(push, hold=False)

    def substep(self) -> None:
        """One physics step: of the push phase while one plays, else of the agent's drive
        (every cue reaches the runner's door as it is read)."""
        d = self.base.decision
        if d.phase == PUSH:
            if d.advance():
                self._push_over()
        else:
            self.base.substep()
        self.filter.update()
        self.interaction.update()

    def substeps(self, n: int) -> None:
        """``n`` physics steps, each what :meth:`substep` does: where the base's compiled steps
        apply (:meth:`~pathpref.sim.coasting.Coaster.drive` outside a push phase: the
        realistic sensing chain idle, no contact; :meth:`~pathpref.sim.coasting.Coaster.push`
        through one), runs of them in one call with the force filter's and the interaction's
        updates, the same numbers; every other step through :meth:`substep`."""
        done, b = 0, self.base
        while done < n:  # every pass takes at least one physics step
            # (not while the base touches something: the kernel would hand every step back)
            coaster = b.coaster if b.data.ncon == 0 else None
            if coaster is not None and coaster.ready():
                if b.decision.phase == PUSH:
                    k, partial, ended = coaster.push(b.decision, n - done, self.filter,
                                                     self.interaction)
                    if ended:
                        self._push_over()
                else:
                    k, partial = coaster.drive(n - done, self.filter)
                done += k
                if partial:  # the step's task part after the base's (as substep)
                    self.filter.update()
                    self.interaction.update()
                if k:
                    continue
            self.substep()
            done += 1

    def _push_over(self) -> None:
        """The push phase ended: note how it was read (no hold: the agent drives)."""
        d, push = self.base.decision, self.body.last_push
        self.body.readings.append((push.intended_heading, -1 if d.cue is None else
                                   d.cue.heading, float("nan") if d.cue is None else
                                   float(self.base.data.time) - push.t0))

    def check_action(self, action) -> np.ndarray:
        """``action`` as ``(vx, vy)``, each clipped to ``[-v_max, v_max]``; a one-line
        ConfigError naming the shape or the range. The bound itself is accepted as every
        library writes it: a Gymnasium ``Box`` holds it in float32 (``float32(0.8)`` is
        ``0.800000011920929``) and PPO clips its actions to that, so a value within the
        float32 rounding of ``v_max`` is in range (and clipped to it)."""
        v = self.v_max
        bound = max(v, float(np.float32(v)))  # float32's rounding of it
        if type(action) is np.ndarray and action.dtype == np.float64 and action.shape == (2,):
            x, y = action.tolist()  # real, the right shape: only the range is left to check
            if abs(x) <= bound and abs(y) <= bound:  # (False for NaN)
                return np.array([min(max(x, -v), v), min(max(y, -v), v)])
            a = action
        else:
            a = self._parse_action(action)
        if not (np.isfinite(a).all() and (np.abs(a) <= bound).all()):
            raise ConfigError(f"action must be (vx, vy) with each in [-{self.v_max:g}, "
                              f"{self.v_max:g}] m/s, got {np.array2string(a, precision=3)}")
        return np.clip(a, -self.v_max, self.v_max)

    def _parse_action(self, action) -> np.ndarray:
        """``action`` as a float array of shape (2,); a one-line ConfigError naming a complex
        number or the shape."""
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
        return a

    def before_step(self, action, physics: Physics) -> None:
        """Hold the commanded velocity; start the human's push when one is due."""
        a = self._take_action(action)
        # the base's controller (the arm's IK target in carry_control)
        self.command.hold(a, float(self.base.data.qpos[self.base.yaw]))
        self._reward = 0.0
        self.interaction.start()
        if (self.base.decision.phase != PUSH
                and float(self.base.data.time) >= self._next_push - 1e-9
                and not self.runner.done and not self.runner.continuous):
            self._next_push += self.push_period_s
            self.runner.give_input()

    def after_step(self, physics: Physics) -> None:
        """A cell change is a step of the runner (success rule, goal, log) and earns the
        reward of its grid move."""
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
        """The base velocity ``(vx, vy)`` in m/s, each within ``+-v_max`` (bounds of the
        action's shape, as the suite's specs have them)."""
        return specs.BoundedArray(shape=(2,), dtype=np.float64, minimum=np.full(2, -self.v_max),
                                  maximum=np.full(2, self.v_max), name="base_velocity")

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

