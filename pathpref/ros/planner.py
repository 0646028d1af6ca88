"""The planner's core, without ROS: the robot's messages in, decisions out.

:class:`PlannerCore` holds the episode of an :class:`~pathpref.episode.spec.EpisodeSpec`
(the instance, the belief and the policy of :class:`~pathpref.episode.runner.EpisodeRunner`,
the same construction as every other door) on a :class:`RemoteBody`: a body the runner does
not drive (the robot moves itself and a person pushes it at times of their own). What the
robot feels comes from its messages:

* a handle wrench (:class:`~.streams.Wrench`, one per force sample, every ``dt`` s) in the
  ``map`` frame is taken as the push estimate ``F_hat`` (world x-y); in the ``base_link`` or
  ``handle`` frame it is turned into ``map`` by the base's yaw, ``F_map = R(yaw) F``. The
  handle's sensor is rigid on the base (the scene's ``handle_site`` has the base's
  orientation). Any other frame is refused with one line;
* ``F_hat`` feeds the detector of the robot's sensing chain
  (:func:`pathpref.sim.sensing_chain.make_detector`: the plain hysteresis detector for the
  ideal sensor, the filtered one for a sensor with faults, with the episode's thresholds), and
  a cue becomes a :class:`~pathpref.episode.body.Felt` record through the base's one cue stream
  (:func:`pathpref.sim.cue_stream.track_cue`), to the runner's one door
  (:meth:`~pathpref.episode.runner.EpisodeRunner.observe`);
* the filtered detector calibrates at rest: the estimator's rest rule
  (:class:`~pathpref.sim.estimator.EstimatorConfig`: no cue under way, the base slower than
  ``still_mps`` and accelerating less than ``still_mps2`` for ``quiet_s``) on the odometry's
  twist (an odometry message's ``|v|``, and ``|dv| / dt`` between two messages);
* the cell a cue is felt in, and the cell a step ends in, is the scene's cell under the
  odometry's position (:meth:`pathpref.sim.scene.Scene.cell_at`).

Messages are taken in stamp order (an odometry message before a wrench of the same stamp),
each as soon as both streams have reached its stamp, so the outcome does not depend on how
the two topics interleave in transport. One exception takes a wrench sooner, with the same
outcome: a wrench in the ``map`` frame while a cue is under way is taken before the odometry
reaches its stamp (:meth:`PlannerCore._ahead`), since its reading needs nothing the odometry
could still change (no yaw for the ``map`` frame; the rest rule is off while a cue is under
way; the cue's cell was fixed at its onset). So the cue's end, and the belief it changes, do
not wait up to one odometry period. Where that sample ends the cue and opens the next, whose
onset cell is the odometry's cell at the sample's stamp, that cell is set again by every
odometry message up to the stamp, and no wrench is taken ahead until the odometry has passed
it. A step mark (:class:`~.streams.StepMark`) ends a
decision step: everything up to its stamp is taken, the detector is reset when a push window
closed (the push phase's reset), the runner records the move (:meth:`EpisodeRunner.finish_step`)
and chooses the next (:meth:`EpisodeRunner.start_step`): a :class:`Decision`.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from ..episode.body import Body, Felt
from ..episode.runner import EpisodeRunner
from ..episode.spec import EpisodeSpec
from ..errors import EpisodeError
from ..geometry.following import human_route
from ..geometry.grid import STAY
from ..sim.body import base_params, scene_for, sensing_kwargs
from ..sim.cue_detector import FilteredCueDetector
from ..sim.cue_stream import track_cue
from ..sim.estimator import EstimatorConfig
from ..sim.sensing_chain import cue_under_way, make_detector
from .streams import BASE_FRAME, HANDLE_FRAME, MAP_FRAME, Odom, StepMark, Wrench


class RemoteBody(Body):
    """The body of a robot that moves itself: the runner neither pushes nor moves it (the
    planner's node reads the robot's messages, :class:`PlannerCore`); it counts the cues it
    handed to the runner's door as the human's inputs."""

    tasks = ("navigate", "carry")

    def __init__(self):
        self.cues = 0

    def reset(self, cell: int) -> None:
        """Nothing to place: the robot stands where it stands."""
        self.cell = cell

    def push(self, heading: int) -> None:
        """Never called: the person pushes the robot themselves."""
        raise EpisodeError("a remote robot is pushed by its person, not by the runner")

    def move(self, action: int) -> int:
        """Never called: the robot's base moves to the published waypoint."""
        raise EpisodeError("a remote robot moves itself (the planner publishes waypoints)")

    def attach_human(self, heading_at, probs, watch=None) -> bool:
        """The person gives their inputs at times of their own."""
        return True

    def inputs_given(self) -> int:
        """The cues felt so far."""
        return self.cues


