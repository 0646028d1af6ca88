"""One episode of the paper's protocol (SPEC 9), fully determined by its spec.

Step ``t = 1..T_max``: when ``(t - 1) mod Delta_T == 0`` the simulated human gives a heading at the
robot's cell and the robot updates its belief with what it observed; the policy acts; the robot
moves. The corrective human (``spec.push_rule``, :mod:`.corrective`) pushes instead only after
the steps that call for it, on any body whose pushes come at decision steps (the grid; MuJoCo
with the physics' ``timing`` ``decision``, the default). Standing on a wrong candidate rules it
out; reaching the true goal ends the episode. Success = goal reached within ``T_max`` AND every
polytope change followed the human's preference (a polytope where the human has no preference,
``-1``, accepts any exit).
Homotopy success, reported beside it = goal reached AND the robot's path goes the same way
round every obstacle as the human's route (:mod:`pathpref.geometry.homotopy`).

The robot's :class:`~.body.Body` (``spec.sim``) turns the human's heading into what the robot
observes and a chosen move into the cell it reaches. Seeds: ``run_seed`` spawns three streams
(human, policy, body noise), so the human's draws do not depend on the simulator; the
corrective human's misses draw from a fourth (:func:`.corrective.miss_stream`).
"""

from __future__ import annotations

import functools
import time

import numpy as np

from ..errors import ConfigError, EpisodeError
from ..geometry.following import human_route
from ..geometry.grid import STAY
from ..geometry.homotopy import route_homotopic
from ..geometry.world import World
from ..inference.human import ObservationModel, SimulatedHuman
from ..kernels import load_cached
from ..planning.policies import PolicyContext, make_policy
from .body import Body, Felt, make_body
from .cache import cached_model, cached_world
from .corrective import CorrectiveHuman, miss_stream, parse_push_rule
from .instances import episode_instance, human_preference
from .physics import DIRECTION_KAPPA
from .results import EpisodeResult, StepLog, route_slack
from .spec import EpisodeSpec

#: the corrective human watches decision steps: a body pushing at times of its own cannot
#: take it
_ANY_TIME = ("push_rule {rule!r} pushes at decision steps (or takes a guiding person's "
             "handle: --timing guidance), but {where} pushes at times of its own; use --timing "
             "decision (the default), --timing guidance or the periodic human (push_rule '')")


def _quiet_numerics(method):
    """Run ``method`` with NumPy's floating-point errors (divide by zero, invalid, overflow)
    recorded on the runner instead of printed: the episode checks its belief after every step
    and fails with one line (:class:`EpisodeError`, naming the first such error), where NumPy
    printed a warning per step (1196 lines on a 500 x 500 map)."""
    @functools.wraps(method)
    def wrapper(self, *args, **kwargs):
        with np.errstate(divide="call", invalid="call", over="call", under="ignore",
                         call=self._numeric_error):
            return method(self, *args, **kwargs)
    return wrapper


