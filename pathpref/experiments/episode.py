"""One episode of the paper's protocol (SPEC 9), fully determined by its spec.

Step ``t = 1..T_max``: when ``(t - 1) mod Delta_T == 0`` the simulated human gives a heading at the
robot's cell and the robot updates its belief with what it observed; the policy acts; the robot
moves. Standing on a wrong candidate rules it out; reaching the true goal ends the episode.
Success = goal reached within ``T_max`` AND every polytope change followed the human's
preference (a polytope where the human has no preference, ``-1``, accepts any exit).

The robot's body is a *mover*: :class:`GridMover` (SPEC 3 moves, headings observed exactly) or
the MuJoCo base of :mod:`pathpref.sim.mover` (pushes detected from a force sensor, moves
tracked at physics rate), chosen by ``spec.sim``. Seeds: ``run_seed`` spawns three streams
(human, policy, simulator noise), so the human's draws do not depend on the simulator.
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np

from ..errors import ConfigError, EpisodeError
from ..geometry.maps import MapSpec, load_map
from ..geometry.world import World
from ..inference.human import ObservationModel, SimulatedHuman
from ..planning.policies import STAY, PolicyContext, make_policy
from ..planning.pomdp import PRESETS, get_preset
from .instances import HUMANS, Instance, fixed_instance, sample_instance


@dataclass(frozen=True)
class EpisodeSpec:
    """Everything that determines an episode. ``key()`` identifies it in the results store.

    ``coupling`` (on by default for experiments, as in the authors' code) applies the paper's
    back-edge remark to the robot's belief at every real polytope change; without it the
    paper's reward can be farmed by crossing a confidently preferred edge back and forth
    (see README, "Reproducing Table I").

    ``fixed`` optionally pins the instance: ``{"start": [x, y], "goals": [[x, y], ...],
    "true_goal": k, "free_goal_polytope": bool}``; otherwise it is drawn from
    ``instance_seed``. ``run_seed`` drives the human and the planner.
    """

    map: str
    method: str
    delta_t: int
    instance: int
    run: int
    instance_seed: int
    run_seed: int
    preset: str = "paper"
    queries: int = 5000
    t_max: int = 30
    n_goals: int = 10
    normalize: bool = True
    coupling: bool | None = None  # None: the preset's (paper, original: on; robust: off)
    sim: str = "grid"
    fixed: str = ""  # JSON of the pinned instance, "" for a sampled one
    task: str = "navigate"
    ucb_c: float = 1.0
    #: robust search's wall-time budget per decision (0: the query count only)
    time_budget_ms: float = 0.0
    #: the human's preference: "map" (the map's, the paper's protocol) or "consistent" (the
    #: true goal is drawn among candidates the map's preference leads to; see instances.py)
    human: str = "map"
    #: wall-clock limit in seconds (0: none); not part of the key, it does not change results
    timeout_s: float = field(default=0.0, compare=False)

    def __post_init__(self) -> None:
        if self.coupling is None:
            object.__setattr__(self, "coupling", get_preset(self.preset).coupling
                               if self.preset in PRESETS else True)

    @property
    def map_hash(self) -> str:
        """Content hash of the map (:attr:`MapSpec.content_hash`): the map's identity."""
        return cached_map(self.map).content_hash

    def key(self) -> str:
        """The episode's identity: every field but the map's path and the timeout, plus the
        map's content hash (so an edited map runs new episodes and the same map under another
        path reuses them)."""
        d = asdict(self)
        d.pop("timeout_s")
        d.pop("map")
        d["map_hash"] = self.map_hash
        return "|".join(f"{k}={d[k]}" for k in sorted(d))

    def validate(self) -> None:
        if self.delta_t < 1:
            raise ConfigError(f"--delta-t must be at least 1, got {self.delta_t}")
        if self.t_max < 1:
            raise ConfigError(f"--t-max must be at least 1, got {self.t_max}")
        if self.queries < 1:
            raise ConfigError(f"--queries must be at least 1, got {self.queries}")
        if not self.timeout_s >= 0:
            raise ConfigError(f"--episode-timeout must be >= 0 seconds, got {self.timeout_s}")
        if self.task not in ("navigate", "carry"):
            raise ConfigError(f"unknown task '{self.task}'; choose navigate or carry")
        if self.task == "carry" and self.sim != "mujoco":
            raise ConfigError("the carry task needs the arm: use --sim mujoco")
        if not self.ucb_c > 0:
            raise ConfigError(f"--ucb-c must be positive, got {self.ucb_c}")
        if not self.time_budget_ms >= 0:
            raise ConfigError(f"--time-budget-ms must be positive, got {self.time_budget_ms}")
        if self.human not in HUMANS:
            raise ConfigError(f"unknown human preference '{self.human}'; choose "
                              f"{' or '.join(HUMANS)}")
        get_preset(self.preset)


@dataclass
class StepLog:
    t: int
    x: int
    y: int
    action: int
    heading: int
    p_true_goal: float
    goal_entropy: float


@dataclass
class EpisodeResult:
    spec: EpisodeSpec
    instance: Instance
    instance_cells: dict[str, Any] = field(default_factory=dict)
    goal_reached: bool = False
    violations: int = 0
    back_crossings: int = 0
    steps: int = 0
    inputs: int = 0
    wall_s: float = 0.0
    status: str = "ok"
    reason: str = ""
    log: list[StepLog] = field(default_factory=list)
    metrics: dict[str, float] = field(default_factory=dict)

    @property
    def pref_followed(self) -> bool:
        return self.violations == 0

    @property
    def success(self) -> bool:
        return self.goal_reached and self.pref_followed and self.status == "ok"


@lru_cache(maxsize=64)
def cached_map(source: str) -> MapSpec:
    """Map files are read once per process."""
    return load_map(source)


@lru_cache(maxsize=8)
def cached_world(source: str) -> World:
    """Worlds are built once per process."""
    return World.from_spec(cached_map(source))


@lru_cache(maxsize=128)
def cached_model(source: str, goals: tuple[int, ...], normalize: bool) -> ObservationModel:
    return ObservationModel.build(cached_world(source), np.array(goals), normalize=normalize)


def episode_instance(world: World, spec: EpisodeSpec) -> tuple[Instance, bool]:
    """The spec's instance, and whether the goal's polytope carries no preference."""
    if spec.fixed:
        f = json.loads(spec.fixed)
        inst = fixed_instance(world, tuple(f["start"]), [tuple(g) for g in f["goals"]],
                              int(f["true_goal"]))
        return inst, bool(f.get("free_goal_polytope", False))
    return sample_instance(world, spec.instance_seed, spec.n_goals,
                           consistent=spec.human == "consistent", t_max=spec.t_max), False


def human_preference(world: World, inst: Instance, free_goal_polytope: bool) -> np.ndarray:
    pref = world.require_preference().copy()
    if free_goal_polytope:
        pref[world.cell_polytope[inst.goal_cell]] = -1
    return pref


class GridMover:
    """The grid world's embodiment: headings are observed exactly, moves follow SPEC 3."""

    def __init__(self, world: World, spec: EpisodeSpec, rng: np.random.Generator):
        self.world = world

    def reset(self, cell: int) -> None:
        self.cell = cell

    def human_input(self, heading: int) -> int | None:
        """The heading the robot observes when the human gives ``heading``."""
        return heading

    def move(self, action: int) -> int:
        """Execute ``action`` (or STAY) from the current cell; return the cell reached."""
        if action != STAY:
            self.cell = int(self.world.motion.next_cell[self.cell, action])
        return self.cell


#: simulators by name: a class, or "module:Class" imported on first use (so that this layer
#: does not import a simulator)
MOVERS: dict[str, Any] = {"grid": GridMover, "mujoco": "pathpref.sim.mover:MujocoMover"}


def make_mover(spec: EpisodeSpec, world: World, rng: np.random.Generator):
    entry = MOVERS.get(spec.sim)
    if entry is None:
        raise ConfigError(f"unknown simulator '{spec.sim}'; choose one of {', '.join(MOVERS)}")
    if isinstance(entry, str):
        import importlib

        module, name = entry.split(":")
        entry = getattr(importlib.import_module(module), name)
    return entry(world, spec, rng)


def simulator_rng(spec: EpisodeSpec) -> np.random.Generator:
    """The simulator's noise stream of an episode (the third stream of ``run_seed``)."""
    return np.random.default_rng(np.random.SeedSequence(spec.run_seed).spawn(3)[2])


class EpisodeRunner:
    """One episode, advanced one decision step at a time (see module docstring).

    :meth:`begin` gives the human's first input (hooks on the mover may be attached between
    construction and ``begin``). ``pending_heading`` is the heading the robot observed for the
    coming step (None when no input was due or none was detected); :meth:`step` takes the
    policy's action unless one is given (the dm_env task passes the agent's action).
    """

    def __init__(self, spec: EpisodeSpec, world: World | None = None, mover=None):
        self.t0 = time.perf_counter()
        spec.validate()
        self.spec = spec
        if world is None:
            world = cached_world(spec.map)
            inst, free_goal = episode_instance(world, spec)
            model = cached_model(spec.map, inst.goals, spec.normalize)
        else:
            inst, free_goal = episode_instance(world, spec)
            model = ObservationModel.build(world, np.array(inst.goals), normalize=spec.normalize)
        self.world, self.instance, self.model = world, inst, model
        self.pref = human_preference(world, inst, free_goal)
        human_seq, policy_seq, _ = np.random.SeedSequence(spec.run_seed).spawn(3)
        self.human_rng = np.random.default_rng(human_seq)
        preset = get_preset(spec.preset, ucb_c=spec.ucb_c)
        ctx = PolicyContext(world=world, model=model, preset=preset, t_max=spec.t_max,
                            queries=spec.queries, rng=np.random.default_rng(policy_seq),
                            coupling=spec.coupling, time_budget_ms=spec.time_budget_ms,
                            true_goal=inst.true_goal, true_preference=self.pref)
        self.policy = make_policy(spec.method, ctx)
        self.human = SimulatedHuman(model, inst.true_goal, self.pref)
        if mover is None:
            mover = make_mover(spec, world, simulator_rng(spec))
        self.mover = mover
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
        self.mover.reset(self.cell)
        self._log(STAY, -1)

    def begin(self) -> None:
        """The human's input before step 1 (when due); :meth:`step` calls it if needed."""
        if not self.started:
            self.started = True
            self._human_phase()

    @property
    def done(self) -> bool:
        return self.result.goal_reached or self.t >= self.spec.t_max

    def _log(self, action: int, heading: int) -> None:
        p = self.policy.belief.goal_marginal()
        if not np.isfinite(p).all():
            raise EpisodeError(f"belief became non-finite at step {self.t}")
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
        if self.done or self.t % self.spec.delta_t != 0:
            return
        intended = self.human.sample(self.cell, self.human_rng)
        self.result.inputs += 1
        observed = self.mover.human_input(intended)
        if observed is not None:
            self.policy.observe(self.cell, observed)
        self.pending_heading = observed

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
        before = self.cell
        self.cell = int(self.mover.move(action))
        v, w = int(self.world.cell_polytope[before]), int(self.world.cell_polytope[self.cell])
        if v != w:
            if self.pref[v] >= 0 and self.pref[v] != w:
                self.result.violations += 1
            if self.last_crossing == (w, v):  # straight back through the face just crossed
                self.result.back_crossings += 1
            self.last_crossing = (v, w)
            if self.world.graph.edge_between(v, w) >= 0:
                self.policy.enter(v, w)
        self.t = t
        self.result.steps = t
        k = self.goal_index.get(self.cell)
        if k is not None:
            if k == self.instance.true_goal:
                self.result.goal_reached = True
            else:
                self.policy.rule_out(k)
        self._log(action, -1 if heading is None else heading)
        self._human_phase()
        self.result.wall_s = time.perf_counter() - self.t0
        if self.done and hasattr(self.mover, "metrics"):
            self.result.metrics = self.mover.metrics()
        return self.result.log[-1]


def run_episode(spec: EpisodeSpec, world: World | None = None) -> EpisodeResult:
    """Run one episode to the end (see module docstring) and return its flags and log."""
    runner = EpisodeRunner(spec, world)
    while not runner.done:
        runner.step()
    return runner.result


def result_row(res: EpisodeResult) -> dict[str, Any]:
    """Flat dictionary of an episode for the results store."""
    d = asdict(res.spec)
    inst = res.instance
    return {
        **d,
        "key": res.spec.key(),
        "map_hash": res.spec.map_hash,
        "start": json.dumps(res.instance_cells.get("start")),
        "goals": json.dumps(res.instance_cells.get("goals")),
        "true_goal": inst.true_goal,
        "status": res.status,
        "reason": res.reason,
        "goal_reached": int(res.goal_reached),
        "pref_followed": int(res.pref_followed),
        "success": int(res.success),
        "steps": res.steps,
        "inputs": res.inputs,
        "violations": res.violations,
        "back_crossings": res.back_crossings,
        "wall_s": res.wall_s,
        "metrics": json.dumps(res.metrics, sort_keys=True),
    }
