"""The public API of ``pathpref`` (the package docstring's tour) works as written."""

from __future__ import annotations

import numpy as np

import pathpref as pp


def test_every_public_name_resolves():
    for name in pp.__all__:
        assert getattr(pp, name) is not None
    assert pp.__version__.count(".") >= 2


def test_docstring_tour_runs(tmp_path):
    world = pp.load_world("simple")
    goals = np.array([world.cell((1, 8)), world.cell((10, 8))])
    model = pp.ObservationModel.build(world, goals)
    belief = pp.PreferenceBelief(model)
    start = world.cell((1, 1))
    for _ in range(3):
        belief.update(start, 0)  # north, toward (1, 8)
    p = belief.goal_marginal()
    assert p[0] > p[1]
    planner = pp.POMCP(world, goals, pp.get_preset("paper").path_preference, queries=200)
    assert 0 <= planner.search(start, belief, depth=30, seed=0).action < 8
    res = pp.run_episode(pp.EpisodeSpec(map="simple", method="compliant", delta_t=5,
                                        instance=0, run=0, instance_seed=1, run_seed=2))
    assert res.steps >= 1


def test_import_is_light():
    """``import pathpref`` loads neither NumPy nor a simulator (names resolve on first use)."""
    import subprocess
    import sys

    code = ("import sys, pathpref; "
            "print(sorted(m for m in sys.modules if m.split('.')[0] in "
            "('numpy', 'mujoco', 'dm_control', 'numba', 'scipy', 'matplotlib')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "[]"
