"""Build a MuJoCo scene from a map: the hand-written ``mjcf/navigate.xml`` plus the map's
obstacles and walls, added with MjSpec.

Scale: ``cell_size`` metres per grid unit (0.5 by default), so map point ``(x, y)`` is at
``(cell_size x, cell_size y)`` and cell ``(i, j)`` is centred at ``cell_size (i - 0.5, j - 0.5)``.
A cell-rectangle obstacle becomes a box; any other convex polygon becomes a convex mesh prism
from its H-representation's vertices. Four walls bound the map.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from importlib import resources
from pathlib import Path

import mujoco
import numba as nb
import numpy as np

from ..episode.physics import CELL_SIZE_M, DRIVE_V_MAX
from ..errors import ConfigError
from ..geometry.footprint import Clearance
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

    @cached_property
    def clearance(self) -> Clearance:
        """Distances to the map's obstacles and walls (:mod:`pathpref.geometry.footprint`)."""
        return Clearance(self.world.spec)

    def fits(self, xy: np.ndarray) -> bool:
        """Whether the robot's footprint centred at ``xy`` (m) keeps its reach (radius plus
        clearance, ``world.footprint``) from every obstacle and wall: the rule that decides
        the grid's moves (:mod:`pathpref.geometry.grid`), at a point."""
        return self.clearance.clear_at(np.asarray(xy, float)[:2] / self.cell_size,
                                       self.world.footprint.reach)

    @property
    def radius_m(self) -> float:
        """The body's plan radius (m): the world's footprint radius, which is the body's own
        (a body whose reach is wider than the map's footprint is refused,
        :func:`check_footprint`)."""
        return self.world.footprint.radius * self.cell_size

    def clear(self, a: np.ndarray, b: np.ndarray) -> bool:
        """Whether the footprint swept straight from ``a`` to ``b`` (m) keeps its radius plus
        the safety filter's margin (:data:`~.keep_clear.MARGIN_M`, the body's reach under a
        person's hand) from every obstacle and wall (it may use up the rest of the clearance:
        a base a person moved stands anywhere that fits)."""
        from .keep_clear import MARGIN_M

        p = np.asarray(a, float)[:2].reshape(1, 2) / self.cell_size
        q = np.asarray(b, float)[:2].reshape(1, 2) / self.cell_size
        return bool(self.clearance.clear(p, q, self.world.footprint.radius
                                         + MARGIN_M / self.cell_size)[0])

    def cell_centre(self, cell: int) -> np.ndarray:
        """Metric position ``(x, y)`` of a free cell's centre."""
        return (self.world.cells[cell] - 0.5) * self.cell_size

    @cached_property
    def cell_index(self) -> np.ndarray:
        """The grid's ``(W, H)`` free-cell ids (-1: in an obstacle), as :func:`grid_cell`
        takes them."""
        return np.ascontiguousarray(self.world.arrangement.cell_index, dtype=np.int64)

    def cell_at(self, xy: np.ndarray) -> int:
        """Free cell holding a metric position (the nearest free cell if it is in an obstacle)."""
        idx = grid_cell(float(xy[0]), float(xy[1]), self.cell_size, self.cell_index)
        if idx >= 0:
            return idx
        g = np.asarray(xy, float)[:2] / self.cell_size
        d = np.linalg.norm(self.world.cells - 0.5 - g, axis=1)
        return int(np.argmin(d))


@nb.njit(cache=True)
def grid_cell(x, y, cell, cell_index):
    """The free cell whose grid square holds ``(x, y)`` (m; ``cell`` m per cell): ``floor(x /
    cell) + 1`` clipped to the grid, on floats, then ``cell_index`` (-1: in an obstacle, or a
    coordinate that is not finite). :meth:`Scene.cell_at` and the compiled steps
    (:mod:`.coasting`) both call it."""
    gx, gy = x / cell, y / cell
    if not (math.isfinite(gx) and math.isfinite(gy)):
        return -1
    w, h = cell_index.shape
    i = min(max(int(math.floor(gx)) + 1, 1), w)
    j = min(max(int(math.floor(gy)) + 1, 1), h)
    return cell_index[i - 1, j - 1]


