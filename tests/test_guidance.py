"""Guidance the way Bajcsy et al.'s participants corrected a robot: the closed-loop person, the
deformation as evidence, the one timed step of every door, crossings along the path."""

from __future__ import annotations

import math
import os

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

import pathpref.sim  # noqa: E402,F401
from pathpref.episode import EpisodeSpec, Physics  # noqa: E402
from pathpref.episode.body import GridBody  # noqa: E402
from pathpref.episode.cache import cached_world  # noqa: E402
from pathpref.episode.physics import HumanModel  # noqa: E402
from pathpref.episode.runner import EpisodeRunner  # noqa: E402
from pathpref.sim.body import scene_for  # noqa: E402
from pathpref.sim.guidance import DEFORMATION_EVIDENCE_M  # noqa: E402
from pathpref.sim.guiding_human import GUIDE_SPEED, HOLD_SHARE, GuidingHuman  # noqa: E402
from pathpref.sim.mobile_base import MobileBase  # noqa: E402
from pathpref.sim.path_crossings import PathCrossings  # noqa: E402

EAST, NORTH = 2, 0  # ACTION_ANGLES: N, NE, E, SE, S, SW, W, NW


def _guided_base(cell_xy=(2, 2), mass=20.0, damping=80.0):
    world = cached_world("simple")
    base = MobileBase(scene_for(world))
    base.enable_guidance(mass, damping)
    base.reset(world.cell(cell_xy))
    return world, base


def _person(base, heading: int, **human):
    """A closed-loop person whose route always wants ``heading``, no noise, grasping 0.1 s
    after attaching, once (a long interval)."""
    probs = np.full(8, 0.01)
    probs[heading] = 0.93
    model = HumanModel(**{**dict(timing="guidance", reaction_s=0.1, interval_s=600.0,
                                 jitter=0.0, noise_deg=0.0, peak_spread=1.0,
                                 duration_spread=1.0), **human})
    person = GuidingHuman(model, np.random.default_rng(0), 5, lambda c: heading,
                          lambda c: probs)
    person.attach(base)
    return person


def test_the_person_pushes_their_way_and_lets_go_when_the_base_follows():
    """Worked out: a standing base is pushed east with the full 25 N (deviation 1); the
    admittance (20 kg, 80 N s/m) carries it east, the person's force falls toward the hold
    share as the base reaches the wanted 0.3 m/s, and once it heads east at >= 0.15 m/s for
    the release reaction (0.4 s) the person lets go, long before the 8 s hold limit."""
    _, base = _guided_base()
    person = _person(base, EAST, peak_n=25.0, hold_s=8.0, reaction_s=0.4)
    x0 = float(base.position[0])
    forces = []
    base.on_substep.append(lambda b, p: forces.append(
        person.push.now[:2].copy() if person.push is not None else np.zeros(2)))
    base.decision.hold(6.0, until_cue=False).run()
    push = person.given[0]
    assert push.released_at is not None
    held = push.released_at - push.t0
    assert 0.5 <= held < 3.0  # let go when the base followed, not at the 8 s limit
    f = np.array(forces)
    mag = np.hypot(f[:, 0], f[:, 1])
    assert np.all(np.abs(f[mag > 1.0, 1]) < 1e-9) and np.all(f[mag > 1.0, 0] > 0)  # east
    # dev = 1 while the base stands: the ramp's share of 25 N; it falls as the base follows
    assert 0.6 * 25.0 < mag.max() <= 25.0
    k_release = int(round((push.released_at - 0.002) / base.dt))
    # the loop's equilibrium: v = F / b with F = F_p (S + (1 - S)(1 - v / V)) gives
    # v = F_p / (b + F_p (1 - S) / V) = 25 / 130 m/s and F = 80 v = 15.4 N
    assert mag[k_release - 5] == pytest.approx(80.0 * 25.0 / 130.0, abs=1.0)
    assert float(base.position[0]) - x0 > 0.08  # it went the person's way, ~0.19 m/s for ~0.6 s
    assert person.push is None  # released and ramped down


