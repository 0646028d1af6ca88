"""One record per robot (issue 62, item 5): :data:`pathpref.sim.robots.ROBOTS` holds each
body's description (scale, footprint, drive defaults), its scene per task and its arm, and
every user reads it."""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")

import pytest  # noqa: E402

from pathpref.episode.physics import ROBOT_MODELS, Physics  # noqa: E402
from pathpref.errors import ConfigError  # noqa: E402
from pathpref.geometry.world import load_world  # noqa: E402
from pathpref.sim import body, robots  # noqa: E402
from pathpref.sim.robots import ROBOTS, Robot  # noqa: E402

#: the maps' footprint radius in cells (docs/motion_rule.md): a body's scale must fit it
MAP_FOOTPRINT_CELLS = 0.3


def test_every_description_has_its_record_and_the_scale_fits_the_footprint():
    assert set(ROBOTS) == set(ROBOT_MODELS) == {"disk", "tidybot"}
    for name, r in ROBOTS.items():
        assert r.model is ROBOT_MODELS[name]
        assert set(r.scenes) == {"navigate", "carry"}
        assert r.model.cell_size_m * MAP_FOOTPRINT_CELLS >= r.model.footprint_m - 1e-12
    assert Physics.of(robot_model="tidybot").cell_size_m == 1.0


def test_the_disks_footprint_is_its_cylinder():
    scene = body.scene_for(load_world("simple"))
    assert scene.model.geom("base_geom").size[0] == ROBOT_MODELS["disk"].footprint_m
    assert scene.cell_size == ROBOT_MODELS["disk"].cell_size_m


def test_a_third_robot_is_read_from_its_record(monkeypatch):
    """A robot added as a record (here the disk's parts under another name) is what
    ``scene_for`` builds and what ``build_base`` arms: no other table to extend."""
    calls = []

    def scene(world, cell_size, base):
        calls.append(cell_size)
        return ROBOTS["disk"].scenes["carry"](world, cell_size, base)

    third = Robot(ROBOT_MODELS["disk"], {"navigate": scene, "carry": scene}, ROBOTS["disk"].arm)
    monkeypatch.setitem(robots.ROBOTS, "third", third)
    world = load_world("simple")
    s = body.scene_for(world, 0.5, "carry", None, "third")
    assert calls == [0.5] and s.model.nu > 3  # the Jaco's servos are there
    with pytest.raises(ConfigError, match="unknown robot model 'fourth'; choose disk, tidybot, "
                                          "third"):
        body.scene_for(world, 0.5, "navigate", None, "fourth")
    with pytest.raises(ConfigError, match="unknown task 'swim'; choose navigate or carry"):
        body.scene_for(world, 0.5, "swim", None, "third")
