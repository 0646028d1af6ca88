"""Problem instances (SPEC 9): start, goal candidates and true goal, reproducible from a seed.

Start: a uniformly drawn free cell. Candidates: ``n_goals`` cells drawn without replacement
from the free cells other than the start that the start can reach, restricted to the map's
``goal_band`` when it has one (office: x in 2..10, y in 8..9). True goal: uniform among the
candidates (the paper's protocol, ``human="map"``).

With ``human="consistent"`` the human's preference depends on the goal: the map's preference
completed into an in-arborescence rooted at the goal's polytope ``r``
(:func:`~pathpref.geometry.following.consistent_preference`): ``q = p`` wherever following the
map's preference reaches ``r``; ``q_r = -1``; every other polytope of ``r``'s component (a
route's end, polytopes past the goal or on loops that miss it) takes the first move of the path
to ``r`` with the fewest departures from the map's preference, then the fewest polytope changes
(ties: the map's exit, then the lowest index). Following ``q`` from anywhere in the component
reaches ``r`` with no cycle: ``q`` lies in the support of the robust preset's route prior, and
the human, the ``oracle`` and the success rule all use this one ``q``. In ``r`` itself the human's
route and pushes stay inside ``r`` wherever the goal can be reached without leaving it (the goal's
polytope is held: :mod:`pathpref.geometry.following`), so the route never leaves a polytope by a
face ``q`` forbids, nor the goal's polytope to come back to it. (The map's preference
with the goal-only push in a route's end sent the human out of the end into polytopes pointing
back along the route: back-and-forth pushes, mutual evidence in the belief.)

The true goal is drawn uniformly among the candidates ``g`` that the map's preference leads to
from the start and that ``q`` reaches in time::

    departures_g(v(start)) = 0   and   F_q(start, g) <= t_max

with ``F_q`` the length of the shortest path that leaves each polytope ``v`` only toward ``q_v``
(:func:`~pathpref.geometry.following.preference_following_distance`; the oracle's path).
A human never prefers a route that cannot reach where they want to go; under the paper's draw
such instances exist (on ``classroom`` the clockwise loop misses the goal's polytope in about
40% of instances) and no method can succeed on them. When no candidate qualifies, the start and
candidates are drawn again from the same seed stream.
"""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError, MapError
from ..geometry.following import consistent_preference, preference_following_distance
from ..geometry.world import World

#: how the human's preference relates to its goal (see module docstring)
HUMANS = ("map", "consistent")


@dataclass(frozen=True)
class Instance:
    """Cell indices of the start and the candidates; ``true_goal`` indexes ``goals``."""

    start: int
    goals: tuple[int, ...]
    true_goal: int

    @property
    def goal_cell(self) -> int:
        """Cell index of the true goal."""
        return self.goals[self.true_goal]


def seed_for(*parts: int) -> int:
    """A 63-bit seed derived from integers (numpy SeedSequence), stable across platforms."""
    return int(np.random.SeedSequence([int(p) for p in parts]).generate_state(2, np.uint64)[0]
               >> np.uint64(1))


def goal_pool(world: World, start: int, min_distance: float = 0.0) -> np.ndarray:
    """Cells that may be goal candidates for this start (see module docstring); with
    ``min_distance`` > 0 only those at least that grid distance ``d(start, g)`` (cells) away."""
    dist = world.motion.distances_from(np.array([start]))[0]
    pool = np.isfinite(dist)
    pool[start] = False
    if min_distance > 0:
        pool &= dist >= min_distance
    band = world.spec.goal_band
    if band:
        x, y = world.cells[:, 0], world.cells[:, 1]
        pool &= (x >= band["x"][0]) & (x <= band["x"][1]) & (y >= band["y"][0]) & (
            y <= band["y"][1]
        )
    return np.flatnonzero(pool)


