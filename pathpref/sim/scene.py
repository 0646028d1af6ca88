"""Build a MuJoCo scene from a map: the hand-written ``mjcf/navigate.xml`` plus the map's
obstacles and walls, added with MjSpec.

Scale: ``cell_size`` metres per grid unit (0.5 by default), so map point ``(x, y)`` is at
``(cell_size x, cell_size y)`` and cell ``(i, j)`` is centred at ``cell_size (i - 0.5, j - 0.5)``.
A cell-rectangle obstacle becomes a box; any other convex polygon becomes a convex mesh prism
from its H-representation's vertices. Four walls bound the map.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import mujoco
import numpy as np

from ..errors import ConfigError
from ..geometry.world import World

MJCF_DIR = Path(str(resources.files("pathpref.mjcf")))
OBSTACLE_HEIGHT = 0.6
WALL_THICKNESS = 0.1


def mjcf_path(name: str) -> Path:
    """Path of a hand-written MJCF file in ``mjcf/``; a clear error when it is missing."""
    path = MJCF_DIR / name
    if not path.exists():
        raise ConfigError(f"MJCF file {path} is missing; reinstall pathpref (its wheel ships "
                          "mjcf/ as the package pathpref.mjcf)")
    return path


@dataclass(frozen=True)
class Scene:
    """A compiled scene and the map it was built from."""

    world: World
    model: mujoco.MjModel
    cell_size: float

    def cell_centre(self, cell: int) -> np.ndarray:
        """Metric position ``(x, y)`` of a free cell's centre."""
        return (self.world.cells[cell] - 0.5) * self.cell_size

    def cell_at(self, xy: np.ndarray) -> int:
        """Free cell holding a metric position (the nearest free cell if it is in an obstacle)."""
        g = np.asarray(xy, float) / self.cell_size
        c = np.floor(g).astype(int) + 1
        W, H = self.world.spec.width, self.world.spec.height
        x, y = int(np.clip(c[0], 1, W)), int(np.clip(c[1], 1, H))
        idx = int(self.world.arrangement.cell_index[x - 1, y - 1])
        if idx >= 0:
            return idx
        d = np.linalg.norm(self.world.cells - 0.5 - g, axis=1)
        return int(np.argmin(d))


def _is_axis_box(vertices: np.ndarray) -> bool:
    if len(vertices) != 4:
        return False
    xs, ys = np.unique(np.round(vertices[:, 0], 9)), np.unique(np.round(vertices[:, 1], 9))
    return len(xs) == 2 and len(ys) == 2


def build_spec(world: World, cell_size: float = 0.5) -> mujoco.MjSpec:
    """The scene as an MjSpec (see module docstring)."""
    if not (np.isfinite(cell_size) and cell_size > 0):
        raise ConfigError(f"cell size must be a positive number of metres, got {cell_size}")
    try:
        spec = mujoco.MjSpec.from_file(str(mjcf_path("navigate.xml")))
    except ValueError as e:
        raise ConfigError(f"mjcf/navigate.xml does not load: {e}") from None
    wb = spec.worldbody
    W, H = world.spec.width * cell_size, world.spec.height * cell_size
    h = OBSTACLE_HEIGHT
    for k, obs in enumerate(world.spec.obstacles):
        v = obs.vertices * cell_size
        if _is_axis_box(v):
            lo, hi = v.min(axis=0), v.max(axis=0)
            g = wb.add_geom(name=f"obstacle_{k}", type=mujoco.mjtGeom.mjGEOM_BOX,
                            size=[*(hi - lo) / 2, h / 2], pos=[*(hi + lo) / 2, h / 2])
        else:
            verts = np.concatenate([np.c_[v, np.zeros(len(v))], np.c_[v, np.full(len(v), h)]])
            spec.add_mesh(name=f"obstacle_mesh_{k}", uservert=verts.ravel().tolist())
            g = wb.add_geom(name=f"obstacle_{k}", type=mujoco.mjtGeom.mjGEOM_MESH,
                            meshname=f"obstacle_mesh_{k}")
        g.classname = spec.find_default("static")
        g.material = "obstacle"
    t = WALL_THICKNESS
    for name, size, pos in (
        ("wall_south", [W / 2 + t, t / 2, h / 2], [W / 2, -t / 2, h / 2]),
        ("wall_north", [W / 2 + t, t / 2, h / 2], [W / 2, H + t / 2, h / 2]),
        ("wall_west", [t / 2, H / 2 + t, h / 2], [-t / 2, H / 2, h / 2]),
        ("wall_east", [t / 2, H / 2 + t, h / 2], [W + t / 2, H / 2, h / 2]),
    ):
        g = wb.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_BOX, size=size, pos=pos)
        g.classname = spec.find_default("static")
        g.material = "wall"
    # cameras over the map's centre
    side = max(W, H)
    spec.camera("top").pos = [W / 2, H / 2, 1.5 * side]
    spec.camera("perspective").pos = [W / 2, -0.55 * side, 1.0 * side]
    return spec


def build_scene(world: World, cell_size: float = 0.5) -> Scene:
    """Compile the scene of ``world``; a ConfigError names the cause when it cannot be built."""
    spec = build_spec(world, cell_size)
    try:
        model = spec.compile()
    except ValueError as e:
        raise ConfigError(f"map '{world.name}' cannot be built into a MuJoCo scene: {e}") from None
    return Scene(world=world, model=model, cell_size=cell_size)