def test_the_person_keeps_a_light_hold_while_the_base_goes_their_way():
    """The force law F = F_p (S + (1 - S) e): a base already moving east at the wanted speed
    is pushed with S F_p only."""
    _, base = _guided_base()
    person = _person(base, EAST, peak_n=30.0)
    base.data.qvel[base.vxy[0]] = GUIDE_SPEED
    t = float(base.data.time) + 0.5
    base.data.time = t  # the grasp is due; the ramp is over 0.2 s after it
    person(base)
    base.data.time = t + 0.3
    person(base)
    assert np.hypot(*person.push.now[:2]) == pytest.approx(HOLD_SHARE * 30.0, rel=1e-9)


def test_a_person_pushing_into_a_wall_lets_go_at_the_longest_hold():
    """Bounded whatever the evidence: the base cannot follow a push into the wall (the target
    never moves where the base does not fit), so the person never sees it go their way and
    lets go at the longest hold (here 1.5 s, no spread)."""
    world = cached_world("simple")
    w = world.spec.width
    start = next(world.cell((w, y)) for y in range(1, world.spec.height + 1)
                 if world.arrangement.cell_index[w - 1, y - 1] >= 0)
    base = MobileBase(scene_for(world))
    base.enable_guidance(20.0, 80.0)
    base.reset(start)
    person = _person(base, EAST, peak_n=40.0, hold_s=1.5, reaction_s=0.6)
    base.decision.hold(4.0, until_cue=False).run()
    push = person.given[0]
    assert push.released_at - push.t0 == pytest.approx(1.5, abs=0.01)
    assert len(person.given) == 1


def _pushed_evidence(peak_n: float, duration_s: float):
    """A push east on a standing guided base: the records felt and the target's travel."""
    from pathpref.sim.force_cue import HumanPush, PushProfile

    _, base = _guided_base()
    seen, xs = [], {}
    base.listener = seen.append
    base.on_substep.append(lambda b, p: xs.__setitem__(round(float(b.data.time), 6),
                                                       float(b.target[0])))
    base.pushes.append(HumanPush(0.0, float(base.data.time),
                                 PushProfile(peak_n=peak_n, duration_s=duration_s,
                                             noise_deg=0.0, shape="plateau"), EAST))
    base.decision.hold(duration_s + 1.0, until_cue=False).run()
    cue = next(f for f in seen if not f.partial)
    t0, t1 = round(cue.t_felt - base.dt, 6), round(cue.t_cue, 6)
    return seen, xs[t1] - xs[t0]  # the target's travel while the cue was under way


def test_the_deformation_is_the_evidence():
    """A push east on a standing guided base: every record's evidence points along the
    deformation (east) with weight |D| / 0.1 m; a short push's weights add up to the target's
    travel while the cue was under way (from its first felt step to its end) over 0.1 m, a
    long one's to the cap of 2 per push."""
    from pathpref.episode.physics import GUIDANCE_MAX_EVIDENCE

    seen, moved = _pushed_evidence(12.0, 0.5)
    assert seen and any(not f.partial for f in seen)
    for f in seen:
        angle, weight = f.evidence
        if weight > 1e-3:
            assert abs(angle) < math.radians(2.0)
    total = sum(f.evidence[1] for f in seen)
    assert 0.02 < moved < 0.1 * GUIDANCE_MAX_EVIDENCE
    # within a physics step of travel at either end (0.25 m/s x 2 ms of 0.02 m: 2.5 %)
    assert total == pytest.approx(moved / DEFORMATION_EVIDENCE_M, rel=0.025)
    seen, moved = _pushed_evidence(20.0, 2.0)
    assert moved > 0.3
    assert sum(f.evidence[1] for f in seen) == pytest.approx(GUIDANCE_MAX_EVIDENCE, abs=1e-12)


def _guided_episode(seed: int, t_max: int):
    """A guided episode (simple, ΔT 2) run to its end: its runner and every record its base
    gave the runner's door."""
    spec = EpisodeSpec.single("simple", "path_preference", 2, seed=seed, sim="mujoco",
                              queries=50, t_max=t_max, physics=Physics.of(timing="guidance"))
    runner = EpisodeRunner(spec)
    seen = []
    door = runner.body.base.listener

    def listen(felt):
        seen.append(felt)
        door(felt)

    runner.body.base.listener = listen
    while not runner.done:
        runner.step()
    return runner, seen


