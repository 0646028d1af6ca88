"""Two policies that know the true goal, the references a reward is judged by
(``tests/test_tasks_route.py``): :class:`Oracle` ``("shortest")`` takes the shortest grid path
to the goal whatever the person prefers; ``Oracle("route")`` follows the person's route, the
shortest path that leaves every polytope only toward the person's preferred neighbour
(:func:`pathpref.geometry.following.preferred_move`, the ``oracle`` method's move).

An oracle is a callable of the dm_control task (``env.task``, or ``env.unwrapped.task`` of a
Gymnasium env): at decisions the move 0..7 (8 = stay when no move leads on), at control rate
the velocity toward the centre of the next cell of its path, the next cell chosen once the
base is within :data:`ARRIVED` of the last one's centre and slower than
:data:`ARRIVED_SPEED`, so the base drives the grid path from centre to centre and cuts no
corner (heading for the next centre from wherever the base enters a cell has struck office's
walls). The velocity
(:func:`velocity_to`) is capped so the base can stop on the centre: the plain tracking law
(``k_p d`` up to ``v_max``, ``policy_action``'s) asks for ``v_max`` until 0.25 m before the
centre, and a drive of the default physics (1 m/s, ``a_max`` 0.8 m/s^2) needs 0.63 m to stop
from it, so the base ran past the centre of a cell by a wall, was given the next cell while
still moving and struck the wall (office, classroom).
"""

from __future__ import annotations

import numpy as np

from pathpref.geometry.following import preference_following_distance, preferred_move
from pathpref.geometry.grid import STAY
from pathpref.geometry.world import World
from pathpref.sim.controller import TrackingController

from .navigate import STAY_ACTION
from .navigate_control import CONTROL_TIMESTEPS
from .route_reward import RouteReward

#: the oracles by name
ORACLES = ("shortest", "route")
#: at control rate, the distance (cells) from a cell's centre at which the base has arrived
ARRIVED = 0.15
#: ... and the speed (m/s) below which it has (it must not sweep past the centre)
ARRIVED_SPEED = 0.1
#: the share of the drive's ``a_max`` the oracle plans to brake with (the drive's ramp lags)
BRAKE = 0.8


def stopping_speed(d: float, a: float, hold_s: float) -> float:
    """The largest speed (m/s) a command held for ``hold_s`` may have so that the base, braking
    at ``a`` (m/s^2) after the hold, stops within ``d`` (m): the root of
    ``v hold_s + v^2 / (2 a) = d``, ``a (sqrt(hold_s^2 + 2 d / a) - hold_s)``."""
    return a * (np.sqrt(hold_s * hold_s + 2.0 * max(d, 0.0) / a) - hold_s)


