"""Map files: the world rectangle, convex obstacles, and optional preference and goal band.

Format (JSON, or the same structure as a Python dict)::

    {
      "name": "my_map",
      "width": 10, "height": 10,               # grid units; cells are 1-based (x, y)
      "obstacles": [
        {"vertices": [[2.0, 2.0], [4.0, 2.5], [3.0, 4.0]]},       # convex polygon, any order
        {"cells": {"lower_left": [5, 5], "size": [2, 2]}}         # cell rectangle
      ],
      "preference": {"table": [{"from": [1, 1], "to": [5, 1]}]},  # optional, see preference.py
      "goal_band": {"x": [2, 10], "y": [8, 9]},                    # optional, instance sampling
      "t_max": 30,                                                  # optional, mission time
      "decomposition": "arrangement",                  # optional: or "coarse" (see coarse.py)
      "description": "free text"                                   # optional
    }

Cell ``(x, y)`` is the unit square ``[x-1, x] x [y-1, y]`` and is free when its centre lies
strictly outside every obstacle. Obstacles may overlap; they must lie inside the map box
(touching the border is fine). Every obstacle is stored in H-representation ``A x <= b`` with
unit-norm rows.

Mission time ``t_max`` (decision steps) is a map field; without it the rule
``t_max = 3 * max(width, height)`` applies, which gives the paper's 30 on its 10 x 10 maps and 60
on the 20 x 20 classroom (the built-in maps also state it). A map's identity is
:attr:`MapSpec.content_hash`, a hash of its canonical form (see :meth:`MapSpec.canonical`), so the
same map under another path or name is the same map, and an edited map is a new one.

Limits (a map past one is refused with a :class:`~pathpref.errors.MapError` before any work):
a map file is a regular file of at most :data:`MAX_MAP_BYTES` (10 MB), nested at most
:data:`MAX_DEPTH` levels, with integers of at most :data:`MAX_INT_DIGITS` digits; width and
height are 1..:data:`MAX_SIDE` (500); at most :data:`MAX_OBSTACLES` obstacles of at most
:data:`MAX_VERTICES` vertices each; every coordinate is a finite number within
``+-`` :data:`MAX_COORD` and lies in the map box (checked before any arithmetic); cell
rectangles fit in the map; the name has at most :data:`MAX_NAME` printable characters. How
long the arrangement takes to build is bounded separately
(:func:`pathpref.geometry.arrangement.check_arrangement_size`).
"""

from __future__ import annotations

import errno
import hashlib
import json
import math
import numbers
import os
import stat
from dataclasses import dataclass, field
from functools import cached_property
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from .. import plugins
from ..errors import MapError, did_you_mean
from .footprint import DEFAULT_FOOTPRINT
from .polygon import convex_vertices_to_h

BUILTIN_MAPS = ("simple", "office", "classroom")
MAX_SIDE = 500
MAX_T_MAX = 100_000
DECOMPOSITIONS = ("arrangement", "coarse")
#: largest map file read (bytes)
MAX_MAP_BYTES = 10 * 2**20
#: deepest nesting of lists/objects in a map (the format needs 6)
MAX_DEPTH = 32
#: longest integer literal in a map file (digits)
MAX_INT_DIGITS = 18
#: largest |coordinate| accepted before any arithmetic (obstacles must lie in the map anyway)
MAX_COORD = 1e6
#: most obstacles in a map, and vertices per obstacle
MAX_OBSTACLES = 10_000
MAX_VERTICES = 1_000
#: longest map name and description (characters)
MAX_NAME = 200
MAX_DESCRIPTION = 10_000


def default_t_max(width: int, height: int) -> int:
    """Mission time of a map without a ``t_max`` field: ``3 * max(width, height)`` steps."""
    return 3 * max(width, height)


