"""``navigate``: reach an unknown goal by the human's preferred path, with force cues.

A dm_env environment (dm_control's ``control.Environment``). One environment step is one
decision step of the paper: the agent's action (0..7: N, NE, E, SE, S, SW, W, NW; 8: stay)
is a move to a neighbouring cell that the base's controller tracks at physics rate; then, when an
input is due, the simulated human pushes the handle and the robot's detector and belief process
it.

Observations: the base's position (m), its cell, the heading the robot detected for the coming
step (one-hot over 8 headings, all zero when none), the goal belief, the candidates' cells,
the current polytope and the joint entropy ``H(g, p_v)``.

Reward (paper, SPEC 6, with the human's true preference): ``-c(move)`` plus ``R_p`` or ``R_n`` on
a polytope change plus ``R_g`` on reaching the goal. The episode ends at the goal (discount 0)
or after ``T_max`` decisions (discount 1, a time limit). Seeds: the ``k``-th episode after
``load(seed=s)`` draws its instance from ``seed_for(s, k)`` and its run from
``seed_for(s, k, 0)``, so a task is reproducible episode by episode.

``env.task.policy_action()`` is the loaded method's own choice (its planner and belief), which
makes the environment runnable end to end without an external agent.

``map`` is a built-in name, a JSON path, a map dictionary (the format of
:mod:`pathpref.geometry.maps`; its world is built directly, nothing is written) or a
:class:`~pathpref.geometry.maps.MapSpec`. A map whose arrangement may exceed
:data:`~pathpref.geometry.arrangement.MAX_POLYTOPES` is refused unless ``force=True``. Bad
arguments (``delta_t="5"``, ``seed=-1``) and bad actions (an array of two numbers, a string,
``None``, ``2**70``) are one-line :class:`~pathpref.errors.ConfigError` s.
"""

from __future__ import annotations

import collections
import math
import numbers
from typing import Any

import numpy as np
from dm_control import mujoco as dm_mujoco
from dm_control.mujoco.wrapper import core
from dm_control.rl import control
from dm_control.suite import base
from dm_env import specs

from pathpref.episode import EpisodeRunner, EpisodeSpec, cached_map, cached_world, simulator_rng
from pathpref.episode import Physics as PhysicalParameters
from pathpref.episode.spec import check_limit
from pathpref.errors import ConfigError
from pathpref.geometry.arrangement import check_arrangement_size
from pathpref.geometry.grid import STAY
from pathpref.geometry.maps import MapSpec, parse_map
from pathpref.geometry.world import World
from pathpref.planning.pomdp import DEFAULT_PRESET, get_preset, transition_reward
from pathpref.sim.body import MujocoBody, base_params, scene_for

#: the action that keeps the base in its cell (the compliant baseline's "stop"); 0..7 are moves
STAY_ACTION = 8


def task_world(map: Any, force: bool = False) -> tuple[World, str]:
    """The world of ``map`` (name, path, dictionary or MapSpec) and the name its episodes
    carry; a dictionary's world is built directly (no file), a name's is cached."""
    if isinstance(map, dict | MapSpec):
        spec = map if isinstance(map, MapSpec) else parse_map(map)
        check_arrangement_size(spec, force)
        return World.from_spec(spec), f"dict:{spec.name}"
    if not isinstance(map, str):
        raise ConfigError(f"map must be a built-in name, a JSON path or a map dictionary, got "
                          f"{type(map).__name__}")
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


def task_scene(world, spec: EpisodeSpec):
    """The compiled scene of ``spec``'s task and physical base (legacy without physics)."""
    ph = PhysicalParameters.from_json(spec.physics)
    return scene_for(world, 0.5, spec.task, None if ph is None else base_params(ph))


class Physics(dm_mujoco.Physics):
    """Named accessors for the navigation scene."""

    def base_position(self) -> np.ndarray:
        """The base's planar position (m), read from the joints ``slide_x``, ``slide_y``."""
        return self.named.data.qpos[["slide_x", "slide_y"]].copy()


