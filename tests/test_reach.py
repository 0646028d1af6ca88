"""The plan reach of each body (pathpref/sim/reach.py): the disk's cylinder, the TidyBot's
bumper, and the arm-on-base at its carrying posture and along the postures near it."""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from pathpref.episode.physics import Physics  # noqa: E402
from pathpref.geometry.world import load_world  # noqa: E402
from pathpref.sim import tidybot_base  # noqa: E402
from pathpref.sim.body import base_params, build_base, scene_for  # noqa: E402
from pathpref.sim.reach import carry_reach_m, plan_reach_m  # noqa: E402


def _body(task: str, robot_model: str):
    p = Physics.of(robot_model=robot_model)
    scene = scene_for(load_world("simple"), p.cell_size_m, task, base_params(p), robot_model)
    base = build_base(scene, task, p, np.random.default_rng(0))
    base.reset(3)
    return base, scene


def test_the_disk_reaches_its_cylinders_radius():
    """``navigate.xml``'s base: the 0.15 m cylinder (the handle does not collide)."""
    base, scene = _body("navigate", "disk")
    root = scene.model.body("base").id
    assert plan_reach_m(scene.model, base.data, root) == pytest.approx(0.15, abs=1e-9)


def test_the_jaco_carrying_reaches_past_the_disks_footprint():
    """The Jaco at its carrying posture reaches 0.208 m from the base's centre below the
    obstacles' 0.6 m (its lower links), beyond the disk's 0.15 m footprint the maps are made
    for; within 0.1 rad of that posture on every joint up to 0.26 m."""
    base, scene = _body("carry", "disk")
    root = scene.model.body("base").id
    at_home = plan_reach_m(scene.model, base.data, root)
    assert at_home == pytest.approx(0.208, abs=0.002)
    assert at_home > scene.radius_m
    near = carry_reach_m(base, samples=16)
    assert at_home <= near <= 0.30


def test_the_tidybot_carrying_stays_within_its_bumper():
    """The Gen3 carrying the tray on the TidyBot: nothing below 0.6 m beyond the bumper's
    corner (0.284 m, :func:`~pathpref.sim.tidybot_base.navigation_radius_m`), at the carrying
    posture and within 0.1 rad of it; the tray (0.8 m up) is above the obstacles."""
    base, scene = _body("carry", "tidybot")
    bumper = tidybot_base.navigation_radius_m(scene.model)
    root = scene.model.body("tidybot/base_link").id
    assert plan_reach_m(scene.model, base.data, root) == pytest.approx(bumper, abs=1e-6)
    assert carry_reach_m(base, samples=16) == pytest.approx(bumper, abs=1e-6)
    assert bumper <= scene.radius_m
    # the scene check takes the carrying body's radius
    assert tidybot_base.TIDYBOT_CARRY.radius_m(scene.model) == pytest.approx(bumper, abs=1e-6)