@dataclass(frozen=True)
class Obstacle:
    """A convex obstacle ``{x : A x <= b}`` with its counter-clockwise vertices."""

    A: np.ndarray
    b: np.ndarray
    vertices: np.ndarray

    def contains(self, points: np.ndarray, eps: float = 1e-9) -> np.ndarray:
        """Boolean mask of the points (N x 2) inside or on the boundary of the obstacle."""
        return np.all(points @ self.A.T - self.b <= eps, axis=1)


@dataclass(frozen=True)
class MapSpec:
    """A validated map: size, obstacles and the optional user fields, unchanged."""

    name: str
    width: int
    height: int
    obstacles: tuple[Obstacle, ...]
    preference: dict[str, Any] | None = None
    goal_band: dict[str, list[int]] | None = None
    description: str = ""
    source: dict[str, Any] = field(default_factory=dict, compare=False, repr=False)
    t_max: int = 0  # 0: the size rule, see default_t_max
    decomposition: str = "arrangement"

    def __post_init__(self) -> None:
        if not self.t_max:
            object.__setattr__(self, "t_max", default_t_max(self.width, self.height))

    def canonical(self) -> dict[str, Any]:
        """What determines an episode on this map: size, obstacles (counter-clockwise vertices,
        starting at the lowest-leftmost one, in file order: the order numbers the lines),
        preference, goal band and decomposition; and, for a map with an obstacle that is not
        a rectangle of whole cells, the reach of the default robot footprint
        (``"footprint_reach"``, :mod:`.footprint`), which decides its moves (on maps of cell
        rectangles it removes none, so their identity is as before the footprint rule). Name,
        description and ``t_max`` (stored with each episode) are left out."""
        obstacles = []
        for o in self.obstacles:
            v = o.vertices
            k = min(range(len(v)), key=lambda i: (v[i, 1], v[i, 0]))
            obstacles.append(np.roll(v, -k, axis=0).tolist())
        out = {"width": self.width, "height": self.height, "obstacles": obstacles,
               "preference": self.preference, "goal_band": self.goal_band,
               "decomposition": self.decomposition}
        if not all(_cell_rectangle(o.vertices) for o in self.obstacles):
            out["footprint_reach"] = DEFAULT_FOOTPRINT.reach
        return out

    @cached_property
    def content_hash(self) -> str:
        """First 16 hex digits of the SHA-256 of :meth:`canonical` as sorted, compact JSON."""
        text = json.dumps(self.canonical(), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def to_dict(self) -> dict[str, Any]:
        """The map in file format (obstacles as vertex lists)."""
        d: dict[str, Any] = {
            "name": self.name,
            "width": self.width,
            "height": self.height,
            "obstacles": [{"vertices": o.vertices.tolist()} for o in self.obstacles],
        }
        if self.preference is not None:
            d["preference"] = self.preference
        if self.goal_band is not None:
            d["goal_band"] = self.goal_band
        if self.description:
            d["description"] = self.description
        d["t_max"] = self.t_max
        if self.decomposition != "arrangement":
            d["decomposition"] = self.decomposition
        return d


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise MapError(f"{where} must be a number, got {value!r}")
    if isinstance(value, int) and abs(value) > MAX_COORD:  # before float(): no overflow
        raise MapError(f"{where} = {_short(value)} is out of range; coordinates must lie "
                       f"within +-{MAX_COORD:g} (and inside the map)")
    if not math.isfinite(value):
        raise MapError(f"{where} is {value!r}; coordinates must be finite numbers")
    if abs(value) > MAX_COORD:
        raise MapError(f"{where} = {value!r} is out of range; coordinates must lie within "
                       f"+-{MAX_COORD:g} (and inside the map)")
    return float(value)


def _short(value: Any, limit: int = 40) -> str:
    """``repr(value)`` cut to ``limit`` characters (huge integers included, without the
    int-string conversion limit)."""
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 120:
        return f"an integer of {value.bit_length()} bits"
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _outside(where: str, x: float, y: float, width: int, height: int) -> MapError:
    return MapError(
        f"{where} extends outside the map (vertex at ({x:g}, {y:g}); the map "
        f"is [0, {width}] x [0, {height}]): clip it to the map or enlarge the map")


def _cell_rectangle(vertices: np.ndarray) -> bool:
    """Whether a convex polygon is an axis-aligned rectangle with whole-number corners."""
    xs, ys = np.unique(vertices[:, 0]), np.unique(vertices[:, 1])
    return (len(vertices) == 4 and len(xs) == 2 and len(ys) == 2
            and bool(np.all(np.round(vertices) == vertices)))


def cell_pair(value: Any, where: str) -> tuple[int, int]:
    """``value`` as a pair of whole numbers ``(x, y)`` (Python or NumPy integers, no bools);
    MapError naming ``where`` otherwise. The one parser of cells in maps, preferences and
    instances."""
    if (
        not isinstance(value, list | tuple | np.ndarray)
        or len(value) != 2
        or not all(isinstance(v, numbers.Integral) and not isinstance(v, bool | np.bool_)
                   for v in value)
    ):
        raise MapError(f"{where} must be a pair of whole numbers [x, y], got {_short(value)}")
    return int(value[0]), int(value[1])


def _parse_obstacle(raw: Any, k: int, width: int, height: int) -> Obstacle:
    where = f"obstacle {k}"
    if not isinstance(raw, dict):
        raise MapError(f"{where} must be an object with 'vertices' or 'cells', got {raw!r}")
    if "vertices" in raw and "cells" in raw:
        raise MapError(f"{where} gives both 'vertices' and 'cells'; keep one")
    if "vertices" in raw:
        verts = raw["vertices"]
        if not isinstance(verts, list):
            raise MapError(f"{where}: 'vertices' must be a list of [x, y] pairs")
        if len(verts) > MAX_VERTICES:
            raise MapError(f"{where} has {len(verts)} vertices; at most {MAX_VERTICES} are "
                           "allowed per obstacle")
        pts = []
        tol = 1e-9
        for j, p in enumerate(verts):
            if not isinstance(p, list | tuple) or len(p) != 2:
                raise MapError(f"{where} vertex {j + 1} must be a pair [x, y], got {_short(p)}")
            px = _number(p[0], f"{where} vertex {j + 1} x")
            py = _number(p[1], f"{where} vertex {j + 1} y")
            if not (-tol <= px <= width + tol and -tol <= py <= height + tol):
                raise _outside(where, px, py, width, height)
            pts.append([px, py])
        try:
            A, b, ccw = convex_vertices_to_h(np.array(pts, dtype=float).reshape(-1, 2))
        except ValueError as e:
            raise MapError(f"{where} {e}") from None
    elif "cells" in raw:
        cells = raw["cells"]
        if not isinstance(cells, dict) or "lower_left" not in cells or "size" not in cells:
            raise MapError(f"{where}: 'cells' must be {{'lower_left': [x, y], 'size': [w, h]}}")
        x, y = cell_pair(cells["lower_left"], f"{where} cells.lower_left")
        w, h = cell_pair(cells["size"], f"{where} cells.size")
        if w <= 0 or h <= 0:
            raise MapError(f"{where} cells.size must be positive, got [{_short(w)}, "
                           f"{_short(h)}]")
        if not (1 <= x <= width and 1 <= y <= height and x + w - 1 <= width
                and y + h - 1 <= height):
            raise MapError(
                f"{where} cells (lower_left [{_short(x)}, {_short(y)}], size [{_short(w)}, "
                f"{_short(h)}]) do not fit in the {width} x {height} map: need 1 <= x, "
                f"x + w - 1 <= {width}, 1 <= y, y + h - 1 <= {height}")
        x0, y0 = x - 1.0, y - 1.0
        ccw = np.array([[x0, y0], [x0 + w, y0], [x0 + w, y0 + h], [x0, y0 + h]])
        A, b, ccw = convex_vertices_to_h(ccw)
    else:
        raise MapError(f"{where} needs 'vertices' (a convex polygon) or 'cells' (a rectangle)")
    tol = 1e-9
    bad = (ccw[:, 0] < -tol) | (ccw[:, 0] > width + tol) | (ccw[:, 1] < -tol) | (
        ccw[:, 1] > height + tol
    )
    if bad.any():
        j = int(np.argmax(bad))
        raise _outside(where, ccw[j, 0], ccw[j, 1], width, height)
    return Obstacle(A=A, b=b, vertices=ccw)


def _parse_goal_band(raw: Any, width: int, height: int) -> dict[str, list[int]]:
    if not isinstance(raw, dict) or set(raw) - {"x", "y"}:
        raise MapError("goal_band must be {'x': [lo, hi], 'y': [lo, hi]} (inclusive cell ranges)")
    band = {}
    for axis, side in (("x", width), ("y", height)):
        lo, hi = cell_pair(raw.get(axis, [1, side]), f"goal_band.{axis}")
        if not 1 <= lo <= hi <= side:
            raise MapError(f"goal_band.{axis} = [{_short(lo)}, {_short(hi)}] must satisfy "
                           f"1 <= lo <= hi <= {side}")
        band[axis] = [lo, hi]
    return band


def _check_depth(raw: Any) -> None:
    """MapError when lists/objects nest deeper than :data:`MAX_DEPTH` (iterative: no
    recursion on a hostile dictionary)."""
    stack = [(raw, 1)]
    while stack:
        value, depth = stack.pop()
        if depth > MAX_DEPTH:
            raise MapError(f"the map nests lists/objects more than {MAX_DEPTH} levels deep; a "
                           "map needs only a few levels")
        if isinstance(value, dict):
            stack.extend((v, depth + 1) for v in value.values())
        elif isinstance(value, list | tuple):
            stack.extend((v, depth + 1) for v in value)


def _check_text(key: str, value: str, limit: int, printable: bool) -> None:
    if len(value) > limit:
        raise MapError(f"map field '{key}' has {len(value)} characters; at most {limit} are "
                       "allowed")
    if printable and not value.isprintable():
        raise MapError(f"map field '{key}' must be printable text (no newlines or control "
                       f"characters), got {_short(value)}")


def parse_map(raw: Any, default_name: str = "map") -> MapSpec:
    """Validate a map dictionary and return a :class:`MapSpec`; raise :class:`MapError`."""
    if not isinstance(raw, dict):
        raise MapError(f"a map must be a JSON object, got {type(raw).__name__}")
    _check_depth(raw)
    known = {"name", "width", "height", "obstacles", "preference", "goal_band", "description",
             "t_max", "decomposition"}
    unknown = sorted(set(raw) - known)
    if unknown:
        raise MapError(f"unknown map field(s) {unknown}; allowed: {sorted(known)}")
    for key in ("width", "height"):
        if key not in raw:
            raise MapError(f"map field '{key}' is missing (a whole number of grid cells)")
        v = raw[key]
        if isinstance(v, bool) or not isinstance(v, numbers.Integral):
            raise MapError(f"map field '{key}' must be a whole number of cells, got "
                           f"{_short(v)}")
        if not 1 <= v <= MAX_SIDE:
            raise MapError(f"map field '{key}' = {_short(v)} must be between 1 and {MAX_SIDE}")
    width, height = int(raw["width"]), int(raw["height"])
    name = raw.get("name", default_name)
    if not isinstance(name, str) or not name:
        raise MapError(f"map field 'name' must be a non-empty string, got {_short(name)}")
    _check_text("name", name, MAX_NAME, printable=True)
    obstacles_raw = raw.get("obstacles", [])
    if not isinstance(obstacles_raw, list):
        raise MapError("map field 'obstacles' must be a list")
    if len(obstacles_raw) > MAX_OBSTACLES:
        raise MapError(f"map '{name}' has {len(obstacles_raw)} obstacles; at most "
                       f"{MAX_OBSTACLES} are allowed")
    obstacles = tuple(
        _parse_obstacle(o, k + 1, width, height) for k, o in enumerate(obstacles_raw)
    )
    pref = raw.get("preference")
    if pref is not None and not isinstance(pref, dict):
        raise MapError("map field 'preference' must be an object with 'table' or 'route'")
    band = _parse_goal_band(raw["goal_band"], width, height) if "goal_band" in raw else None
    desc = raw.get("description", "")
    if not isinstance(desc, str):
        raise MapError("map field 'description' must be a string")
    _check_text("description", desc, MAX_DESCRIPTION, printable=False)
    t_max = raw.get("t_max", 0)
    if "t_max" in raw and (isinstance(t_max, bool) or not isinstance(t_max, int)
                           or not 1 <= t_max <= MAX_T_MAX):
        raise MapError(f"map field 't_max' must be a whole number of decision steps in "
                       f"1..{MAX_T_MAX}, got {_short(t_max)}")
    decomposition = raw.get("decomposition", "arrangement")
    if decomposition not in DECOMPOSITIONS:
        raise MapError(f"map field 'decomposition' must be one of {list(DECOMPOSITIONS)}, "
                       f"got {_short(decomposition)}")
    spec = MapSpec(name=name, width=width, height=height, obstacles=obstacles,
                   preference=pref, goal_band=band, description=desc, source=raw,
                   t_max=int(t_max), decomposition=decomposition)
    if not free_cell_mask(spec).any():
        raise MapError(f"map '{name}' has no free cell: every cell centre lies in an obstacle")
    return spec


def free_cell_mask(spec: MapSpec) -> np.ndarray:
    """Boolean array ``[x-1, y-1]`` (shape W x H): True where the cell centre is free.

    Each obstacle tests only the cell centres in its bounding box (so many small obstacles on
    a large map stay cheap)."""
    occupied = np.zeros((spec.width, spec.height), dtype=bool)
    for o in spec.obstacles:
        lo = np.floor(o.vertices.min(axis=0) - 0.5 - 1e-6)
        hi = np.ceil(o.vertices.max(axis=0) - 0.5 + 1e-6)
        x0, y0 = max(int(lo[0]), 0), max(int(lo[1]), 0)
        x1, y1 = min(int(hi[0]), spec.width - 1), min(int(hi[1]), spec.height - 1)
        if x0 > x1 or y0 > y1:
            continue
        xs, ys = np.meshgrid(np.arange(x0, x1 + 1) + 0.5, np.arange(y0, y1 + 1) + 0.5,
                             indexing="ij")
        centres = np.stack([xs.ravel(), ys.ravel()], axis=1)
        occupied[x0:x1 + 1, y0:y1 + 1] |= o.contains(centres).reshape(xs.shape)
    return ~occupied


def builtin_map_path(name: str) -> Path:
    """Path of a built-in map file (``simple``, ``office``, ``classroom``)."""
    return Path(str(resources.files("pathpref.maps").joinpath(f"{name}.json")))


def _plugin_map(name: str) -> MapSpec | None:
    """The map another package declares as ``name`` in the entry-point group
    ``pathpref.maps`` (:mod:`pathpref.plugins`): a dictionary, a :class:`MapSpec` or the path
    of an existing JSON map, or a function returning one; None when no package declares it.
    A built-in name or an existing file always wins (the caller looks there first)."""
    found = plugins.load(plugins.MAPS, name)
    if found is None:
        return None
    try:
        given = found() if callable(found) else found
    except Exception as e:  # noqa: BLE001 - any failure of another package's code
        raise MapError(f"entry point {name!r} of group {plugins.MAPS} failed to give a map: "
                       f"{type(e).__name__}: {' '.join(str(e).split())[:200]}") from None
    if isinstance(given, MapSpec):
        return given
    if isinstance(given, dict):
        return parse_map(given)
    if isinstance(given, str | os.PathLike) and os.path.isfile(given):
        return load_map(Path(given))
    raise MapError(f"map entry point {name!r} must give a map dictionary, a MapSpec or an "
                   f"existing JSON path, got {given!r}"[:300])


def load_map(source: str | Path | dict[str, Any]) -> MapSpec:
    """Load a map from a built-in name, a JSON file path, a dictionary, or the name of a map
    another package declares (entry-point group ``pathpref.maps``)."""
    if not isinstance(source, str | Path):
        return parse_map(source)
    s = str(source)
    if s in BUILTIN_MAPS:
        path = builtin_map_path(s)
    else:
        path = Path(s)
        try:
            exists = path.exists()
        except (OSError, ValueError):  # e.g. a name too long for the file system
            exists = False
        if not exists:
            given = _plugin_map(s)
            if given is not None:
                return given
            raise MapError(
                f"no map named {_short(s, 80)}{did_you_mean(s, BUILTIN_MAPS)}: give a built-in "
                f"name ({', '.join(BUILTIN_MAPS)}) or the path of a JSON map file"
            )
    text = read_map_text(path)
    try:
        raw = json.loads(text, parse_int=_parse_int)
    except json.JSONDecodeError as e:
        raise MapError(f"map file {path} is not valid JSON (line {e.lineno}: {e.msg})") from None
    except RecursionError:
        raise MapError(f"map file {path} nests lists/objects too deeply to read; a map needs "
                       f"at most {MAX_DEPTH} levels") from None
    except ValueError as e:  # e.g. a number too long (from _parse_int)
        raise MapError(f"map file {path}: {e}") from None
    return parse_map(raw, default_name=path.stem)


def _parse_int(text: str) -> int:
    digits = len(text.lstrip("-"))
    if digits > MAX_INT_DIGITS:
        raise ValueError(f"an integer of {digits} digits ({text[:12]}...) is out of range; "
                         f"numbers in a map have at most {MAX_INT_DIGITS} digits")
    return int(text)


def read_map_text(path: Path) -> str:
    """The text of the map file ``path``: a regular file of at most :data:`MAX_MAP_BYTES`,
    UTF-8; MapError otherwise. Opened without blocking (a FIFO or device is refused, not
    waited on) and read through one descriptor (no race between the check and the read)."""
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError as e:
        raise MapError(f"cannot read map file {path}: {e.strerror or e}") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            kind = "a folder" if stat.S_ISDIR(st.st_mode) else "not a regular file"
            raise MapError(f"map file {path} is {kind} (a device, pipe or folder cannot be a "
                           "map); give the path of a JSON map file")
        if st.st_size > MAX_MAP_BYTES:
            raise MapError(f"map file {path} has {st.st_size:,} bytes, above the limit of "
                           f"{MAX_MAP_BYTES:,} (10 MB)")
        chunks, total = [], 0
        while True:
            try:
                chunk = os.read(fd, 1 << 20)
            except OSError as e:
                if e.errno == errno.EAGAIN:
                    continue
                raise
            if not chunk:
                break
            total += len(chunk)
            if total > MAX_MAP_BYTES:  # the file grew while being read
                raise MapError(f"map file {path} is larger than the limit of "
                               f"{MAX_MAP_BYTES:,} bytes (10 MB)")
            chunks.append(chunk)
    except OSError as e:
        raise MapError(f"cannot read map file {path}: {e.strerror or e}") from None
    finally:
        os.close(fd)
    try:
        return b"".join(chunks).decode("utf-8")
    except UnicodeDecodeError as e:
        raise MapError(f"map file {path} is not UTF-8 text (byte {e.start}); a map is a JSON "
                       "text file") from None