class Navigate(base.Task):
    """The ``navigate`` task (module docstring); ``task="carry"`` gives the arm's scene."""

    def __init__(self, map: str = "simple", method: str = "path_preference", delta_t: int = 5,
                 seed: int = 0, preset: str = DEFAULT_PRESET, queries: int = 5000,
                 t_max: int | None = None, coupling: bool | None = None, n_goals: int = 10,
                 task: str = "navigate", force: bool = False, physics=None):
        super().__init__()  # episodes draw from seed_for(seed, k), not from the task's random
        self.seed = check_limit("seed", seed, "seed")
        if t_max is not None:
            check_limit("t_max", t_max, "t_max")
        self.world, map_name = task_world(map, force)
        self.template = EpisodeSpec(
            map=map_name, method=method, delta_t=delta_t, instance=0, run=0, instance_seed=0,
            run_seed=0, preset=preset, queries=queries,
            t_max=t_max or self.world.spec.t_max, n_goals=n_goals, coupling=coupling,
            sim="mujoco", task=task, physics=PhysicalParameters.coerce(physics))
        self.template.validate()
        # the environment's reward is the paper's (SPEC 6) whatever preset the planner uses
        self.rewards = get_preset("paper").path_preference
        self.episode = -1
        self.runner: EpisodeRunner | None = None
        self._reward = 0.0

    # --- episode -------------------------------------------------------------------------
    def initialize_episode(self, physics: Physics) -> None:
        """Draw the next episode's instance and run (see module docstring for seeds)."""
        from dataclasses import asdict

        self.episode += 1
        fields = {k: v for k, v in asdict(self.template).items()
                  if k not in ("map", "method", "delta_t", "instance", "run", "instance_seed",
                               "run_seed")}
        spec = EpisodeSpec.single(self.template.map, self.template.method,
                                  self.template.delta_t, seed=self.seed, instance=self.episode,
                                  **fields)
        body = MujocoBody(self.world, spec, simulator_rng(spec),
                          scene=task_scene(self.world, spec), data=physics.data.ptr)
        self.runner = EpisodeRunner(spec, self.world, body)
        self.runner.begin()
        self._reward = 0.0

    def before_step(self, action, physics: Physics) -> None:
        """Run the decision step with the agent's action and keep its reward."""
        r = self.runner
        a = parse_action(action)
        if a == STAY_ACTION:
            a = STAY
        before = r.cell
        r.step(a)
        self._reward = self._step_reward(before, r.cell, a)

    def _step_reward(self, before: int, after: int, a: int) -> float:
        """The paper's reward (SPEC 6) of the move, with the human's true preference."""
        r = self.runner
        v = int(self.world.cell_polytope[before])
        return transition_reward(self.world, before, after, a, r.instance.goal_cell,
                                 int(r.pref[v]), self.rewards)

    # --- dm_env interface ----------------------------------------------------------------
    def action_spec(self, physics: Physics) -> specs.DiscreteArray:
        """A discrete action in 0..8: the eight moves (N, NE, ..., NW), then 8 = stay."""
        return specs.DiscreteArray(num_values=STAY_ACTION + 1, dtype=np.int32, name="move")

    def observation_spec(self, physics: Physics) -> collections.OrderedDict:
        """Shapes of the observations (module docstring)."""
        G = self.template.n_goals
        shapes = {"position": (2,), "cell": (2,), "heading": (8,), "goal_belief": (G,),
                  "goal_cells": (G, 2), "polytope": (1,), "entropy": (1,)}
        return collections.OrderedDict(
            (k, specs.Array(shape=v, dtype=np.float64, name=k)) for k, v in shapes.items())

    def get_observation(self, physics: Physics) -> collections.OrderedDict:
        """Position, cell, detected heading, goal belief, candidates, polytope, entropy."""
        r = self.runner
        heading = np.zeros(8)
        if r.pending_heading is not None:
            heading[r.pending_heading] = 1.0
        v = int(self.world.cell_polytope[r.cell])
        obs = collections.OrderedDict()
        obs["position"] = physics.base_position()
        obs["cell"] = self.world.cells[r.cell].astype(np.float64)
        obs["heading"] = heading
        obs["goal_belief"] = r.policy.belief.goal_marginal().astype(np.float64)
        obs["goal_cells"] = self.world.cells[list(r.instance.goals)].astype(np.float64)
        obs["polytope"] = np.array([v], dtype=np.float64)
        obs["entropy"] = np.array([r.policy.belief.joint_entropy(v)])
        return obs

    def get_reward(self, physics: Physics) -> float:
        """The reward of the last step (:meth:`_step_reward`)."""
        return float(self._reward)

    def get_termination(self, physics: Physics):
        """0 (terminal) at the goal, 1 (time limit) after ``T_max`` decisions, else None."""
        if self.runner.result.goal_reached:
            return 0.0
        if self.runner.t >= self.runner.spec.t_max:
            return 1.0
        return None

    def policy_action(self) -> int:
        """The loaded method's action for the coming step (its planner on its belief)."""
        r = self.runner
        a = int(r.policy.act(r.t + 1, r.cell, r.pending_heading))
        return STAY_ACTION if a == STAY else a


def environment(task: Navigate) -> control.Environment:
    """Wrap a task over the compiled scene of its map (and variant) in dm_control."""
    scene = task_scene(task.world, task.template)
    # dm_control wraps a compiled mujoco.MjModel; the wrapper copies nothing
    return control.Environment(Physics.from_model(core.MjModel(scene.model)), task,
                               n_sub_steps=1)


def load(map: str = "simple", method: str = "path_preference", delta_t: int = 5, seed: int = 0,
         **kwargs) -> control.Environment:
    """The ``navigate`` environment (see module docstring)."""
    return environment(Navigate(map=map, method=method, delta_t=delta_t, seed=seed, **kwargs))