def test_guidance_records_update_the_belief_as_enumeration_does(simple):
    """The deformation records of a guided episode, taken by the preference belief, give the
    posterior enumeration over every preference gives (the likelihood of
    :mod:`pathpref.sim.guidance`)."""
    from pathpref.episode.physics import DIRECTION_KAPPA
    from pathpref.inference.belief import PreferenceBelief
    from tests.test_belief import brute_direction_posterior

    runner, seen = _guided_episode(3, 6)
    obs = [(f.cell, f.evidence[0], f.evidence[1]) for f in seen if f.evidence[1] > 0]
    assert len(obs) >= 3
    belief = PreferenceBelief(runner.model)
    for s, angle, w in obs:
        belief.update_direction(s, angle, DIRECTION_KAPPA, w)
    post, _ = brute_direction_posterior(runner.model, obs, DIRECTION_KAPPA)
    assert np.allclose(belief.goal_marginal(), post.sum(axis=1), atol=1e-9)


def test_guidance_reads_a_sustained_push_while_it_lasts():
    """A guidance episode: partial records reach the runner while a push lasts, carry at
    most GUIDANCE_MAX_EVIDENCE per cue, and are not cues (the cue count is the body's)."""
    from pathpref.episode.physics import GUIDANCE_MAX_EVIDENCE
    from pathpref.errors import ConfigError

    runner, seen = _guided_episode(1, 8)
    cues = [f for f in seen if not f.partial]
    partial = [f for f in seen if f.partial]
    assert len(cues) >= 1 and len(partial) >= 5 * len(cues)
    assert all(f.evidence is not None and f.evidence[1] >= 0 for f in seen)
    total = sum(f.evidence[1] for f in seen)
    assert total <= GUIDANCE_MAX_EVIDENCE * len(cues) + 1e-9
    assert runner.result.metrics["cues_felt"] == len(cues)
    with pytest.raises(ConfigError, match="timing guidance needs base holonomic"):
        Physics.of(timing="guidance", base="diffdrive")


def test_a_guided_step_is_the_same_in_the_cli_and_the_task():
    """One end-of-step rule under guidance: the ``--sim mujoco`` body and the dm_control task
    run the same episode (same seeds, the policy's own actions) along the same cells, with
    the same pushes."""
    from pathpref_tasks import load

    physics = Physics.of(timing="guidance")
    spec_kw = dict(seed=7, queries=40, t_max=8)
    env = load("navigate", map="simple", method="path_preference", delta_t=2,
               physics=physics, **spec_kw)
    env.reset()
    task = env.task
    cells_task = [task.runner.cell]
    while not task.runner.done:
        env.step(task.policy_action())
        cells_task.append(task.runner.cell)
    spec = EpisodeSpec.single("simple", "path_preference", 2, seed=7, instance=0,
                              sim="mujoco", queries=40, t_max=8, physics=physics)
    assert spec.instance_seed == task.runner.spec.instance_seed
    assert spec.run_seed == task.runner.spec.run_seed
    runner = EpisodeRunner(spec)
    cells_cli = [runner.cell]
    while not runner.done:
        runner.step()
        cells_cli.append(runner.cell)
    assert cells_cli == cells_task
    assert runner.result.inputs == task.runner.result.inputs


class _FakeBase:
    """A base whose cell and position the test sets (``xy`` None: the cell's centre)."""

    def __init__(self, world=None):
        self.data = type("D", (), {"time": 0.0})()
        self.pushes = []
        self.cell = 0
        self.xy = None
        self.world = world
        self.scene = type("S", (), {"cell_size": 0.5})()
        self.guidance = type("G", (), {"mass": 20.0, "damping": 80.0})()

    @property
    def position(self):
        if self.xy is not None:
            return np.array(self.xy, float)
        return (self.world.cells[self.cell] - 0.5) * self.scene.cell_size


