"""``navigate``: reach an unknown goal by the human's preferred path, with force cues, one
decision per environment step.

A dm_env environment (dm_control's ``control.Environment``) by the suite's contract: the task
sets controls in ``before_step`` and the Environment advances the physics (see
:mod:`.stage`). One environment step is one decision step of the paper and lasts exactly
``decision_s`` seconds of physics (``control_timestep()``; with ``physics`` the one rule of
every door, :meth:`~pathpref.episode.physics.Physics.step_s`, 3.4 s by default; 2.5 s with the
legacy physics):

1. *move* (at most ``decision_s`` minus the push window, 0.7 s in the legacy physics, and the
   drive's move limit, ``Physics.move_limit_s``): the agent's action (0..7: N, NE, E, SE, S,
   SW, W, NW; 8: stay) is a move to the grid neighbour of SPEC 3 (the current cell when the
   grid move is blocked); the base's tracking controller drives there at physics rate until
   it settles;
2. *push* (when the human's input is due for the next decision, at most the push window): the
   simulated human pushes the handle where the base stopped; the robot's detector, fed only
   by its force sensor, reports the heading and the belief is updated;
3. *hold* the cell for the rest of the step.

The episode's first push happens in ``reset`` (physics time runs there too). Observations:
the base's position (m), its cell, the heading detected for the coming step (one-hot over 8
headings, zero when none), the filtered force (N, world frame, low-pass with tau = 0.05 s),
whether the detector is active, the goal belief, the candidates' cells, the current polytope
and the joint entropy ``H(g, p_v)``; and what the robot felt *during* the step
(:class:`~.stage.StepInteraction`), not an end-of-step snapshot: ``push_felt`` (peak N,
cos and sin of its direction, duration s of the strongest cue read), ``cues_felt`` (cues read
per heading) and ``detector_active_s``. Bounded observations are ``BoundedArray`` s.

Episode metrics (``success``, ``pushes``, ``violations``, ``cues_felt``, ``return``, ...:
:meth:`Navigate.episode_metrics`) are the environment's ``env.episode_metrics`` (final at the
last time step) and every Gymnasium ``info``.

Reward: :func:`pathpref.planning.pomdp.transition_reward` (the paper's, SPEC 6, the one rule
the POMDP uses) with the human's true preference; with ``reward="potential"`` the loop-free
rule of :mod:`.reward` (the preference as a potential); with ``reward="route"`` that of
:mod:`.route_reward` (the ``-v1`` ids': its optimum is the person's route; shaped with the
discount ``gamma``, and a violation ends the episode). The episode ends at the goal (discount
0) or after ``T_max`` decisions (discount 1). Seeds: the ``k``-th episode after ``load(seed=s)``
draws its instance from ``seed_for(s, k)`` and its run from ``seed_for(s, k, 0)``, so a task
is reproducible episode by episode. ``env.task.policy_action()`` is the loaded method's own
choice (its planner and belief), so the environment runs end to end without an agent.

``physics`` (a :class:`~pathpref.episode.physics.Physics`, a dict of its fields or its JSON;
None: ``Physics()``, every door's default; ``"legacy"``: the legacy physics)
builds the base as ``--sim mujoco`` does and goes into every
episode's spec; its default ``decision_s`` is ``Physics.step_s()`` (the drive's diagonal move
with a settle allowance and the longest push with the detector's release). With ``timing``
other than ``decision`` the human pushes at any physics step
(:class:`~pathpref.sim.pushing_human.PushingHuman`): a cue felt while driving ends the move
(*move* above; the runner records the step and reads the cue, the belief is updated in the next
physics step) and the base holds its cell for the rest of the step; a cue felt while holding is
read at once too; there is no *push* phase then.

``human`` is the person's preference, as ``pathpref evaluate --human``: ``"map"`` (the
map's, the paper's protocol; on a generated plan its route often does not lead to the true
goal, so no policy can succeed there) or ``"consistent"`` (the true goal is drawn among the
candidates the map's preference leads to, and the person pushes along one route to it
consistently: :func:`pathpref.episode.instances.sample_instance`).

``map`` is a built-in name, a JSON path, a map dictionary or a
:class:`~pathpref.geometry.maps.MapSpec`; a map whose arrangement may exceed
:data:`~pathpref.geometry.arrangement.MAX_POLYTOPES` is refused unless ``force=True``. Bad
arguments and actions are one-line :class:`~pathpref.errors.ConfigError` s.
"""

