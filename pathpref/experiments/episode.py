"""One grid-world episode of the paper's protocol (SPEC 9), fully determined by its spec.

Step ``t = 1..T_max``: when ``(t - 1) mod Delta_T == 0`` the simulated human gives a heading at the
robot's cell and the robot updates its belief; the policy acts; the robot moves (SPEC 3). Standing
on a wrong candidate rules it out; reaching the true goal ends the episode. Success = goal
reached within ``T_max`` AND every polytope transition followed the human's preference (a
polytope where the human has no preference, ``-1``, accepts any exit).
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np

from ..errors import ConfigError, EpisodeError
from ..geometry.world import World, load_world
from ..inference.human import ObservationModel, SimulatedHuman
from ..planning.policies import STAY, PolicyContext, make_policy
from ..planning.pomdp import get_preset
from .instances import Instance, fixed_instance, sample_instance


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
    coupling: bool = True
    sim: str = "grid"
    fixed: str = ""  # JSON of the pinned instance, "" for a sampled one
    task: str = "navigate"
    ucb_c: float = 1.0
    #: wall-clock limit in seconds (0: none); not part of the key, it does not change results
    timeout_s: float = field(default=0.0, compare=False)

    def key(self) -> str:
        d = asdict(self)
        d.pop("timeout_s")
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
        if not self.ucb_c > 0:
            raise ConfigError(f"--ucb-c must be positive, got {self.ucb_c}")
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
    steps: int = 0
    inputs: int = 0
    wall_s: float = 0.0
    status: str = "ok"
    reason: str = ""
    log: list[StepLog] = field(default_factory=list)

    @property
    def pref_followed(self) -> bool:
        return self.violations == 0

    @property
    def success(self) -> bool:
        return self.goal_reached and self.pref_followed and self.status == "ok"


@lru_cache(maxsize=8)
def cached_world(source: str) -> World:
    """Worlds are built once per process."""
    return load_world(source)


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
    return sample_instance(world, spec.instance_seed, spec.n_goals), False


def human_preference(world: World, inst: Instance, free_goal_polytope: bool) -> np.ndarray:
    pref = world.require_preference().copy()
    if free_goal_polytope:
        pref[world.cell_polytope[inst.goal_cell]] = -1
    return pref


def run_episode(spec: EpisodeSpec, world: World | None = None) -> EpisodeResult:
    """Run one episode (see module docstring) and return its flags and per-step log."""
    t0 = time.perf_counter()
    spec.validate()
    if world is None:
        world = cached_world(spec.map)
        inst, free_goal = episode_instance(world, spec)
        model = cached_model(spec.map, inst.goals, spec.normalize)
    else:
        inst, free_goal = episode_instance(world, spec)
        model = ObservationModel.build(world, np.array(inst.goals), normalize=spec.normalize)
    pref = human_preference(world, inst, free_goal)
    human_seq, policy_seq = np.random.SeedSequence(spec.run_seed).spawn(2)
    human_rng = np.random.default_rng(human_seq)
    preset = get_preset(spec.preset, ucb_c=spec.ucb_c)
    ctx = PolicyContext(world=world, model=model, preset=preset,
                        t_max=spec.t_max, queries=spec.queries,
                        rng=np.random.default_rng(policy_seq), coupling=spec.coupling)
    policy = make_policy(spec.method, ctx)
    human = SimulatedHuman(model, inst.true_goal, pref)
    res = EpisodeResult(spec=spec, instance=inst, instance_cells={
        "start": world.cells[inst.start].tolist(),
        "goals": world.cells[list(inst.goals)].tolist(),
    })
    goal_index = {g: k for k, g in enumerate(inst.goals)}
    motion, poly = world.motion, world.cell_polytope
    s = inst.start

    def log(t: int, a: int, h: int) -> None:
        p = policy.belief.goal_marginal()
        if not np.isfinite(p).all():
            raise EpisodeError(f"belief became non-finite at step {t}")
        if spec.timeout_s and time.perf_counter() - t0 > spec.timeout_s:
            raise EpisodeError(f"timeout: episode exceeded {spec.timeout_s:g} s at step {t}")
        x, y = world.cells[s]
        res.log.append(StepLog(t, int(x), int(y), a, h, float(p[inst.true_goal]),
                               float(policy.belief.goal_entropy())))

    log(0, STAY, -1)
    for t in range(1, spec.t_max + 1):
        heading = None
        if (t - 1) % spec.delta_t == 0:
            heading = human.sample(s, human_rng)
            policy.observe(s, heading)
            res.inputs += 1
        a = int(policy.act(t, s, heading))
        if a != STAY:
            s2 = int(motion.next_cell[s, a])
            if motion.crossed_edge[s, a] >= 0:
                v, w = int(poly[s]), int(poly[s2])
                if pref[v] >= 0 and pref[v] != w:
                    res.violations += 1
                policy.enter(v, w)
            s = s2
        res.steps = t
        k = goal_index.get(s)
        if k is not None:
            if k == inst.true_goal:
                res.goal_reached = True
            else:
                policy.rule_out(k)
        log(t, a, -1 if heading is None else heading)
        if res.goal_reached:
            break
    res.wall_s = time.perf_counter() - t0
    return res


def result_row(res: EpisodeResult) -> dict[str, Any]:
    """Flat dictionary of an episode for the results store."""
    d = asdict(res.spec)
    inst = res.instance
    return {
        **d,
        "key": res.spec.key(),
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
        "wall_s": res.wall_s,
    }
