"""The machinery the dm_control tasks share: a Physics the Environment steps one physics step
at a time, the body the episode runner sees while the Environment owns the physics, and the
human's push as a phase of substeps.

dm_control's contract: ``Environment.step`` calls ``task.before_step(action, physics)`` (the
task sets controls), ``physics.step(n_sub_steps)`` (the Environment advances the physics) and
``task.after_step(physics)``; ``control_timestep() = n_sub_steps * timestep``. Here
:meth:`Physics.step` advances each of its ``n_sub_steps`` through the task's ``substep``: the
robot's onboard loop (its controller, the pushed body's force, ``mj_step``, sensing, cue
detection and every ``on_substep`` hook: renderers and loggers see every physics step), so the
time an environment step advances is exactly ``control_timestep()``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from dm_control import mujoco as dm_mujoco

from pathpref.sim.body import MujocoBody
from pathpref.sim.force_cue import HumanPush
from pathpref.sim.mobile_base import RELEASE_WINDOW_S, MobileBase

#: time constant (s) of the low-pass force the observations carry
FORCE_TAU_S = 0.05


class Physics(dm_mujoco.Physics):
    """The scene's physics. With a task's ``substep`` attached, :meth:`step` runs it once per
    physics step (module docstring); without one it is dm_control's plain ``mj_step``."""

    substep: Callable[[], None] | None = None

    def step(self, nstep: int = 1) -> None:
        """Advance ``nstep`` physics steps (each through the task's ``substep``)."""
        if self.substep is None:
            super().step(nstep)
            return
        with self.check_invalid_state():
            for _ in range(nstep):
                self.substep()

    def base_position(self) -> np.ndarray:
        """The base's planar position (m), read from the joints ``slide_x``, ``slide_y``."""
        return self.named.data.qpos[["slide_x", "slide_y"]].copy()


class StagedBody(MujocoBody):
    """The robot as the :class:`~pathpref.episode.runner.EpisodeRunner` sees it when the
    Environment steps the physics: the MuJoCo body of ``--sim mujoco`` (its push sampling,
    pushes at any time, felt cues and metrics) over a ``base`` the task built with
    :func:`~pathpref.sim.body.build_base` on the Environment's data; only two things differ:
    :meth:`move` reports the cell the base reached during the physics steps already taken,
    and :meth:`human_input` hands the human's push to the task (``on_input``), which plays it
    over the coming physics steps and reports the detected cue through
    ``EpisodeRunner.receive_input``."""

    def __init__(self, world, spec, rng: np.random.Generator, base: MobileBase,
                 on_input: Callable[[HumanPush], None]):
        super().__init__(world, spec, rng, base=base)
        self.on_input = on_input
        #: the push :meth:`human_input` started last (None before the first)
        self.last_push: HumanPush | None = None
        self.cell = -1

    def human_input(self, heading: int) -> None:
        """Start a push toward ``heading`` (drawn as :meth:`MujocoBody.draw_push` draws it,
        from the body's stream); nothing is observed yet."""
        self.last_push = push = self.draw_push(heading)
        self.on_input(push)
        return None

    def move(self, action: int) -> int:
        """The cell the base is in now (the physics has moved it already)."""
        self.cell = self.base.cell
        return self.cell


class PushPhase:
    """A push in progress: it acts for its profile's duration and the detector may release
    up to ``RELEASE_WINDOW_S`` after it (as in ``MobileBase.receive_push``); it ends at the
    first detected cue or then."""

    def __init__(self, push: HumanPush, base: MobileBase):
        push.t0 = float(base.data.time)
        self.push = push
        self.end = push.t0 + push.profile.duration_s + RELEASE_WINDOW_S
        base.last_onset_s = None

    def substep(self, base: MobileBase):
        """One physics step under the push; ``(over, cue)``."""
        cue = base.substep(self.push)
        if base.last_onset_s is None and base.detector.active:
            base.last_onset_s = float(base.data.time) - self.push.t0
        return cue is not None or base.data.time >= self.end, cue


class ForceFilter:
    """A first-order low-pass of the push estimate the detector reads (N, world frame):
    ``f += (dt / (tau + dt)) (f_raw - f)`` at every physics step, ``tau = FORCE_TAU_S``."""

    def __init__(self, base: MobileBase):
        self.base = base
        self.alpha = base.dt / (FORCE_TAU_S + base.dt)
        self.f = np.zeros(2)
        s, d = base.sensor, base.data
        # views into MjData (its buffers stay put): the sensor's rotation and reading
        self._R = d.site_xmat[s.site].reshape(3, 3)[:2]
        self._reading = d.sensordata[s.adr:s.adr + 3]

    def update(self, raw: np.ndarray | None = None) -> None:
        """Feed this physics step's estimate: ``raw`` when the caller has it, else the raw
        sensor for the ideal model (as ``HandleSensor.force_xy``: minus the reading rotated
        into the world frame) or the estimator's output."""
        b = self.base
        if raw is None:
            raw = -(self._R @ self._reading) if b.sensor_model is None else b.force_estimate
        self.f += self.alpha * (raw - self.f)
