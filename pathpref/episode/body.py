"""The robot's body in an episode: how the human's input reaches the robot and how a move is
carried out. A :class:`Body` is a plug-in: the grid body lives here; a simulator package
registers its own with :func:`register_body` when it is imported, so this layer never names a
simulator.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .. import plugins
from ..errors import ConfigError
from ..geometry.grid import STAY
from ..geometry.world import World

if TYPE_CHECKING:
    from .spec import EpisodeSpec


@dataclass(frozen=True)
class Felt:
    """One cue the robot felt, the record every body gives the episode runner's one door
    (:meth:`~pathpref.episode.runner.EpisodeRunner.observe`): the ``cell`` it was felt in, its
    ``heading`` (0..7), when it was first felt and when it was read (``t_felt``, ``t_cue``:
    simulated s) and its force profile (``peak_n`` in N, ``impulse`` in N s, world x-y,
    ``duration_s``); a grid body's cue has no force (None).

    A sustained push (guidance, :mod:`.physics`) is also read while it lasts: ``partial``
    records of a cue under way, and its final record, carry ``evidence`` ``(angle, weight)``:
    the direction (radians) of the force felt since the last record and the share of one
    observation it is worth; the belief takes them as force directions instead of the
    heading. A partial record is not a cue: it neither counts nor sets the next heading."""

    cell: int
    heading: int
    t_felt: float = 0.0
    t_cue: float = 0.0
    peak_n: float | None = None
    impulse: tuple[float, float] | None = None
    duration_s: float | None = None
    evidence: tuple[float, float] | None = None
    partial: bool = False

    @property
    def angle(self) -> float | None:
        """The impulse's direction (radians, counter-clockwise from +x); None without one."""
        return None if self.impulse is None else math.atan2(self.impulse[1], self.impulse[0])


#: one sample of a recorded path (:meth:`Body.recorded_path`): simulated time (s since the
#: episode's reset), the base's pose (x, y in m in the scene's world frame; yaw in rad), the
#: end effector's position (m; None for a body without one) and the force the human applies
#: to the robot at that moment (world x-y, N; 0 while nobody pushes)
PATH_FIELDS = ("time_s", "x", "y", "yaw", "ee_x", "ee_y", "ee_z", "fx", "fy")


class Body(ABC):
    """An embodiment of the robot. Built per episode with ``(world, spec, rng)``, where
    ``rng`` is the episode's simulator stream (:func:`simulator_rng`).

    Attributes:
        tasks: the tasks this body can run (``navigate``; ``carry`` needs an arm).
    """

    tasks: tuple[str, ...] = ("navigate",)
    #: the most samples per simulated second :meth:`record_path` takes (its physics rate);
    #: 0: the body has no continuous path (:func:`check_runnable`)
    record_rate_hz: float = 0.0
    #: the episode runner's door (:meth:`connect`): every cue the robot feels goes there
    observe: Callable[[Felt], None] = staticmethod(lambda felt: None)

    def connect(self, observe: Callable[[Felt], None]) -> None:
        """Give every cue the robot feels from now on to ``observe`` (the runner's door), at
        the moment it is felt."""
        self.observe = observe

    @abstractmethod
    def reset(self, cell: int) -> None:
        """Place the robot at the centre of ``cell``."""

    @abstractmethod
    def push(self, heading: int) -> None:
        """The human pushes toward ``heading`` (0..7) now; what the robot feels reaches
        :attr:`observe` (nothing when it detected nothing). A body whose physics is advanced
        by someone else (the dm_control tasks) only starts the push here."""

    @abstractmethod
    def move(self, action: int) -> int:
        """Carry out ``action`` (0..7 or :data:`STAY`) from the current cell; return the
        cell the robot ends in."""

    def metrics(self) -> dict[str, float]:
        """Per-episode measurements stored with the result (none by default)."""
        return {}

    def attach_human(self, heading_at: Callable[[int], int],
                     probs: Callable[[int], np.ndarray], watch=None) -> bool:
        """Offer to give the human's inputs at times of the body's own (pushes at any time):
        ``heading_at(cell)`` draws the human's heading at a cell, ``probs(cell)`` is its
        distribution; ``watch`` the episode's corrective rule (a
        :class:`~.corrective.CorrectiveHuman`, guided episodes: the guiding person takes the
        handle when it says the robot errs; None: on the clock). True when the body took them
        over; then the runner gives no inputs at decision steps. False by default."""
        return False

    def inputs_given(self) -> int:
        """How many inputs the human has given (bodies that took the human over)."""
        return 0

    def record_path(self, hz: float) -> None:
        """Record the robot's continuous path from the next :meth:`reset` on, at least ``hz``
        samples per simulated second (:meth:`recorded_path`). A body without a continuous
        path (the grid) refuses (ConfigError)."""
        raise ConfigError(f"the {type(self).__name__} has no continuous path to record; "
                          "--record-path needs a physical body (--sim mujoco)")

    def recorded_path(self) -> list[tuple]:
        """The path recorded since the last :meth:`reset` (:meth:`record_path`), one
        :data:`PATH_FIELDS` tuple per sample in time order, the first at the start, the last at
        the moment of the call; empty when nothing is recorded."""
        return []

    def path_crossings(self) -> list[tuple[int, int, bool]] | None:
        """The polytope crossings ``(v, w, person_led)`` along the robot's continuous path
        since the last call, for a body whose path a person leads (guidance); None (the
        default): a step is judged by its start and end cells."""
        return None


