"""How far a robot reaches in plan from its base's centre: the footprint a body needs on a map
(:func:`plan_reach_m`), for the arm-on-base at its carrying posture and along the postures its
IK visits (:func:`carry_reach_m`, :func:`posture_reach_m`).

A robot's part can touch a wall or an obstacle only below their height
(:data:`~.scene.OBSTACLE_HEIGHT`, 0.6 m): its plan reach is the largest horizontal distance
from the base's centre to a point of a collision geom (``contype`` or ``conaffinity`` set) of
the robot's tree that lies at or below that height. Points, per geom type: a mesh's vertices;
a box's eight corners; a sphere's centre plus its radius; a capsule's or cylinder's two axis
ends plus its radius (a cylinder's rim is within its radius of its axis end); other types
their bounding sphere (``geom_rbound``). A point counts when its lowest part (less the radius
for round geoms) is at or below the height.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import mujoco
import numpy as np

from .scene import OBSTACLE_HEIGHT

if TYPE_CHECKING:
    from .arm import ArmModel

_ROUND = (int(mujoco.mjtGeom.mjGEOM_CAPSULE), int(mujoco.mjtGeom.mjGEOM_CYLINDER))
_CORNERS = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float)


def geom_points(model: mujoco.MjModel, data: mujoco.MjData, g: int
                ) -> tuple[np.ndarray, float]:
    """Geom ``g``'s points in the world (module docstring) and the radius about them (0 for
    a mesh's vertices and a box's corners)."""
    t = int(model.geom_type[g])
    R, p = data.geom_xmat[g].reshape(3, 3), data.geom_xpos[g]
    size = model.geom_size[g]
    if t == mujoco.mjtGeom.mjGEOM_MESH:
        mid = model.geom_dataid[g]
        v = model.mesh_vert[model.mesh_vertadr[mid]:model.mesh_vertadr[mid]
                            + model.mesh_vertnum[mid]]
        return v @ R.T + p, 0.0
    if t == mujoco.mjtGeom.mjGEOM_BOX:
        return (_CORNERS * size) @ R.T + p, 0.0
    if t == mujoco.mjtGeom.mjGEOM_SPHERE:
        return p.reshape(1, 3), float(size[0])
    if t in _ROUND:  # capsule, cylinder: the axis (local z) ends
        axis = R[:, 2] * size[1]
        return np.array([p - axis, p + axis]), float(size[0])
    return p.reshape(1, 3), float(model.geom_rbound[g])


def plan_reach_m(model: mujoco.MjModel, data: mujoco.MjData, root: int,
                 height_m: float = OBSTACLE_HEIGHT, exclude: tuple[int, ...] = ()) -> float:
    """The largest horizontal distance (m) from body ``root``'s origin to a point of a
    collision geom of ``root``'s tree at or below ``height_m`` (module docstring), in
    ``data``'s pose (``mj_forward`` done); the geoms ``exclude`` (ids) left out."""
    centre = data.xpos[root, :2]
    tree = model.body_rootid[root]
    far = 0.0
    for g in range(model.ngeom):
        if model.body_rootid[model.geom_bodyid[g]] != tree or g in exclude or \
                not (model.geom_contype[g] or model.geom_conaffinity[g]):
            continue
        pts, r = geom_points(model, data, g)
        low = pts[pts[:, 2] - r <= height_m]
        if len(low):
            far = max(far, float(np.hypot(*(low[:, :2] - centre).T).max()) + r)
    return far


def posture_reach_m(model: mujoco.MjModel, data: mujoco.MjData, arm: ArmModel,
                    home: np.ndarray, samples: int = 64, spread: float = 0.1, seed: int = 0
                    ) -> float:
    """The largest :func:`plan_reach_m` of ``arm``'s base body (an
    :class:`~.arm.ArmModel` of ``model``) in ``data`` with the arm's joints at ``home`` and at
    ``samples`` postures drawn uniformly within ``spread`` rad of it on every arm joint,
    clipped to the joints' ranges; the other joints as ``data`` has them. ``data``'s
    configuration is left as it was."""
    m, d = model, data
    q0 = d.qpos.copy()
    root = m.body(arm.base_body).id
    ids = [m.joint(j).id for j in arm.joints]
    adr = m.jnt_qposadr[ids]
    lim, limited = m.jnt_range[ids], m.jnt_limited[ids].astype(bool)
    rng = np.random.default_rng(seed)
    home = np.asarray(home, float)
    far = 0.0
    for k in range(samples + 1):
        q = home if k == 0 else home + rng.uniform(-spread, spread, home.size)
        d.qpos[adr] = np.where(limited, np.clip(q, lim[:, 0], lim[:, 1]), q)
        mujoco.mj_forward(m, d)
        far = max(far, plan_reach_m(m, d, root))
    d.qpos[:] = q0
    mujoco.mj_forward(m, d)
    return far


def carry_reach_m(base, samples: int = 64, spread: float = 0.1, seed: int = 0) -> float:
    """The carrying body's plan reach (m): :func:`posture_reach_m` of ``base`` (an
    :class:`~.arm.ArmBase`, reset) about its carrying posture ``base.home`` (the IK holds the
    arm near it: its posture task and the tray's fixed offset; ``spread`` bounds how far it
    may go), in the base's own data, whose pose is left as it was."""
    return posture_reach_m(base.model, base.data, base.arm, base.home, samples, spread, seed)