def _is_axis_box(vertices: np.ndarray) -> bool:
    if len(vertices) != 4:
        return False
    xs, ys = np.unique(np.round(vertices[:, 0], 9)), np.unique(np.round(vertices[:, 1], 9))
    return len(xs) == 2 and len(ys) == 2


@dataclass(frozen=True)
class BaseParams:
    """A physical base (episodes with physical parameters; None keeps ``navigate.xml``'s
    12 kg base with 120 N, ``kv`` 120 velocity servos). ``kind`` ``holonomic`` or
    ``diffdrive``; ``mass_kg`` of the whole base (Clearpath Ridgeback: 135 kg, datasheet
    figure recalled, not verified here); ``force_limit_n`` per drive axis; ``kv`` the velocity
    servo's gain (N s/m; 3000 gives the 135 kg base a 45 ms time constant, stiff like a geared
    wheel drive); ``friction_n`` the floor's Coulomb resistance to sliding per planar axis (N,
    MuJoCo's ``frictionloss`` on the slide joints: the drive must exceed it to move the base).
    ``docs/physics.md`` has the figures."""

    kind: str = "holonomic"
    mass_kg: float = 135.0
    force_limit_n: float = 120.0
    kv: float = 3000.0
    grip_n: float = 2000.0  # diffdrive: the wheels' lateral grip (N), a velocity servo at 0
    friction_n: float = 0.0


def apply_base(spec: mujoco.MjSpec, base: BaseParams) -> None:
    """Make ``navigate.xml``'s base the physical one: its mass, stiff force-limited velocity
    servos; for ``diffdrive``, the planar servos become a forward drive along the base's
    heading and a lateral grip (site transmissions on ``drive_site``, so they act in the
    base's frame as it yaws): the base cannot move sideways but by skidding past the grip."""
    body = spec.body("base")
    geom = spec.geom("base_geom")
    others = 0.2 + 0.01  # the handle and the nose
    geom.mass = base.mass_kg - others
    r = float(geom.size[0])
    spin = 0.5 * base.mass_kg * r * r  # the cylinder's yaw inertia (kg m^2)
    names = {a.name: a for a in spec.actuators}
    floor_friction(spec, base.friction_n)
    if base.kind == "diffdrive":
        body.add_site(name="drive_site", pos=[0.0, 0.0, 0.0])
        for old in ("vx", "vy"):
            spec.delete(names[old])
        for name, gear, limit, ctrl in (("drive", [1, 0, 0, 0, 0, 0], base.force_limit_n, 1.5),
                                        ("grip", [0, 1, 0, 0, 0, 0], base.grip_n, 0.0)):
            a = spec.add_actuator(name=name, target="drive_site",
                                  trntype=mujoco.mjtTrn.mjTRN_SITE)
            a.set_to_velocity(kv=base.kv)
            a.gear = gear
            a.forcerange = [-limit, limit]
            a.forcelimited = 1
            if ctrl > 0:  # the grip's control stays 0 (no lateral velocity)
                a.ctrlrange = [-ctrl, ctrl]
                a.ctrllimited = 1
    else:
        holonomic_servos(spec, base.kv, base.force_limit_n)
    yaw_servo(spec, spin)


def floor_friction(spec: mujoco.MjSpec, friction_n: float) -> None:
    """The floor's Coulomb resistance to sliding on the planar joints ``slide_x``,
    ``slide_y`` (N, MuJoCo's ``frictionloss``; 0: none)."""
    if friction_n > 0:
        for j in ("slide_x", "slide_y"):
            spec.joint(j).frictionloss = friction_n


def holonomic_servos(spec: mujoco.MjSpec, kv: float, limit_n: float) -> None:
    """The planar velocity servos ``vx``, ``vy``: gain ``kv`` (N s/m), force limited to
    ``limit_n`` per axis, commands within ``DRIVE_V_MAX``."""
    for name in ("vx", "vy"):
        a = spec.actuator(name)
        a.set_to_velocity(kv=kv)
        a.forcerange = [-limit_n, limit_n]
        a.ctrlrange = [-DRIVE_V_MAX, DRIVE_V_MAX]


