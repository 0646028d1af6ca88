"""One simulated person for taps and guidance: the guiding person chooses their aim as the
tapping person chooses a heading (the human model at ``gamma_h``), and under ``push_rule =
corrective`` takes the handle when the robot starts a move off their route, by the corrective
tapping person's rule and reaction delay."""

from __future__ import annotations

import os

import numpy as np
import pytest

os.environ.setdefault("MUJOCO_GL", "egl")

from pathpref.episode.physics import HumanModel, Physics  # noqa: E402
from pathpref.errors import ConfigError  # noqa: E402
from pathpref.sim.guiding_human import GuidingHuman  # noqa: E402


class _Base:
    """What the person reads of a base: the time, the cell, the velocity, the pushes."""

    def __init__(self):
        self.data = type("D", (), {"time": 0.0})()
        self.cell, self.velocity, self.dt = 7, np.zeros(2), 0.002
        self.pushes, self.pre_substep = [], []


def _person(human: HumanModel, drawn: list[int], best: int = 2):
    """A guiding person whose heading draws are ``drawn`` in turn and whose model's most
    likely heading is ``best`` everywhere (probability 0.6, the rest 0.4 / 7 each)."""
    q = np.full(8, 0.4 / 7)
    q[best] = 0.6
    draws = iter(drawn)
    person = GuidingHuman(human, np.random.default_rng(0), 1, lambda c: next(draws),
                          lambda c: q, 1.0)
    base = _Base()
    person.attach(base)
    return person, base


def _run(person, base, until: float) -> None:
    while base.data.time < until:
        person(base)
        base.data.time += base.dt


def test_the_guiding_persons_aim_is_their_draw_at_gamma_h_not_the_best_heading():
    """The person's grasp aims at the heading the human model draws (5 here), not at the
    most likely one (2), and a new cell draws again (6): the tapping person's choice. (Before,
    the guiding person always aimed at the most likely heading, whatever ``gamma_h``.)"""
    person, base = _person(HumanModel(timing="guidance"), [5, 6])
    _run(person, base, 0.5)  # the first grasp: reaction_s (0.4 s) after the start
    assert person.push is not None and person.push.intended_heading == 5
    base.cell = 8
    _run(person, base, 0.6)
    assert person.push.intended_heading == 6


def test_the_corrective_guiding_person_takes_the_handle_when_the_robot_errs():
    """``push_rule = corrective`` (``p_correct`` 1, ``p_needless`` 0): no grasp on a clock
    (nothing in 5 s); a right move (heading 2) brings none; a wrong one (heading 4) brings a
    grasp after the reaction delay ``reaction_s (1 + 0.25 z)`` (at least 0.05 s), and no next
    one is due while the robot does not err again."""
    human = HumanModel(timing="guidance", push_rule="corrective", p_correct=1.0,
                       p_needless=0.0)
    person, base = _person(human, [2, 2, 2])
    _run(person, base, 5.0)
    assert person.given == [] and person.next_t is None
    person.robot_moves(base.cell, 2)
    _run(person, base, 7.0)
    assert person.given == []
    t_wrong = base.data.time
    person.robot_moves(base.cell, 4)
    delay = person.next_t - t_wrong
    assert 0.05 <= delay <= 0.4 * 2.5
    _run(person, base, t_wrong + delay + 0.01)
    assert len(person.given) == 1 and person.given[0].t0 >= t_wrong + delay - 1e-9
    assert person.next_t is None


def test_push_rule_is_named_in_a_guided_key_and_refused_for_taps():
    """A guided episode's physics names its push rule (so rows of the earlier guiding person,
    who aimed at the best heading, never share a key with it); other timings leave it out;
    ``corrective`` with taps is one line naming the flag and the taps' own rule."""
    assert '"push_rule":"interval"' in Physics.of(timing="guidance").to_json()
    assert '"push_rule":"corrective"' in Physics.of(timing="guidance",
                                                    push_rule="corrective").to_json()
    assert "push_rule" not in Physics().to_json()
    assert "push_rule" not in Physics.of(timing="interval").to_json()
    with pytest.raises(ConfigError, match="--push-rule.*--timing corrective"):
        Physics.of(timing="interval", push_rule="corrective")


def test_a_corrective_guided_episode_runs_and_measures_the_persons_effort():
    """A guided episode with the corrective rule on ``simple`` (6 decision steps, seed 5: the
    robot erred twice, two grasps): the person's pushes are the episode's, and their effort
    is measured."""
    from pathpref.episode import EpisodeSpec
    from pathpref.episode.runner import EpisodeRunner

    spec = EpisodeSpec.single("simple", "path_preference", 1, seed=5, sim="mujoco", t_max=6,
                              physics=Physics.of(timing="guidance", push_rule="corrective",
                                                 p_correct=1.0, p_needless=0.0).to_json())
    runner = EpisodeRunner(spec)
    while not runner.done:
        runner.step()
    m = runner.result.metrics
    assert m["pushes"] == len(runner.body.human.given) == 2
    assert m["person_impulse_ns"] > 0 and m["person_contact_s"] > 0
