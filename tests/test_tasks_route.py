"""The ``-v1`` reward's optimum is the person's route (``pathpref_tasks.route_reward``): two
oracles that know the goal, the shortest path and the person's route
(``pathpref_tasks.oracles``), and wherever their success differs the one that succeeds (always
the route-follower) earns more, in return and in discounted return.

On the grid alone (the reward's arithmetic on the oracles' paths, the success rule's
violations) over 40 instances of each built-in map and a generated plan; through the physics,
on every registered ``-v1`` id, on an instance pinned per map where the two differ (worked out
beforehand on the grid: the shortcut crosses a face the person does not want crossed, the route
is longer): ``Navigate-v1`` on ``simple``, ``office``, ``classroom`` and a generated plan,
``NavigateControl-v1`` on the same four (see ``CASES``), the arm's ids (a decision
costs seconds) on ``simple``."""

from __future__ import annotations

import gymnasium as gym
import pathpref_tasks  # noqa: F401  # registers the ids
import pytest
from pathpref_tasks.gym_v1 import gym_id_v1
from pathpref_tasks.oracles import Oracle, grid_rollout
from pathpref_tasks.registry import BUILTIN_TASKS
from pathpref_tasks.route_reward import DISCOUNT, RouteReward, violation_penalty

from pathpref.episode.instances import human_preference, sample_instance
from pathpref.geometry.generate import floor_plan
from pathpref.geometry.maps import parse_map
from pathpref.geometry.world import World, load_world

#: the generated plan of the tests (``floor_plan(21)``, never one the example trains on)
PLAN_SEED = 21
#: map -> a ``seed`` of the ``-v1`` ids whose first episode the two oracles end differently
#: (the shortcut violates after 3, 2, 11 and 3 decisions, the route arrives after 10, 20, 15
#: and 10)
PINNED = {"simple": 1, "office": 6, "classroom": 4, "plan": 0}


def plan_map() -> dict:
    return floor_plan(PLAN_SEED, name=f"plan{PLAN_SEED}")


def test_penalty_formula():
    # F_max (1 + (1 - gamma)(T - 1)) against F_max gamma^-(T - 1): the larger
    assert violation_penalty(10.0, 1.0, 30) == pytest.approx(10.0)
    assert violation_penalty(10.0, 0.99, 30) == pytest.approx(10.0 * 0.99 ** -29, rel=1e-12)
    assert violation_penalty(10.0, 0.9, 2) == pytest.approx(10.0 * max(1.1, 1 / 0.9))


@pytest.mark.parametrize("map_name", ["simple", "office", "classroom", "plan"])
def test_grid_route_earns_more_where_success_differs(map_name):
    w = World.from_spec(parse_map(plan_map())) if map_name == "plan" else load_world(map_name)
    differ = 0
    for seed in range(40):
        inst = sample_instance(w, seed, 10, min_distance=4.0)
        pref = human_preference(w, inst, False)
        short, route = (grid_rollout(w, inst.start, inst.goal_cell, pref, kind, DISCOUNT,
                                     w.spec.t_max) for kind in ("shortest", "route"))
        if route["success"]:  # the route's return: R_g plus (1 - gamma) F >= 0 a step
            assert route["return"] >= 50.0 - 1e-9
            assert route["discounted"] >= DISCOUNT ** (route["steps"] - 1) * 50.0 - 1e-9
        if short["violations"]:  # any episode with a violation: below 0, both ways
            assert short["return"] < 0.0 and short["discounted"] < 0.0
        if short["success"] != route["success"]:
            differ += 1
            assert route["success"]  # the shortcut never succeeds where the route fails
            assert route["return"] > short["return"]
            assert route["discounted"] > short["discounted"]
    assert differ >= (1 if map_name == "plan" else 5)


def test_route_reward_steps_worked_by_hand(simple):
    # on the route each step earns (1 - gamma) F(s'); the step into the goal R_g besides
    inst = sample_instance(simple, 1, 10, min_distance=4.0)
    pref = human_preference(simple, inst, False)
    rr = RouteReward(simple, inst.goal_cell, pref, 0.9, 30, 50.0)
    s = inst.start
    from pathpref.geometry.following import preferred_move

    for _ in range(30):
        a = preferred_move(simple, pref, rr.togo, s)
        s2 = int(simple.motion.next_cell[s, a])
        goal = 50.0 if s2 == inst.goal_cell else 0.0
        assert rr(s, s2, a, False) == pytest.approx(0.1 * rr.togo[s2] + goal, abs=1e-9)
        assert rr(s, s2, a, True) == pytest.approx(0.1 * rr.togo[s2] - rr.penalty, abs=1e-9)
        s = s2
        if s == inst.goal_cell:
            break
    assert s == inst.goal_cell


V1 = {name: gym_id_v1(name) for name in BUILTIN_TASKS}
NAMES = {i: name for name, i in V1.items()}


def drive(env_id: str, map_, seed: int, kind: str) -> tuple[float, float, dict]:
    """One episode of the ``kind`` oracle: its return, its discounted return (``gamma`` per
    rewarded step: per decision, per cell change at control rate) and last info."""
    control = not BUILTIN_TASKS[NAMES[env_id]].decides
    extra = {"environment_kwargs": {"control_timestep": 0.1}} if control else {}
    env = gym.make(env_id, map=map_, seed=seed, delta_t=1, **extra)
    env.reset()
    task, oracle = env.unwrapped._env.task, Oracle(kind)
    total, disc, g = 0.0, 0.0, 1.0
    for _ in range(5000):  # the task's limits end it first
        _, r, term, trunc, info = env.step(oracle(task))
        total += r
        if r != 0.0 or not control:
            disc, g = disc + g * r, g * task.gamma
        if term or trunc:
            break
    env.close()
    return total, disc, info


CASES = [(V1["navigate"], m) for m in ("simple", "office", "classroom", "plan")]
# at control rate on every map too: the oracles' velocity lets the drive (1 m/s, a_max 0.8 m/s^2)
# stop on each cell's centre (pathpref_tasks.oracles.velocity_to); with the plain tracking law
# they ran past the centre of a cell by a wall and struck it (office seed 6, classroom seed 4),
# and the route-follower's base cut through a cell of another polytope (plan seed 0)
CASES += [(V1["navigate_control"], m) for m in ("simple", "office", "classroom", "plan")]
CASES += [(V1[t], "simple") for t in ("carry", "carry_control")]


def test_every_v1_id_is_covered():
    assert {i for i, _ in CASES} == set(V1.values())
    assert all(i in gym.registry for i in V1.values())


@pytest.mark.parametrize(("env_id", "map_name"), CASES)
def test_physics_route_earns_more_where_success_differs(env_id, map_name):
    map_ = plan_map() if map_name == "plan" else map_name
    seed = PINNED[map_name]
    (r_s, d_s, short), (r_r, d_r, route) = (drive(env_id, map_, seed, k)
                                            for k in ("shortest", "route"))
    assert short["violations"] >= 1 and not short["success"]
    assert route["success"] and route["violations"] == 0
    assert short["contact_safe"] and route["contact_safe"]  # neither strikes a wall
    assert r_r > r_s and d_r > d_s
    assert r_s < 0.0
    if BUILTIN_TASKS[NAMES[env_id]].decides:  # at decisions the grid's route exactly
        assert r_r >= 50.0 - 1e-9
    assert abs(r_r - route["return"]) < 1e-9  # the task's own sum of the rewards