class EpisodeRunner:
    """One episode, advanced one decision step at a time (see module docstring).

    :meth:`begin` gives the human's first input (hooks on the body may be attached between
    construction and ``begin``). Everything the robot feels enters through one door,
    :meth:`observe` (the body is connected to it); ``pending_heading`` is the heading of the
    last cue since the last decision (None: none), which the coming step is chosen with.
    :meth:`step` is one decision step (:meth:`start_step`, the body's move,
    :meth:`finish_step`), the policy's action unless one is given; a task whose physics is
    advanced by its Environment calls the two halves itself, and a control-rate task calls
    :meth:`arrive` at every cell change and :meth:`give_input` on its own clock. ``world``
    and ``body`` default to the spec's (cached world, registered body).
    """

    #: the body gives the human's inputs itself (pushes at any time; set in ``__init__``)
    continuous: bool = False
    #: the first NumPy floating-point error of the episode and their number
    numeric_errors: int = 0
    first_numeric_error: str = ""

    def _numeric_error(self, kind: str, flag: int) -> None:
        if not self.numeric_errors:
            self.first_numeric_error = kind
        self.numeric_errors += 1

    @_quiet_numerics
    def __init__(self, spec: EpisodeSpec, world: World | None = None, body: Body | None = None):
        self.t0 = time.perf_counter()
        spec.validate()
        self.spec = spec
        cached = world is None
        world = cached_world(spec.map) if cached else world
        inst, free_goal = episode_instance(world, spec.fixed, spec.instance_seed, spec.n_goals,
                                           spec.human, spec.t_max)
        model = (cached_model(spec.map, inst.goals, spec.normalize) if cached else
                 ObservationModel.build(world, np.array(inst.goals), normalize=spec.normalize))
        self.world, self.instance, self.model = world, inst, model
        self.pref = self._preference(free_goal)
        human_seq, policy_seq, _ = np.random.SeedSequence(spec.run_seed).spawn(3)
        self.human_rng = np.random.default_rng(human_seq)
        ctx = PolicyContext(world=world, model=model, preset=spec.planner(), t_max=spec.t_max,
                            rng=np.random.default_rng(policy_seq), true_goal=inst.true_goal,
                            true_preference=self.pref, start=inst.start)
        self.policy = make_policy(spec.method, ctx)
        self.physics = spec.physical
        gamma_h = spec.human_model.gamma_h  # the human's rationality, any body (grid too)
        human_model = model if gamma_h == model.gamma else \
            ObservationModel(world, model.tables, gamma_h, model.normalize)
        # the consistent human holds the goal's polytope (pathpref.geometry.following)
        self.human = SimulatedHuman(human_model, inst.true_goal, self.pref,
                                    hold=spec.human == "consistent")
        rule = parse_push_rule(spec.push_rule)
        physical = spec.physical
        guided = physical is not None and physical.human.timing == "guidance"
        if rule is not None and physical is not None and \
                physical.human.timing not in ("decision", "guidance"):
            raise ConfigError(_ANY_TIME.format(rule=spec.push_rule, where=(
                f"--timing {physical.human.timing}")))
        #: the corrective human (None: the periodic one)
        self.corrective = None if rule is None else CorrectiveHuman(
            rule, world, self.pref, inst.goal_cell, miss_stream(spec.run_seed))
        self.body = body if body is not None else make_body(spec, world)
        load_cached()  # the body's kernels too, from numba's cache (pathpref.kernels)
        self.body.connect(self.observe)  # the one door of what the robot feels
        #: the body gives the human's inputs at times of its own (pushes at any time)
        self.continuous = self.body.attach_human(
            self._heading_at, self.human.probs, watch=self.corrective if guided else None)
        if self.corrective is not None and self.continuous and not guided:
            raise ConfigError(_ANY_TIME.format(rule=spec.push_rule, where="this body"))
        self.result = EpisodeResult(spec=spec, instance=inst, instance_cells={
            "start": world.cells[inst.start].tolist(),
            "goals": world.cells[list(inst.goals)].tolist(),
        }, slack=route_slack(spec.t_max, human_route(world, self.pref, inst.start,
                                                      inst.goal_cell)))
        self.goal_index = {g: k for k, g in enumerate(inst.goals)}
        self.cell = inst.start
        #: the last step's move (cell before, action, cell after; None before step 1)
        self.last_move: tuple[int, int, int] | None = None
        self.last_crossing: tuple[int, int] | None = None
        #: crossings a person led (bodies judged along their path, :meth:`_cross`)
        self.path_metrics = {"person_crossings": 0.0, "person_violations": 0.0}
        self._path_judged = False
        self.t = 0
        self.pending_heading: int | None = None
        self.started = False
        if spec.record_path_hz:
            self.body.record_path(spec.record_path_hz)
        self.body.reset(self.cell)
        self._log(STAY, -1)

    def _heading_at(self, cell: int) -> int:
        """The human's heading at ``cell`` drawn from the run's human stream (what a body
        that pushes at its own times asks for; a bound method, not a closure, so a copy of
        the episode (a task's snapshot) draws from the copy's stream)."""
        return self.human.sample(cell, self.human_rng)

    def _preference(self, free_goal: bool) -> np.ndarray:
        """The human's preference per polytope (the map's, or the consistent human's completion
        of it for this goal; see ``human_preference``). The human pushes along it, the oracle
        follows it and the success rule judges against it."""
        return human_preference(self.world, self.instance, free_goal, self.spec.human)

    @_quiet_numerics
    def begin(self) -> None:
        """The human's input before step 1 (when due); :meth:`step` calls it if needed."""
        if not self.started:
            self.started = True
            self._human_phase()

    @property
    def done(self) -> bool:
        """The goal is reached or ``T_max`` steps are spent."""
        return self.result.goal_reached or self.t >= self.spec.t_max

    def _log(self, action: int, heading: int) -> None:
        p = self.policy.belief.goal_marginal()
        if not np.isfinite(p).all():
            why = (f" (after {self.numeric_errors} floating-point errors, the first: "
                   f"{self.first_numeric_error})" if self.numeric_errors else "")
            raise EpisodeError(f"belief became non-finite at step {self.t}{why}")
        if self.spec.timeout_s and time.perf_counter() - self.t0 > self.spec.timeout_s:
            raise EpisodeError(
                f"timeout: episode exceeded {self.spec.timeout_s:g} s at step {self.t}")
        x, y = self.world.cells[self.cell]
        self.result.log.append(StepLog(self.t, int(x), int(y), action, heading,
                                       float(p[self.instance.true_goal]),
                                       float(self.policy.belief.goal_entropy()),
                                       None if self.continuous else 0))

    def _human_phase(self) -> None:
        """Before step t+1: the human gives an input when one is due (a body that took the
        human over gives its own, and they reach :meth:`observe` as they are felt)."""
        if self.continuous:
            self.result.inputs = self.body.inputs_given()
            return
        if self.done:
            return
        if self.corrective is not None:
            if self.last_move is None or not self.corrective.pushes_after(self.t,
                                                                           *self.last_move):
                return
        elif self.t % self.spec.delta_t != 0:
            return
        self.give_input()

    @_quiet_numerics
    def give_input(self) -> None:
        """The human pushes now, at the robot's cell: a heading drawn from the human model
        goes to the body (:meth:`~.body.Body.push`); what the robot feels comes back through
        :meth:`observe` (a body whose physics is advanced by someone else, the dm_control
        tasks, reports it when its push phase ends). The coming step's heading is that cue's,
        or None when the push was missed."""
        intended = self.human.sample(self.cell, self.human_rng)
        self.result.inputs += 1
        if self.result.log:
            self.result.log[-1].is_intervention = 1
        self.pending_heading = None
        self.body.push(intended)

    @_quiet_numerics
    def observe(self, felt: Felt) -> None:
        """The one door of the robot's observations: a cue the body felt updates the belief at
        the cell where it was felt (weighted by its strength with ``use_strength``), and its
        heading is the coming step's (the last one felt wins). Ignored once the episode is
        over (a task's physics runs on to the end of its step)."""
        if self.done:
            return
        if felt.evidence is not None:  # a sustained push, read as it lasts (Felt)
            angle, weight = felt.evidence
            if weight > 0:
                self.policy.observe_direction(felt.cell, angle, DIRECTION_KAPPA, weight)
        else:
            self.policy.observe(felt.cell, felt.heading, self._weight(felt.peak_n))
        if felt.partial:
            return
        self.pending_heading = felt.heading
        if self.continuous:
            self.result.inputs = self.body.inputs_given()

    def _weight(self, strength: float | None) -> float:
        """How confident an observation is: with ``use_strength``, its push's peak force over
        the human model's median strength, clipped to 0.5..2 (a firm push is a confident one);
        else 1."""
        if self.physics is None or not self.physics.sensing.use_strength or strength is None:
            return 1.0
        return float(np.clip(strength / self.physics.human.peak_n, 0.5, 2.0))

    @_quiet_numerics
    def start_step(self, action: int | None = None) -> tuple[int, int | None]:
        """The action of step t+1 (the policy's unless one is given, checked) and the heading
        it was chosen with, which the step consumes (cues felt from now on are the next
        step's). A staged body (the dm_control tasks) calls this when the move begins and
        :meth:`finish_step` when it ends; :meth:`step` does both around the body's move."""
        if self.done:
            raise EpisodeError("the episode is over; start a new one")
        self.begin()
        heading = self.pending_heading
        if action is None:
            action = int(self.policy.act(self.t + 1, self.cell, heading))
        else:
            try:
                a = float(action)
            except (TypeError, ValueError):
                a = float("nan")
            if not (np.isfinite(a) and a == int(a) and (int(a) == STAY or 0 <= int(a) < 8)):
                raise ConfigError(f"action must be 0..7 (N, NE, ..., NW), got {action!r}")
        self.pending_heading = None
        return int(action), heading

    @_quiet_numerics
    def finish_step(self, action: int, cell: int, heading: int | None) -> StepLog:
        """Step t+1 is over: ``action`` took the robot to ``cell`` (:meth:`arrive`); the human's
        next input when due. Its log entry."""
        self.arrive(action, cell, heading)
        self._human_phase()
        self.result.wall_s = time.perf_counter() - self.t0
        if self.done:
            self.result.metrics = self.body.metrics()
            self.result.path = self.body.recorded_path()
            if self._path_judged:
                self.result.metrics.update(self.path_metrics)
            completed = getattr(getattr(self.policy, "planner", None), "completed_trees", 0)
            if completed:  # trees completed, not drawn (POMCP.completed_trees): said, not hidden
                self.result.metrics["completed_trees"] = float(completed)
        return self.result.log[-1]

    def step(self, action: int | None = None) -> StepLog:
        """Advance one decision step (:meth:`start_step`, the body's move,
        :meth:`finish_step`); its log entry."""
        action, heading = self.start_step(action)
        return self.finish_step(action, int(self.body.move(action)), heading)

    @_quiet_numerics
    def arrive(self, action: int, cell: int, heading: int | None) -> None:
        """Record step t+1: ``action`` (0..7 or STAY) took the robot to ``cell`` with
        ``heading`` observed before it (None: none). The success rule, the goal (reaching
        a wrong candidate rules it out) and the step's log; :meth:`step` calls it after the
        body's move, a control-rate task at every cell change."""
        before = self.cell
        self.cell = cell
        self.last_move = (before, int(action), cell)
        path = self.body.path_crossings()
        self._path_judged = path is not None
        if path is None:
            self._score(before, cell)
        else:  # judged along the path: the person's crossings beside the robot's own
            for v, w, person in path:
                self._cross(v, w, person)
        self.t += 1
        self.result.steps = self.t
        self._arrive(cell)
        self._log(action, -1 if heading is None else heading)

    def _arrive(self, cell: int) -> None:
        """The robot ended a step on ``cell``: the true goal ends the episode, another
        candidate is ruled out (the paper's protocol)."""
        k = self.goal_index.get(cell)
        if k is not None:
            if k == self.instance.true_goal:
                self.result.goal_reached = True
                self.result.homotopic = self._homotopic(cell)
            else:
                self.policy.rule_out(k)

    def _homotopic(self, goal: int) -> bool:
        """Whether the robot's path (the logged cells, then ``goal``) goes the same way round
        every obstacle as the human's route from the start to ``goal``
        (:func:`~pathpref.geometry.homotopy.route_homotopic`)."""
        path = [(s.x, s.y) for s in self.result.log] + [tuple(self.world.cells[goal])]
        return route_homotopic(self.world, self.pref, self.instance.start, goal, path)

    def _score(self, before: int, after: int) -> None:
        """The success rule on the move ``before -> after`` (:meth:`_cross`)."""
        v, w = int(self.world.cell_polytope[before]), int(self.world.cell_polytope[after])
        if v != w:
            self._cross(v, w, False)

    def _cross(self, v: int, w: int, person: bool) -> None:
        """The success rule on a crossing from polytope ``v`` into ``w``: leaving ``v``
        toward anything but ``p_v`` (when ``p_v != -1``) is a violation, the robot's own
        unless a person led the robot across (``person``: counted in the metrics
        ``person_violations`` of ``person_crossings``, not in ``violations``); crossing
        straight back through the face just crossed is a back-crossing. The policy is told of
        every polytope change."""
        if person:
            self.path_metrics["person_crossings"] += 1.0
        if self.pref[v] >= 0 and self.pref[v] != w:
            if person:
                self.path_metrics["person_violations"] += 1.0
            else:
                self.result.violations += 1
        if self.last_crossing == (w, v):
            self.result.back_crossings += 1
        self.last_crossing = (v, w)
        if self.world.graph.edge_between(v, w) >= 0:
            self.policy.enter(v, w)


def run_episode(spec: EpisodeSpec, world: World | None = None,
                body: Body | None = None) -> EpisodeResult:
    """Run one episode to the end (see module docstring) and return its flags and log."""
    runner = EpisodeRunner(spec, world, body)
    while not runner.done:
        runner.step()
    return runner.result