def test_crossings_along_the_path_are_labelled_with_who_made_them():
    """A crossing while a push acts, or within 3 M / b = 0.75 s after it ends, is the
    person's; later ones and ones with no push are the robot's."""
    from pathpref.sim.force_cue import HumanPush, PushProfile

    world = cached_world("simple")
    a, b = 0, int(np.flatnonzero(world.cell_polytope != world.cell_polytope[0])[0])
    base, path = _FakeBase(world), None
    path = PathCrossings(base, world)
    path.reset(a)
    base.pushes.append(HumanPush(0.0, 1.0, PushProfile(20.0, 1.0, 0.0, "plateau"), EAST))
    changes = {250: b, 750: a, 1350: b, 1400: a}  # physics steps of 2 ms; push 1.0..2.0 s
    for k in range(1, 1600):
        base.data.time = 0.002 * k
        base.cell = changes.get(k, base.cell)
        path(base)
    pa, pb = int(world.cell_polytope[a]), int(world.cell_polytope[b])
    assert path.take() == [(pa, pb, False), (pb, pa, True), (pa, pb, True), (pb, pa, False)]
    assert path.take() == []


def _face_pair(world):
    """Two side-adjacent cells ``a``, ``b = a + (1, 0)`` in different polytopes."""
    index = {(int(x), int(y)): i for i, (x, y) in enumerate(world.cells)}
    for (x, y), a in index.items():
        b = index.get((x + 1, y), -1)
        if b >= 0 and world.cell_polytope[a] != world.cell_polytope[b]:
            return a, b
    raise AssertionError("no face on the map")


def test_chatter_on_a_face_counts_no_crossing_and_a_real_one_counts_once():
    """The worked chatter case (``docs/physics.md``, hysteresis): a push leaves the base on
    the face between ``a`` (polytope 4 in the report) and ``b`` (6), 1 mm either side of it,
    so the cell under it flips a, b, a, b, a: the base is never 0.25 cell = 0.125 m inside
    ``b``, so no crossing counts (it counted four). Then the base goes to ``b``'s centre, 0.25
    m past the face: one crossing, the person's (a push acted)."""
    from pathpref.sim.force_cue import HumanPush, PushProfile
    from pathpref.sim.path_crossings import HYSTERESIS_CELLS

    assert HYSTERESIS_CELLS == 0.25
    world = cached_world("simple")
    a, b = _face_pair(world)
    face_x = float(world.cells[a][0]) * 0.5  # the right side of a (cells 0.5 m wide)
    y = (float(world.cells[a][1]) - 0.5) * 0.5
    base = _FakeBase(world)
    path = PathCrossings(base, world)
    path.reset(a)
    base.pushes.append(HumanPush(0.0, 0.0, PushProfile(20.0, 10.0, 0.0, "plateau"), EAST))
    k = 0
    for cell, dx in [(a, -0.001), (b, 0.001), (a, -0.001), (b, 0.001), (a, -0.001)] * 3:
        k += 1
        base.data.time, base.cell, base.xy = 0.002 * k, cell, (face_x + dx, y)
        path(base)
    assert path.take() == [] and path.pending is None
    for dx in (0.001, 0.1, 0.124, 0.126, 0.25):  # commits past 0.125 m
        k += 1
        base.data.time, base.cell, base.xy = 0.002 * k, b, (face_x + dx, y)
        path(base)
        assert (path.pending is None) == (dx > 0.125)
    pa, pb = int(world.cell_polytope[a]), int(world.cell_polytope[b])
    assert path.take() == [(pa, pb, True)]


class _LedBody(GridBody):
    """A grid body that reports scripted crossings along its path."""

    script: list = []

    def path_crossings(self):
        out, self.script = list(self.script), []
        return out