from __future__ import annotations

import collections
import json
import math
import numbers
import os
from dataclasses import asdict, replace
from typing import Any

import numpy as np
from dm_control.suite import base
from dm_env import specs

from pathpref.episode import (
    EpisodeRunner,
    EpisodeSpec,
    cached_map,
    cached_world,
    sample_instance,
    simulator_rng,
)
from pathpref.episode.physics import CELL_SIZE_M
from pathpref.episode.physics import Physics as PhysicalParameters
from pathpref.episode.safety import contact_safe
from pathpref.episode.spec import check_limit, check_number
from pathpref.errors import ConfigError, EpisodeError
from pathpref.geometry.arrangement import check_arrangement_size
from pathpref.geometry.grid import STAY
from pathpref.geometry.maps import BUILTIN_MAPS, MapSpec, parse_map
from pathpref.geometry.world import World
from pathpref.planning.pomdp import DEFAULT_PRESET, get_preset, transition_reward
from pathpref.sim.body import base_params, build_base, scene_for
from pathpref.sim.controller import TrackingController
from pathpref.sim.decision import HOLD, MOVE, PUSH, RELEASE_WINDOW_S, move_limit
from pathpref.sim.force_cue import HumanPush, PushProfile
from pathpref.sim.mobile_base import MobileBase
from pathpref.sim.scene import Scene

from .drawing import TaskDrawing
from .plugins import entry_point_map
from .reward import REWARDS, potential_reward, preference_potential
from .route_reward import DISCOUNT, RouteReward
from .stage import ForceFilter, Physics, StagedBody, StepInteraction

#: the action that keeps the base in its cell (the compliant baseline's "stop"); 0..7 are moves
STAY_ACTION = 8
#: metres per grid unit of the disk's scenes (the one home: ``pathpref.episode.physics.
#: CELL_SIZE_M``; a task's is :attr:`Navigate.cell_size`, its body's)
CELL_SIZE = CELL_SIZE_M
#: physics seconds of one decision step (the default ``decision_s`` of the legacy physics)
DECISION_S = 2.5
#: the shortest move a decision step must leave room for (s)
MIN_MOVE_S = 0.5
#: the longest move (s): the tracking controller's limit, as ``MobileBase.move_to`` drives
MOVE_LIMIT_S = TrackingController().time_limit_s


def task_world(map: Any, force: bool = False) -> tuple[World, str]:
    """The world of ``map`` (name, path, dictionary or MapSpec, or the name of another
    package's map: :mod:`.registry`) and the name its episodes carry; a dictionary's world is
    built directly (no file), a name's is cached."""
    if isinstance(map, dict | MapSpec):
        spec = map if isinstance(map, MapSpec) else parse_map(map)
        check_arrangement_size(spec, force)
        return World.from_spec(spec), f"dict:{spec.name}"
    if not isinstance(map, str):
        raise ConfigError(f"map must be a built-in name, a JSON path or a map dictionary, got "
                          f"{type(map).__name__}")
    if map not in BUILTIN_MAPS and not os.path.exists(map):
        given = entry_point_map(map)
        if given is not None:
            if isinstance(given, str | os.PathLike):
                given = os.fspath(given)
                if given in BUILTIN_MAPS or not os.path.exists(given):
                    raise ConfigError(f"map entry point {map!r} must give a map dictionary, "
                                      f"a MapSpec or an existing JSON path, got {given!r}")
            return task_world(given, force)
    check_arrangement_size(cached_map(map), force)
    return cached_world(map), map


