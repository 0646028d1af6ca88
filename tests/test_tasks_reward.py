"""The potential-shaped reward (``reward="potential"``, :mod:`pathpref_tasks.reward`): no
closed path earns reward, and a policy that farms the paper's crossing bonus without ever
reaching the goal earns a negative return on every built-in map, driven through the task; staying
costs a straight move per decision (worked by hand)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pathpref_tasks import load
from pathpref_tasks.reward import STAY_COST, move_cost, potential_reward, preference_potential

from pathpref.errors import ConfigError
from pathpref.geometry.grid import STAY
from pathpref.geometry.world import load_world
from pathpref.planning.pomdp import transition_reward


def crossing_farmer(task, rng: np.random.Generator) -> int:
    """Goal-blind: the move with the best one-step paper reward (SPEC 6: preferred crossings
    pay R_p) among those that do not enter the goal cell (ties broken at random by ``rng``,
    which keeps it from sitting on one tie)."""
    r, w = task.runner, task.world
    s, g = r.cell, r.instance.goal_cell
    pref = int(r.pref[int(w.cell_polytope[s])])
    best, value = 8, -math.inf
    for a in range(8):
        s2 = int(w.motion.next_cell[s, a])
        if s2 == g:
            continue
        x = transition_reward(w, s, s2, a, g, pref, task.rewards) + 1e-3 * rng.random()
        if x > value:
            best, value = a, x
    return best


def drive(map_name: str, reward: str) -> tuple[float, bool]:
    env = load("navigate", task_kwargs=dict(map=map_name, seed=0, reward=reward, delta_t=1))
    ts, total, rng = env.reset(), 0.0, np.random.default_rng(0)
    for _ in range(200):  # T_max <= 60 decisions ends it first
        if ts.last():
            break
        ts = env.step(crossing_farmer(env.task, rng))
        total += ts.reward
    reached = bool(env.task.episode_metrics(body=False)["goal_reached"])
    env.close()
    return total, reached


@pytest.mark.parametrize("map_name", ["simple", "office", "classroom"])
def test_crossing_farmer_earns_a_negative_return_with_the_potential(map_name):
    shaped, reached = drive(map_name, "potential")
    assert not reached
    assert shaped < 0.0
    if map_name != "simple":  # the paper's rule pays this policy for circling there
        paper, reached = drive(map_name, "paper")
        assert not reached and paper > 0.0


def test_a_closed_path_earns_minus_its_move_cost():
    """A square (``k`` straight moves of cost 1 each way: the first of the squares of sides
    3, 2, 1 in four orientations through the start of seed 0 on office whose moves are all
    free) returns to its start: its return is ``-4 k`` exactly (the shaping terms cancel),
    within 1e-9."""
    env = load("navigate", task_kwargs=dict(map="office", seed=0, reward="potential"))
    ts, task = env.reset(), env.task
    start, motion = task.runner.cell, task.world.motion

    def closes(loop: list[int]) -> bool:
        cell = start
        for a in loop:
            if motion.blocked[cell, a]:
                return False
            cell = int(motion.next_cell[cell, a])
        return cell == start

    squares = [[d for d in order for _ in range(k)] for k in (3, 2, 1)
               for order in ((0, 2, 4, 6), (0, 6, 4, 2), (4, 2, 0, 6), (4, 6, 0, 2))]
    loop = next(sq for sq in squares if closes(sq))
    total = 0.0
    for a in loop:
        ts = env.step(a)
        total += ts.reward
    assert task.runner.cell == start
    assert abs(total - (-float(len(loop)))) < 1e-9
    env.close()


def test_staying_costs_a_straight_move_per_decision():
    """Worked by hand: staying leaves the cell, so Phi(s') - Phi(s) = 0 and no goal is
    reached; each decision to stay returns -1 (a straight move's cost), three of them -3,
    within 1e-9; the base holds its cell."""
    assert STAY_COST == 1.0
    env = load("navigate", task_kwargs=dict(map="office", seed=0, reward="potential",
                                            delta_t=1))
    env.reset()
    task = env.task
    start, rewards = task.runner.cell, []
    for _ in range(3):
        ts = env.step(8)
        rewards.append(ts.reward)
        assert not ts.last() and task.runner.cell == start
    np.testing.assert_allclose(rewards, [-1.0, -1.0, -1.0], atol=1e-9)
    env.close()


def test_standing_still_a_whole_episode_returns_minus_t_max():
    """Worked by hand: ``T_max`` = 30 decisions on ``simple``, each a stay of cost 1 with no
    change of potential: the episode is cut by the time limit (not the goal) with return
    -30, within 1e-9 (the paper's rule pays staying 0, which a learner settled on)."""
    env = load("navigate", task_kwargs=dict(map="simple", seed=0, reward="potential",
                                            delta_t=1))
    ts, total, n = env.reset(), 0.0, 0
    for _ in range(100):  # T_max = 30 ends it first
        if ts.last():
            break
        ts = env.step(8)
        total += ts.reward
        n += 1
    assert n == 30 and ts.discount == 1.0  # truncated at T_max, not terminal
    assert abs(total - (-30.0)) < 1e-9
    env.close()


def test_move_cost_of_staying_and_of_a_jump():
    """c(s, STAY, s) = 1; a control-rate cell change between cells that are no grid
    neighbours (recorded as STAY) costs the straight distance between their centres: 2 for
    two cells apart in a row, sqrt(5) for (2, 1) apart; the reward of a stay two cells from the
    goal is -1 (the potential does not change)."""
    world = load_world("simple")
    cells = [tuple(int(v) for v in c) for c in world.cells]
    index = {c: i for i, c in enumerate(cells)}
    s, (x, y) = next((i, c) for i, c in enumerate(cells)
                     if (c[0] + 2, c[1]) in index and (c[0] + 2, c[1] + 1) in index)
    assert move_cost(world, s, s, STAY) == 1.0
    assert abs(move_cost(world, s, index[(x + 2, y)], STAY) - 2.0) < 1e-12
    assert abs(move_cost(world, s, index[(x + 2, y + 1)], STAY) - math.sqrt(5.0)) < 1e-12
    goal = index[(x + 2, y)]
    phi = preference_potential(world, goal, -np.ones(world.n_polytopes, dtype=int))
    assert abs(potential_reward(world, phi, s, s, STAY, goal, 50.0) - (-1.0)) < 1e-12


def test_potential_is_minus_the_constrained_cost_to_go():
    """Phi is 0 at the goal and -d(s, g) where no polytope has a preference."""
    world = load_world("simple")
    goal = int(world.n_cells // 2)
    phi = preference_potential(world, goal, -np.ones(world.n_polytopes, dtype=int))
    dist = world.motion.distances_from(np.array([goal]))[0]
    assert phi[goal] == 0.0
    finite = np.isfinite(dist)
    np.testing.assert_allclose(phi[finite], -dist[finite], atol=1e-12)


def test_unknown_reward_is_a_config_error():
    with pytest.raises(ConfigError, match="reward must be one of"):
        load("navigate", task_kwargs=dict(map="simple", reward="loops"))