@dataclass(frozen=True)
class Decision:
    """A step's decision: the action (0..7 or STAY) chosen at ``cell`` with ``heading`` (None:
    none since the last), the target cell and its centre (m, ``map``), the planned route
    (cells), the goal marginal and the route's probabilities (:meth:`PlannerCore.route`);
    ``done`` when the episode is over (no action then)."""

    step: int
    stamp_ns: int
    done: bool
    action: int = STAY
    heading: int | None = None
    cell: int = -1
    target: int = -1
    target_xy: tuple[float, float] = (0.0, 0.0)
    route: tuple[int, ...] = ()
    goal_marginal: tuple[float, ...] = ()
    route_probs: tuple[float, ...] = ()


class PlannerCore:
    """The planner of ``spec``'s episode on a remote robot (module docstring). ``warn`` takes
    the one line of every message it refuses."""

    def __init__(self, spec: EpisodeSpec, warn: Callable[[str], None] = print,
                 odom_frame: str = MAP_FRAME):
        self.spec, self.warn, self.odom_frame = spec, warn, odom_frame
        self.body = RemoteBody()
        self.runner = EpisodeRunner(spec, body=self.body)
        self.world = self.runner.world
        physics = spec.physical
        params = None if physics is None else base_params(physics)
        cell_size = None if physics is None else physics.cell_size_m
        robot = "disk" if physics is None else physics.drive.robot_model
        from ..episode.physics import CELL_SIZE_M

        self.scene = scene_for(self.world, cell_size or CELL_SIZE_M, spec.robot, params, robot)
        self.dt = float(self.scene.model.opt.timestep)
        model, settings = None, {}
        if physics is not None:  # (the generator is not drawn from: only the settings)
            kw = sensing_kwargs(physics, np.random.default_rng(0))
            model, settings = kw["sensor_model"], kw["detector"]
        self.detector = make_detector(self.dt, model, settings)
        self._filtered = isinstance(self.detector, FilteredCueDetector)
        self.rest = EstimatorConfig()
        # the base-like state the cue stream (track_cue) reads and writes
        self.sensing = self
        self.guidance = None
        self.data = SimpleNamespace(time=0.0)
        self.cell = self.runner.cell
        self._onset = None
        self.felt: list[Felt] = []
        self.listener = self._observe
        self.force_estimate = np.zeros(2)
        # the two streams, waiting for each other (module docstring)
        self._wrenches: deque[Wrench] = deque()
        self._odoms: deque[Odom] = deque()
        self.n_wrench = self.n_odom = 0
        #: wrenches taken ahead of the odometry (:meth:`_ahead`)
        self.n_ahead = 0
        #: the stamp of a wrench taken ahead whose sample opened a cue (its onset cell is the
        #: odometry's at that stamp: set again by the odometry up to it); None: none
        self._onset_due: int | None = None
        self.last_odom: Odom | None = None
        self._prev_odom: Odom | None = None
        self._quiet = 0.0
        self.at_rest = False
        self.pose = tuple(float(v) for v in self.scene.cell_centre(self.cell)) + (0.0,)
        #: the action under way and the heading it was chosen with (None: none yet)
        self._pending: tuple[int, int | None] | None = None
        self.decisions: list[Decision] = []
        #: the route planned at the last decision (cells)
        self.planned: list[int] = [self.cell]
        #: their probabilities then (:meth:`route_probs`)
        self.planned_probs: list[float] = []
        #: per cue: the stamp (ns) of the wrench sample that ended it
        self.cue_stamps: list[int] = []

    # --- the streams ----------------------------------------------------------------------
    @property
    def under_way(self) -> bool:
        """A cue is under way in the detector."""
        return cue_under_way(self.detector)

    def _observe(self, felt: Felt) -> None:
        self.body.cues += 0 if felt.partial else 1
        self.cue_stamps.append(self._stamp)
        self.runner.observe(felt)

    def wrench(self, w: Wrench) -> None:
        """A wrench message (counted for the step marks; refused with one line when its frame
        is not one of the ``map``, ``base_link`` or ``handle`` frames)."""
        self.n_wrench += 1
        if w.frame not in (MAP_FRAME, BASE_FRAME, HANDLE_FRAME):
            self.warn(f"wrench in frame {w.frame!r} refused: the handle's wrench must be in "
                      f"'{MAP_FRAME}', '{BASE_FRAME}' or '{HANDLE_FRAME}'")
            return
        self._wrenches.append(w)
        self._drain()

    def odom(self, o: Odom) -> None:
        """An odometry message (counted; refused with one line in a frame other than the
        planner's ``odom_frame``)."""
        self.n_odom += 1
        if o.frame != self.odom_frame:
            self.warn(f"odometry in frame {o.frame!r} refused: the base's pose must be in "
                      f"'{self.odom_frame}' (the map's frame; parameter odom_frame)")
            return
        self._odoms.append(o)
        self._drain()

    def _drain(self, until: int | None = None) -> None:
        """Take the waiting messages in stamp order up to ``until`` (None: as far as both
        streams have come, and the wrenches that may go ahead of the odometry, :meth:`_ahead`),
        odometry first at equal stamps."""
        w, o = self._wrenches, self._odoms
        streaming = until is None  # (a step mark's drain takes nothing ahead: its stamp bounds it)
        if until is None:
            until = min(w[-1].stamp_ns, o[-1].stamp_ns) if w and o else -1
        while True:
            tw = w[0].stamp_ns if w else None
            to = o[0].stamp_ns if o else None
            if to is not None and to <= until and (tw is None or to <= tw):
                self._take_odom(o.popleft())
            elif tw is not None and tw <= until:
                self._onset_due = None  # the odometry has passed every earlier stamp
                self._take_wrench(w.popleft())
            elif streaming and tw is not None and self._ahead(w[0]):
                self.n_ahead += 1
                onset = self._onset
                self._take_wrench(w.popleft())
                if self._onset is not None and self._onset is not onset \
                        and self._onset[0] == self.data.time:  # a cue opened at this sample
                    self._onset_due = tw
            else:
                return

    def _ahead(self, w: Wrench) -> bool:
        """Whether wrench ``w`` may be taken before the odometry reaches its stamp (module
        docstring): in the ``map`` frame, while a cue is under way, and no cue opened by a
        wrench taken ahead still waits for its cell."""
        return w.frame == MAP_FRAME and self.under_way and self._onset_due is None

    def _take_odom(self, o: Odom) -> None:
        prev, self._prev_odom, self.last_odom = self.last_odom, self.last_odom, o
        self.cell = self.scene.cell_at(np.array([o.x, o.y]))
        self.pose = (o.x, o.y, o.yaw)
        if self._onset_due is not None and o.stamp_ns <= self._onset_due \
                and self._onset is not None:
            self._onset = (self._onset[0], self.cell)  # the cell at the opening sample's stamp
        self._speed = math.hypot(o.vx, o.vy)
        if prev is not None and o.stamp_ns > prev.stamp_ns:
            dt = 1e-9 * (o.stamp_ns - prev.stamp_ns)
            self._accel = math.hypot(o.vx - prev.vx, o.vy - prev.vy) / dt

    def _at_rest(self) -> bool:
        """The estimator's rest rule, one force sample on (module docstring)."""
        still = (not self.under_way and self.last_odom is not None
                 and self._speed < self.rest.still_mps
                 and getattr(self, "_accel", 0.0) < self.rest.still_mps2)
        self._quiet = self._quiet + self.dt if still else 0.0
        return self._quiet >= self.rest.quiet_s - 1e-12

    def _take_wrench(self, w: Wrench) -> None:
        self._stamp = w.stamp_ns
        self.data.time = 1e-9 * w.stamp_ns
        fx, fy = w.force[0], w.force[1]
        if w.frame != MAP_FRAME:
            c, s = math.cos(self.pose[2]), math.sin(self.pose[2])
            fx, fy = c * fx - s * fy, s * fx + c * fy
        f = np.array([fx, fy])
        self.force_estimate = f
        if self._filtered:
            cue = self.detector.update(f, at_rest=self._at_rest())
        else:
            cue = self.detector.update(f)
        if cue is not None or self._onset is not None or self.under_way:
            track_cue(self, cue)

    # --- decisions ------------------------------------------------------------------------
    def step(self, mark: StepMark) -> Decision:
        """The decision at the base's step mark (module docstring)."""
        self._drain(until=mark.stamp_ns)
        if mark.window_closed:
            self.detector.reset()
        r = self.runner
        if self._pending is not None and not r.done:
            action, heading = self._pending
            r.finish_step(action, self.cell, heading)
        self._pending = None
        if r.done:
            d = Decision(mark.step, mark.stamp_ns, True, cell=self.cell,
                         goal_marginal=tuple(self._marginal()))
        else:
            action, heading = r.start_step()
            self._pending = (action, heading)
            target = self.cell if action == STAY else \
                int(self.world.motion.next_cell[self.cell, action])
            route, probs = self.route()
            x, y = (float(v) for v in self.scene.cell_centre(target))
            d = Decision(mark.step, mark.stamp_ns, False, action, heading, self.cell, target,
                         (x, y), tuple(route), tuple(self._marginal()), tuple(probs))
        self.decisions.append(d)
        return d

    def _marginal(self) -> list[float]:
        return [float(p) for p in self.runner.policy.belief.goal_marginal()]

    def route(self) -> tuple[list[int], list[float]]:
        """The planned route: the human's route (:func:`~pathpref.geometry.following.
        human_route`) from the robot's cell to the most probable goal under the most probable
        preference of every polytope (``argmax_k P(p_v = N(v)[k] | o)``; no preference where
        the belief has none: a goal-only belief), and along it the probability of each
        polytope change it makes, ``P(p_v = w | o)`` (none for a goal-only belief)."""
        belief = self.runner.policy.belief
        goals = self.runner.instance.goals
        goal = goals[int(np.argmax(belief.goal_marginal()))]
        graph = self.world.graph
        marginal = getattr(belief, "preference_marginal", None)
        pref = np.full(len(graph.neighbors), -1, dtype=int)
        if marginal is not None:
            for v, nb in enumerate(graph.neighbors):
                if len(nb):
                    pref[v] = int(nb[int(np.argmax(marginal(v)))])
        route = human_route(self.world, pref, self.cell, goal) or [self.cell]
        self.planned, self.planned_probs = route, self.route_probs(route)
        return route, self.planned_probs

    def route_probs(self, route: list[int]) -> list[float]:
        """``P(p_v = w | o)`` of each polytope change ``v -> w`` along ``route`` (none for a
        goal-only belief)."""
        marginal = getattr(self.runner.policy.belief, "preference_marginal", None)
        probs: list[float] = []
        if marginal is not None:
            poly, graph = self.world.cell_polytope, self.world.graph
            for a, b in zip(route, route[1:], strict=False):
                v, w = int(poly[a]), int(poly[b])
                if v != w:
                    nb = list(graph.neighbors[v])
                    probs.append(float(marginal(v)[nb.index(w)]) if w in nb else 0.0)
        return probs

    def velocity_command(self, target_xy: tuple[float, float], v_max: float | None = None
                         ) -> tuple[float, float, float]:
        """The base's velocity command toward ``target_xy`` (m/s and rad/s in ``base_link``):
        the tracking law of the simulated base (:class:`~pathpref.sim.controller.
        TrackingController`: ``v = kp (target - p)`` saturated at ``v_max``, yaw held at 0)
        from the last odometry, turned into the base's frame."""
        from ..sim.controller import TrackingController

        physics = self.spec.physical
        law = TrackingController() if physics is None and v_max is None else \
            TrackingController(v_max=v_max or physics.drive.v_max)
        x, y, yaw = self.pose
        vx, vy, wz = (float(v) for v in law.command(np.array([x, y]), yaw,
                                                     np.array(target_xy)))
        c, s = math.cos(yaw), math.sin(yaw)
        return c * vx + s * vy, -s * vx + c * vy, wz