def yaw_servo(spec: mujoco.MjSpec, spin: float) -> None:
    """The yaw velocity servo ``wz`` for a yaw inertia ``spin`` (kg m^2): a 20 ms time
    constant, its torque limited to ``20 spin`` (N m)."""
    wz = spec.actuator("wz")
    wz.set_to_velocity(kv=spin / 0.02)
    wz.forcerange = [-spin * 20.0, spin * 20.0]


@dataclass(frozen=True)
class RobotBody:
    """The robot a scene carries in place of ``navigate.xml``'s cylinder: ``spec(base)`` is
    ``navigate.xml``'s spec with the robot's base under ``navigate.xml``'s names (joints
    ``slide_x``, ``slide_y``, ``yaw``; actuators ``vx``, ``vy``, ``wz``; body ``handle`` with
    ``handle_site`` and the sensor ``handle_force``), ``radius_m(model)`` its plan radius in
    the compiled scene, and ``finish(spec, model)`` (optional) adds what needs the compiled
    addresses (a ``rest`` keyframe, which a base's reset starts from)."""

    name: str
    spec: Callable[[BaseParams | None], mujoco.MjSpec]
    radius_m: Callable[[mujoco.MjModel], float]
    finish: Callable[[mujoco.MjSpec, mujoco.MjModel], None] | None = None


def build_spec(world: World, cell_size: float = CELL_SIZE_M,
               base: BaseParams | None = None, robot: RobotBody | None = None
               ) -> mujoco.MjSpec:
    """The scene as an MjSpec (see module docstring); ``base`` a physical base; ``robot``
    another body than ``navigate.xml``'s cylinder (:class:`RobotBody`)."""
    if not (np.isfinite(cell_size) and cell_size > 0):
        raise ConfigError(f"cell size must be a positive number of metres, got {cell_size}")
    if robot is not None:
        spec = robot.spec(base)
    else:
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
    if base is not None and robot is None:
        apply_base(spec, base)
    # cameras over the map's centre
    side = max(W, H)
    spec.camera("top").pos = [W / 2, H / 2, 1.5 * side]
    spec.camera("perspective").pos = [W / 2, -0.55 * side, 1.0 * side]
    return spec


def build_scene(world: World, cell_size: float = CELL_SIZE_M, base: BaseParams | None = None,
                robot: RobotBody | None = None) -> Scene:
    """Compile the scene of ``world`` (``robot``: another body, :class:`RobotBody`); a
    ConfigError names the cause when it cannot be built."""
    spec = build_spec(world, cell_size, base, robot)
    try:
        model = spec.compile()
        if robot is not None and robot.finish is not None:
            robot.finish(spec, model)
            model = spec.compile()
    except ValueError as e:
        raise ConfigError(f"map '{world.name}' cannot be built into a MuJoCo scene: {e}") from None
    if robot is None:
        check_footprint(world, cell_size, float(model.geom("base_geom").size[0]), "the base")
    else:
        check_footprint(world, cell_size, robot.radius_m(model), f"the {robot.name}")
    return Scene(world=world, model=model, cell_size=cell_size)


def check_footprint(world: World, cell_size: float, radius_m: float, what: str,
                    fix: str | None = None) -> None:
    """A ConfigError when the body's footprint (``radius_m`` from the base's centre) is larger
    than the footprint the world's moves were made for (``world.footprint``): its moves
    would not be clear for this body. ``fix``: the body's own remedy, named before the
    world's (a footprint of that radius)."""
    fp = world.footprint
    if radius_m > fp.radius * cell_size + 1e-9:
        remedy = "build the world with a footprint of that radius " \
                 "(load_world(..., footprint=Footprint(r, c)))"
        raise ConfigError(
            f"{what} reaches {radius_m:.3f} m from the base's centre, more than the footprint "
            f"the map's moves were made for ({fp.describe(cell_size)}); "
            f"{remedy if fix is None else f'{fix}, or {remedy}'}")
