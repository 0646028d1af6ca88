"""One episode of the paper's protocol (SPEC 9), fully determined by its spec.

Step ``t = 1..T_max``: when ``(t - 1) mod Delta_T == 0`` the simulated human gives a heading at the
robot's cell and the robot updates its belief with what it observed; the policy acts; the robot
moves. Standing on a wrong candidate rules it out; reaching the true goal ends the episode.
Success = goal reached within ``T_max`` AND every polytope change followed the human's
preference (a polytope where the human has no preference, ``-1``, accepts any exit).

The robot's :class:`~.body.Body` (``spec.sim``) turns the human's heading into what the robot
observes and a chosen move into the cell it reaches. Seeds: ``run_seed`` spawns three streams
(human, policy, body noise), so the human's draws do not depend on the simulator.
"""

from __future__ import annotations

import functools
import time

import numpy as np

from ..errors import ConfigError, EpisodeError
from ..geometry.grid import STAY
from ..geometry.world import World
from ..inference.human import ObservationModel, SimulatedHuman
from ..planning.policies import PolicyContext, make_policy
from .body import Body, make_body
from .cache import cached_model, cached_world
from .instances import episode_instance, human_preference
from .physics import Physics
from .results import EpisodeResult, StepLog
from .spec import EpisodeSpec


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
    construction and ``begin``). ``pending_heading`` is the heading the robot observed for the
    coming step (None when no input was due or none was detected); :meth:`step` takes the
    policy's action unless one is given (the dm_env task passes the agent's action).
    ``world`` and ``body`` default to the spec's (cached world, registered body).
    """

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
                            true_preference=self.pref)
        self.policy = make_policy(spec.method, ctx)
        self.physics = physics = Physics.from_json(spec.physics)
        human_model = model if physics is None or physics.gamma_h == model.gamma else \
            ObservationModel(world, model.tables, physics.gamma_h, model.normalize)
        self.human = SimulatedHuman(human_model, inst.true_goal, self.pref)
        self.body = body if body is not None else make_body(spec, world)
        #: the body gives the human's inputs at times of its own (pushes at any time)
        self.continuous = self.body.attach_human(
            lambda cell: self.human.sample(cell, self.human_rng), self.human.probs)
        self.result = EpisodeResult(spec=spec, instance=inst, instance_cells={
            "start": world.cells[inst.start].tolist(),
            "goals": world.cells[list(inst.goals)].tolist(),
        })
        self.goal_index = {g: k for k, g in enumerate(inst.goals)}
        self.cell = inst.start
        self.last_crossing: tuple[int, int] | None = None
        self.t = 0
        self.pending_heading: int | None = None
        self.started = False
        self.body.reset(self.cell)
        self._log(STAY, -1)

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
                                       float(self.policy.belief.goal_entropy())))

    def _human_phase(self) -> None:
        """Before step t+1: the human gives an input when one is due; the robot updates."""
        self.pending_heading = None
        if self.continuous:
            self.read_felt_inputs()
            return
        if self.done or self.t % self.spec.delta_t != 0:
            return
        self.give_input()

    @_quiet_numerics
    def give_input(self) -> None:
        """The human gives an input now, at the robot's cell: a heading drawn from the human
        model goes to the body, and the robot updates with what the body observed. A body
        that senses over time (the dm_control tasks) returns None here and reports the cue
        later through :meth:`receive_input`."""
        intended = self.human.sample(self.cell, self.human_rng)
        self.result.inputs += 1
        self.receive_input(self.body.human_input(intended))

    @_quiet_numerics
    def receive_input(self, observed: int | None) -> None:
        """The robot observed ``observed`` (a heading 0..7, None: nothing detected) for the
        human's last input: the belief update, and the heading of the coming step."""
        if observed is not None:
            self.policy.observe(self.cell, observed, self._weight(self.body.input_strength()))
        self.pending_heading = observed

    def _weight(self, strength: float | None) -> float:
        """How confident an observation is: with ``use_strength``, its push's peak force over
        the human model's median strength, clipped to 0.5..2 (a firm push is a confident one);
        else 1."""
        if self.physics is None or not self.physics.use_strength or strength is None:
            return 1.0
        return float(np.clip(strength / self.physics.peak_n, 0.5, 2.0))

    @_quiet_numerics
    def read_felt_inputs(self) -> None:
        """Pushes at any time: every cue the body felt since the last call updates the belief
        at the cell where it was felt; the last one is this step's heading. Called after
        every move; a body whose physics runs outside :meth:`step` (the dm_control tasks)
        calls it the moment a cue is felt."""
        for cell, heading, strength in self.body.felt_inputs():
            self.policy.observe(cell, heading, self._weight(strength))
            self.pending_heading = heading
        self.result.inputs = self.body.inputs_given()

    @_quiet_numerics
    def step(self, action: int | None = None) -> StepLog:
        """Advance one decision step; returns its log entry."""
        if self.done:
            raise EpisodeError("the episode is over; start a new one")
        self.begin()
        t = self.t + 1
        heading = self.pending_heading
        if action is None:
            action = int(self.policy.act(t, self.cell, heading))
        else:
            try:
                a = float(action)
            except (TypeError, ValueError):
                a = float("nan")
            if not (np.isfinite(a) and a == int(a) and (int(a) == STAY or 0 <= int(a) < 8)):
                raise ConfigError(f"action must be 0..7 (N, NE, ..., NW), got {action!r}")
        action = int(action)
        self.arrive(action, int(self.body.move(action)), heading)
        self._human_phase()
        self.result.wall_s = time.perf_counter() - self.t0
        if self.done:
            self.result.metrics = self.body.metrics()
        return self.result.log[-1]

    @_quiet_numerics
    def arrive(self, action: int, cell: int, heading: int | None) -> None:
        """Record step t+1: ``action`` (0..7 or STAY) took the robot to ``cell`` with
        ``heading`` observed before it (None: none). The success rule, the goal (reaching
        a wrong candidate rules it out) and the step's log; :meth:`step` calls it after the
        body's move, a control-rate task at every cell change."""
        before = self.cell
        self.cell = cell
        self._score(before, cell)
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
            else:
                self.policy.rule_out(k)

    def _score(self, before: int, after: int) -> None:
        """The success rule on the move ``before -> after``: leaving ``v`` toward anything but
        ``p_v`` (when ``p_v != -1``) is a violation; crossing straight back through the face
        just crossed is a back-crossing. The policy is told of every polytope change."""
        v, w = int(self.world.cell_polytope[before]), int(self.world.cell_polytope[after])
        if v == w:
            return
        if self.pref[v] >= 0 and self.pref[v] != w:
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
