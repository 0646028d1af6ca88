"""The safety filter on every motion (pathpref/sim/keep_clear.py): a move that starts off its
cell's centre or still moving (after a tap stopped a move, a yield, guidance) is filtered as
a guided base is, on the Python path and in the compiled move alike, and the move check keeps
the filter's margin."""

from __future__ import annotations

import math
import os

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from pathpref.episode.physics import Physics  # noqa: E402
from pathpref.geometry.world import load_world  # noqa: E402
from pathpref.sim import native  # noqa: E402
from pathpref.sim.body import base_params, build_base, scene_for  # noqa: E402
from pathpref.sim.decision import ON_GRID_M, off_the_grid  # noqa: E402
from pathpref.sim.keep_clear import MARGIN_M  # noqa: E402


def _base(kind: str = "holonomic"):
    world = load_world("simple")
    physics = Physics.of(base=kind)
    scene = scene_for(world, base=base_params(physics))
    return build_base(scene, "navigate", physics, np.random.default_rng(0)), scene


def _wall_cell(scene):
    """A free cell on the map's south wall and its free east neighbour."""
    cells = scene.world.cells
    for i, c in enumerate(cells):
        east = np.flatnonzero((cells[:, 0] == c[0] + 1) & (cells[:, 1] == c[1]))
        if c[1] == 1 and east.size:
            return i, int(east[0])
    raise AssertionError("no cell on the south wall")


def test_a_move_off_the_grid_is_filtered():
    """At a cell's centre at rest the next move is the grid's own (no filter); 5 cm off it, or
    moving at 0.2 m/s, it is not (the filter acts)."""
    base, scene = _base()
    s, _ = _wall_cell(scene)
    base.reset(s)
    pos = base.data.qpos[base.xy]
    assert not off_the_grid(base, pos.copy())
    base.data.qpos[base.xy[1]] += ON_GRID_M + 0.01
    assert off_the_grid(base, base.data.qpos[base.xy].copy())
    base.reset(s)
    base.data.qvel[base.vxy] = (0.2, 0.0)
    assert off_the_grid(base, base.data.qpos[base.xy].copy())


@pytest.mark.parametrize("kind", ["holonomic", "diffdrive"])
def test_the_filter_caps_the_approach_to_a_wall(kind):
    """A base 3 cm from the south wall (its edge; the cell's centre is 10 cm from it),
    its target inside the wall: unfiltered the command approaches the wall, filtered its
    approach is at most ``sqrt(2 a (gap - MARGIN_M))`` (a = half ``a_max``), and when ``gap``
    is inside the margin the base backs out."""
    base, scene = _base(kind)
    s, _ = _wall_cell(scene)
    base.reset(s)
    r = scene.radius_m
    for gap in (0.03, 0.01):
        base.data.qpos[base.xy[1]] = r + gap  # the wall's face at y = 0
        if kind == "diffdrive":
            base.data.qpos[base.yaw] = -math.pi / 2  # facing the wall
        base.target = np.array([base.data.qpos[base.xy[0]], -1.0])
        approach = []
        for flag in (False, True):
            base.keep_clear = flag
            base.controller.reset()
            if kind == "diffdrive":
                base.forward = 0.0
            for _ in range(400):  # the ramp builds the command up (a_max dt a step)
                base._control()
            c = base.data.ctrl[base.actuators]
            vy = c[1] if kind == "holonomic" else c[0] * math.sin(-math.pi / 2)
            approach.append(-vy)
        cap = math.sqrt(2 * 0.5 * base.controller.a_max * (gap - MARGIN_M)) \
            if gap >= MARGIN_M else 0.0
        assert approach[0] > cap + 0.01
        assert approach[1] <= cap + 1e-9


@pytest.mark.skipif(not native.ready(), reason=f"no compiled path: {native.WHY}")
def test_a_filtered_move_is_the_same_in_the_compiled_move(monkeypatch):
    """A move started 4.5 cm off its cell's centre toward the wall (its edge 5.5 cm from it)
    and moving at 0.15 m/s toward it (13 mm to stop at the drive's 120 N on 135 kg): the same
    state, to the bit, with the compiled steps off and on; the compiled move took it; no
    contact."""
    import pickle

    from pathpref.sim import coasting

    seen = {"steps": 0}
    kernel = coasting._coast

    def counted(*args):
        reason, steps = kernel(*args)
        seen["steps"] += steps
        return reason, steps

    monkeypatch.setattr(coasting, "_coast", counted)
    out = []
    for flag in ("0", "1"):
        monkeypatch.setenv("PATHPREF_COMPILED_STEPS", flag)
        base, scene = _base()
        s, t = _wall_cell(scene)
        base.reset(s)
        base.data.qpos[base.xy[1]] -= 0.045
        base.data.qvel[base.vxy] = (0.0, -0.15)
        base.move_to(t)
        assert base.keep_clear and base.measurements.collisions == 0
        d = base.data
        out.append(pickle.dumps((d.time, d.qpos.tobytes(), d.qvel.tobytes(),
                                 d.ctrl.tobytes())))
    assert out[0] == out[1]
    assert seen["steps"] > 100


def test_the_move_check_keeps_the_margin():
    """``Scene.clear``: a segment that keeps the bare radius but not the filter's margin from
    the wall is not clear (the move check uses the body's reach under a push)."""
    _, scene = _base()
    r = scene.radius_m
    a, b = np.array([0.6, r + 0.5 * MARGIN_M]), np.array([1.2, r + 0.5 * MARGIN_M])
    assert not scene.clear(a, b)
    assert scene.clear(a + [0.0, MARGIN_M], b + [0.0, MARGIN_M])
