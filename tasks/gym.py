"""Gymnasium environments over the dm_control tasks: ``pathpref/Navigate-v0``,
``pathpref/NavigateControl-v0``, ``pathpref/Carry-v0`` and ``pathpref/CarryControl-v0``,
registered when :mod:`pathpref_tasks` is imported::

    import gymnasium as gym
    env = gym.make("pathpref_tasks:pathpref/Navigate-v0", map="simple", delta_t=5)
    obs, info = env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())

(``"pathpref_tasks:"`` imports the package first, so the ids exist; after ``import
pathpref_tasks`` the bare id works too.) One step is one step of the dm_control task (a
decision; at control rate a velocity command, a ``Box(-0.8, 0.8, (2,))``), the same reward and
termination: ``terminated`` at the goal (dm_env discount 0), ``truncated`` at the time or step
limit (discount 1); stepping after either without ``reset`` is a one-line error.
``reset(seed=s)`` starts the episode sequence of ``load(seed=s)`` again, so a seed gives the
same episode every time; ``reset()`` moves to the next episode. Observations are the dm_env
ones, as float64 boxes bounded where the spec is; ``render_mode="rgb_array"`` renders the top
camera. Keyword arguments are the task's (``task_kwargs``), plus ``environment_kwargs`` and
``time_limit`` of :func:`pathpref_tasks.load`. Each id is registered with a string entry point
(:data:`ENTRY_POINT`: ``gym.spec(id).to_json()`` works) and ``max_episode_steps``
(:func:`max_episode_steps`); ``info`` also holds ``is_success``, ``is_intervention`` and
``intervention_heading`` every step (:meth:`PathprefEnv._info`). ``env.unwrapped.snapshot()``
and ``env.unwrapped.restore(s)`` save and restore an episode (:mod:`.snapshot`).

Vectorised (each sub-environment gets its own seed from ``reset(seed=...)``)::

    envs = gym.vector.SyncVectorEnv([lambda: gym.make("pathpref/Navigate-v0", map="simple")
                                     for _ in range(4)])
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
from dm_env import specs
from gymnasium import spaces

from pathpref.episode.spec import check_number
from pathpref.errors import ConfigError
from pathpref.geometry.maps import load_map

from .environment import load
from .navigate_control import CONTROL_TIMESTEP
from .registry import BUILTIN_TASKS, gym_id, gym_ids

#: the largest render size asked for at all (the scene's offscreen buffer may allow less)
MAX_RENDER = 8192

#: gymnasium id -> built-in dm_control task name (derived: :func:`pathpref_tasks.gym_id`)
IDS = {gym_id(name): name for name in BUILTIN_TASKS}

#: the entry point every id is registered with (a string, so ``gym.spec(id).to_json()`` works)
ENTRY_POINT = "pathpref_tasks.gym:PathprefEnv"
#: the reward rule of the Gymnasium ids (``reward="paper"`` selects SPEC 6's): the potential of
#: :mod:`.reward`, under which circling never pays
GYM_REWARD = "potential"
#: the shortest start-to-candidate grid distance (cells) of the Gymnasium ids' episodes
#: (``min_goal_distance`` of the task; the dm_control tasks keep the paper's draw, 0): no
#: episode ends after a step or two because a goal was drawn beside the start
GYM_MIN_GOAL_DISTANCE = 4.0
#: the built-in maps whose horizons ``max_episode_steps`` must cover
HORIZON_MAPS = ("simple", "office", "classroom")
#: the longest decision step of the default physics (s), for the control-rate horizon
DECISION_S_MAX = 3.4


def max_episode_steps(task: str) -> int:
    """The ``max_episode_steps`` an id is registered with: the longest natural episode of its
    task over the built-in maps (:data:`HORIZON_MAPS`) with the default arguments, so the
    ``TimeLimit`` never cuts an episode the task would have run: ``max T_max`` decisions
    (60, ``classroom``), and at control rate ``max T_max * decision_s / control_timestep``
    (60 * 3.4 s / 0.02 s = 10200 steps). The task still ends its own episode first (``t_max``,
    ``time_limit``); another package's task, not imported at registration, gets the decision
    bound."""
    t_max = max(load_map(m).t_max for m in HORIZON_MAPS)
    cls = BUILTIN_TASKS.get(task)
    if cls is not None and not cls.decides:
        return int(math.ceil(t_max * DECISION_S_MAX / CONTROL_TIMESTEP))
    return int(t_max)


#: bounds the Gymnasium spaces give the observations the dm_env specs leave unbounded (values
#: beyond them are clipped): the filtered force and the strongest cue's peak (N) within
#: ``FORCE_BOUND_N``, far above any push of the human models (30 N legacy, at most 60 N);
#: ``push_felt``'s cos and sin within 1, its duration (s) within ``CUE_BOUND_S``; velocity
#: (m/s) within ``SPEED_BOUND``; the tray's position (m) within ``TRAY_BOUND_M`` of the origin
FORCE_BOUND_N = 200.0
CUE_BOUND_S = 10.0
SPEED_BOUND = 5.0
TRAY_BOUND_M = 100.0
GYM_BOUNDS = {
    "force": (-FORCE_BOUND_N, FORCE_BOUND_N),
    "push_felt": ([0.0, -1.0, -1.0, 0.0], [FORCE_BOUND_N, 1.0, 1.0, CUE_BOUND_S]),
    "velocity": (-SPEED_BOUND, SPEED_BOUND),
    "tray_position": (-TRAY_BOUND_M, TRAY_BOUND_M),
}


def box(spec) -> spaces.Box:
    """The Box of a dm_env spec: its bounds for a ``BoundedArray``, else those of
    :data:`GYM_BOUNDS` (every observation of the built-in tasks is bounded; another
    package's unbounded one stays unbounded)."""
    lo, hi = (spec.minimum, spec.maximum) if isinstance(spec, specs.BoundedArray) else \
        GYM_BOUNDS.get(spec.name, (-np.inf, np.inf))
    return spaces.Box(np.broadcast_to(np.asarray(lo, np.float64), spec.shape).copy(),
                      np.broadcast_to(np.asarray(hi, np.float64), spec.shape).copy(),
                      shape=spec.shape, dtype=np.float64)


def learner_spaces(observation_space: spaces.Dict) -> dict[str, spaces.Box]:
    """The observations added for learners (:func:`learner_features`), from the task's
    spaces: ``G`` goals (``goal_cells``), a map of side ``L`` cells (``goal_cells``' upper
    bound) and ``P`` polytopes (``polytope``'s upper bound + 1)."""
    G = observation_space["goal_cells"].shape[0]
    P = int(round(float(observation_space["polytope"].high[0]))) + 1
    return {"goal_vectors": spaces.Box(-1.0, 1.0, (G, 2), np.float64),
            "goal_direction": spaces.Box(-1.0, 1.0, (2,), np.float64),
            "polytope_onehot": spaces.Box(0.0, 1.0, (P,), np.float64)}


def learner_features(space: spaces.Dict, observation) -> dict[str, np.ndarray]:
    """Scaled observations a learner can use, computed from the task's own (so from a dm_env
    time step as well):

    - ``goal_vectors`` ``(G, 2)``: each candidate goal's centre seen from the base,
      ``(c_g - 1/2 - p / s) / L`` with ``c_g`` its cell (1-based), ``p`` the base's position
      (m), ``s`` the cell size (m) and ``L`` the map's side in cells: in [-1, 1]; robot-centred
      in the world frame, which is the base's own (its yaw is held at zero);
    - ``goal_direction`` ``(2,)``: the belief's expected goal vector
      ``sum_g b(g) goal_vectors[g]`` (in [-1, 1]);
    - ``polytope_onehot`` ``(P,)``: the current polytope, one-hot."""
    side = float(space["goal_cells"].high.max())
    cell = float(space["position"].high.max()) / side  # the position's bound is side * s
    cells = np.asarray(observation["goal_cells"], np.float64).reshape(-1, 2)
    here = np.asarray(observation["position"], np.float64).reshape(2) / cell
    vectors = np.clip((cells - 0.5 - here) / side, -1.0, 1.0)
    belief = np.asarray(observation["goal_belief"], np.float64).reshape(-1)
    P = int(round(float(space["polytope"].high[0]))) + 1
    onehot = np.zeros(P)
    v = int(round(float(np.asarray(observation["polytope"]).reshape(-1)[0])))
    onehot[min(max(v, 0), P - 1)] = 1.0
    return {"goal_vectors": vectors,
            "goal_direction": np.clip(belief @ vectors, -1.0, 1.0),
            "polytope_onehot": onehot}


def gym_observation(space: spaces.Dict, observation) -> dict[str, np.ndarray]:
    """A dm_env observation as the Gymnasium one of ``space``: float64 arrays of the spaces'
    shapes, within their bounds, with the learner's features (:func:`learner_features`) when
    ``space`` has them (an agent trained through Gymnasium reads a dm_env time step through
    this, e.g. to be filmed by ``pathpref render --policy``)."""
    out = {}
    for k, v in observation.items():
        box_k = space[k]
        out[k] = np.clip(np.asarray(v, dtype=np.float64).reshape(box_k.shape), box_k.low,
                         box_k.high)
    if "goal_direction" in space.spaces and "goal_cells" in out:
        out.update(learner_features(space, out))
    return out


class PathprefEnv(gym.Env):
    """A dm_control task of :mod:`pathpref_tasks` behind the Gymnasium API (module docstring)."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 4}

    def __init__(self, task: str = "navigate", render_mode: str | None = None,
                 width: int = 480, height: int = 360, environment_kwargs: dict | None = None,
                 time_limit: float | None = None, **task_kwargs: Any):
        if render_mode not in (None, "rgb_array"):
            raise ConfigError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        #: the task's arguments; the reward is the loop-free one unless asked otherwise
        self.task_kwargs = {"reward": GYM_REWARD, "min_goal_distance": GYM_MIN_GOAL_DISTANCE,
                            **task_kwargs}
        self.task_name = task
        self.render_mode = render_mode
        self.width = check_number("width", width, 1, MAX_RENDER, integer=True)
        self.height = check_number("height", height, 1, MAX_RENDER, integer=True)
        self._load = lambda seed: load(task, task_kwargs={**self.task_kwargs, "seed": seed},
                                       environment_kwargs=environment_kwargs,
                                       time_limit=time_limit)
        self._env = self._load(self.task_kwargs.get("seed", 0))
        self._over, self._pushes = False, 0
        a = self._env.action_spec()
        self.action_space = spaces.Discrete(a.num_values) \
            if isinstance(a, specs.DiscreteArray) else \
            spaces.Box(np.float32(a.minimum), np.float32(a.maximum), shape=a.shape,
                       dtype=np.float32)
        task_spaces = {k: box(v) for k, v in self._env.observation_spec().items()}
        if "goal_cells" in task_spaces and "polytope" in task_spaces:
            task_spaces.update(learner_spaces(spaces.Dict(task_spaces)))
        self.observation_space = spaces.Dict(task_spaces)
        self.metadata = {**self.metadata,
                         "render_fps": max(1, round(1.0 / self._env.control_timestep()))}
        vis = self._env.physics.model.vis.global_
        for name, value, most in (("width", self.width, int(vis.offwidth)),
                                  ("height", self.height, int(vis.offheight))):
            if render_mode is not None and value > most:
                self._env.close()
                raise ConfigError(f"{name} must be at most {most} pixels (the scene's "
                                  f"offscreen buffer, 1..{most}), got {value}")

    def _obs(self, ts) -> dict[str, np.ndarray]:
        return gym_observation(self.observation_space, ts.observation)

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Start an episode: the first of ``load(seed=seed)`` when a seed is given, else the
        next one."""
        super().reset(seed=seed)
        if seed is not None:
            self._env = self._load(int(seed))
        ts = self._env.reset()
        self._over, self._pushes = False, 0
        return self._obs(ts), self._info()

    def step(self, action):
        """One step (a decision, ``action`` in 0..8 with 8 = stay; at control rate a velocity
        ``(vx, vy)``)."""
        if self._over:
            raise ConfigError("the episode is over (terminated or truncated); call reset()")
        if isinstance(self.action_space, spaces.Box):
            action = self._env.task.check_action(action)  # complex, shape, range: one line
        ts = self._env.step(action)
        self._over = ts.last()
        terminated = bool(ts.last() and ts.discount == 0.0)
        truncated = bool(ts.last() and not terminated)
        return self._obs(ts), float(ts.reward), terminated, truncated, self._info()

    def _info(self) -> dict[str, Any]:
        """The episode's metrics so far (``Navigate.episode_metrics``: ``success``,
        ``goal_reached``, ``violations``, ``pushes``, ``cues_felt``, ``return``, ...; the
        body's measurements at the last step only), ``t``, the decisions (cell changes
        at control rate) taken, ``is_success`` (``success``, the key SB3 reads),
        ``is_intervention`` (the human pushed during this step, or in ``reset`` for the
        first info: the key gym-hil and LeRobot read) and ``intervention_heading``, the
        heading (0..7) the human meant by the last push of this step, -1 without one."""
        task = self._env.task
        metrics = task.episode_metrics(body=self._over)
        pushes = int(metrics["pushes"])
        pushed = pushes > self._pushes
        self._pushes = pushes
        push = task.body.last_push
        heading = int(push.intended_heading) if pushed and push is not None else -1
        return {**metrics, "t": task.runner.t, "is_success": bool(metrics["success"]),
                "is_intervention": bool(pushed), "intervention_heading": heading}

    def snapshot(self) -> dict[str, Any]:
        """The episode now (:meth:`pathpref_tasks.Environment.snapshot`: physics, parts, task)
        and this env's own count of pushes and whether the episode is over. Through
        ``gym.make``'s wrappers call ``env.unwrapped.snapshot()``; the ``TimeLimit``
        wrapper's step count is the wrapper's, not the episode's."""
        return {"episode": self._env.snapshot(), "over": self._over, "pushes": self._pushes}

    def restore(self, snapshot: dict[str, Any]) -> None:
        """Put the episode of ``snapshot`` (:meth:`snapshot`, of this env or one made with the
        same arguments) back: replaying the same actions gives the same observations,
        rewards and infos bit for bit."""
        if not isinstance(snapshot, dict) or set(snapshot) != {"episode", "over", "pushes"}:
            raise ConfigError("restore takes a snapshot from env.unwrapped.snapshot(), got "
                              f"{type(snapshot).__name__}")
        self._env.restore(snapshot["episode"])
        self._over, self._pushes = snapshot["over"], snapshot["pushes"]

    def render(self):
        """The top camera as an ``(height, width, 3)`` uint8 image (``rgb_array``)."""
        if self.render_mode != "rgb_array":
            return None
        return self._env.physics.render(height=self.height, width=self.width, camera_id="top")

    def close(self) -> None:
        """Release the dm_control environment."""
        self._env.close()


def register_envs() -> None:
    """Register the id of every task (:func:`pathpref_tasks.registry.gym_ids`: the built-in
    ones and other packages') with Gymnasium (idempotent; call again after installing a
    package of tasks)."""
    for env_id, task in gym_ids().items():
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point=ENTRY_POINT, kwargs={"task": task},
                         max_episode_steps=max_episode_steps(task))
