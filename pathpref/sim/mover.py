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

from ..errors import ConfigError
from ..geometry.world import World
from ..planning.policies import STAY
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


class MujocoMover:
    def __init__(self, world: World, spec, rng: np.random.Generator,
                 profile: PushProfile | None = None, cell_size: float = 0.5,
                 scene: Scene | None = None, data=None):
        self.world = world
        self.rng = rng
        task = getattr(spec, "task", "navigate")
        self.scene = scene or scene_for(world, cell_size, task)
        if task == "carry":
            from .arm import ArmBase

            self.base = ArmBase(self.scene, profile=profile, data=data)
        else:
            self.base = MobileBase(self.scene, profile=profile, data=data)
        self.profile = self.base.profile
        self.last_cue = None
        self.max_penetration = 0.0

    def reset(self, cell: int) -> None:
        self.base.reset(cell)
        self.cell = cell

    def human_input(self, heading: int) -> int | None:
        push = HumanPush.sample(heading, float(self.base.data.time), self.profile, self.rng)
        self.last_cue = cue = self.base.receive_push(push)
        self.cell = self.base.cell
        return None if cue is None else cue.heading

    def metrics(self) -> dict[str, float]:
        """Per-episode physical measurements (tilt and penetration for the arm)."""
        out = {"sim_time_s": float(self.base.data.time)}
        if hasattr(self.base, "tilt_rms"):
            out["tilt_rms_deg"] = self.base.tilt_rms()
            out["tilt_max_deg"] = float(max(self.base.tilts, default=0.0))
            out["max_penetration_mm"] = 1e3 * self.max_penetration
            out["ik_solves"] = float(self.base.ik_solves)
        return out

    def move(self, action: int) -> int:
        target = self.cell if action == STAY else int(self.world.motion.next_cell[self.cell,
                                                                                  action])
        self.cell = self.base.move_to(target)
        if hasattr(self.base, "max_penetration"):
            self.max_penetration = max(self.max_penetration, self.base.max_penetration())
        return self.cell
