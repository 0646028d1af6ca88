"""The MuJoCo bodies of an episode (``--sim mujoco``): the robot observes a push through its
force sensor and moves by tracking cell centres at physics rate. Registered as ``mujoco`` in
the episode layer's body registry when :mod:`pathpref.sim` is imported.

* ``push(heading)``: the human's intended heading becomes a noisy half-sine push on the
  pushed body (the handle, or the tray of the ``carry`` arm); the robot observes the sector of
  the impulse its detector measured, or nothing if no cue was detected. The sampled heading
  and ``xfrc_applied`` are never read by the robot.
* ``move(action)``: the planner's target is the grid neighbour of SPEC 3 (the current cell when
  the grid move is blocked); the base drives there and the episode continues from the cell the
  base actually ends in.

Scenes are built once per process and map; each episode gets fresh ``MjData``.

With ``spec.physics`` set (:class:`~pathpref.episode.physics.Physics`) the body senses with the
chosen sensor model and detector thresholds, draws each push's strength, duration and shape
from the human model's distributions, and, unless the timing is ``decision``, takes the human
over: pushes come at any time (:mod:`.pushing_human`), the base yields and stops on a cue.
Every cue the base feels, in any phase, reaches the runner's door as it is felt
(:meth:`MujocoBody.connect`). An empty ``physics`` is the
legacy body, bit for bit.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..episode.body import Body, register_body
from ..episode.physics import CELL_SIZE_M, Physics
from ..errors import ConfigError
from ..geometry.grid import STAY
from ..geometry.world import World
from .arm import ArmBase
from .controller import ProfiledController, TrackingController
from .decision import RELEASE_WINDOW_S, move_limit, timed_steps
from .diffdrive import DiffDriveBase
from .force_cue import HumanPush, PushProfile
from .guiding_human import GuidingHuman
from .mobile_base import MobileBase
from .path_crossings import PathCrossings
from .path_record import PathRecorder
from .pushing_human import PushingHuman, sample_profile
from .robots import ROBOTS
from .scene import BaseParams, Scene


@lru_cache(maxsize=8)
def scene_for(world: World, cell_size: float = CELL_SIZE_M, task: str = "navigate",
              base: BaseParams | None = None, robot: str = "disk") -> Scene:
    """One compiled scene per world (worlds hash by identity), cell size, task, base and
    body (``robot``, :data:`~.robots.ROBOTS`: its scene for ``task``)."""
    if robot not in ROBOTS:
        raise ConfigError(f"unknown robot model '{robot}'; choose {', '.join(ROBOTS)}")
    if task not in ROBOTS[robot].scenes:
        raise ConfigError(f"unknown task '{task}'; choose "
                          f"{' or '.join(ROBOTS[robot].scenes)}")
    return ROBOTS[robot].scenes[task](world, cell_size, base)


class MujocoBody(Body):
    """The MuJoCo robot: the planar base for ``navigate``, the base with the Jaco arm and tray
    for ``carry``. ``scene``/``data`` reuse a compiled scene or a caller's ``MjData``; ``base``
    a base the caller built with :func:`build_base` (the dm_control tasks build theirs on
    their physics' data, with their own controller at control rate)."""

    tasks = ("navigate", "carry")
    #: its physics rate: ``navigate.xml``'s 2 ms timestep (``<option timestep>``)
    record_rate_hz = 500.0

    def __init__(self, world: World, spec, rng: np.random.Generator,
                 profile: PushProfile | None = None, cell_size: float | None = None,
                 scene: Scene | None = None, data=None, base: MobileBase | None = None):
        self.world = world
        self.rng = rng
        self.physics = physics = spec.physical
        self.delta_t = int(spec.delta_t)
        if base is None:
            params = None if physics is None else base_params(physics)
            if cell_size is None:  # the body's own scale
                cell_size = CELL_SIZE_M if physics is None else physics.cell_size_m
            robot = "disk" if physics is None else physics.drive.robot_model
            scene = scene or scene_for(world, cell_size, spec.robot, params, robot)
            base = build_base(scene, spec.robot, physics, rng, profile=profile, data=data)
        self.scene = base.scene
        self.base: MobileBase = base
        self.profile = self.base.profile
        self.human: PushingHuman | None = None
        #: the crossings along the path (guidance; None: a step is judged by its end cells)
        self.path: PathCrossings | None = None
        #: decision-timing pushes: (intended heading, detected heading or -1, latency s)
        self.readings: list[tuple[int, int, float]] = []
        #: decision-timing pushes as drawn (:meth:`effort_metrics`)
        self.pushes_given: list[HumanPush] = []
        #: the continuous path's sampler (:meth:`record_path`; None: not recorded)
        self.path_recorder: PathRecorder | None = None

    def reset(self, cell: int) -> None:
        """Reset the physics with the base at the centre of ``cell``."""
        self.base.reset(cell)
        self.cell = cell
        if self.path is not None:
            self.path.reset(cell)
        if self.path_recorder is not None:
            self.path_recorder.reset()

    def record_path(self, hz: float) -> None:
        """Sample the base's pose, the end effector and the applied force at least ``hz``
        times per simulated second from the next reset on (:mod:`.path_record`)."""
        if self.path_recorder is None:
            self.path_recorder = PathRecorder(self.base, hz)
            self.path_recorder.attach()

    def recorded_path(self) -> list[tuple]:
        """The samples since the last reset, the last one now (:mod:`.path_record`)."""
        return [] if self.path_recorder is None else self.path_recorder.take()

    def path_crossings(self) -> list[tuple[int, int, bool]] | None:
        """Guidance: the polytope crossings along the path since the last call, labelled
        person-led or not (:mod:`.path_crossings`); else None."""
        return None if self.path is None else self.path.take()

    def attach_human(self, heading_at, probs, watch=None) -> bool:
        """Take the human over when the physics' timing is not ``decision`` (pushes at any
        time, :mod:`.pushing_human`); the human's own stream is a child of the body's. A
        guided episode's person takes the handle when ``watch`` (the episode's corrective
        rule, :class:`~pathpref.episode.corrective.CorrectiveHuman`) says the robot errs, else
        on the clock."""
        self.probs = probs
        if self.physics is None or self.physics.human.timing == "decision":
            return False
        drive, human = self.physics.drive, self.physics.human
        person = PushingHuman
        if human.timing == "guidance":
            self.enable_guidance()
            person = GuidingHuman if human.guide == "closed" else PushingHuman
        else:
            self.base.enable_pushes_any_time(drive.admittance_b)
        self.human = person(human, self.rng.spawn(1)[0], self.delta_t, heading_at, probs,
                            self.physics.step_s(self.scene.cell_size),
                            watch=watch if human.timing == "guidance" else None)
        self.human.attach(self.base)
        return True

    def enable_guidance(self) -> None:
        """The base complies to pushes with the drive's guidance admittance and the path is
        judged along the way (:mod:`.guidance`, :mod:`.path_crossings`)."""
        drive = self.physics.drive
        self.base.enable_guidance(drive.admittance_m, drive.admittance_b)
        self.path = PathCrossings(self.base, self.world)
        self.base.on_substep.append(self.path)

    def guided_move(self, target: int) -> int:
        """The guided decision step of every door (:mod:`.decision`): a timed move toward the
        centre of ``target`` lasting exactly ``Physics.step_s``; the cell the base ends in."""
        step = self.physics.step_s(self.scene.cell_size)
        self.base.decision.move(target, _guided_limit(self.physics, self.scene.cell_size, step,
                                                      self.base.dt),
                                steps=timed_steps(step, self.base.dt)).run()
        self.cell = self.base.cell
        return self.cell

    @property
    def last_cue(self):
        """The last cue the base felt (a :class:`~pathpref.episode.body.Felt`), None before
        the first."""
        return self.base.felt[-1] if self.base.felt else None

    def connect(self, observe) -> None:
        """Every cue the base feels goes to ``observe`` (the runner's door) as it is felt
        (:mod:`.mobile_base`, one cue stream)."""
        self.observe = observe
        self.base.listener = observe

    def _confidence(self, heading: int) -> float:
        """The human's confidence in ``heading`` at the current cell: its probability over
        the most likely heading's (1 when the human model is not known)."""
        probs = getattr(self, "probs", None)
        if probs is None:
            return 1.0
        q = probs(self.base.cell)
        return float(q[heading] / q.max())

    def inputs_given(self) -> int:
        """Pushes the simulated human has begun."""
        return 0 if self.human is None else len(self.human.given)

    def draw_push(self, heading: int) -> HumanPush:
        """The human's push toward ``heading``, starting now: the legacy fixed profile, or
        strength and duration drawn from the physics' human model (:func:`sample_profile`),
        then the profile's angle noise, all from the body's stream."""
        profile = self.profile if self.physics is None else \
            sample_profile(self.physics.human, self.rng, self._confidence(heading))
        return HumanPush.sample(heading, float(self.base.data.time), profile, self.rng)

    def push(self, heading: int) -> None:
        """Push toward ``heading`` (:meth:`draw_push`) while the base holds its cell (the push
        phase run to completion); its cue reaches the runner's door when it is read."""
        push = self.draw_push(heading)
        self.pushes_given.append(push)
        cue = self.base.receive_push(push)
        self.cell = self.base.cell
        self.readings.append((heading, -1 if cue is None else cue.heading,
                              float("nan") if cue is None else
                              float(self.base.data.time) - push.t0))

    def metrics(self) -> dict[str, float]:
        """Simulated time, and the base's own measurements (tilt, penetration for the arm)."""
        out = {"sim_time_s": float(self.base.data.time), **self.base.metrics()}
        if self.physics is not None:
            out.update(self.base.physical_metrics())
            out.update(self.cue_metrics())
            out.update(self.effort_metrics())
        return out

    def effort_metrics(self) -> dict[str, float]:
        """What the person's pushes cost them (the effort measures of pHRI studies), summed
        over every push of the episode on the physics steps it acted at
        (:meth:`~.force_cue.HumanPush.effort`; a guiding push as the person set it, step by
        step): ``person_impulse_ns`` (``integral |F| dt``, N s), ``person_peak_n`` (the
        largest ``|F|``, N) and ``person_contact_s`` (the time a hand pushed, s; two pushes
        that overlap count their overlap twice)."""
        given = self.pushes_given if self.human is None else self.human.given
        t_end, dt = float(self.base.data.time), float(self.base.dt)
        impulse = peak = contact = 0.0
        for p in given:
            j, top, c = p.effort(dt, t_end)
            impulse, peak, contact = impulse + j, max(peak, top), contact + c
        return {"person_impulse_ns": impulse, "person_peak_n": peak,
                "person_contact_s": contact}

    def cue_metrics(self) -> dict[str, float]:
        """How the robot read the human's pushes (episodes with physical parameters):

        * ``pushes``: pushes the human made;
        * ``pushes_missed``: pushes that gave no cue (decision timing: the detector stayed
          silent; pushes at any time: no cue was first felt while the push acted or within
          the detector's release window after it);
        * ``pushes_misread``: cues whose heading is not the heading the human meant (with
          pushes at any time: of the push that was acting, or last began, when the cue was
          first felt; a false cue with no push before it counts too);
        * ``cue_latency_ms``: mean time from a push's start to its cue (absent without a cue:
          the stored JSON holds no NaN);
        * with pushes at any time also ``cues_felt`` and ``cue_hits`` (cues read right)."""
        if self.human is None:
            pushes = len(self.readings)
            missed = sum(d < 0 for _, d, _ in self.readings)
            misread = sum(d >= 0 and d != h for h, d, _ in self.readings)
            lat = [t for _, d, t in self.readings if d >= 0]
            out = {"pushes": float(pushes), "pushes_missed": float(missed),
                   "pushes_misread": float(misread)}
        else:
            given, felt = self.human.given, self.base.felt
            hits, lat = 0, []
            for f in felt:
                began = [p for p in given if p.t0 <= f.t_felt + 1e-9]
                hits += bool(began) and began[-1].intended_heading == f.heading
                if began:
                    lat.append(f.t_cue - began[-1].t0)
            window = RELEASE_WINDOW_S
            missed = sum(not any(p.t0 - 1e-9 <= f.t_felt <= p.t0 + p.profile.duration_s + window
                                 for f in felt) for p in given)
            out = {"cues_felt": float(len(felt)), "cue_hits": float(hits),
                   "pushes": float(len(given)), "pushes_missed": float(missed),
                   "pushes_misread": float(len(felt) - hits)}
        if lat:
            out["cue_latency_ms"] = 1e3 * float(np.mean(lat))
        return out

    def move(self, action: int) -> int:
        """Drive to the grid neighbour of SPEC 3; the cell the base ends in. When the human
        pushes on a clock of its own (pushes at any time) a decision step lasts the one rule's
        ``Physics.step_s`` (the base holds its target for the rest of it), so ``delta_t`` steps
        are ``delta_t`` of the human's nominal steps, as in the dm_control tasks; a cue ends
        it early (the planner replans)."""
        target = self.cell if action == STAY else int(self.world.motion.next_cell[self.cell,
                                                                                  action])
        if self.human is None:
            self.cell = self.base.move_to(target)
            return self.cell
        self.cell = self.base.cell
        self.human.robot_moves(self.cell, None if target == self.cell else action)
        step = self.physics.step_s(self.scene.cell_size)
        if self.physics.human.timing == "guidance":  # the one guided step of every door
            return self.guided_move(target)
        if target == self.cell:
            self.cell = self.base.hold(step)
        else:
            self.cell = self.base.move_to(target, min_s=step)
        return self.cell


def _guided_limit(physics: Physics, cell_size: float, step_s: float, dt: float) -> float:
    """The drive's limit within a guided step of ``step_s`` (:func:`.decision.move_limit`)."""
    return move_limit(physics.move_limit_s(cell_size), step_s, physics.push_window_s(), dt)


def build_base(scene: Scene, task: str, physics: Physics | None, rng: np.random.Generator,
               profile: PushProfile | None = None, data=None,
               controller: TrackingController | None = None) -> MobileBase:
    """The robot's base for ``task`` in ``scene`` as ``physics`` makes it (None: legacy, the
    original base and controller, ideal sensor). With physics: the sensor model, its faults
    and the detector thresholds (:func:`sensing_kwargs`, the faults drawn from a child of
    ``rng``), ``controller`` or a :class:`~.controller.ProfiledController` within ``v_max``
    and ``a_max``, the differential-drive base for ``base="diffdrive"``, the physical arm
    (``ArmBase(physical=True)``) for ``carry``, and the base's measurements on. The one
    construction :class:`MujocoBody` and the dm_control tasks share; ``scene`` must be built
    with :func:`base_params` of the same physics (:func:`scene_for`)."""
    kwargs: dict = {} if controller is None else {"controller": controller}
    if physics is not None:
        kwargs = {**sensing_kwargs(physics, rng), "controller": controller or
                  ProfiledController(v_max=physics.drive.v_max, a_max=physics.drive.a_max,
                                     time_limit_s=physics.move_limit_s(scene.cell_size))}
    if task == "carry":
        if physics is not None:
            kwargs["physical"] = True
            kwargs["stiffness"] = physics.drive.arm_stiffness
            kwargs["arm"] = ROBOTS[physics.drive.robot_model].arm
        base: MobileBase = ArmBase(scene, profile=profile, data=data, **kwargs)
    elif physics is not None and physics.drive.kind == "diffdrive":
        base = DiffDriveBase(scene, profile=profile, data=data, **kwargs)
    else:
        base = MobileBase(scene, profile=profile, data=data, **kwargs)
    base.measure = physics is not None
    return base


def base_params(physics: Physics) -> BaseParams:
    """The physical base of ``physics``'s drive (kind, mass, floor friction, actuator force
    limit)."""
    d = physics.drive
    return BaseParams(kind=d.kind, mass_kg=d.mass_kg, force_limit_n=d.force_limit_n,
                      friction_n=d.friction_n)


def sensing_kwargs(physics: Physics, rng: np.random.Generator) -> dict:
    """The base's sensing settings from ``physics``: the sensor preset with its overrides,
    the body's generator and the detector thresholds."""
    from dataclasses import replace

    from .sensing import SensorModel

    s = physics.sensing
    model = getattr(SensorModel, s.sensor)()
    over = {k: v for k, v in (("noise_n", s.sensor_noise_n), ("bias_n", s.sensor_bias_n),
                              ("drift_n_per_sqrt_s", s.sensor_drift_n)) if v >= 0}
    if s.sensor_thermal_n > 0:
        over["thermal_n"] = s.sensor_thermal_n
    model = replace(model, **over)
    return {"sensor_model": model, "rng": rng, "detector": s.detector}


register_body("mujoco", MujocoBody)