class GridBody(Body):
    """The grid world (SPEC 3): headings are observed exactly, moves follow the grid motion."""

    def __init__(self, world: World, spec: EpisodeSpec | None = None,
                 rng: np.random.Generator | None = None):
        self.world = world

    def reset(self, cell: int) -> None:
        """Place the robot in ``cell``."""
        self.cell = cell

    def push(self, heading: int) -> None:
        """The grid robot observes the heading exactly, at its cell."""
        self.observe(Felt(self.cell, int(heading)))

    def move(self, action: int) -> int:
        """``next_cell[s, a]`` (the same cell for STAY or a blocked move)."""
        if action != STAY:
            self.cell = int(self.world.motion.next_cell[self.cell, action])
        return self.cell


#: bodies by the name an :class:`EpisodeSpec` gives in ``sim``
BODIES: dict[str, type[Body]] = {}


def register_body(name: str, body: type[Body]) -> None:
    """Make ``body`` available as ``EpisodeSpec(sim=name)``."""
    BODIES[name] = body


def body_class(sim: str, task: str = "navigate") -> type[Body]:
    """The registered body ``sim`` (or the one another package declares under that name in
    the entry-point group ``pathpref.bodies``, :mod:`pathpref.plugins`), checked to offer
    ``task``."""
    body = BODIES.get(sim)
    if body is None and isinstance(sim, str):
        found = plugins.load(plugins.BODIES, sim)
        if found is not None:
            if not (isinstance(found, type) and issubclass(found, Body)):
                raise ConfigError(f"entry point {sim!r} of group {plugins.BODIES} must name a "
                                  f"Body subclass, got {found!r}")
            register_body(sim, found)
            body = found
    if body is None:
        raise ConfigError(f"unknown simulator '{sim}'; registered: {', '.join(BODIES)} (a "
                          "simulator's bodies register when its package is imported)")
    if task not in body.tasks:
        need = [n for n, b in BODIES.items() if task in b.tasks]
        raise ConfigError(f"the '{sim}' body cannot run the task '{task}'"
                          + (f": use --sim {need[0]}" if need else ""))
    return body


def check_runnable(spec: EpisodeSpec) -> type[Body]:
    """The body of ``spec``, refused (one ConfigError line naming the fix) unless it can
    honour every option of the episode: it exists and offers the task (:func:`body_class`),
    it records a continuous path at ``record_path_hz`` (at most its
    :attr:`Body.record_rate_hz`), and the physical parameters fit the body (parsed by
    :attr:`EpisodeSpec.physical`, :class:`~.physics.Physics`: the drive a body has, the
    guided base). The one check every command that runs episodes calls before any work."""
    body = body_class(spec.sim, spec.robot)
    hz = spec.record_path_hz
    if hz:
        rate = body.record_rate_hz or (math.inf if body.record_path is not Body.record_path
                                       else 0.0)
        if not rate:
            raise ConfigError(f"--record-path: the '{spec.sim}' body has no continuous path to "
                              "record (use --sim mujoco)")
        if hz > rate * (1 + 1e-9):
            raise ConfigError(f"--record-path {hz:g}: at most the '{spec.sim}' body's physics "
                              f"rate, {rate:g} Hz; give a lower rate (e.g. 100)")
    spec.validate()
    return body


def simulator_rng(spec: EpisodeSpec) -> np.random.Generator:
    """The body's noise stream of an episode (the third stream of ``run_seed``)."""
    return np.random.default_rng(np.random.SeedSequence(spec.run_seed).spawn(3)[2])


def make_body(spec: EpisodeSpec, world: World) -> Body:
    """The body ``spec.sim`` for an episode of ``spec`` on ``world``."""
    return body_class(spec.sim, spec.robot)(world, spec, simulator_rng(spec))


register_body("grid", GridBody)
