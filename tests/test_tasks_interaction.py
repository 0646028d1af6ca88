"""The observations that carry a step's interaction (the push felt during the step, the
detector's events) and the episode metrics of Gymnasium ``info`` and the dm_env environment."""

from __future__ import annotations

import math
import os

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from pathpref_tasks import load  # noqa: E402

#: heading k (N, NE, E, ..., NW) points at 90 - 45 k degrees counter-clockwise from +x
HEADING_DEG = [90.0 - 45.0 * k for k in range(8)]


def _angle_between(a_deg: float, b_deg: float) -> float:
    return abs((a_deg - b_deg + 180.0) % 360.0 - 180.0)


def _run(env, steps: int):
    ts = env.reset()
    out = [ts]
    while not ts.last() and len(out) <= steps:
        ts = env.step(env.task.policy_action())
        out.append(ts)
    return out


@pytest.mark.parametrize("physics", ["legacy", None])
def test_decision_step_carries_the_push_it_felt(physics):
    """Legacy: the human pushes 30 N for 0.3 s at t = 0, 2, 4 (delta_t 2) and the robot feels
    each push within the step it happens in (the first in ``reset``): ``push_felt`` has the
    push's peak (30 N within 2 N, the legacy profile; with the default physics above the
    detector's 8 N threshold), its direction within 22.5 degrees of the heading the detector
    reported (the ``heading`` one-hot of the same observation), its duration; ``cues_felt``
    counts that one cue at that heading; the detector was active for the push's duration
    within 50 ms (its 25 ms onset and its release). Steps without a push observe zeros."""
    env = load("navigate", map="simple", method="path_preference", delta_t=2, seed=5,
               queries=20, t_max=6, physics=physics)
    steps = _run(env, 6)
    assert len(steps) == 7 and steps[-1].last()
    pushed = []
    for i, ts in enumerate(steps):
        o = ts.observation
        if o["cues_felt"].sum() == 0:
            assert not o["push_felt"].any() and o["detector_active_s"][0] == 0.0
            continue
        pushed.append(i)
        assert o["cues_felt"].sum() == 1
        k = int(np.argmax(o["cues_felt"]))
        assert o["heading"][k] == 1.0  # the cue felt is the heading for the coming step
        peak, c, s, dur = o["push_felt"]
        if physics == "legacy":
            assert abs(peak - 30.0) < 2.0 and abs(dur - 0.3) < 0.05
        else:
            assert peak > 8.0 and 0.05 < dur < 2.0
        assert math.isclose(c * c + s * s, 1.0, rel_tol=1e-9)
        assert _angle_between(math.degrees(math.atan2(s, c)), HEADING_DEG[k]) <= 22.5
        assert abs(o["detector_active_s"][0] - dur) <= 0.05
        assert peak > np.linalg.norm(o["force"])  # the end-of-step snapshot misses it
    # pushes at t = 0, 2, 4: in reset and in steps 2 and 4, read where they happen
    assert pushed == [0, 2, 4]
    m = env.episode_metrics
    assert (m["pushes"], m["cues_felt"], m["steps"]) == (3, 3, 6)
    assert m["success"] == (m["goal_reached"] and m["violations"] == 0)
    assert math.isclose(m["return"], sum(ts.reward for ts in steps[1:]), rel_tol=1e-12)


def test_control_rate_push_felt_in_the_step_its_cue_ends():
    """At control rate (delta_t 1: a push at once) the detector is active for a run of
    control steps (at most the 0.02 s step each) and the cue is read in exactly one step;
    the active seconds summed over the steps equal the cue's duration within 50 ms."""
    env = load("navigate_control", map="simple", method="path_preference", delta_t=1, seed=5,
               queries=20, t_max=6)
    steps = _run(env, 200)
    active = np.array([ts.observation["detector_active_s"][0] for ts in steps])
    cues = np.array([ts.observation["cues_felt"].sum() for ts in steps])
    assert (active <= 0.02 + 1e-9).all()
    read = np.flatnonzero(cues)
    assert len(read) >= 1
    first = read[0]
    assert cues[first] == 1
    dur = steps[first].observation["push_felt"][3]
    assert abs(active[: first + 1].sum() - dur) <= 0.05
    assert np.flatnonzero([ts.observation["push_felt"].any() for ts in steps]).tolist() == \
        read.tolist()
    assert env.episode_metrics["cues_felt"] == int(cues.sum())


@pytest.mark.parametrize("env_id", ["pathpref/Navigate-v0", "pathpref/NavigateControl-v0"])
def test_gymnasium_info_carries_the_episode_metrics(env_id):
    """Every ``info`` has the metrics (the body's measurements only the last one's, which
    go over every physics step); the last one's equal the dm_env environment's
    ``episode_metrics``; ``return`` is the sum of the rewards; ``success`` is the rule."""
    gym = pytest.importorskip("gymnasium")
    control = "Control" in env_id
    env = gym.make(f"pathpref_tasks:{env_id}", map="simple", method="compliant", delta_t=1,
                   queries=20, t_max=4, time_limit=1.0 if control else None)
    _, info = env.reset(seed=2)
    assert info["pushes"] == (0 if control else 1) and info["return"] == 0.0
    assert "pushes_missed" not in info  # the body's measurements: at the last step
    total, done = 0.0, False
    while not done:
        _, r, term, trunc, info = env.step(np.zeros(2, np.float32) if control else 8)
        total += r
        done = term or trunc
    shared = ("t", "is_success", "is_intervention", "intervention_heading")
    assert info == {**env.unwrapped._env.episode_metrics, **{k: info[k] for k in shared}}
    assert info["is_success"] == info["success"]
    assert "pushes_missed" in info  # the default physics: the cue metrics
    assert math.isclose(info["return"], total, rel_tol=1e-12, abs_tol=1e-12)
    assert info["success"] == (info["goal_reached"] and info["violations"] == 0)
    for k in ("pushes", "cues_felt", "violations", "steps", "back_crossings"):
        assert isinstance(info[k], int)
    env.close()
