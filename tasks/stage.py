"""The machinery the dm_control tasks share: a Physics the Environment steps one physics step
at a time, the body the episode runner sees while the Environment owns the physics, and the
human's push started as a phase of the base's decision step.

dm_control's contract: ``Environment.step`` calls ``task.before_step(action, physics)`` (the
task sets controls), ``physics.step(n_sub_steps)`` (the Environment advances the physics) and
``task.after_step(physics)``; ``control_timestep() = n_sub_steps * timestep``. Here
:meth:`Physics.step` advances each of its ``n_sub_steps`` through the task's ``substep``: the
robot's onboard loop (its controller, the pushed body's force, ``mj_step``, sensing, cue
detection and every ``on_substep`` hook: renderers and loggers see every physics step), so the
time an environment step advances is exactly ``control_timestep()``. A task may take the
steps as one run (``substeps``: ``navigate_control`` runs its drive on the base's compiled
steps, the same numbers).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from dm_control import mujoco as dm_mujoco

from pathpref.sim.body import MujocoBody
from pathpref.sim.force_cue import HumanPush
from pathpref.sim.kernel_parts import Slot
from pathpref.sim.mobile_base import MobileBase

#: time constant (s) of the low-pass force the observations carry
FORCE_TAU_S = 0.05


class Physics(dm_mujoco.Physics):
    """The scene's physics. With a task's ``substep`` attached, :meth:`step` runs it once per
    physics step (module docstring); without one it is dm_control's plain ``mj_step``."""

    substep: Callable[[], None] | None = None
    #: the task's runs of physics steps (``substeps(n)``: ``n`` steps, each as ``substep``
    #: would take it, on compiled steps where they apply); None: ``substep`` one at a time
    substeps: Callable[[int], None] | None = None
    #: the task drawn into every render (:class:`~.drawing.TaskDrawing`, a callable of an
    #: ``MjvScene``); None draws the physics only
    drawing: Callable[[object], None] | None = None

    def render(self, *args, scene_callback=None, **kwargs) -> np.ndarray:
        """dm_control's ``render`` with the task drawn into the scene (:attr:`drawing`, before
        the caller's own ``scene_callback``); depth and segmentation images show the physics
        only."""
        drawing = self.drawing
        if drawing is not None and not (kwargs.get("depth") or kwargs.get("segmentation")):
            given = scene_callback

            def scene_callback(physics, scn):
                drawing(scn)
                if given is not None:
                    given(physics, scn)

        return super().render(*args, scene_callback=scene_callback, **kwargs)

    def step(self, nstep: int = 1) -> None:
        """Advance ``nstep`` physics steps (each through the task's ``substep``)."""
        if self.substep is None:
            super().step(nstep)
            return
        with self.check_invalid_state():
            if self.substeps is not None:
                self.substeps(nstep)
                return
            for _ in range(nstep):
                self.substep()


class StagedBody(MujocoBody):
    """The robot as the :class:`~pathpref.episode.runner.EpisodeRunner` sees it when the
    Environment steps the physics: the MuJoCo body of ``--sim mujoco`` (its push sampling,
    pushes at any time, its cue stream into the runner's door, metrics) over a ``base`` the task
    built with :func:`~pathpref.sim.body.build_base` on the Environment's data; only two things
    differ: :meth:`move` reports the cell the base reached during the physics steps already
    taken, and :meth:`push` only starts the push phase of the base's decision step
    (:mod:`pathpref.sim.decision`), which the task advances over the coming physics steps
    (``on_push``: the task is told, e.g. to hold the cell)."""

    def __init__(self, world, spec, rng: np.random.Generator, base: MobileBase,
                 on_push: Callable[[HumanPush], None]):
        super().__init__(world, spec, rng, base=base)
        self.on_push = on_push
        #: the push :meth:`push` started last (None before the first)
        self.last_push: HumanPush | None = None
        self.cell = -1

    def push(self, heading: int) -> None:
        """Start a push toward ``heading`` (drawn as :meth:`MujocoBody.draw_push` draws it,
        from the body's stream); its cue, if any, is felt later."""
        self.last_push = push = self.draw_push(heading)
        self.on_push(push)

    def move(self, action: int) -> int:
        """The cell the base is in now (the physics has moved it already)."""
        self.cell = self.base.cell
        return self.cell