def sample_instance(world: World, seed: int, n_goals: int = 10,
                    consistent: bool = False, t_max: float = np.inf,
                    min_distance: float = 0.0) -> Instance:
    """Draw an instance from ``seed`` (see module docstring). ``min_distance`` > 0 keeps every
    candidate at least that grid distance from the start (a start that leaves too few such
    cells is drawn again); 0, the paper's draw, leaves the draws as they were."""
    if n_goals < 1:
        raise ConfigError(f"--goals must be at least 1, got {n_goals}")
    rng = np.random.default_rng(seed)
    # a start must leave enough candidates; redraw (deterministically) when it does not
    for _ in range(1000):
        start = int(rng.integers(world.n_cells))
        pool = goal_pool(world, start, min_distance)
        if len(pool) >= n_goals:
            goals = tuple(int(g) for g in rng.choice(pool, size=n_goals, replace=False))
            if not consistent:
                return Instance(start, goals, int(rng.integers(n_goals)))
            ok = np.flatnonzero([consistent_reach(world, g, start) <= t_max for g in goals])
            if len(ok):
                return Instance(start, goals, int(ok[rng.integers(len(ok))]))
    if consistent:
        raise ConfigError(
            f"map '{world.name}': in 1000 draws no start had a goal candidate that its "
            "preference leads to; check the map's preference or use the map's human")
    raise too_few_candidates(world.name, n_goals, world.n_cells)


def too_few_candidates(name: str, n_goals: int, free_cells: int) -> ConfigError:
    """The error of a map with fewer than ``n_goals`` cells besides the start."""
    return ConfigError(
        f"map '{name}' has too few candidate cells for {n_goals} goal candidates "
        f"(at most {free_cells - 1} free cells, fewer in the goal band); lower --goals"
    )


def consistent_reach(world: World, goal: int, start: int) -> float:
    """The consistent human's route length from ``start`` to ``goal`` (the oracle's path, see
    module docstring); inf when the map's preference does not lead there from the start."""
    q, departures = consistent_preference(world, world.require_preference(),
                                          int(world.cell_polytope[goal]))
    if departures[world.cell_polytope[start]] != 0:
        return float("inf")
    return float(preference_following_distance(world, q, goal)[start])


def fixed_instance(world: World, start: tuple[int, int], goals: list[tuple[int, int]],
                   true_goal: int) -> Instance:
    """An instance given by cells, checked: free cells, distinct, reachable from the start."""
    s = world.cell(start, "start")
    g = [world.cell(c, f"goal candidate {k + 1}") for k, c in enumerate(goals)]
    if len(set(g)) != len(g) or s in g:
        raise ConfigError("goal candidates must be distinct cells other than the start")
    if not 0 <= true_goal < len(g):
        raise ConfigError(f"true goal index {true_goal} is not among the {len(g)} candidates")
    d = world.motion.distances_from(np.array([s]))[0, g]
    if not np.isfinite(d).all():
        k = int(np.flatnonzero(~np.isfinite(d))[0])
        raise MapError(f"goal candidate {tuple(goals[k])} cannot be reached from {tuple(start)}")
    return Instance(s, tuple(g), int(true_goal))


def episode_instance(world: World, fixed: str, instance_seed: int, n_goals: int, human: str,
                     t_max: int) -> tuple[Instance, bool]:
    """An episode's instance (pinned by the JSON ``fixed``, else drawn from
    ``instance_seed``), and whether the goal's polytope carries no preference."""
    if fixed:
        f = json.loads(fixed)
        inst = fixed_instance(world, tuple(f["start"]), [tuple(g) for g in f["goals"]],
                              int(f["true_goal"]))
        return inst, bool(f.get("free_goal_polytope", False))
    return sample_instance(world, instance_seed, n_goals, consistent=human == "consistent",
                           t_max=t_max), False


def human_preference(world: World, inst: Instance, free_goal_polytope: bool,
                     human: str = "map") -> np.ndarray:
    """The simulated human's preference per polytope. ``human="map"`` (the paper's protocol):
    the map's, with none (-1) in the goal's polytope when ``free_goal_polytope``.
    ``human="consistent"``: the map's completed into an in-arborescence rooted at the goal's
    polytope (module docstring; the goal's polytope has none, so ``free_goal_polytope`` holds
    already)."""
    if human == "consistent":
        return consistent_preference(world, world.require_preference(),
                                     int(world.cell_polytope[inst.goal_cell]))[0]
    pref = world.require_preference().copy()
    if free_goal_polytope:
        pref[world.cell_polytope[inst.goal_cell]] = -1
    return pref


#: The instance of the paper's Fig. 4 on ``simple`` (start (1,1), candidates (1..10, 8), true
#: goal (1, 8); the goal's polytope carries no preference), as an ``EpisodeSpec.fixed``.
FIG4 = json.dumps({"start": [1, 1], "goals": [[x, 8] for x in range(1, 11)], "true_goal": 0,
                   "free_goal_polytope": True}, sort_keys=True)