def velocity_to(task, position: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """The oracle's velocity (m/s) from ``position`` toward ``centre`` (m, planar): the
    tracking law's (``k_p d`` up to ``v_max``) capped at :func:`stopping_speed` for the drive's
    ``a_max`` (the task's ``command``; times :data:`BRAKE`) and a command held for the longest
    control step the task accepts, so the base stops on the centre whatever the control step."""
    law = TrackingController(v_max=task.v_max)
    e = np.asarray(centre, float)[:2] - np.asarray(position, float)[:2]
    d = float(np.hypot(*e))
    if d < 1e-9:
        return np.zeros(2)
    speed = min(law.v_max, law.kp * d,
                stopping_speed(d, BRAKE * task.command.a_max, CONTROL_TIMESTEPS[1]))
    return e * (speed / d)


def oracle_togo(kind: str, world: World, pref: np.ndarray, goal: int) -> np.ndarray:
    """Cost-to-go per cell: the grid distance to ``goal`` (``shortest``; the grid's moves are
    symmetric, so the distance from the goal) or the preference-following distance under the
    person's preference ``pref`` (``route``)."""
    if kind == "shortest":
        return world.motion.distances_from(np.array([goal]))[0]
    return preference_following_distance(world, np.asarray(pref, dtype=int), goal)


def oracle_move(kind: str, world: World, pref: np.ndarray, togo: np.ndarray, cell: int) -> int:
    """The ``kind`` oracle's grid move (0..7, or ``STAY``) from ``cell`` (``togo`` of
    :func:`oracle_togo`)."""
    if kind == "route":
        return preferred_move(world, np.asarray(pref, dtype=int), togo, cell)
    m = world.motion
    score = np.where(m.blocked[cell], np.inf, m.cost[cell] + togo[m.next_cell[cell]])
    return int(np.argmin(score)) if np.isfinite(score).any() else STAY


class Oracle:
    """The ``kind`` oracle of the module docstring (``"shortest"`` or ``"route"``)."""

    def __init__(self, kind: str):
        if kind not in ORACLES:
            raise ValueError(f"kind must be one of {ORACLES}, got {kind!r}")
        self.kind = kind
        self._key = self._target_key = None
        self._togo: np.ndarray | None = None
        self._target = self._origin = -1

    def __call__(self, task):
        """The action for the coming step (module docstring)."""
        r, w = task.runner, task.world
        if self._key is not r:  # a new episode
            self._togo = oracle_togo(self.kind, w, r.pref, r.instance.goal_cell)
            self._key = r
        if task.decides:
            a = oracle_move(self.kind, w, r.pref, self._togo, r.cell)
            return STAY_ACTION if a == STAY else a
        b = task.base
        centre = task.scene.cell_centre
        target = self._target
        if self._target_key is not r or (b.cell != target and b.cell != self._origin):
            target = None  # a new episode, or the base left its segment: plan from its cell
        elif b.cell == target and np.hypot(*(np.asarray(b.position)[:2]
                                             - centre(target)[:2])) < ARRIVED * task.cell_size \
                and np.hypot(*np.asarray(b.velocity)[:2]) < ARRIVED_SPEED:
            target = None  # at rest on the target's centre: the next move
        if target is None:
            self._origin = cell = b.cell
            a = oracle_move(self.kind, w, r.pref, self._togo, cell)
            target = cell if a == STAY else int(w.motion.next_cell[cell, a])
            self._target, self._target_key = target, r
        return np.clip(velocity_to(task, b.position, centre(target)), -task.v_max, task.v_max)


def grid_rollout(world: World, start: int, goal: int, pref: np.ndarray, kind: str,
                 gamma: float, t_max: int, goal_reward: float = 50.0) -> dict:
    """The ``kind`` oracle's episode on the grid alone (no physics): its moves from ``start``
    under the ``route`` reward (:class:`~.route_reward.RouteReward`) and the success rule
    (leaving ``v`` toward anything but ``pref[v] >= 0`` is a violation, which ends the
    episode; so does the goal; at most ``t_max`` decisions): ``success``, ``violations``,
    ``steps``, ``return`` (the sum of rewards) and ``discounted`` (with ``gamma``)."""
    pref = np.asarray(pref, dtype=int)
    reward = RouteReward(world, goal, pref, gamma, t_max, goal_reward)
    togo = oracle_togo(kind, world, pref, goal)
    poly = world.cell_polytope
    s, total, disc, violated, t = int(start), 0.0, 0.0, False, 0
    while t < t_max and s != goal and not violated:  # bounded by t_max
        a = oracle_move(kind, world, pref, togo, s)
        s2 = s if a == STAY else int(world.motion.next_cell[s, a])
        v, w = int(poly[s]), int(poly[s2])
        violated = bool(v != w and pref[v] >= 0 and pref[v] != w)
        r = reward(s, s2, a, violated)
        total += r
        disc += gamma ** t * r
        s, t = s2, t + 1
    return {"success": s == goal and not violated, "violations": int(violated), "steps": t,
            "return": total, "discounted": disc}
