"""A safety filter for a base that a person moves: never approach an obstacle faster than the
base can stop before it.

Where the base does not follow its own straight, clear moves (a guiding push deforms its path, a
push at any time makes it yield, and every move that starts off its cell's centre or still
moving: after a tap stopped a move, a yield or guidance, :meth:`.decision.DecisionStep.move`),
its velocity command ``v`` is filtered before it reaches the drive (the holonomic base's
planar command; the differential drive's forward speed, :mod:`.diffdrive`): for every
obstacle or wall whose nearest point lies within reach, with ``n`` the unit vector from that
point to the base's centre and ``gap`` the distance from the base's edge (the footprint's
radius) to it, the approach speed ``-v . n`` is capped at

    ``sqrt(2 a (gap - MARGIN_M))``   while ``gap >= MARGIN_M``,

the speed from which braking at ``a`` stops the base ``MARGIN_M`` short of the obstacle (only
obstacles within the stopping distance ``|v|^2 / (2 a)`` plus the margin can be met), and
at ``-BACK_PER_S (MARGIN_M - gap)`` closer in: the base backs out. A velocity servo holding a
base against a person's steady push drifts with it (29 N against ``kv`` 3000 N s/m: 1 cm/s),
so a cap of 0 would still let the push lean the base onto the obstacle; backing out
proportionally settles it about ``F / (kv BACK_PER_S)`` inside the margin instead (2 mm). The
excess is removed along ``n`` only, so the base still slides along a wall toward its target.
Two passes over the constraints settle a corner where two obstacles meet. Away from obstacles
the filter is the identity.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from ..geometry.footprint import near_into
from .scene import Scene

#: how close the base's edge may come to an obstacle under a push (m): inside the footprint's
#: clearance (0.05 m by default), so a body on a clear move never meets it
MARGIN_M = 0.02
#: how fast the base backs out from inside the margin, per metre inside it (1/s)
BACK_PER_S = 5.0
#: beyond its stopping distance ``|v|^2 / (2 a)`` and the margin, obstacles this much farther
#: from the base's edge are considered too (m); farther ones cannot be reached before it stops
LOOK_M = 0.05


def keep_clear(scene: Scene, pos: np.ndarray, v: np.ndarray, a_brake: float) -> np.ndarray:
    """``v`` (m/s, planar, modified in place and returned) with its approach to every nearby
    obstacle and wall capped (module docstring); ``pos`` the base's centre (m). The
    arithmetic is :func:`keep_clear_xy`'s, which the compiled steps call too."""
    clearance = scene.clearance
    v[0], v[1] = keep_clear_xy(float(pos[0]), float(pos[1]), float(v[0]), float(v[1]),
                               scene.cell_size, scene.radius_m, a_brake, clearance.arrays,
                               clearance.near_rows)
    return v


@nb.njit(cache=True)
def keep_clear_xy(px, py, vx, vy, cell, radius, a_brake, clr, rows):
    """The filtered ``(vx, vy)`` (module docstring) for a base at ``(px, py)`` (m) with
    footprint ``radius`` (m) on a map of ``cell`` m per cell (``clr``:
    :attr:`~pathpref.geometry.footprint.Clearance.arrays`, ``rows`` its scratch,
    :func:`~pathpref.geometry.footprint.near_into`): only obstacles within the stopping
    distance ``|v|^2 / (2 a_brake)`` plus ``MARGIN_M + LOOK_M`` of the base's edge are taken,
    each pass removing the approach above its cap along ``n``; allocates nothing."""
    reach = (vx * vx + vy * vy) / (2.0 * a_brake) + MARGIN_M + LOOK_M
    n = near_into(px / cell, py / cell, (radius + reach) / cell, clr, rows)
    for _ in range(2):
        for i in range(n):
            gap = rows[i, 0] * cell - radius
            if gap >= MARGIN_M:
                cap = math.sqrt(2.0 * a_brake * (gap - MARGIN_M))
            else:
                cap = -BACK_PER_S * (MARGIN_M - gap)
            nx, ny = rows[i, 1], rows[i, 2]
            approach = -(vx * nx + vy * ny)
            if approach > cap:
                vx += (approach - cap) * nx
                vy += (approach - cap) * ny
    return vx, vy
