"""The robots a physical episode can run, one record each (:data:`ROBOTS`): the body's
description (:class:`~pathpref.episode.physics.RobotModel`: its scale in metres per cell, its
footprint's plan radius and the drive settings that differ from the defaults, read by the
episode layer as ``Physics(robot_model=...)`` is parsed) and its simulator parts: the scene it
stands in for each task and the arm its ``carry`` drives. Every user reads this record
(:func:`~.body.scene_for`, :func:`~.body.build_base`, the dm_control tasks through them, the
warm-up); a third robot is one entry here beside its description in
:data:`~pathpref.episode.physics.ROBOT_MODELS` (the episode layer cannot name this module:
docs/architecture.md), and importing the simulator refuses a description without parts.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import partial

from ..episode.physics import ROBOT_MODELS, RobotModel
from ..geometry.world import World
from .arm import JACO, ArmModel, build_arm_scene
from .scene import BaseParams, Scene, build_scene
from .tidybot_base import TIDYBOT, TIDYBOT_ARM, TIDYBOT_CARRY

#: builds a robot's scene of a map: ``(world, cell_size, base) -> Scene``
SceneBuilder = Callable[[World, float, BaseParams | None], Scene]


@dataclass(frozen=True)
class Robot:
    """One robot: ``model`` its description (scale, footprint, drive defaults), ``scenes`` the
    builder of its scene per task (``navigate``, ``carry``) and ``arm`` the arm ``carry``
    drives (:class:`~.arm.ArmModel`)."""

    model: RobotModel
    scenes: Mapping[str, SceneBuilder]
    arm: ArmModel


#: the robots by the drive's ``robot_model``: ``disk``, ``navigate.xml``'s 12 kg cylinder (the
#: Jaco on it for ``carry``, attached after the map as its scenes always were), and ``tidybot``,
#: MuJoCo Menagerie's Stanford TidyBot with its Kinova Gen3 (:mod:`.tidybot_base`)
ROBOTS: dict[str, Robot] = {
    "disk": Robot(ROBOT_MODELS["disk"], {"navigate": build_scene, "carry": build_arm_scene},
                  JACO),
    "tidybot": Robot(ROBOT_MODELS["tidybot"],
                     {"navigate": partial(build_scene, robot=TIDYBOT),
                      "carry": partial(build_scene, robot=TIDYBOT_CARRY)}, TIDYBOT_ARM),
}
if set(ROBOTS) != set(ROBOT_MODELS):  # pragma: no cover - a robot described but not built
    raise ImportError(f"pathpref.sim.robots.ROBOTS {sorted(ROBOTS)} and "
                      f"pathpref.episode.physics.ROBOT_MODELS {sorted(ROBOT_MODELS)} differ: "
                      "give each robot its record in both")