class ForceFilter:
    """A first-order low-pass of the push estimate the detector reads (N, world frame):
    ``f += (dt / (tau + dt)) (f_raw - f)`` at every physics step, ``tau = FORCE_TAU_S``."""

    def __init__(self, base: MobileBase):
        self.base = base
        self.alpha = base.dt / (FORCE_TAU_S + base.dt)
        self.f = np.zeros(2)
        s, d = base.sensing.sensor, base.data
        # views into MjData (its buffers stay put): the sensor's rotation and reading
        self._R = d.site_xmat[s.site].reshape(3, 3)[:2]
        self._reading = d.sensordata[s.adr:s.adr + 3]

    def update(self, raw: np.ndarray | None = None) -> None:
        """Feed this physics step's estimate: ``raw`` when the caller has it, else the raw
        sensor for the ideal model (as ``HandleSensor.force_xy``: minus the reading rotated
        into the world frame) or the estimator's output."""
        b = self.base
        if raw is None:
            raw = -(self._R.dot(self._reading)) if b.sensing.sensor_model is None else \
                b.sensing.force_estimate  # dot: the same gemv as ``@``, cheaper to call
        # on Python floats, element by element the same operations as ``f += a (raw - f)``
        f, a = self.f, self.alpha
        (r0, r1), (f0, f1) = np.asarray(raw, float).tolist(), f.tolist()
        f[0], f[1] = f0 + a * (r0 - f0), f1 + a * (r1 - f1)


class StepInteraction:
    """What the robot felt during one environment step (since the last observation), the
    observations that carry the step's interaction instead of an end-of-step snapshot:

    * ``push_felt`` = ``(peak_n, cos a, sin a, duration_s)`` of the strongest cue the
      detector read during the step (a :class:`~pathpref.episode.body.Felt` record of
      ``base.felt``: its peak force in N, its impulse's direction ``a`` in the world frame
      and how long the push lasted in s); zeros when none was read;
    * ``cues_felt``: the number of cues read during the step, per detected heading (0..7:
      N, NE, ..., NW);
    * ``detector_active_s``: physics seconds of the step during which the detector was
      active (a cue under way), ``dt`` per physics step it was.

    :meth:`start` begins a step, :meth:`update` follows every physics step."""

    def __init__(self, base: MobileBase):
        self.base = base
        self._from = len(base.felt)
        #: the state the compiled steps read and write in place: ``[active_s]``
        self.rec = np.zeros(1)
        self.active_s = 0.0

    #: physics seconds of the step with the detector active, in :attr:`rec`
    active_s = Slot(0)

    def start(self) -> None:
        """A new environment step: forget what the previous one felt."""
        self._from = len(self.base.felt)
        self.active_s = 0.0

    def update(self) -> None:
        """After a physics step: count it when the detector is active."""
        if self.base.sensing.detector.active:
            self.active_s += self.base.dt

    def felt(self) -> list:
        """The cue records read since :meth:`start` (all of them after a sensing reset)."""
        felt = self.base.felt
        return felt[self._from:] if len(felt) >= self._from else list(felt)

    def observation(self) -> dict[str, np.ndarray]:
        """``push_felt``, ``cues_felt`` and ``detector_active_s`` (class docstring)."""
        felt = self.felt() if len(self.base.felt) != self._from else ()
        push, counts = np.zeros(4), np.zeros(8)
        for f in felt:
            counts[f.heading] += 1.0
        strongest = max(felt, key=lambda f: f.peak_n or 0.0, default=None)
        if strongest is not None and strongest.peak_n is not None:
            a = strongest.angle
            push[:] = (strongest.peak_n, math.cos(a), math.sin(a), strongest.duration_s or 0.0)
        return {"push_felt": push, "cues_felt": counts,
                "detector_active_s": np.array([self.active_s])}
