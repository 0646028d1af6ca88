"""One simulated person for taps and guidance: the guiding person chooses their aim as the
tapping person chooses a heading (the human model at ``gamma_h``), and under the episode's
``--push-rule corrective ...`` takes the handle when the robot starts a move off their route,
by the corrective tapping person's rule, after a reaction delay."""

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


def _watch(world, miss: float = 0.0):
    """The episode's corrective rule on ``world`` (goal: the last free cell; the map's
    preference), delay 0."""
    from pathpref.episode.corrective import CorrectiveHuman, PushRule

    return CorrectiveHuman(PushRule(0, miss), world, world.require_preference(),
                           world.n_cells - 1, np.random.default_rng(1))


def test_the_corrective_guiding_person_takes_the_handle_when_the_robot_errs():
    """A guided episode's corrective rule (``--push-rule corrective delay=0 miss=0.0``): no
    grasp on a clock (nothing in 5 s); a move the rule finds right brings none; one it finds
    wrong brings a grasp after the reaction delay ``reaction_s (1 + 0.25 z)`` (at least
    0.05 s), and no next one is due until the robot errs again."""
    from pathpref.episode import cached_world
    from pathpref.geometry.grid import STAY

    world = cached_world("simple")
    watch = _watch(world)
    m = world.motion
    moves = [(c, a, int(m.next_cell[c, a])) for c in range(world.n_cells) for a in range(8)
             if not m.blocked[c, a]]
    right, wrong = next((r, w) for r in moves for w in moves
                        if r[0] == w[0] and not watch.needs_push(*r) and watch.needs_push(*w))
    q = np.full(8, 1 / 8)
    person = GuidingHuman(HumanModel(timing="guidance"), np.random.default_rng(0), 1,
                          lambda c: 2, lambda c: q, 1.0, watch=watch)
    base = _Base()
    base.cell = right[0]
    person.attach(base)
    _run(person, base, 5.0)
    assert person.given == [] and person.next_t is None
    person.robot_moves(right[0], right[1])
    _run(person, base, 7.0)
    assert person.given == []
    t_wrong = base.data.time
    person.robot_moves(wrong[0], wrong[1])
    delay = person.next_t - t_wrong
    assert 0.05 <= delay <= 0.4 * 2.5
    _run(person, base, t_wrong + delay + 0.01)
    assert len(person.given) == 1 and person.given[0].t0 >= t_wrong + delay - 1e-9
    assert person.next_t is None
    assert watch.needs_push(right[0], STAY, right[0])  # standing still is no gain: a push


def test_a_missed_need_brings_no_grasp():
    """``miss=1``: every need is missed, no grasp."""
    from pathpref.episode import cached_world

    world = cached_world("simple")
    watch = _watch(world, miss=1.0)
    person = GuidingHuman(HumanModel(timing="guidance"), np.random.default_rng(0), 1,
                          lambda c: 2, lambda c: np.full(8, 1 / 8), 1.0, watch=watch)
    base = _Base()
    person.attach(base)
    person.robot_moves(0, None)
    assert person.next_t is None


def test_the_corrective_rule_with_taps_elsewhere_is_refused_and_named():
    """The episode's corrective rule takes the tapping person at decision steps or the
    guiding person; with pushes on the interval clock it is one line naming both."""
    from pathpref.episode import EpisodeSpec
    from pathpref.episode.runner import EpisodeRunner

    spec = EpisodeSpec.single("simple", "path_preference", 1, seed=5, sim="mujoco", t_max=3,
                              push_rule="corrective delay=0 miss=0.0",
                              physics=Physics.of(timing="interval").to_json())
    with pytest.raises(ConfigError, match="--timing guidance"):
        EpisodeRunner(spec)


def test_a_corrective_guided_episode_runs_and_measures_the_persons_effort():
    """A guided episode under ``--push-rule corrective delay=0 miss=0.0`` on ``office`` (8
    decision steps, seed 3: the robot erred once): the person's push is the episode's, it
    began within ``0.4 (1 + 0.25 x 6)`` = 1 s of a decision step's start (a reaction to the
    move that step began), and its effort is measured."""
    from pathpref.episode import EpisodeSpec
    from pathpref.episode.runner import EpisodeRunner

    spec = EpisodeSpec.single("office", "path_preference", 1, seed=3, sim="mujoco", t_max=8,
                              push_rule="corrective delay=0 miss=0.0",
                              physics=Physics.of(timing="guidance").to_json())
    runner = EpisodeRunner(spec)
    while not runner.done:
        runner.step()
    m = runner.result.metrics
    given = runner.body.human.given
    assert m["pushes"] == len(given) > 0
    step = Physics.of(timing="guidance").step_s(0.5)
    assert all((p.t0 % step) <= 1.0 + 1e-6 for p in given)
    assert m["person_impulse_ns"] > 0 and m["person_contact_s"] > 0
