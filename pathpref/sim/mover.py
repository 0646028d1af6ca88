"""The MuJoCo embodiment of an episode (``--sim mujoco``): the robot observes a push through its
handle force sensor and moves by tracking cell centres at physics rate.

* ``human_input(heading)``: the human's intended heading becomes a noisy half-sine push; the
  robot observes the sector of the impulse its detector measured, or nothing if no cue was
  detected. The sampled heading and ``xfrc_applied`` are never read by the robot.
* ``move(action)``: the planner's target is the grid neighbour of SPEC 3 (the current cell when
  the grid move is blocked); the base drives there and the episode continues from the cell the
  base actually ends in.

Scenes are built once per process and map; each episode gets fresh ``MjData``.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..geometry.world import World
from ..planning.policies import STAY
from .force_cue import HumanPush, PushProfile
from .mobile_base import MobileBase
from .scene import Scene, build_scene


@lru_cache(maxsize=8)
def scene_for(world: World, cell_size: float = 0.5) -> Scene:
    """One compiled scene per world (worlds hash by identity) and cell size."""
    return build_scene(world, cell_size)


class MujocoMover:
    def __init__(self, world: World, spec, rng: np.random.Generator,
                 profile: PushProfile | None = None, cell_size: float = 0.5,
                 scene: Scene | None = None, data=None):
        self.world = world
        self.rng = rng
        self.scene = scene or scene_for(world, cell_size)
        self.base = MobileBase(self.scene, profile=profile, data=data)
        self.profile = self.base.profile
        self.last_push: HumanPush | None = None
        self.last_cue = None

    def reset(self, cell: int) -> None:
        self.base.reset(cell)
        self.cell = cell

    def human_input(self, heading: int) -> int | None:
        push = HumanPush.sample(heading, float(self.base.data.time), self.profile, self.rng)
        self.last_push = push
        self.last_cue = cue = self.base.receive_push(push)
        self.cell = self.base.cell
        return None if cue is None else cue.heading

    def move(self, action: int) -> int:
        target = self.cell if action == STAY else int(self.world.motion.next_cell[self.cell,
                                                                                  action])
        self.cell = self.base.move_to(target)
        return self.cell
