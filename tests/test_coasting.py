"""The compiled steps of a move (:mod:`pathpref.sim.coasting`) give the Python path's numbers,
bit for bit: whole episodes, and each way the kernel hands back (a detector that fires, a
base that hits a wall, a state that is not finite), run with the kernel on and off on the same
machine; the C functions it calls (:mod:`pathpref.sim.native`) against what NumPy and CPython
compute."""

from __future__ import annotations

import math
import os
import pickle

os.environ.setdefault("MUJOCO_GL", "egl")

import numba as nb  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

import pathpref.sim  # noqa: E402,F401 - registers the MuJoCo body
from pathpref.episode import EpisodeSpec, Physics  # noqa: E402
from pathpref.episode.runner import EpisodeRunner  # noqa: E402
from pathpref.errors import ConfigError, EpisodeError  # noqa: E402
from pathpref.geometry.world import load_world  # noqa: E402
from pathpref.sim import coasting, native  # noqa: E402
from pathpref.sim.body import scene_for  # noqa: E402
from pathpref.sim.controller import ProfiledController  # noqa: E402
from pathpref.sim.force_cue import HumanPush, PushProfile  # noqa: E402
from pathpref.sim.mobile_base import MobileBase  # noqa: E402
from pathpref.sim.sensing import SensorModel  # noqa: E402

pytestmark = pytest.mark.skipif(not native.ready(), reason=f"no compiled path: {native.WHY}")


@pytest.fixture
def reasons(monkeypatch):
    """Counts the kernel's hand-back reasons (and steps) while the test runs."""
    seen = {"steps": 0}
    kernel = coasting._coast

    def counted(*args):
        reason, steps = kernel(*args)
        seen[reason] = seen.get(reason, 0) + 1
        seen["steps"] += steps
        return reason, steps

    monkeypatch.setattr(coasting, "_coast", counted)
    return seen


def _both(monkeypatch, run):
    """``run()`` with the compiled steps off, then on: the two results."""
    out = []
    for flag in ("0", "1"):
        monkeypatch.setenv("PATHPREF_COMPILED_STEPS", flag)
        out.append(run())
    return out


def _state(base) -> bytes:
    """Everything a step changes, as bytes (exact comparison)."""
    d, s = base.data, base.sensing
    return pickle.dumps((
        d.time, d.qpos.tobytes(), d.qvel.tobytes(), d.ctrl.tobytes(),
        [(f.cell, f.heading, f.t_felt, f.t_cue, f.peak_n, f.impulse) for f in base.felt],
        sorted(base.physical_metrics().items()), base.controller.last.tobytes(),
        s.force_estimate.tobytes(), s.estimator.bias.tobytes(), s.estimator.quiet,
        s.estimator.at_rest, s.estimator.pending().tobytes(),
        s.faulty.bias.tobytes(), s.faulty.win.tobytes(),
        s.faulty.held.tobytes(), s.detector.f.tobytes(), s.detector.baseline.tobytes(),
        s.detector.var, s.detector.on_n, s.detector.off_n, s.detector.pending().tobytes(),
        s.detector.active, s.faulty.rng.bit_generator.state["state"]))


@pytest.mark.cross_cpu
@pytest.mark.parametrize("map_name,instance,timing", [
    ("simple", 0, "decision"), ("simple", 3, "decision"), ("office", 1, "decision"),
    ("simple", 1, "interval"), ("office", 2, "corrective")])
def test_episodes_are_the_same_with_compiled_steps(monkeypatch, reasons, map_name, instance,
                                                   timing):
    """A realistic physical episode (``Physics()``: faulty sensor, estimator, filtered
    detector, measurements; pushes at decisions, or at any time from the simulated human, the
    kernel running up to each push): the same final state, cues, metrics and noise stream."""
    def run():
        physics = Physics() if timing == "decision" else Physics.of(timing=timing)
        spec = EpisodeSpec.single(map_name, "path_preference", 5, seed=11, instance=instance,
                                  sim="mujoco", t_max=12, physics=physics.to_json())
        runner = EpisodeRunner(spec)
        while not runner.done:
            runner.step()
        return _state(runner.body.base), [(s.t, s.x, s.y, s.action) for s in runner.result.log]

    off, on = _both(monkeypatch, run)
    assert off == on
    assert reasons["steps"] > 1000  # the kernel ran most of the moves


