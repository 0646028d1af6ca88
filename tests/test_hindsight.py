"""Hindsight optimisation (:mod:`pathpref.planning.hindsight`, ``--methods hindsight``): its
value by hand, the oracle's route when the hypothesis is known, and the doors it is offered in."""

from __future__ import annotations

import numpy as np
import pytest

from pathpref.errors import ConfigError
from pathpref.inference.human import ObservationModel
from pathpref.inference.routes import RouteBelief
from pathpref.planning.crossing import route_steps
from pathpref.planning.hindsight import hindsight_action, hindsight_values, past_against
from pathpref.planning.policies import PolicyContext, make_policy, resolve_methods
from pathpref.planning.pomcp import POMCP
from pathpref.planning.pomdp import get_preset


def _planner(world, goals, depth=60):
    model = ObservationModel.build(world, goals)
    rewards = get_preset("robust-slack").path_preference.for_mission(depth)
    return POMCP(world, goals, rewards, queries=1000, tables=model.tables), RouteBelief(model)


def _q(planner, cell, depth, pool_g, pool_theta, past=None):
    r = planner.rewards
    past = np.zeros(len(pool_g), np.int64) if past is None else past
    return hindsight_values(cell, depth, pool_g, pool_theta, past, planner.goal_cells,
                            planner.goal_poly, planner.cell_poly, planner.next_cell,
                            planner.cross_slot, planner.moves, float(r.discount),
                            float(r.arrival), float(r.goal_after_violation))


def test_values_by_hand(simple):
    """At (8, 8) with two particles, one for the goal at (9, 9) (one diagonal step away, the
    same polytope) and one for the far goal at (1, 8) (7 steps away), and 2 steps left: the move
    onto the goal is worth 1/2 (the near particle arrives now, strictly; the far one cannot
    arrive), a move one step from the goal 1/2 gamma, a move two steps from it 0. With one past
    crossing against the near particle's exits, its arrival pays alpha + (1 - alpha) rho."""
    goals = np.array([simple.cell((9, 9)), simple.cell((1, 8))])
    planner, belief = _planner(simple, goals)
    s = simple.cell((8, 8))
    pool_g, pool_theta = planner.particles(belief, 3)
    near = np.flatnonzero(pool_g == 0)[0]
    far = np.flatnonzero(pool_g == 1)[0]
    pg, pt = pool_g[[near, far]], pool_theta[[near, far]]
    onto = int(np.flatnonzero(planner.next_cell[s] == goals[0])[0])
    gamma, r = planner.rewards.discount, planner.rewards
    q = _q(planner, s, 2, pg, pt)
    assert q[onto] == pytest.approx(0.5, abs=1e-12)
    one_away = [a for a in range(8) if a != onto and max(
        abs(np.subtract(simple.cells[planner.next_cell[s, a]], (9, 9)))) == 1
        and planner.cell_poly[planner.next_cell[s, a]] == planner.cell_poly[s]]
    assert one_away
    for a in one_away:
        assert q[a] == pytest.approx(0.5 * gamma, abs=1e-12)
    two_away = [a for a in range(8) if max(
        abs(np.subtract(simple.cells[planner.next_cell[s, a]], (9, 9)))) == 2]
    assert two_away
    for a in two_away:
        assert q[a] == pytest.approx(0.0, abs=1e-12)
    q1 = _q(planner, s, 2, pg, pt, np.array([1, 0]))
    assert q1[onto] == pytest.approx(0.5 * (r.arrival + (1 - r.arrival) * r.goal_after_violation),
                                     abs=1e-12)


