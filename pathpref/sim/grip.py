"""The person's push as a wrench at the handle's force sensor: its torque.

The push acts at the handle's centre of mass (``xfrc_applied`` on the ``handle`` body: the
grip), the force sensor's origin is ``handle_site``, so a horizontal push ``F = (F_x, F_y, 0)``
has the torque ``tau = r x F`` (N m) about the sensor, ``r = p_grip - p_sensor``. On every body
the handle is a post on the base with the grip straight below the sensor, ``r = (0, 0, -h)``
(``h`` 0.05 m on the disk, 0.3 m on the TidyBot, navigating or carrying), so
``tau = (h F_y, -h F_x, 0)``: a push tilts the handle about the horizontal axis across it, and
``r`` does not change as the base yaws. :func:`grip_offset` reads ``r`` from a simulation's
state (the ROS sim's wrench), :func:`rest_offset` from a body's scene at rest (a study's
export, which has the recorded force but not the simulation), and :func:`torque` is the one
formula of both.
"""

from __future__ import annotations

from functools import cache

import mujoco
import numpy as np


def grip_ids(model: mujoco.MjModel) -> tuple[int, int]:
    """The ``handle`` body's and the ``handle_site``'s ids (looked up once per model)."""
    return int(model.body("handle").id), int(model.site("handle_site").id)


def grip_offset(data: mujoco.MjData, ids: tuple[int, int]) -> np.ndarray:
    """``r = p_grip - p_sensor`` (m, world axes) in ``data``'s state (``mj_forward`` done): the
    ``handle`` body's centre of mass less the ``handle_site``'s origin (``ids``:
    :func:`grip_ids`)."""
    return data.xipos[ids[0]] - data.site_xpos[ids[1]]


@cache
def rest_offset(task: str = "navigate", robot_model: str = "disk") -> tuple[float, ...]:
    """:func:`grip_offset` of the body ``robot_model`` built for ``task`` (its scene on the
    built-in map ``simple`` at its own scale), at rest in its initial pose."""
    from ..episode.cache import cached_world
    from ..episode.physics import ROBOT_MODELS
    from .body import scene_for

    scene = scene_for(cached_world("simple"), ROBOT_MODELS[robot_model].cell_size_m, task,
                      None, robot_model)
    data = mujoco.MjData(scene.model)
    mujoco.mj_forward(scene.model, data)
    return tuple(float(v) for v in grip_offset(data, grip_ids(scene.model)))


def torque(r, f) -> np.ndarray:
    """``tau = r x (F_x, F_y, 0)`` (N m): ``f`` one horizontal force ``(2,)`` or rows of them
    ``(n, 2)``; ``r`` (m) as :func:`grip_offset`."""
    f = np.asarray(f, float)
    f3 = np.zeros(f.shape[:-1] + (3,))
    f3[..., :2] = f
    return np.cross(np.asarray(r, float), f3)
