"""The physics step's cost measurement (``pathpref bench --json``, ``physics``:
``overhead_vs_bare_mujoco`` and its parts) and a rule the step's shortcuts rely on."""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402

from pathpref.geometry.world import load_world  # noqa: E402
from pathpref.sim.cue_detector import FilteredCueDetector  # noqa: E402
from pathpref.sim.decision import DecisionStep  # noqa: E402
from pathpref.sim.mobile_base import MobileBase  # noqa: E402
from pathpref.sim.scene import build_scene  # noqa: E402


def test_idle_detector_goes_above_exactly_when_the_norm_exceeds_on():
    """While idle the detector skips ``np.hypot`` when ``|e|^2 < 0.98 on^2``; that changes no
    onset: for points on and around the circle ``|e| = on`` and the skip's boundary (a
    fresh detector with no low-pass, so ``e`` is the sample), the onset timer starts exactly
    when ``np.hypot(x, y) > on`` (brute force, both sides of both boundaries)."""
    rng = np.random.default_rng(3)
    on = 8.0
    angles = rng.uniform(0.0, 2.0 * np.pi, 4000)
    radii = np.concatenate([on * (1.0 + rng.uniform(-1e-12, 1e-12, 1500)),
                            on * np.sqrt(0.98) * (1.0 + rng.uniform(-1e-12, 1e-12, 1500)),
                            on * rng.uniform(0.9, 1.1, 1000)])
    above = 0
    for r, a in zip(radii, angles, strict=True):
        x, y = float(r * np.cos(a)), float(r * np.sin(a))
        det = FilteredCueDetector(0.002, tau_s=0.0, on_n=on)
        det.update(np.array([x, y]))
        want = float(np.hypot(x, y)) > on
        assert (det._above > 0.0) == want, (x, y)
        above += want
    assert 1000 < above < 3000  # both sides were reached


def test_timed_phases_adds_the_phases_and_restores_run():
    """The bench's phase timer adds every phase's wall time and puts ``DecisionStep.run``
    back, also when a phase raises."""
    from pathpref.apps.benchmarks.physics import timed_phases

    run = DecisionStep.run
    world = load_world("simple")
    base = MobileBase(build_scene(world))
    base.reset(world.cell((1, 1)))
    spent = [0.0]
    with timed_phases(spent):
        assert DecisionStep.run is not run
        base.hold(0.01)
    assert DecisionStep.run is run and spent[0] > 0.0
    assert round(float(base.data.time) / base.dt) == 5
    try:
        with timed_phases(spent):
            raise KeyError("x")
    except KeyError:
        pass
    assert DecisionStep.run is run


def test_bare_step_leaves_the_state_alone():
    """``bare_step_us`` steps a copy: the base's own state does not move."""
    from pathpref.apps.benchmarks.physics import bare_step_us

    world = load_world("simple")
    base = MobileBase(build_scene(world))
    base.reset(world.cell((1, 1)))
    base.data.qvel[base.vxy] = (0.5, 0.0)
    q, v, t = base.data.qpos.copy(), base.data.qvel.copy(), float(base.data.time)
    assert bare_step_us(base.model, base.data, steps=50, repeats=2) > 0.0
    assert (base.data.qpos == q).all() and (base.data.qvel == v).all()
    assert float(base.data.time) == t


def test_overhead_keys():
    """``physics_overhead``: the episode against bare MuJoCo plus planning is about 1 or
    above (the step has Python; wall-time ratios of one episode, so within 10 % of noise when
    another process shares the cores, as under ``make test``'s two) and its parts are
    positive."""
    from pathpref.apps.benchmarks.physics import physics_overhead

    out = physics_overhead(1)
    assert set(out) == {"overhead_vs_bare_mujoco", "python_us_per_step", "bare_step_us",
                        "overhead_vs_bare_mujoco_control", "navigate_control_vs_bare",
                        "navigate_control_vs_bare_cpu"}
    assert out["overhead_vs_bare_mujoco"] > 0.9 and out["overhead_vs_bare_mujoco_control"] > 0.9
    assert out["navigate_control_vs_bare_cpu"] > 0.9
    assert out["python_us_per_step"] > 0.0 and out["bare_step_us"] > 0.0


def test_cell_at_is_the_floor_rule_on_floats():
    """``Scene.cell_at`` (floats, no arrays) against the rule computed with NumPy: grid
    coordinates ``floor(xy / cell) + 1`` clipped to the grid, the free cell there, else the
    free cell whose centre is nearest; points inside, on cell borders, in obstacles and off
    the grid on every side."""
    world = load_world("simple")
    scene = build_scene(world)
    rng = np.random.default_rng(5)
    size, W, H = scene.cell_size, world.spec.width, world.spec.height
    pts = np.concatenate([rng.uniform(-1.0, 1.0, (1500, 2)) * (W * size, H * size) * 1.3,
                          rng.integers(-2, max(W, H) + 2, (500, 2)) * size])
    obstacles = 0
    for p in pts:
        c = np.clip(np.floor(p / size).astype(int) + 1, 1, (W, H))
        idx = int(world.arrangement.cell_index[c[0] - 1, c[1] - 1])
        if idx < 0:
            obstacles += 1
            idx = int(np.argmin(np.linalg.norm(world.cells - 0.5 - p / size, axis=1)))
        assert scene.cell_at(p) == idx, p
    assert obstacles > 0


def test_dot_is_matmul_bit_for_bit():
    """The sensor and estimator call ``ndarray.dot`` where the original code had ``@``: on this
    machine's BLAS both give the same bits for every shape and layout they use (3x3 in C and
    in Fortran order, a transposed view, its first two rows, 3 x nv), including inputs where a
    fused multiply-add changes the last bit (most random ones)."""
    rng = np.random.default_rng(11)
    for _ in range(3000):
        m = rng.standard_normal((3, 3)) * 10.0 ** rng.uniform(-3, 3)
        j = rng.standard_normal((3, 9))
        v, w = rng.standard_normal(3) * 10.0 ** rng.uniform(-3, 3), rng.standard_normal(9)
        for a, x in ((m, v), (m.T, v), (np.asfortranarray(m), v), (m[:2], v), (j, w)):
            assert (a.dot(x) == a @ x).all()
            out = np.zeros(len(a))
            assert (a.dot(x, out=out) == a @ x).all()