def test_the_runner_judges_the_robots_crossings_and_reports_the_persons():
    """A violation the person led is reported (``person_violations``), not counted against
    the robot (``violations``); the robot's own is counted."""
    world = cached_world("simple")
    spec = EpisodeSpec.single("simple", "path_preference", 5, seed=1, t_max=3)
    body = _LedBody(world, spec)
    runner = EpisodeRunner(spec, world, body)
    pref = runner.pref
    v = next(v for v in range(world.n_polytopes) if pref[v] >= 0)
    wrong = next(int(w) for w in range(world.n_polytopes)
                 if w != v and w != pref[v] and world.graph.edge_between(v, w) >= 0)
    body.script = [(v, wrong, True)]
    runner.step()
    assert runner.result.violations == 0
    body.script = [(v, wrong, False)]
    runner.step()
    assert runner.result.violations == 1
    while not runner.done:
        runner.step()
    assert runner.result.metrics["person_violations"] == 1.0
    assert runner.result.metrics["person_crossings"] == 1.0


def test_the_guided_person_is_named_in_the_key_and_nowhere_else():
    """``guide`` is written under guidance timing (old open-loop rows never share a key) and
    left out elsewhere (every other stored key unchanged)."""
    assert '"guide":"closed"' in Physics.of(timing="guidance").to_json()
    assert '"guide":"open"' in Physics.of(timing="guidance", guide="open").to_json()
    assert "guide" not in Physics.of(timing="interval").to_json()
    assert "guide" not in Physics().to_json()
    assert "guide" not in HumanModel(gamma_h=0.5).to_json()
    with pytest.raises(Exception, match="guide"):
        Physics.of(timing="guidance", guide="sideways")


def _lean_then_push(detector, push_deg: float):
    """A hand rests on the handle at 12 N east (arriving over 0.3 s at 1 s, leaving over 0.3 s
    at 20 s); a 25 N half-sine push of 0.5 s toward ``push_deg`` at 10 s. The cues with the
    time each ended."""
    dt, cues = detector.dt, []
    a = math.radians(push_deg)
    for k in range(int(22.0 / dt)):
        t = k * dt
        hand = 12.0 * min(1.0, max(0.0, (t - 1.0) / 0.3)) * \
            (1.0 - min(1.0, max(0.0, (t - 20.0) / 0.3)))
        push = 25.0 * math.sin(math.pi * (t - 10.0) / 0.5) if 10.0 <= t <= 10.5 else 0.0
        cue = detector.update(np.array([hand + push * math.cos(a), push * math.sin(a)]))
        if cue is not None:
            cues.append((t, cue))
    return cues


@pytest.mark.parametrize("push_deg, heading", [(0.0, EAST), (90.0, NORTH)])
def test_a_resting_hand_above_threshold_becomes_the_baseline(push_deg, heading):
    """Leaning at 12 N (above the 8 N onset) for 19 s: the lean becomes the baseline after 3 s
    steady and is reported (``leaned``), the push at 10 s is felt as one cue toward its
    heading, ending within the release window, and the hand leaving gives no cue. (Before,
    the lean held one cue active until the hand left: the push merged into it.)"""
    from pathpref.sim.cue_detector import FilteredCueDetector

    detector = FilteredCueDetector(0.002, split=True)
    cues = _lean_then_push(detector, push_deg)
    assert detector.leaned == 1
    assert len(cues) == 1
    t, cue = cues[0]
    assert 10.0 < t < 10.5 + 0.2 and cue.heading == heading
    assert np.all(detector.lean == 0.0)  # the lean left and gave the baseline back


def test_the_carry_robot_complies_to_a_guiding_push_on_its_tray():
    """25 N on the tray for 2 s under guidance: the arm's impedance takes the push and the
    base's guidance admittance follows it as far as the admittance's closed form (the
    defaults M, b of ``Physics().drive``) takes a target; before, it stood still."""
    from pathpref.apps.benchmarks.physics import guided_push
    from tests.admittance_helpers import admittance_travel

    drive = Physics().drive
    ideal = admittance_travel(25.0, 2.0, 1.0, drive.admittance_m, drive.admittance_b,
                              drive.v_max)
    carry = guided_push("carry", 25.0, 2.0, after_s=1.0)
    assert carry >= 0.3
    assert carry == pytest.approx(ideal, rel=0.1)