@pytest.mark.cross_cpu
def test_guided_episodes_are_the_same_with_compiled_steps(monkeypatch, reasons):
    """Guided episodes (the closed-loop person, ``timing`` guidance): between pushes the
    kernel drives the guided base (the safety filter on its command, the admittance's tail
    after a release, the path's polytope changes handed back to the crossing hook). The same
    final state, admittance, target, crossings, cues with their evidence and decisions."""
    def run():
        out = []
        for map_name, instance in (("simple", 0), ("office", 1), ("office", 2)):
            spec = EpisodeSpec.single(map_name, "path_preference", 5, seed=11,
                                      instance=instance, sim="mujoco", t_max=12,
                                      physics=Physics.of(timing="guidance").to_json())
            runner = EpisodeRunner(spec)
            while not runner.done:
                runner.step()
            b, res = runner.body.base, runner.result
            g = b.guidance
            out.append((_state(b), g.v.tobytes(), g.deformation.tobytes(), g.moving,
                        b.target.tobytes(), [f.evidence for f in b.felt],
                        [(s.t, s.x, s.y, s.action, s.heading) for s in res.log],
                        sorted(res.metrics.items()), res.violations))
        return out

    off, on = _both(monkeypatch, run)
    assert off == on
    assert reasons["steps"] > 10_000  # the kernel drove most of the guided steps
    assert reasons.get(coasting.CROSS, 0) > 0  # and handed the crossings back
    assert sum(dict(o[7])["person_crossings"] for o in on) > 0


@pytest.mark.cross_cpu
@pytest.mark.parametrize("robot_model,timing", [("disk", "decision"), ("disk", "interval"),
                                                ("tidybot", "decision"),
                                                ("tidybot", "guidance")])
