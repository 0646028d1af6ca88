"""The plan reach of each body (pathpref/sim/reach.py): the disk's cylinder, the TidyBot's
bumper, and the arm-on-base at its carrying posture and along the postures near it; the disk's
carry scene refuses a carrying posture beyond its footprint."""

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


def test_the_jaco_carrying_stays_within_the_disks_footprint():
    """The Jaco at its carrying posture (``ARM_HOME``, the tray at ``TRAY_OFFSET``) and within
    0.1 rad of it on every joint: nothing below the obstacles' 0.6 m beyond the disk's 0.15 m
    cylinder, the footprint the maps are made for; the arm's own links reach 0.118 m (the
    earlier posture, the tray at (0.05, 0, 0.75) m: 0.208 m, up to 0.26 m within 0.1 rad)."""
    from pathpref.sim.arm import TRAY_OFFSET

    base, scene = _body("carry", "disk")
    m, root = scene.model, scene.model.body("base").id
    assert plan_reach_m(m, base.data, root) == pytest.approx(0.15, abs=1e-9)
    assert carry_reach_m(base) == pytest.approx(0.15, abs=1e-9)
    assert scene.radius_m == pytest.approx(0.15, abs=1e-9)
    # the arm and tray alone, the base's cylinder left out
    arm = plan_reach_m(m, base.data, root, exclude=(m.geom("base_geom").id,))
    assert arm == pytest.approx(0.118, abs=0.002)
    tray = base.data.xpos[base.tray] - base.data.xpos[root]
    assert np.abs(tray - TRAY_OFFSET).max() < 1e-3  # the posture holds the tray there
    assert np.hypot(*TRAY_OFFSET[:2]) < scene.radius_m  # over the base


def test_the_carry_scene_refuses_a_posture_beyond_the_footprint():
    """The disk's carry scene checks the carrying body's reach (``posture_reach_m``, as
    ``carry_reach_m``): the earlier posture (the tray at (0.05, 0, 0.75) m), whose lower links
    reach 0.208 m and up to 0.26 m within 0.1 rad, is refused with one line naming the body
    and the fix."""
    from dataclasses import replace

    from pathpref.errors import ConfigError
    from pathpref.sim.arm import JACO, build_arm_scene

    wide = replace(JACO, home=(-4.429, 3.997, 5.648, -0.675, 2.026, -2.53),
                   tray_offset=(0.05, 0.0, 0.75))
    with pytest.raises(ConfigError) as e:
        build_arm_scene(load_world("simple"), 0.5, None, arm=wide)
    msg = str(e.value)
    assert "\n" not in msg
    assert msg.startswith("the Jaco carrying the tray on the disk reaches 0.26")
    assert "scripts/carry_posture.py" in msg and "footprint=Footprint(r, c)" in msg
    build_arm_scene(load_world("simple"), 0.5, None)  # the carrying posture fits


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
