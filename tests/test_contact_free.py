"""The physical base makes every move the grid allows without touching an obstacle, on floor
plans with rotated obstacles (the footprint rule of pathpref/geometry/footprint.py, shared by
the grid and the body), with a tap before each move and under guidance; and an episode with a
contact above the limits of pathpref/episode/safety.py is not a success anywhere."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pathpref.episode import EpisodeSpec, run_episode
from pathpref.episode.physics import Physics
from pathpref.episode.results import EpisodeResult
from pathpref.episode.safety import CONTACT_LIMITS, contact_safe
from pathpref.experiments.outcomes import failure_kind
from pathpref.geometry.generate import floor_plan
from pathpref.geometry.grid import MOVES
from pathpref.geometry.world import load_world
from pathpref.sim.body import base_params, build_base, scene_for
from pathpref.sim.force_cue import HumanPush, PushProfile

#: small plans with rotated obstacles only (seeds drawn for this test)
PLANS = [dict(seed=s, width=10, height=8, rotated=3, boxes=0, size_range=(1.2, 3.0))
         for s in (41, 42)]


def _every_move(world):
    """Each unordered allowed move once: ``(s, t)`` with ``t`` the N, NE, E or SE target."""
    m = world.motion
    return [(int(s), int(m.next_cell[s, a])) for a in range(4)
            for s in np.flatnonzero(~m.blocked[:, a])]


@pytest.mark.parametrize("plan", PLANS, ids=lambda p: f"seed{p['seed']}")
def test_every_allowed_move_is_made_without_contact_after_a_tap(plan):
    world = load_world(floor_plan(**plan))
    physics = Physics()
    scene = scene_for(world, base=base_params(physics))
    base = build_base(scene, "navigate", physics, np.random.default_rng(0))
    rng = np.random.default_rng(1)
    moves = _every_move(world)
    assert len(moves) > 100
    for s, t in moves:
        base.reset(s)
        base.receive_push(HumanPush.sample(int(rng.integers(8)), float(base.data.time),
                                           PushProfile(peak_n=40.0), rng))
        base.move_to(t)
        m = base.measurements
        assert m.collisions == 0, (world.cells[s], world.cells[t], m.impact_speed)
        assert np.linalg.norm(base.data.qpos[base.xy] - scene.cell_centre(t)) < 0.05
    # the moves went both ways of every direction the plan allows
    assert {tuple(MOVES[a]) for a in range(4)} <= {
        tuple(world.cells[t] - world.cells[s]) for s, t in moves}


def test_guided_and_tapped_episodes_on_rotated_plans_touch_nothing(tmp_path):
    """Episodes end to end (path preference and compliant, pushes any time and guidance):
    no contact, and every episode's contact measurements are reported."""
    path = tmp_path / "plan.json"
    path.write_text(json.dumps(floor_plan(**PLANS[0])))
    for timing in ("interval", "guidance"):
        for method in ("path_preference", "compliant"):
            for run in range(2):
                spec = EpisodeSpec.single(str(path), method, 5, instance=run, run=run,
                                          sim="mujoco",
                                          physics=Physics.from_json(json.dumps(
                                              {"timing": timing})).to_json())
                res = run_episode(spec)
                assert res.status == "ok"
                assert res.metrics["collisions"] == 0, (timing, method, run, res.metrics)
                assert res.contact_safe


def test_the_contact_limits_decide_success_everywhere():
    """By hand: a touch at 0.04 m/s and 15 N is safe; 0.06 m/s or 25 N is not; no contact or
    no measurements is safe. An unsafe episode that reached its goal in order is no success,
    its failure kind is 'contact', and the stored row's success agrees."""
    assert CONTACT_LIMITS == {"contact_impact_speed": 0.05, "contact_peak_force_n": 20.0}
    touch = {"collisions": 1.0, "contact_impact_speed": 0.04, "contact_peak_force_n": 15.0}
    assert contact_safe(touch) and contact_safe(None) and contact_safe("")
    assert contact_safe({"collisions": 0.0, "contact_impact_speed": 3.0})
    assert not contact_safe({**touch, "contact_impact_speed": 0.06})
    assert not contact_safe(json.dumps({**touch, "contact_peak_force_n": 25.0}))
    spec = EpisodeSpec.single("simple", "oracle", 5)
    from pathpref.episode.instances import Instance
    from pathpref.episode.results import result_row

    res = EpisodeResult(spec=spec, instance=Instance(0, (5, 6), 0), goal_reached=True,
                        homotopic=True, metrics={**touch, "contact_peak_force_n": 25.0})
    assert not res.success and not res.homotopy_success and not res.contact_safe
    row = result_row(res)
    assert row["success"] == 0 and row["homotopy_success"] == 0
    assert failure_kind(row) == "contact"
    res.metrics = touch
    assert res.success and failure_kind(result_row(res)) is None


def test_the_tasks_end_and_penalise_an_unsafe_contact():
    """The dm_control task ends the episode at a contact beyond the limits, takes the goal's
    reward off that step and reports no success; a safe touch changes nothing."""
    from pathpref_tasks import load

    env = load("navigate", delta_t=2, seed=0, t_max=6, physics={"timing": "interval"})
    ts = env.reset()
    task = env.task
    ts = env.step(task.policy_action())
    assert not ts.last() and task.episode_metrics()["contact_safe"]
    m = task.base.measurements
    m.collisions, m.impact_speed, m.contact_force = 1, 0.01, 10.0  # a light, slow touch
    ts = env.step(task.policy_action())
    assert not ts.last() or task.runner.result.goal_reached
    m.contact_force = 80.0  # pressed with 80 N: unsafe
    a = task.policy_action()
    ts = env.step(a)
    assert ts.last() and ts.discount == 0.0
    assert ts.reward == pytest.approx(task._reward - task.rewards.goal)
    metrics = task.episode_metrics()
    assert metrics["success"] is False and metrics["contact_safe"] is False