def test_carry_episodes_are_the_same_with_compiled_steps(monkeypatch, reasons, robot_model,
                                                         timing):
    """The physical carry arm between IK solves runs in the kernel too (its impedance's servo
    targets, :func:`~pathpref.sim.arm_step.arm_step`; the tilt's record), the Jaco on the disk
    and the TidyBot's Gen3: the same final state, servo targets, tilts, IK count, metrics and
    decisions, the kernel taking most steps and handing each IK solve back."""
    def run():
        spec = EpisodeSpec.single("office", "path_preference", 5, seed=11, instance=2,
                                  sim="mujoco", t_max=10, robot="carry",
                                  physics=Physics.of(robot_model=robot_model,
                                                     timing=timing).to_json())
        runner = EpisodeRunner(spec)
        while not runner.done:
            runner.step()
        b = runner.body.base
        return (_state(b), b.tilts, b._k, b.ik_solves, b.q_kin.tobytes(),
                sorted(runner.result.metrics.items()),
                [(s.t, s.x, s.y, s.action) for s in runner.result.log])

    off, on = _both(monkeypatch, run)
    assert off == on
    k, solves = on[2], on[3]
    assert len(on[1]) == k and reasons["steps"] > 0.8 * k  # the kernel took most steps
    assert solves == -(-k // runner_ik_every(robot_model))  # one solve per IK period


def runner_ik_every(robot_model: str) -> int:
    """The physical arm's IK period in physics steps (50 ms on the Jaco, 100 ms on the
    TidyBot's Gen3, at 2 ms steps)."""
    return {"disk": 25, "tidybot": 50}[robot_model]


@pytest.mark.cross_cpu
def test_recorded_paths_are_the_same_with_compiled_steps(monkeypatch, reasons):
    """A path recorder (``--record-path``) lets the kernel run the steps between its samples
    and takes each sample in Python: the same samples, state and decisions either way."""
    def run():
        out = []
        for timing in ("decision", "guidance"):
            physics = Physics() if timing == "decision" else Physics.of(timing=timing)
            spec = EpisodeSpec.single("office", "path_preference", 5, seed=11, instance=1,
                                      sim="mujoco", t_max=8, physics=physics.to_json(),
                                      record_path_hz=60)
            runner = EpisodeRunner(spec)
            while not runner.done:
                runner.step()
            res = runner.result
            out.append((_state(runner.body.base), res.path,
                        [(s.t, s.x, s.y, s.action) for s in res.log]))
        return out

    off, on = _both(monkeypatch, run)
    assert off == on
    assert all(len(o[1]) > 100 for o in on)
    assert reasons["steps"] > 1000 and reasons.get(coasting.CROSS, 0) > 100


def _base(detector=None):
    world = load_world("simple")
    base = MobileBase(scene_for(world), sensor_model=SensorModel.realistic(),
                      rng=np.random.default_rng(7), detector=detector)
    base.controller = ProfiledController()
    base.measure = True
    base.reset(world.cell((3, 3)))
    return base, world


@pytest.mark.cross_cpu
def test_a_detector_that_fires_mid_move_hands_back_the_same(monkeypatch, reasons):
    """A hair-trigger detector (2.5 N onset, not scaled to the noise) under 2 N noise fires in
    moves: the onset rule and the cues run in Python from the step the kernel handed back."""
    def run():
        base, world = _base({"on_n": 2.5, "off_n": 1.5, "on_k": 0.0, "off_k": 0.0})
        for cell in ((8, 3), (8, 8), (3, 8), (3, 3)):
            base.move_to(world.cell(cell))
        return _state(base), len(base.felt)

    off, on = _both(monkeypatch, run)
    assert off == on and off[1] > 0
    assert reasons.get(coasting.DETECT, 0) > 0


@pytest.mark.cross_cpu
def test_a_base_against_a_wall_hands_back_the_same(monkeypatch, reasons):
    """A target beyond the map's wall: the base drives into it until the move's time limit;
    the contact measurements run in Python at each step with a contact."""
    def run():
        base, world = _base()
        step = base.decision.move(world.cell((1, 1)), limit_s=4.0)
        base.target = np.array([-1.0, -1.0])  # outside the walls
        step.run()
        return _state(base), base.physical_metrics()["collisions"]

    off, on = _both(monkeypatch, run)
    assert off == on and off[1] >= 1
    assert reasons.get(coasting.CONTACTS, 0) > 0


def test_a_state_that_is_not_finite_ends_the_same(monkeypatch, tmp_path):
    """A NaN velocity before a move: whatever MuJoCo and the base make of it (an error or a
    state; MuJoCo resets the data and logs a warning to ``MUJOCO_LOG.TXT`` in the working
    directory, here a temporary one), the same with the kernel."""
    monkeypatch.chdir(tmp_path)
    def run():
        base, world = _base()
        base.substep()  # the float path decided, the first step taken in Python
        base.data.qvel[0] = np.nan
        try:
            base.move_to(world.cell((5, 3)))
        except EpisodeError as exc:
            return str(exc)
        return _state(base)

    off, on = _both(monkeypatch, run)
    assert off == on


def test_hypot_is_cpythons():
    """CPython's ``math.hypot``, exactly, over magnitudes from subnormal to huge (the C
    library's ``hypot`` differs on about 1 in 200 of these) and the special values."""
    rng = np.random.default_rng(0)
    pairs = rng.normal(size=(200_000, 2)) * 10.0 ** rng.uniform(-320, 300, size=(200_000, 2))
    special = [0.0, -0.0, 5e-324, 1e-310, 1.0, math.inf, -math.inf, math.nan, 1.7e308]
    pairs = np.concatenate([pairs, [(a, b) for a in special for b in special]])
    many = nb.njit(lambda p: [native.hypot(p[i, 0], p[i, 1]) for i in range(len(p))])
    got = np.array(many(pairs))
    want = np.array([math.hypot(a, b) for a, b in pairs])
    assert np.array_equal(got, want, equal_nan=True)


@pytest.mark.cross_cpu
def test_blas_products_are_numpys():
    """``A x``, ``A^T x`` and ``sqrt(v . v)`` through NumPy's OpenBLAS give ``ndarray.dot``'s
    bits (the kernel NumPy picks for this CPU, FMA or not)."""
    @nb.njit
    def products(A, x, y, yt, v):
        native.matvec(A, x, y)
        if A.shape[0] == A.shape[1]:
            native.matTvec(A, x[: A.shape[0]], yt)
        return native.norm(v)

    rng = np.random.default_rng(1)
    for n in (3, 3, 3, 7, 9):
        for _ in range(2000):
            A = rng.normal(size=(3, n)) * 10.0 ** rng.uniform(-3, 3)
            x, v = rng.normal(size=n), rng.normal(size=rng.integers(2, 4))
            y, yt = np.empty(3), np.empty(3)
            r = products(A, x, y, yt, v)
            assert np.array_equal(y, A.dot(x))
            if n == 3:
                assert np.array_equal(yt, A.T.dot(x))
            assert r == math.sqrt(v.dot(v))


def test_the_contact_sensor_counts_mjdatas_contacts(monkeypatch):
    """The scene's contact sensor (what the kernel reads) holds ``MjData.ncon`` after every
    step of a base driven into a wall: none at first, then contacts."""
    monkeypatch.setenv("PATHPREF_COMPILED_STEPS", "0")
    base, world = _base()
    adr = base.model.sensor(coasting.CONTACT_SENSOR).adr[0]
    base.target = np.array([-1.0, -1.0])  # outside the walls
    seen = set()
    for _ in range(1500):
        base.substep()
        assert base.data.sensordata[adr] == base.data.ncon
        seen.add(int(base.data.ncon))
    assert 0 in seen and max(seen) >= 1


@pytest.mark.parametrize("task,physics,coasts", [
    ("navigate", Physics(), True),
    ("navigate", None, False),  # legacy: ideal sensor, plain detector
    ("navigate", Physics.of(base="diffdrive"), False),
    ("carry", Physics(), True),
    ("navigate", Physics.of(timing="guidance"), True),
    ("carry", Physics.of(timing="guidance"), True),
    ("carry", None, False),  # the legacy arm: its IK drives the base at 100 Hz
])
def test_only_the_setups_it_mirrors_coast(task, physics, coasts):
    """The kernel runs for the plain base and the physical carry arm with the realistic chain
    only (guided too); the differential drive, the legacy arm and the legacy sensing keep
    the Python path."""
    from pathpref.sim.body import base_params, build_base

    world = load_world("simple")
    scene = scene_for(world, task=task, base=None if physics is None else base_params(physics))
    base = build_base(scene, task, physics, np.random.default_rng(0))
    if physics is not None and physics.human.timing == "guidance":
        base.enable_guidance(2.0, 20.0)
    assert (base.coaster is not None) is coasts


@pytest.mark.cross_cpu
def test_the_step_handed_back_at_an_onset_is_measured(monkeypatch):
    """The kernel hands back within the step whose force crosses the detector's onset, after
    the detector's step (:func:`~pathpref.sim.cue_detector.decide_step`): the rest of that
    step (the cue stream, the measurements of its force) runs in Python. Stopped right there,
    the two paths agree, the peak push estimate included. Without the low-pass
    (``tau_s`` 0) the estimate crosses at a sensor sample: a new estimate, the largest so far,
    that only that step's measurement sees."""
    settings = {"on_n": 2.5, "off_n": 1.5, "on_k": 0.0, "off_k": 0.0, "tau_s": 0.0}

    def start():
        base, world = _base(settings)
        step = base.decision.move(world.cell((8, 3)), limit_s=3.0)
        base.substep()  # the float path decided
        return base, step

    monkeypatch.setenv("PATHPREF_COMPILED_STEPS", "1")
    seen = []
    kernel = coasting._coast
    monkeypatch.setattr(coasting, "_coast", lambda *a: seen.append(kernel(*a)) or seen[-1])
    base, step = start()
    assert base.coaster.ready()
    base.coaster.move(step)
    assert seen[0][0] == coasting.DETECT and base.sensing.faulty.fresh
    t_on, on = base.data.time, _state(base)
    monkeypatch.setenv("PATHPREF_COMPILED_STEPS", "0")
    base, step = start()
    while base.data.time < t_on:
        step.advance()
    assert base.data.time == t_on and _state(base) == on


@pytest.mark.cross_cpu
@pytest.mark.parametrize("physics", [{}, {"timing": "interval"}])
def test_the_control_rate_task_drives_the_same_compiled(monkeypatch, reasons, physics):
    """``navigate_control`` with realistic sensing (pushes every decision, or the simulated
    human's own clock), random velocity commands and the task's own policy: its runs of drive
    steps on the kernel (:meth:`~pathpref.sim.coasting.Coaster.drive`) give every observation,
    reward and final state of the Python steps, bit for bit."""
    from pathpref_tasks import load

    def run():
        env = load("navigate_control", map="simple", method="goal_only", seed=3, queries=30,
                   physics=physics)
        spec, rng = env.action_spec(), np.random.default_rng(1)
        env.reset()
        seen = []
        for k in range(300):  # 6 s of physics at 50 Hz
            a = env.task.policy_action() if k % 3 == 0 else \
                rng.uniform(spec.minimum, spec.maximum)
            ts = env.step(a)
            seen.append((ts.reward, [np.asarray(v).tobytes() for v in ts.observation.values()]))
            if ts.last():
                env.reset()
        return _state(env.task.base), seen

    off, on = _both(monkeypatch, run)
    assert off == on
    assert reasons["steps"] > 1000  # most physics steps ran on the kernel


@pytest.mark.cross_cpu
@pytest.mark.parametrize("shape,peak_n,duration_s", [
    ("half_sine", 30.0, 0.3), ("bell", 25.0, 0.5), ("plateau", 20.0, 1.2),
    ("half_sine", 5.0, 0.3)])  # the last too weak to feel: the release window runs out
def test_a_push_phase_runs_compiled_the_same(monkeypatch, reasons, shape, peak_n, duration_s):
    """A push phase on the standing base (:meth:`~pathpref.sim.mobile_base.MobileBase.
    receive_push`, the realistic chain) runs in the kernel (the push's force, the estimator
    with a cue under way, the detector's whole step), handing back only when the cue begins,
    goes active or ends: the same cue, onset time and state as the Python steps, bit for
    bit, for each push shape, and for a push the detector misses."""
    def run():
        base, world = _base()
        base.hold(0.5)
        cues, pushed = [], 0
        for heading in (0, 3, 6):
            push = HumanPush.sample(heading, 0.0, PushProfile(peak_n, duration_s, 0.0, shape),
                                    np.random.default_rng(heading))
            before = reasons["steps"]
            t0 = base.data.time
            step = base.decision.push(push, hold=True).run()
            pushed += round((base.data.time - t0) / base.dt)
            cues.append((None if step.cue is None else (step.cue.heading, step.cue.peak_n,
                                                         step.cue.impulse.tobytes()),
                         step.onset_s, reasons["steps"] - before))
            base.hold(0.4)
        return _state(base), cues, pushed

    off, on = _both(monkeypatch, run)
    assert off[0] == on[0] and [c[:2] for c in off[1]] == [c[:2] for c in on[1]]
    felt = [c for c, _, _ in on[1] if c is not None]
    assert len(felt) == (0 if peak_n < 8.0 else 3)
    if felt:
        assert [c[0] for c in felt] == [0, 3, 6]  # as pushed (no heading noise)
        assert reasons.get(coasting.DETECT, 0) >= 3  # a hand-back per cue's begin and end
    # the push phases' steps ran on the kernel (all but the steps of each hand-back)
    assert sum(k for _, _, k in on[1]) >= on[2] - 10 and on[2] > 300


def test_a_push_force_that_is_not_finite_is_refused_not_looped(monkeypatch):
    """A push whose force is not finite (a NaN angle) is left by the kernel to the Python
    step, which refuses it with one ConfigError: the push phase's loop cannot spin on a
    kernel that takes no step."""
    monkeypatch.setenv("PATHPREF_COMPILED_STEPS", "1")
    base, _ = _base()
    base.hold(0.3)
    push = HumanPush(float("nan"), 0.0, PushProfile(), 0)
    assert base.coaster is not None
    with pytest.raises(ConfigError, match="not finite"):
        base.receive_push(push)
