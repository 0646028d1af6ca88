"""The person's effort per physical episode (``person_impulse_ns``, ``person_peak_n``,
``person_contact_s``): the integral of |F| over the physics steps a push acts at, its peak and
the time a hand pushed; in the metrics of every physical episode and in the report."""

from __future__ import annotations

import math
import os

import pytest

os.environ.setdefault("MUJOCO_GL", "egl")

from pathpref.sim.force_cue import HumanPush, PushProfile, push_effort  # noqa: E402


def test_a_half_sine_push_costs_its_closed_form():
    """30 N over 0.3 s, half-sine, on 2 ms steps: the impulse tends to ``2 F T / pi`` =
    5.7296 N s (the step sum within 0.1 %), the peak is hit at ``t = 0.15`` (step 75), and the
    force is at least 0.1 N (``CONTACT_N``) except within ``T asin(0.1 / 30) / pi`` = 0.3 ms
    of either end: steps 1..149, 0.298 s. Cut at 0.1 s the
    impulse is ``F T / pi (1 - cos(pi / 3))`` = 1.4324 N s."""
    j, peak, contact = push_effort(0, 30.0, 0.3, 0.3, 0.002)
    assert j == pytest.approx(2 * 30.0 * 0.3 / math.pi, rel=1e-3)
    assert peak == pytest.approx(30.0, abs=1e-9)
    assert contact == pytest.approx(0.298, abs=1e-6)
    push = HumanPush(0.0, 2.0, PushProfile(30.0, 0.3, 0.0), 2)
    j, _, contact = push.effort(0.002, 2.1)
    assert j == pytest.approx(30.0 * 0.3 / math.pi * (1 - math.cos(math.pi / 3)), rel=2e-2)
    assert contact == pytest.approx(0.1, abs=0.0021)
    assert push.effort(0.002, 1.0) == (0.0, 0.0, 0.0)  # not begun


@pytest.mark.parametrize("timing", ["decision", "guidance"])
def test_every_physical_episode_reports_the_persons_effort(timing):
    """A short episode on ``simple`` (4 decision steps, Delta_T 1): the three measures are in
    the metrics; with taps (decision timing) the impulse is the sum of each push's closed
    form within 1 %, with guidance the person's force as set step by step (the impulse at
    most peak x contact time); no push, no effort."""
    from pathpref.episode import EpisodeSpec, Physics
    from pathpref.episode.runner import EpisodeRunner
    from pathpref.sim.guiding_human import GuidingPush

    spec = EpisodeSpec.single("simple", "path_preference", 1, seed=3, sim="mujoco", t_max=4,
                              physics=Physics.of(timing=timing).to_json())
    runner = EpisodeRunner(spec)
    while not runner.done:
        runner.step()
    m = runner.result.metrics
    body = runner.body
    given = body.pushes_given if body.human is None else body.human.given
    assert m["pushes"] == len(given) > 0
    if timing == "decision":
        closed = sum(2 * p.profile.peak_n * p.profile.duration_s / math.pi
                     if p.profile.shape == "half_sine" else 0.0 for p in given)
        assert m["person_impulse_ns"] == pytest.approx(closed, rel=0.01)
        assert m["person_peak_n"] == pytest.approx(max(p.profile.peak_n for p in given),
                                                   rel=1e-3)
    else:
        assert all(isinstance(p, GuidingPush) for p in given)
        assert 0 < m["person_impulse_ns"] <= m["person_peak_n"] * m["person_contact_s"] + 1e-9
        assert m["person_peak_n"] <= Physics().human.peak_max_n + 1e-9
    assert m["person_contact_s"] > 0


def test_the_report_gives_the_mean_effort_and_the_effort_per_success():
    """Three rows: impulses 4, 6 and 8 N s, two successes: the mean 6 N s per episode, 9 N s
    per success (18 / 2), the largest peak, the mean contact time; rows without the measures
    leave them None."""
    import json

    from pathpref.experiments.report import physical_summary

    rows = [{"success": s, "metrics": json.dumps({"person_impulse_ns": j, "person_peak_n": p,
                                                  "person_contact_s": c})}
            for s, j, p, c in ((1, 4.0, 20.0, 1.0), (0, 6.0, 35.0, 2.0), (1, 8.0, 30.0, 3.0))]
    out = physical_summary(rows)
    assert (out["person_impulse_ns"], out["person_peak_n"], out["person_contact_s"],
            out["person_impulse_per_success_ns"]) == (6.0, 35.0, 2.0, 9.0)
    assert physical_summary([{"success": 1, "metrics": "{}"}])["person_impulse_ns"] is None