def test_past_against_by_hand(simple):
    """A transition counts against a particle when it leaves a polytope by another face than the
    particle's exit, never in the particle's goal polytope."""
    goals = np.array([simple.cell((9, 9)), simple.cell((9, 1))])
    planner, belief = _planner(simple, goals)
    pool_g, pool_theta = planner.particles(belief, 5)
    j = 0
    g = int(pool_g[j])
    v = next(v for v in range(len(planner.nbr))
             if v != planner.goal_poly[g] and (planner.nbr[v] >= 0).sum() >= 2)
    pref = int(planner.nbr[v, pool_theta[j, v]])
    other = int(next(u for u in planner.nbr[v] if u >= 0 and u != pref))
    gp = int(planner.goal_poly[g])
    pg, pt = pool_g[[j]], pool_theta[[j]]
    assert past_against(planner, [(v, pref)], pg, pt)[0] == 0
    assert past_against(planner, [(v, other)], pg, pt)[0] == 1
    assert past_against(planner, [(v, other), (v, other), (v, pref)], pg, pt)[0] == 2
    w = int(next(u for u in planner.nbr[gp] if u >= 0))
    assert past_against(planner, [(gp, w)], pg, pt)[0] == 0


@pytest.mark.parametrize("start", [(4, 2), (1, 8)])
def test_known_hypothesis_follows_the_persons_route(simple, start):
    """With every particle the same ``(g, p)``, hindsight's moves cross only by ``p``'s exits and
    reach ``g`` in the steps of the person's route (the preferred route pays 1, the shortcut at
    most alpha + (1 - alpha) rho = 0.28, and the routes here differ by far fewer than the 76
    steps that would make gamma^dL fall below that)."""
    goals = np.array([simple.cell((9, 9)), simple.cell((9, 1)), simple.cell((1, 8))])
    planner, belief = _planner(simple, goals)
    s = simple.cell(start)
    pool_g, pool_theta = planner.particles(belief, 11)
    for j in range(min(len(pool_g), 12)):
        g, theta = int(pool_g[j]), pool_theta[j]
        if planner.goal_cells[g] == s:
            continue
        pg, pt = np.full(4, g), np.repeat(theta[None], 4, axis=0)
        expect = int(route_steps(s, 60, pg[:1], pt[:1], planner.goal_cells, planner.cell_poly,
                                 planner.next_cell, planner.moves)[0])
        cell, steps = s, 0
        while cell != planner.goal_cells[g] and steps < 60:
            a = int(np.argmax(_q(planner, cell, 60 - steps, pg, pt)))
            nxt = int(planner.next_cell[cell, a])
            v, u = int(planner.cell_poly[cell]), int(planner.cell_poly[nxt])
            if u != v and v != planner.goal_poly[g]:
                assert u == planner.nbr[v, theta[v]], f"particle {j}: left {v} for {u}"
            cell, steps = nxt, steps + 1
        assert cell == planner.goal_cells[g]
        assert steps == expect


def test_methods_and_presets(simple):
    """'all' stays the paper's four; 'baselines' names hindsight; a preset without the route
    prior is refused in one line that names the presets that work."""
    assert "hindsight" not in resolve_methods(["all"])
    assert resolve_methods(["baselines"]) == ["hindsight"]
    goals = np.array([simple.cell((9, 9)), simple.cell((9, 1))])
    model = ObservationModel.build(simple, goals)
    ctx = PolicyContext(simple, model, get_preset("paper"), 30, np.random.default_rng(0))
    with pytest.raises(ConfigError, match="robust-slack"):
        make_policy("hindsight", ctx)
    ctx = PolicyContext(simple, model, get_preset("robust-slack"), 30,
                        np.random.default_rng(0))
    policy = make_policy("hindsight", ctx)
    a = policy.act(1, simple.cell((4, 2)), None)
    assert 0 <= a < 8 and not simple.motion.blocked[simple.cell((4, 2)), a]
    planner, belief = _planner(simple, goals)
    assert hindsight_action(planner, belief, simple.cell((4, 2)), 30, 0, []) in range(8)


def test_a_task_runs_hindsight_to_its_end():
    """The tasks take the method like every other door: a navigate task loaded with
    ``method="hindsight"`` holds the hindsight policy and, driven by its own choices
    (``policy_action``), ends within ``T_max`` decisions."""
    from pathpref_tasks import load

    env = load("navigate", task_kwargs={"map": "simple", "method": "hindsight"})
    ts = env.reset()
    task = env.task
    assert task.runner.policy.name == "hindsight"
    t_max = task.runner.spec.t_max
    for _ in range(t_max):
        ts = env.step(task.policy_action())
        if ts.last():
            break
    assert ts.last()
    assert task.runner.done
