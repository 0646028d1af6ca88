"""Episodes and instances: reproducible, the paper's input schedule, flags, bad input."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from pathpref.episode import EpisodeSpec, run_episode
from pathpref.episode.instances import (
    FIG4,
    episode_instance,
    fixed_instance,
    goal_pool,
    sample_instance,
    seed_for,
)
from pathpref.errors import ConfigError, MapError
from pathpref.geometry.grid import STAY
from pathpref.planning.policies import resolve_methods


def spec(**kw):
    d = dict(map="simple", method="path_preference", delta_t=5, instance=0, run=0,
             instance_seed=seed_for(0, 0), run_seed=seed_for(0, 0, 0), queries=500)
    d.update(kw)
    return EpisodeSpec(**d)


@pytest.mark.parametrize("method", ["compliant", "goal_only", "path_preference", "blended"])
def test_episode_is_replayable(method):
    a, b = run_episode(spec(method=method)), run_episode(spec(method=method))
    assert [(s.x, s.y, s.action, s.heading) for s in a.log] == [
        (s.x, s.y, s.action, s.heading) for s in b.log]
    assert (a.success, a.goal_reached, a.violations) == (b.success, b.goal_reached, b.violations)


@pytest.mark.parametrize("dt", [1, 3, 7])
def test_inputs_follow_schedule(dt):
    r = run_episode(spec(delta_t=dt, t_max=20))
    given = [s.t for s in r.log if s.heading >= 0]
    assert given == [t for t in range(1, r.steps + 1) if (t - 1) % dt == 0]
    assert r.inputs == len(given)


def test_flags_are_consistent():
    for i in range(4):
        r = run_episode(spec(instance=i, instance_seed=seed_for(0, i), method="compliant",
                             delta_t=1))
        assert r.success == (r.goal_reached and r.violations == 0)
        last = r.log[-1]
        goal_xy = r.instance_cells["goals"][r.instance.true_goal]
        assert r.goal_reached == ([last.x, last.y] == goal_xy)
        assert r.steps <= 30 and 0.0 <= last.p_true_goal <= 1.0


def test_compliant_stops_after_momentum():
    r = run_episode(spec(method="compliant", delta_t=30, t_max=30))
    moves = [s.action for s in r.log[1:]]
    # one input, then 5 steps of momentum (paper preset), then it stays
    if not r.goal_reached:
        assert all(a == STAY for a in moves[6:])
        assert all(a != STAY for a in moves[:6])


def test_instances_reproducible_and_banded(worlds):
    w = worlds["office"]
    a, b = sample_instance(w, 123), sample_instance(w, 123)
    assert a == b
    ys = w.cells[list(a.goals), 1]
    xs = w.cells[list(a.goals), 0]
    assert ((ys >= 8) & (ys <= 9) & (xs >= 2)).all() and a.start not in a.goals
    assert len(set(a.goals)) == 10
    assert len(goal_pool(w, a.start)) <= 18


def test_fig4_instance(simple):
    inst, free_goal = episode_instance(simple, FIG4, 0, 10, "map", 30)
    assert simple.cells[inst.start].tolist() == [1, 1] and free_goal
    assert simple.cells[inst.goal_cell].tolist() == [1, 8]
    assert simple.cells[list(inst.goals)].tolist() == [[x, 8] for x in range(1, 11)]


def test_bad_episode_input(simple):
    with pytest.raises(ConfigError, match="delta-t"):
        run_episode(spec(delta_t=0))
    with pytest.raises(ConfigError, match="t-max"):
        run_episode(spec(t_max=0))
    with pytest.raises(ConfigError, match="unknown method"):
        run_episode(spec(method="telepathy"))
    with pytest.raises(ConfigError, match="unknown method"):
        resolve_methods(["all", "nope"])
    with pytest.raises(ConfigError, match="too few candidate"):
        sample_instance(simple, 0, n_goals=500)
    with pytest.raises(ConfigError, match="preset"):
        run_episode(spec(preset="fast"))
    with pytest.raises(MapError, match="obstacle"):
        fixed_instance(simple, (1, 1), [(5, 5)], 0)


def test_unreachable_goal_candidate():
    from pathpref.geometry.world import load_world

    w = load_world({"name": "split", "width": 5, "height": 3, "obstacles": [
        {"cells": {"lower_left": [3, 1], "size": [1, 3]}}],
        "preference": {"route": [[1, 1], [1, 3]]}})
    with pytest.raises(MapError, match="cannot be reached"):
        fixed_instance(w, (1, 1), [(5, 1)], 0)
    inst = sample_instance(w, 0, n_goals=3)  # only from the start's side
    d = w.motion.distances_from(np.array([inst.start]))[0, list(inst.goals)]
    assert np.isfinite(d).all()


def test_fixed_instance_in_spec():
    fixed = json.dumps({"start": [1, 1], "goals": [[x, 8] for x in range(1, 11)],
                        "true_goal": 0, "free_goal_polytope": True})
    r = run_episode(replace(spec(), fixed=fixed))
    assert r.instance_cells["start"] == [1, 1]


def _recount(world, res):
    """Violations and back-crossings recomputed from the logged cells and the map's
    preference, independently of the runner."""
    pref = world.preference
    cells = [world.cell((s.x, s.y)) for s in res.log]
    viol = back = 0
    last = None
    for a, b in zip(cells, cells[1:], strict=False):
        v, w = int(world.cell_polytope[a]), int(world.cell_polytope[b])
        if v == w:
            continue
        viol += pref[v] >= 0 and pref[v] != w
        back += last == (w, v)
        last = (v, w)
    return viol, back


def test_success_rule_against_an_independent_count(simple):
    """Success = goal reached and no polytope left by a face other than p_v: recounted from
    the step log over episodes that cover every outcome (success, goal by another route,
    goal not reached)."""
    kinds = set()
    for i in range(12):
        r = run_episode(spec(instance=i, instance_seed=seed_for(5, i), run_seed=seed_for(5, i, 0),
                             method="compliant", delta_t=1 + i % 3))
        viol, back = _recount(simple, r)
        assert (r.violations, r.back_crossings) == (viol, back)
        assert r.success == (r.goal_reached and viol == 0)
        kinds.add((r.goal_reached, viol == 0))
    assert {(True, True), (True, False)} <= kinds


def test_step_checks_actions_and_returns_its_own_log():
    from pathpref.episode import EpisodeRunner
    from pathpref.errors import EpisodeError

    r = EpisodeRunner(spec(method="compliant", t_max=3))
    for bad in (8, 9, -2, 2.5, float("nan"), "N"):
        with pytest.raises(ConfigError, match=r"action must be 0\.\.7"):
            r.step(bad)
    log = r.step(7)
    assert log is r.result.log[-1] and log.t == 1 and log.action == 7
    assert r.step(STAY).t == 2 and r.step(0).t == 3
    with pytest.raises(EpisodeError, match="the episode is over"):
        r.step(0)
    assert 0.0 <= r.result.wall_s < 60.0


def test_a_generous_timeout_changes_nothing():
    a = run_episode(spec(method="goal_only", queries=200))
    b = run_episode(spec(method="goal_only", queries=200, timeout_s=1000.0))
    assert b.status == "ok" and [s.x for s in a.log] == [s.x for s in b.log]


def test_the_runner_uses_the_world_and_body_it_is_given(simple):
    """A world given to the runner (here: office for a spec that names simple) is the one it
    plays on, with the spec's likelihood setting; a body given is the one that senses."""
    from pathpref.episode import GridBody
    from pathpref.geometry.world import load_world

    other = load_world("office")
    s = spec(method="compliant", delta_t=1)
    mine, cached = run_episode(s, world=other), run_episode(s)
    assert mine.instance_cells != cached.instance_cells
    lo = run_episode(replace(s, normalize=False), world=other)
    assert [x.p_true_goal for x in lo.log] != [x.p_true_goal for x in mine.log]

    class Deaf(GridBody):
        def push(self, heading):
            pass  # feels nothing: nothing reaches the runner's door

    deaf = run_episode(s, body=Deaf(simple))
    assert deaf.inputs > 0 and all(x.heading == -1 for x in deaf.log)
    assert all(x.p_true_goal == deaf.log[0].p_true_goal for x in deaf.log[:3])


def test_the_goal_polytope_is_free_on_the_fig4_instance():
    from pathpref.episode import FIG4, EpisodeRunner

    r = EpisodeRunner(spec(fixed=FIG4))
    v = r.world.cell_polytope[r.instance.goal_cell]
    assert r.pref[v] == -1 and r.world.preference[v] >= 0
    assert (np.delete(r.pref, v) == np.delete(r.world.preference, v)).all()


def test_the_runner_draws_the_consistent_humans_instance():
    from pathpref.episode import EpisodeRunner

    differ = 0
    for i in range(8):
        kw = dict(map="classroom", t_max=60, instance_seed=seed_for(2, i), method="compliant")
        a = EpisodeRunner(spec(**kw)).instance
        b = EpisodeRunner(spec(human="consistent", **kw)).instance
        differ += a != b
    assert differ > 0  # the consistent human redraws where the map's route misses the goal


def test_an_episode_past_its_timeout_says_so():
    from pathpref.errors import EpisodeError

    with pytest.raises(EpisodeError, match=r"^timeout: episode exceeded 1e-09 s at step \d+$"):
        run_episode(spec(method="goal_only", queries=100, timeout_s=1e-9))
