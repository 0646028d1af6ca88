"""The MuJoCo bodies of an episode (``--sim mujoco``): the robot observes a push through its
force sensor and moves by tracking cell centres at physics rate. Registered as ``mujoco`` in
the episode layer's body registry when :mod:`pathpref.sim` is imported.

* ``human_input(heading)``: the human's intended heading becomes a noisy half-sine push on the
  pushed body (the handle, or the tray of the ``carry`` arm); the robot observes the sector of
  the impulse its detector measured, or nothing if no cue was detected. The sampled heading
  and ``xfrc_applied`` are never read by the robot.
* ``move(action)``: the planner's target is the grid neighbour of SPEC 3 (the current cell when
  the grid move is blocked); the base drives there and the episode continues from the cell the
  base actually ends in.

Scenes are built once per process and map; each episode gets fresh ``MjData``.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..episode.body import Body, register_body
from ..errors import ConfigError
from ..geometry.grid import STAY
from ..geometry.world import World
from .force_cue import HumanPush, PushProfile
from .mobile_base import MobileBase
from .scene import Scene, build_scene


@lru_cache(maxsize=8)
def scene_for(world: World, cell_size: float = 0.5, task: str = "navigate") -> Scene:
    """One compiled scene per world (worlds hash by identity), cell size and task."""
    if task == "carry":
        from .arm import build_arm_scene

        return build_arm_scene(world, cell_size)
    if task != "navigate":
        raise ConfigError(f"unknown task '{task}'; choose navigate or carry")
    return build_scene(world, cell_size)


class MujocoBody(Body):
    """The MuJoCo robot: the planar base for ``navigate``, the base with the Jaco arm and tray
    for ``carry``. ``scene``/``data`` reuse a compiled scene or a caller's ``MjData`` (the
    dm_control task passes its physics' data)."""

    tasks = ("navigate", "carry")

    def __init__(self, world: World, spec, rng: np.random.Generator,
                 profile: PushProfile | None = None, cell_size: float = 0.5,
                 scene: Scene | None = None, data=None):
        self.world = world
        self.rng = rng
        task = spec.task
        self.scene = scene or scene_for(world, cell_size, task)
        if task == "carry":
            from .arm import ArmBase

            self.base: MobileBase = ArmBase(self.scene, profile=profile, data=data)
        else:
            self.base = MobileBase(self.scene, profile=profile, data=data)
        self.profile = self.base.profile
        self.last_cue = None

    def reset(self, cell: int) -> None:
        """Reset the physics with the base at the centre of ``cell``."""
        self.base.reset(cell)
        self.cell = cell

    def human_input(self, heading: int) -> int | None:
        """Push toward ``heading`` (with the profile's noise); the detected sector or None."""
        push = HumanPush.sample(heading, float(self.base.data.time), self.profile, self.rng)
        self.last_cue = cue = self.base.receive_push(push)
        self.cell = self.base.cell
        return None if cue is None else cue.heading

    def metrics(self) -> dict[str, float]:
        """Simulated time, and the base's own measurements (tilt, penetration for the arm)."""
        return {"sim_time_s": float(self.base.data.time), **self.base.metrics()}

    def move(self, action: int) -> int:
        """Drive to the grid neighbour of SPEC 3; the cell the base ends in."""
        target = self.cell if action == STAY else int(self.world.motion.next_cell[self.cell,
                                                                                  action])
        self.cell = self.base.move_to(target)
        return self.cell


register_body("mujoco", MujocoBody)