def parse_action(action: Any) -> int:
    """``action`` (an int, a whole float, a NumPy scalar or a one-element array) as 0..8; a
    one-line ConfigError otherwise."""
    def bad(shown: str) -> ConfigError:
        return ConfigError(f"action must be 0..{STAY_ACTION} (8 = stay), got {shown}")

    a = action
    if isinstance(a, np.ndarray):
        if a.size != 1:
            raise bad(f"an array of shape {a.shape}")
        a = a.reshape(()).item()
    if isinstance(a, bool | np.bool_) or not isinstance(a, numbers.Real):
        raise bad(repr(a)[:40])
    if not isinstance(a, numbers.Integral):
        if not (math.isfinite(a) and float(a).is_integer()):
            raise bad(repr(a)[:40])
    if not 0 <= a <= STAY_ACTION:
        raise bad(repr(a)[:40] if abs(a) < 1e30 else "a number out of range")
    return int(a)


def bounded(shape: tuple, lo: float, hi: float, name: str) -> specs.BoundedArray:
    """A float64 ``BoundedArray`` spec."""
    return specs.BoundedArray(shape=shape, dtype=np.float64, minimum=lo, maximum=hi, name=name)


class Navigate(base.Task):
    """The ``navigate`` task (module docstring); ``task="carry"`` gives the arm's scene."""

    #: one environment step is one decision (False: control rate, :mod:`.navigate_control`)
    decides = True

    def __init__(self, map: str = "simple", method: str = "path_preference", delta_t: int = 5,
                 seed: int = 0, preset: str = DEFAULT_PRESET, queries: int | None = None,
                 t_max: int | None = None, coupling: bool | None = None, n_goals: int = 10,
                 task: str = "navigate", force: bool = False, decision_s: float | None = None,
                 physics: Any = None, reward: str = "paper", min_goal_distance: float = 0.0,
                 gamma: float = DISCOUNT, human: str = "map"):
        super().__init__()  # episodes draw from seed_for(seed, k), not from the task's random
        self.seed = check_limit("seed", seed, "seed")
        if t_max is not None:
            check_limit("t_max", t_max, "t_max")
        self.world, map_name = task_world(map, force)
        self.template = EpisodeSpec(
            map=map_name, method=method, delta_t=delta_t, instance=0, run=0, instance_seed=0,
            run_seed=0, preset=preset, queries=queries,
            t_max=t_max or self.world.spec.t_max, n_goals=n_goals, coupling=coupling,
            sim="mujoco", robot=task, physics=PhysicalParameters.coerce(physics), human=human)
        self.template.validate()
        #: the physical parameters (None: the legacy physics, asked for by name)
        self.physics = ph = self.template.physical
        #: metres per grid unit: the body's (:attr:`~pathpref.episode.physics.Physics.cell_size_m`)
        self.cell_size = CELL_SIZE if ph is None else ph.cell_size_m
        self.scene: Scene = scene_for(self.world, self.cell_size, task,
                                      None if ph is None else base_params(ph),
                                      "disk" if ph is None else ph.drive.robot_model)
        self.dt = float(self.scene.model.opt.timestep)
        #: the longest a push phase lasts (s): the longest push and the detector's release
        self.push_window_s = (PushProfile().duration_s if ph is None else
                              ph.human.duration_max_s) + RELEASE_WINDOW_S
        if decision_s is None:
            decision_s = DECISION_S if ph is None else self.physical_decision_s()
        self.decision_s = check_number("decision_s", decision_s, 1.5, 10.0, integer=False)
        if self.move_limit_s < MIN_MOVE_S:
            raise ConfigError(
                f"decision_s must leave {MIN_MOVE_S:g} s to move after the longest push and its "
                f"release ({self.push_window_s:g} s: physics duration_max_s + "
                f"{RELEASE_WINDOW_S:g}), so at least {self.push_window_s + MIN_MOVE_S:.2f}; "
                f"got {self.decision_s:g}")
        # the environment's reward is the paper's (SPEC 6) whatever preset the planner uses
        self.rewards = get_preset("paper").path_preference
        #: the action :meth:`check_action` returned for the step under way (the Environment
        #: checks it before dm_control's step; ``before_step`` takes it as it is)
        self.checked_action = None
        if reward not in REWARDS:
            raise ConfigError(f"reward must be one of {', '.join(REWARDS)}, got {reward!r}")
        #: the reward rule: ``paper`` (SPEC 6), ``potential`` (:mod:`.reward`, no loops) or
        #: ``route`` (:mod:`.route_reward`, the person's route its optimum)
        self.reward = reward
        self._phi: np.ndarray | None = None
        #: the discount of the ``route`` reward's shaping (:mod:`.route_reward`)
        self.gamma = check_number("gamma", gamma, 0.5, 1.0, integer=False)
        self._route: RouteReward | None = None
        #: the shortest grid distance (cells) from the start to any goal candidate (0: the
        #: paper's draw, :func:`~pathpref.episode.instances.sample_instance`)
        self.min_goal_distance = check_number("min_goal_distance", min_goal_distance, 0.0,
                                              1000.0, integer=False)
        self.episode = -1
        self.runner: EpisodeRunner | None = None
        self.base: MobileBase | None = None
        self._reward = 0.0

    # --- the physics of a step -----------------------------------------------------------
    @property
    def n_sub_steps(self) -> int:
        """Physics steps of one environment step."""
        return int(round(self.decision_s / self.dt))

    @property
    def move_limit_s(self) -> float:
        """The longest move of a decision step (s): the controller's limit, within what the
        step leaves after the push window."""
        limit = MOVE_LIMIT_S if self.physics is None else \
            self.physics.move_limit_s(self.cell_size)
        return move_limit(limit, self.decision_s, self.push_window_s, self.dt)

    def physical_decision_s(self) -> float:
        """The default step with physics: the one rule every door uses,
        :meth:`~pathpref.episode.physics.Physics.step_s` (a move and the push window)."""
        return self.physics.step_s(self.cell_size)

    def make_base(self, data, rng: np.random.Generator) -> MobileBase:
        """The robot's base on the Environment's ``MjData``, built as the ``--sim mujoco``
        body builds it (:func:`~pathpref.sim.body.build_base`) from the task's physics."""
        return build_base(self.scene, self.template.robot, self.physics, rng, data=data)

    def initialize_episode(self, physics: Physics) -> None:
        """Draw the next episode's instance and run (see module docstring for seeds), place
        the base and play the human's first push."""
        self.episode += 1
        fields = {k: v for k, v in asdict(self.template).items()
                  if k not in ("map", "method", "delta_t", "instance", "run", "instance_seed",
                               "run_seed")}
        spec = EpisodeSpec.single(self.template.map, self.template.method,
                                  self.template.delta_t, seed=self.seed, instance=self.episode,
                                  **fields)
        if self.min_goal_distance > 0:
            spec = self.distant_instance(spec)
        rng = simulator_rng(spec)
        self.base = self.make_base(physics.data.ptr, rng)
        self.body = StagedBody(self.world, spec, rng, self.base, self._start_push)
        self.filter = ForceFilter(self.base)
        self._reward = 0.0
        #: the sum of the episode's rewards (the Environment adds each step's)
        self.episode_return = 0.0
        self.runner = EpisodeRunner(spec, self.world, self.body)
        self._goal_cells = self.world.cells[list(self.runner.instance.goals)].astype(np.float64)
        # per cell: its grid coordinates and polytope, as the observations carry them
        self._cells = self.world.cells.astype(np.float64)
        self._polytopes = self.world.cell_polytope.tolist()
        self._belief_key = self._belief_obs = None  # (_belief_observation)
        self._phi = None if self.reward != "potential" else preference_potential(
            self.world, self.runner.instance.goal_cell, self.runner.pref)
        self._route = None if self.reward != "route" else RouteReward(
            self.world, self.runner.instance.goal_cell, self.runner.pref, self.gamma,
            self.runner.spec.t_max, self.rewards.goal)
        #: what the robot felt since the last observation (the observations of the step)
        self.interaction = StepInteraction(self.base)
        physics.drawing = TaskDrawing(self)  # the task in every render
        self.base.decision.hold(until_cue=False)
        physics.substep = self.substep
        if self.decides:
            self.runner.begin()
            while self.base.decision.phase == PUSH:  # the first push, before the first move
                self.substep()

    def distant_instance(self, spec: EpisodeSpec) -> EpisodeSpec:
        """``spec`` with its instance drawn from its own seed with every candidate at least
        ``min_goal_distance`` from the start, pinned (``EpisodeSpec.fixed``)."""
        w = self.world
        inst = sample_instance(w, spec.instance_seed, spec.n_goals,
                               consistent=spec.human == "consistent", t_max=spec.t_max,
                               min_distance=self.min_goal_distance)
        cell = lambda c: [int(v) for v in w.cells[c]]  # noqa: E731
        fixed = {"start": cell(inst.start), "goals": [cell(g) for g in inst.goals],
                 "true_goal": inst.true_goal}
        return replace(spec, fixed=json.dumps(fixed, sort_keys=True))

    def _start_push(self, push: HumanPush) -> None:
        """The human pushes now: the push phase of the base's decision step, the cell held."""
        self.base.decision.push(push)

    def _push_over(self) -> None:
        """The push phase ended (its cue, if any, reached the runner's door when it was
        read): note how it was read, then hold the cell for the rest of the step."""
        d, push = self.base.decision, self.body.last_push
        self.body.readings.append((push.intended_heading, -1 if d.cue is None else
                                   d.cue.heading, float("nan") if d.cue is None else
                                   float(self.base.data.time) - push.t0))
        self.body.cell = self.base.cell
        d.hold(until_cue=False)

    def substep(self) -> None:
        """One physics step of the base's decision step (module docstring): when its push
        ends the cell is held; when its move ends the runner records the decision (and may
        start the next push)."""
        d = self.base.decision
        phase = d.phase
        if d.advance():
            if phase == PUSH:
                self._push_over()
            elif phase == MOVE:
                self._arrive()
        self.filter.update()
        self.interaction.update()

    def check_action(self, action) -> int:
        """``action`` as 0..8 (:func:`parse_action`)."""
        return parse_action(action)

    def _take_action(self, action):
        """``action`` checked (:meth:`check_action`) unless it is the one the Environment
        checked for this step (:attr:`checked_action`)."""
        checked, self.checked_action = self.checked_action, None
        return action if action is checked else self.check_action(action)

    def before_step(self, action, physics: Physics) -> None:
        """Set the base's target: the grid neighbour the action names (module docstring)."""
        a = self._take_action(action)
        self._action, self._heading = self.runner.start_step(STAY if a == STAY_ACTION else a)
        cell = self.body.cell
        target = cell if self._action == STAY else int(self.world.motion.next_cell[cell, a])
        guided = self.physics is not None and self.physics.human.timing == "guidance"
        # a guided step is one timed move of the whole step in every door (.decision)
        self.base.decision.move(target, self.move_limit_s,
                                steps=self.n_sub_steps if guided else None)
        self._reward = 0.0
        self.interaction.start()
        if self.body.human is not None:  # the corrective human watches the move begin
            self.body.human.robot_moves(cell, None if target == cell else self._action)

    def _arrive(self) -> None:
        """The move is over: the runner records the decision (success rule, goal, log) and
        gives the human's next input when due (which starts a push)."""
        r, d = self.runner, self.base.decision
        before = r.cell
        d.hold(until_cue=False)
        r.finish_step(self._action, self.body.move(self._action), self._heading)
        self._reward = self._step_reward(before, r.cell, self._action)

    def after_step(self, physics: Physics) -> None:
        """Every phase of the decision fits in ``decision_s`` by construction."""
        phase = self.base.decision.phase
        if phase != HOLD:  # pragma: no cover - a broken invariant, not bad input
            raise EpisodeError(f"decision step ended in phase {phase}")

    def _step_reward(self, before: int, after: int, a: int) -> float:
        """The reward of the move with the human's true preference: the paper's (SPEC 6), or
        the potential-shaped one (:func:`~.reward.potential_reward`) or the route's
        (:class:`~.route_reward.RouteReward`; a violation is the runner's count rising, which
        ends the episode: :meth:`get_termination`)."""
        r = self.runner
        if self._route is not None:
            return self._route(before, after, a, r.result.violations > 0)
        if self._phi is not None:
            return potential_reward(self.world, self._phi, before, after, a,
                                    r.instance.goal_cell, self.rewards.goal)
        v = int(self.world.cell_polytope[before])
        return transition_reward(self.world, before, after, a, r.instance.goal_cell,
                                 int(r.pref[v]), self.rewards)

    # --- dm_env interface ----------------------------------------------------------------
    def action_spec(self, physics: Physics) -> specs.DiscreteArray:
        """A discrete action in 0..8: the eight moves (N, NE, ..., NW), then 8 = stay."""
        return specs.DiscreteArray(num_values=STAY_ACTION + 1, dtype=np.int32, name="move")

    def observation_spec(self, physics: Physics) -> collections.OrderedDict:
        """Shapes and bounds of the observations (module docstring)."""
        G, w = self.template.n_goals, self.world.spec
        side = float(max(w.width, w.height))
        h_max = math.log(G) + math.log(max(2, self.world.n_polytopes))
        return collections.OrderedDict([
            ("position", bounded((2,), 0.0, side * self.cell_size, "position")),
            ("cell", bounded((2,), 1.0, side, "cell")),
            ("heading", bounded((8,), 0.0, 1.0, "heading")),
            ("force", specs.Array((2,), np.float64, name="force")),
            ("detector_active", bounded((1,), 0.0, 1.0, "detector_active")),
            ("goal_belief", bounded((G,), 0.0, 1.0, "goal_belief")),
            ("goal_cells", bounded((G, 2), 1.0, side, "goal_cells")),
            ("polytope", bounded((1,), 0.0, self.world.n_polytopes - 1.0, "polytope")),
            ("entropy", bounded((1,), 0.0, h_max, "entropy")),
            *self.interaction_spec().items(),
        ])

    def interaction_spec(self) -> dict[str, specs.Array]:
        """The specs of the step's interaction (:class:`~.stage.StepInteraction`): a step
        observes at most ``max(decision_s, push window)`` of physics (the first observation
        includes the push played in ``reset``), so at most that many seconds of an active
        detector and one cue per physics step of it."""
        span = max(self.decision_s, self.push_window_s)
        return {
            "push_felt": specs.Array((4,), np.float64, name="push_felt"),
            "cues_felt": bounded((8,), 0.0, float(math.ceil(span / self.dt)), "cues_felt"),
            "detector_active_s": bounded((1,), 0.0, span, "detector_active_s"),
        }

    def get_observation(self, physics: Physics) -> collections.OrderedDict:
        """The observations of the module docstring."""
        r = self.runner
        heading = np.zeros(8)
        if r.pending_heading is not None:
            heading[r.pending_heading] = 1.0
        cell = r.cell
        v = self._polytopes[cell]
        marginal, h = self._belief_observation(v)
        obs = collections.OrderedDict((
            ("position", self.base.position), ("cell", self._cells[cell].copy()),
            ("heading", heading), ("force", self.filter.f.copy()),
            ("detector_active", np.array([1.0 if self.base.sensing.detector.active else 0.0])),
            ("goal_belief", marginal.copy()), ("goal_cells", self._goal_cells.copy()),
            ("polytope", np.array([float(v)])), ("entropy", np.array([h]))))
        obs.update(self.interaction.observation())
        return obs

    def _belief_observation(self, v: int) -> tuple[np.ndarray, float]:
        """The goal marginal and ``H(g, p_v)`` at polytope ``v``: computed again only when
        the policy has fed its belief an event since
        (:attr:`pathpref.planning.policies.Policy.evidence`) or ``v`` changed; most
        control-rate steps change neither."""
        p = self.runner.policy
        key = (p, p.evidence, v)
        if self._belief_key != key:
            self._belief_obs = (p.belief.goal_marginal().astype(np.float64),
                                p.belief.joint_entropy(v))
            self._belief_key = key
        return self._belief_obs

    def episode_metrics(self, body: bool = True) -> dict[str, float | bool]:
        """The episode so far (final once the episode is over): ``success`` (goal reached
        without a violation and no unsafe contact), ``contact_safe``, ``goal_reached``,
        ``violations``, ``back_crossings``, ``steps`` (decisions, or cell changes at control
        rate), ``pushes`` (the human's inputs), ``cues_felt`` (cues the detector gave),
        ``sim_time_s``, ``p_true_goal`` (the belief's probability of the true goal),
        ``return`` (sum of rewards) and, with ``body``, the body's measurements
        (:meth:`pathpref.sim.body.MujocoBody.metrics`: with physics the cue metrics
        ``pushes_missed``, ``pushes_misread``, ..., ``collisions``; the arm's tilt; they go
        over the episode's physics steps, so a Gymnasium ``info`` has them at the episode's
        last step only)."""
        r = self.runner
        res = r.result
        out: dict[str, float | bool] = dict(self.body.metrics()) if body else {}
        out.update({
            "success": bool(res.success) and not self.contact_unsafe(),
            "contact_safe": not self.contact_unsafe(), "goal_reached": bool(res.goal_reached),
            "violations": int(res.violations), "back_crossings": int(res.back_crossings),
            "steps": int(res.steps), "pushes": int(res.inputs),
            "cues_felt": int(len(self.base.felt)), "sim_time_s": float(self.base.data.time),
            "p_true_goal": float(r.policy.belief.goal_marginal()[r.instance.true_goal]),
            "return": float(self.episode_return)})
        return out

    def contact_unsafe(self) -> bool:
        """Whether the base has struck an obstacle or a wall beyond the limits of
        :mod:`pathpref.episode.safety` (measured with physical parameters only)."""
        b = self.base  # (no collision yet: safe, as contact_safe says, without the metrics)
        return b.measure and b.measurements.collisions > 0 and \
            not contact_safe(b.measurements.metrics())

    def get_reward(self, physics: Physics) -> float:
        """The reward of the last step (:meth:`_step_reward`); a step that ends the episode
        with an unsafe contact (:meth:`get_termination`) also loses the goal's reward, so
        striking an obstacle never pays (ending early would otherwise spare the move
        costs)."""
        penalty = self.rewards.goal if self.contact_unsafe() else 0.0
        return float(self._reward) - penalty

    def get_termination(self, physics: Physics):
        """0 (terminal) at the goal or at an unsafe contact (:meth:`contact_unsafe`: as in
        every report, a contact-unsafe episode is no success), with the ``route`` reward also
        at the first violation (:mod:`.route_reward`), 1 (time limit) after ``T_max``
        decisions, else None."""
        if self.runner.result.goal_reached or self.contact_unsafe():
            return 0.0
        if self._route is not None and self.runner.result.violations > 0:
            return 0.0
        if self.runner.t >= self.runner.spec.t_max:
            return 1.0
        return None

    def policy_action(self) -> int:
        """The loaded method's action for the coming step (its planner on its belief)."""
        r = self.runner
        a = int(r.policy.act(r.t + 1, r.cell, r.pending_heading))
        return STAY_ACTION if a == STAY else a
