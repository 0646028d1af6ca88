"""The ``-v1`` Gymnasium ids: ``pathpref/Navigate-v1``, ``pathpref/NavigateControl-v1``,
``pathpref/Carry-v1`` and ``pathpref/CarryControl-v1`` (and ``-v1`` of every task another package
registers), :class:`PathprefEnvV1`: the reward whose optimum is the person's route
(:mod:`.route_reward`) and observations of the same spaces on every map, so an agent trained on
some maps runs on any other. The ``-v0`` ids (:mod:`.gym`) stay as they were.

Fixed-size features are computed from the task (:func:`fixed_features`): the candidates'
belief padded to :data:`MAX_GOALS`, the goals and the exits of the current polytope seen from
the base in cells over a fixed scale (:data:`VECTOR_SCALE_CELLS`, not the map's side), the
belief's top :data:`TOP_EXITS` exits, and the occupancy of the cells around the base.
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from pathpref.errors import ConfigError
from pathpref.geometry.world import World

from .gym import PathprefEnv, box, max_episode_steps
from .registry import gym_id, task_names

#: the largest number of goal candidates (``n_goals``) the ``-v1`` observations carry
MAX_GOALS = 16
#: how many of the current polytope's exits the observation carries (the belief's likeliest)
TOP_EXITS = 4
#: the local occupancy grid's radius: ``(2R + 1) x (2R + 1)`` cells around the base
OCCUPANCY_RADIUS = 3
#: cells per unit of the goal and exit vectors (clipped to [-1, 1] beyond)
VECTOR_SCALE_CELLS = 32.0
#: the dm_env observations the ``-v1`` ids drop: their bounds or shapes depend on the map
#: (its size, its polytopes, the candidates' count), or they are not egocentric
MAP_DEPENDENT = ("position", "cell", "goal_cells", "goal_belief", "polytope", "entropy")
#: the entry point of the ``-v1`` ids
ENTRY_POINT_V1 = "pathpref_tasks.gym_v1:PathprefEnvV1"


def gym_id_v1(name: str) -> str:
    """The ``-v1`` id of task ``name`` (:func:`pathpref_tasks.registry.gym_id` with ``-v1``)."""
    return gym_id(name)[:-len("-v0")] + "-v1"


def fixed_spaces() -> dict[str, spaces.Box]:
    """The spaces of :func:`fixed_features` (the same on every map; flat vectors, which
    stable-baselines3's checker asks for: row-major flattenings of the tables of
    :class:`PathprefEnvV1`)."""
    G, K, n = MAX_GOALS, TOP_EXITS, 2 * OCCUPANCY_RADIUS + 1
    return {
        "goal_belief": spaces.Box(0.0, 1.0, (G,), np.float64),
        "goal_mask": spaces.Box(0.0, 1.0, (G,), np.float64),
        "goal_vectors": spaces.Box(-1.0, 1.0, (2 * G,), np.float64),
        "goal_direction": spaces.Box(-1.0, 1.0, (2,), np.float64),
        "goal_entropy": spaces.Box(0.0, 1.0, (1,), np.float64),
        "exit_probs": spaces.Box(0.0, 1.0, (K,), np.float64),
        "exit_vectors": spaces.Box(np.tile([-1.0, -1.0, 0.0], K), np.ones(3 * K), (3 * K,),
                                   np.float64),
        "local_occupancy": spaces.Box(0.0, 1.0, (n * n,), np.float64),
        "time_left": spaces.Box(0.0, 1.0, (1,), np.float64),
    }


class MapFeatures:
    """What the features need of a world, computed once per world: its occupancy padded by
    :data:`OCCUPANCY_RADIUS` (1: no free cell there, or off the map) and the centre of each
    face between two polytopes (the mean of the midpoints of the grid moves that cross it,
    in cell coordinates, 1-based)."""

    _cache: dict[int, tuple[World, MapFeatures]] = {}

    def __init__(self, world: World):
        R = OCCUPANCY_RADIUS
        w, h = world.spec.width, world.spec.height
        occ = np.ones((w + 2 * R, h + 2 * R))
        xy = world.cells.astype(int)
        occ[xy[:, 0] - 1 + R, xy[:, 1] - 1 + R] = 0.0
        #: ``occupied[x - 1 + R, y - 1 + R]`` for cell ``(x, y)``
        self.occupied = occ
        m, poly = world.motion, world.cell_polytope
        n = world.n_cells
        src = np.repeat(np.arange(n), 8)
        dst = m.next_cell.ravel()
        ok = ~m.blocked.ravel() & (poly[src] != poly[dst])
        mids = (world.cells[src[ok]] + world.cells[dst[ok]]) / 2.0
        keys = poly[src[ok]].astype(np.int64) * world.n_polytopes + poly[dst[ok]]
        #: ``(v, w)`` -> centre of their face (cells)
        self.faces: dict[tuple[int, int], np.ndarray] = {}
        for key in np.unique(keys):
            v, u = divmod(int(key), world.n_polytopes)
            self.faces[(v, u)] = mids[keys == key].mean(axis=0)
        #: each polytope's centroid (cells): the exit's centre when no move crosses a face
        self.centroids = np.array([world.cells[poly == v].mean(axis=0)
                                   for v in range(world.n_polytopes)])

    @classmethod
    def of(cls, world: World) -> MapFeatures:
        """The features of ``world``, cached while the world lives (keyed by identity)."""
        hit = cls._cache.get(id(world))
        if hit is None or hit[0] is not world:
            if len(cls._cache) > 64:
                cls._cache.clear()
            hit = cls._cache[id(world)] = (world, cls(world))
        return hit[1]


def fixed_features(task) -> dict[str, np.ndarray]:
    """The ``-v1`` features of a dm_control task's current state (:class:`PathprefEnvV1`'s
    docstring gives each)."""
    world, r = task.world, task.runner
    feats = MapFeatures.of(world)
    here = np.asarray(task.base.position, float)[:2] / task.cell_size + 0.5  # cells, 1-based
    G = len(r.instance.goals)
    goals = world.cells[list(r.instance.goals)].astype(float)
    v = int(world.cell_polytope[r.cell])
    marginal, _ = task._belief_observation(v)
    belief = np.zeros(MAX_GOALS)
    belief[:G] = marginal
    mask = np.zeros(MAX_GOALS)
    mask[:G] = 1.0
    vectors = np.zeros((MAX_GOALS, 2))
    vectors[:G] = np.clip((goals - here) / VECTOR_SCALE_CELLS, -1.0, 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        h = -np.nansum(np.where(marginal > 0, marginal * np.log(marginal), 0.0))
    exits_p, exits_v = np.zeros(TOP_EXITS), np.zeros((TOP_EXITS, 3))
    nbrs = list(world.graph.neighbors[v])
    if nbrs:
        belief_obj = r.policy.belief
        p = belief_obj.preference_marginal(v) if hasattr(belief_obj, "preference_marginal") \
            else np.full(len(nbrs), 1.0 / len(nbrs))
        order = np.argsort(-np.asarray(p), kind="stable")[:TOP_EXITS]
        for i, k in enumerate(order):
            u = int(nbrs[k])
            c = feats.faces.get((v, u), feats.centroids[u])
            d = c - here
            dist = float(np.hypot(*d))
            exits_p[i] = float(p[k])
            if dist > 1e-9:
                exits_v[i, :2] = d / dist
            exits_v[i, 2] = min(dist / VECTOR_SCALE_CELLS, 1.0)
    R = OCCUPANCY_RADIUS
    x, y = (int(c) for c in world.cells[r.cell])
    occ = feats.occupied[x - 1:x + R + R, y - 1:y + R + R].T  # [dy + R, dx + R]
    return {"goal_belief": belief, "goal_mask": mask, "goal_vectors": vectors.ravel(),
            "goal_direction": np.clip(belief @ vectors, -1.0, 1.0),
            "goal_entropy": np.array([min(h / math.log(MAX_GOALS), 1.0)]),
            "exit_probs": exits_p, "exit_vectors": exits_v.ravel(),
            "local_occupancy": occ.ravel(),
            "time_left": np.array([max(0.0, 1.0 - r.t / r.spec.t_max)])}


class PathprefEnvV1(PathprefEnv):
    """A dm_control task of :mod:`pathpref_tasks` behind the Gymnasium API, version 1: the
    person's route as the reward's optimum, observations of the same spaces on every map.

    **Action space.** As ``-v0``: ``Discrete(9)`` at decisions (0..7: a move to the grid
    neighbour N, NE, E, SE, S, SW, W, NW; 8: stay), ``Box(-v_max, v_max, (2,), float32)`` at
    control rate (the base's velocity, m/s, world frame).

    **Observation space.** A ``Dict`` of float64 ``Box`` es, identical on every map (built-in,
    JSON, generated) for a given task and physics. World frame = the base's frame (its yaw is
    held at zero); vectors in cells over ``S = 32`` (:data:`VECTOR_SCALE_CELLS`), clipped to
    [-1, 1]:

    ==================== ============ =================================================
    key                  shape        meaning
    ==================== ============ =================================================
    ``heading``          (8,)         the push detected for the coming step, one-hot
                                      (N, NE, ..., NW); zeros when none
    ``detector_active``  (1,)         the detector is reading a cue now
    ``force``            (2,)         filtered push force (N), within +-200
    ``push_felt``        (4,)         the step's strongest cue: peak N, cos, sin, s
    ``cues_felt``        (8,)         cues read during the step per heading
    ``detector_active_s`` (1,)        seconds of the step with the detector active
    ``goal_belief``      (16,)        P(g) of each candidate, zero-padded to 16
    ``goal_mask``        (16,)        1 for a real candidate, 0 for padding
    ``goal_vectors``     (32,)        each candidate from the base, ``(c_g - p) / S``
                                      (16 rows of x, y, flattened)
    ``goal_direction``   (2,)         the belief's expected goal vector
    ``goal_entropy``     (1,)         H(P(g)) / log 16
    ``exit_probs``       (4,)         the belief's P(p_v = w) of the current polytope's
                                      likeliest 4 exits w, descending, zero-padded
    ``exit_vectors``     (12,)        each of those exits' face centre from the base:
                                      unit direction (2) and distance / S (4 rows of
                                      3, flattened); the first row is the preferred
                                      (likeliest) exit's direction
    ``local_occupancy``  (49,)        1 where no free cell is (obstacle, off the map):
                                      the 7 x 7 cells ``[dy + 3, dx + 3]`` around the
                                      base's cell, flattened; dx east, dy north
    ``time_left``        (1,)         1 - t / T_max
    ``velocity``         (2,)         (control rate) base velocity, m/s, within +-5
    ``tray_tilt``,       (1,), (3,)   (carry ids) the tray's tilt (deg) and position (m)
    ``tray_position``
    ==================== ============ =================================================

    The map-dependent dm_env observations (:data:`MAP_DEPENDENT`: absolute position and
    cell, candidate cells, the polytope's index, the joint entropy, whose bounds grow with the
    map) are left out; ``n_goals`` may be at most 16.

    **Reward.** ``reward="route"`` (:mod:`pathpref_tasks.route_reward`): per decision (at
    control rate per cell change) ``-c + gamma Phi(s') - Phi(s) + 50 [goal] - P [violation]``
    with ``Phi = -F``, the cost-to-go along the person's preferred route (every exit, the
    true preference), ``gamma`` the task argument (0.99 by default, the example's training
    discount) and ``P`` a per-instance penalty large enough that an episode with a violation
    returns less than 0, the person's route at least 50.

    **Episode end.** ``terminated`` at the goal, at the first violation of the person's
    preference (success is impossible after one) and at an unsafe contact; ``truncated``
    after ``T_max`` decisions (cell changes at control rate) or the time limit.
    ``info["is_success"]``: goal reached without a violation.

    **Arguments.** Those of ``-v0`` (``map``, ``method``, ``delta_t``, ``seed``, ``n_goals``,
    ``physics``, ...; :class:`~pathpref_tasks.gym.PathprefEnv`), ``gamma``, ``human``
    (``"map"``, the default, or ``"consistent"``: the person pushes along one route to the
    true goal, as ``pathpref evaluate --human``) and ``reward`` to select another rule.

    **Version history.**

    * v1: the reward whose optimum is the person's route (violations end the episode), the
      shaping discounted with ``gamma``; observations of fixed size on every map; the
      ``human`` argument (also on v0).
    * v0: the potential-shaped reward (undiscounted; the first preferred exit only), the
      task's observations plus ``goal_vectors``, ``goal_direction`` and
      ``polytope_onehot``, whose sizes depend on the map.
    """

    def __init__(self, task: str = "navigate", render_mode: str | None = None,
                 width: int = 480, height: int = 360, environment_kwargs: dict | None = None,
                 time_limit: float | None = None, **task_kwargs: Any):
        task_kwargs.setdefault("reward", "route")
        n_goals = task_kwargs.get("n_goals", 10)
        if isinstance(n_goals, int) and n_goals > MAX_GOALS:
            raise ConfigError(f"n_goals must be at most {MAX_GOALS} for the -v1 ids (their "
                              f"observations are padded to {MAX_GOALS}), got {n_goals}")
        super().__init__(task, render_mode, width, height, environment_kwargs, time_limit,
                         **task_kwargs)
        kept = {k: box(s) for k, s in self._env.observation_spec().items()
                if k not in MAP_DEPENDENT}
        self.observation_space = spaces.Dict({**kept, **fixed_spaces()})
        self._kept = tuple(kept)

    def _obs(self, ts) -> dict[str, np.ndarray]:
        space = self.observation_space
        out = {k: np.clip(np.asarray(ts.observation[k], np.float64).reshape(space[k].shape),
                          space[k].low, space[k].high) for k in self._kept}
        out.update(fixed_features(self._env.task))
        return out


def register_envs_v1() -> None:
    """Register the ``-v1`` id of every task (idempotent, as
    :func:`pathpref_tasks.gym.register_envs`)."""
    for name in task_names():
        env_id = gym_id_v1(name)
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point=ENTRY_POINT_V1, kwargs={"task": name},
                         max_episode_steps=max_episode_steps(name))
