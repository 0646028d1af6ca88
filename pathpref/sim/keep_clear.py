"""A safety filter for a base that a person moves: never approach an obstacle faster than the
base can stop before it.

Where the base does not follow its own straight, clear moves (a guiding push deforms its path, a
push at any time makes it yield), its velocity command ``v`` is filtered before it reaches the
drive: for every obstacle or wall whose nearest point lies within reach, with ``n`` the unit
vector from that point to the base's centre and ``gap`` the distance from the base's edge (the
footprint's radius) to it, the approach speed ``-v . n`` is capped at

    ``sqrt(2 a (gap - MARGIN_M))``   (0 once ``gap <= MARGIN_M``),

the speed from which braking at ``a`` stops the base ``MARGIN_M`` short of the obstacle. The
excess is removed along ``n`` only, so the base still slides along a wall toward its target.
Two passes over the constraints settle a corner where two obstacles meet. The filter only ever
slows an approach: it is the identity away from obstacles.
"""

from __future__ import annotations

import math

import numpy as np

from .scene import Scene

#: how close the base's edge may come to an obstacle under a push (m): inside the footprint's
#: clearance (0.05 m by default), so a body on a clear move never meets it
MARGIN_M = 0.02
#: obstacles farther than this from the base's edge are not considered (m): a base at the
#: drive's top speed, 1 m/s, braking at 0.8 m/s^2 needs 0.63 m
LOOK_M = 1.0


def keep_clear(scene: Scene, pos: np.ndarray, v: np.ndarray, a_brake: float) -> np.ndarray:
    """``v`` (m/s, planar, modified in place and returned) with its approach to every nearby
    obstacle and wall capped (module docstring); ``pos`` the base's centre (m)."""
    cell, radius = scene.cell_size, scene.world.footprint.radius * scene.cell_size
    near = scene.clearance.near(np.asarray(pos, float) / cell, (radius + LOOK_M) / cell)
    for _ in range(2):
        for d, n in near:
            gap = d * cell - radius
            cap = math.sqrt(2.0 * a_brake * max(gap - MARGIN_M, 0.0))
            approach = -(v[0] * n[0] + v[1] * n[1])
            if approach > cap:
                v[:2] += (approach - cap) * n
    return v
