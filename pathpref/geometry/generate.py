"""Random floor plans for tests and benchmarks: rotated rectangles and axis-aligned boxes.

:func:`random_floor_plan` places ``n_rotated`` rectangles at random angles and ``n_boxes``
cell-aligned boxes in a ``width x height`` map, all inside the map box, from a seed. Obstacles may
overlap (valid in the map format). The result is a map dictionary (see :mod:`.maps`).

:func:`four_connected_components` labels free cells by 4-connectivity, the reference the motion
rule must match (:mod:`.grid`).

:func:`floor_plan` is a whole plan from a seed (``pathpref map generate``, and the held-out
plans of ``scripts/homotopy_prior_eval.py``): :func:`random_floor_plan` with the defaults of
:data:`PLAN_DEFAULTS` (24 x 16 cells, 7 rotated rectangles, 2 boxes, sides 1.5..4) and a
preferred route, either

- ``open``: through four waypoints drawn without replacement (``default_rng(seed)``) from the
  cells of the largest free area (ordered by x, then y, 1-based), in the order drawn; or
- ``loop``: the closed route round the map of :func:`with_loop_preference`.

The *free area* is where the robot goes: the largest connected component of the grid motion of
the plan for the robot's :class:`~.footprint.Footprint` (:mod:`.grid`; ``footprint`` argument,
:data:`~.footprint.DEFAULT_FOOTPRINT` by default), so every waypoint can be reached by the
robot. The plans stored in ``docs/results/heldout_plans`` were drawn for a point robot
(``Footprint(0, 0)``, whose moves are those of the grid's corner rule alone and whose
components are the 4-connected ones); some of them need passages the default robot cannot make.

A plan whose largest free area has fewer than :data:`MIN_ROUTE_CELLS` cells is refused
(:class:`~pathpref.errors.MapError`, one line): its free space is too fragmented to place a
route and draw the instances' start and goal candidates. So is, before anything is built, a
request it cannot honour (:func:`check_plan_request`: sides that are not ``0 < LO <= HI`` or
rotated rectangles that cannot fit the map) and a drawn plan whose arrangement may exceed
:data:`MAX_PLAN_POLYTOPES` (:func:`check_plan_size`); the rectangles' rejection draws are
bounded (:data:`DRAWS_PER_RECTANGLE`), so a plan is made in bounded time.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.ndimage import label

from ..errors import MapError
from .footprint import DEFAULT_FOOTPRINT, Footprint

#: the defaults of :func:`floor_plan` (and of ``pathpref map generate``'s flags)
PLAN_DEFAULTS = {"width": 24, "height": 16, "rotated": 7, "boxes": 2, "size_range": (1.5, 4.0)}
#: the kinds of preferred route of :func:`floor_plan`
ROUTE_KINDS = ("open", "loop")
#: the fewest cells the largest free area of a generated plan may have: the waypoints of an
#: open route (4) and an instance's start and 10 goal candidates
MIN_ROUTE_CELLS = 11
#: the most polytopes a plan of :func:`floor_plan` may have (the bound of
#: :func:`~.arrangement.arrangement_size`, checked on the drawn obstacles before anything is
#: built): with at most 200 x 200 cells (``pathpref map generate``), a plan then builds in
#: seconds (docs/errors.md, "Limits")
MAX_PLAN_POLYTOPES = 5000
#: draws of a rotated rectangle's size per rectangle before :func:`random_floor_plan` gives up
#: (a size that does not fit the map is drawn again)
DRAWS_PER_RECTANGLE = 100


def check_plan_request(width: int, height: int, rotated: int,
                       size_range: tuple[float, float]) -> None:
    """Refuse (one MapError line) obstacle sides that cannot be honoured: ``0 < LO <= HI``,
    finite, and, with rotated rectangles, ``HI * sqrt(2) < min(width, height)`` (a rectangle of
    any drawn size fits the map at any angle, so every draw is kept)."""
    lo, hi = size_range
    if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo <= hi):
        raise MapError(f"--sizes LO HI must be finite with 0 < LO <= HI, got {lo:g} {hi:g}")
    side = min(width, height)
    if rotated and not float(np.hypot(hi, hi)) < side:
        raise MapError(f"--sizes HI = {hi:g}: a rotated rectangle of side {hi:g} does not fit a "
                       f"{width} x {height} map at every angle; give HI below "
                       f"{side / np.sqrt(2):.4g} (min(width, height) / sqrt 2) or a larger map")


def check_plan_size(raw: dict[str, Any]) -> None:
    """Refuse (one MapError line) a drawn plan whose arrangement may have more than
    :data:`MAX_PLAN_POLYTOPES` polytopes, before it is built."""
    from .arrangement import arrangement_size
    from .maps import parse_map

    m, n, bound = arrangement_size(parse_map({k: v for k, v in raw.items()
                                              if k != "preference"}))
    if bound > MAX_PLAN_POLYTOPES:
        raise MapError(f"the plan may have up to {bound:,} polytopes ({m} distinct obstacle "
                       f"lines, {n:,} free cells), above the limit {MAX_PLAN_POLYTOPES:,} of a "
                       "generated plan; use fewer or larger obstacles, or a smaller map")


def rotated_rectangle(centre: np.ndarray, size: np.ndarray, angle: float) -> np.ndarray:
    """Vertices (CCW) of a ``size[0] x size[1]`` rectangle turned by ``angle`` about ``centre``."""
    c, s = np.cos(angle), np.sin(angle)
    half = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * (np.asarray(size) / 2)
    return half @ np.array([[c, -s], [s, c]]).T + centre


def random_floor_plan(
    width: int,
    height: int,
    n_rotated: int,
    n_boxes: int = 0,
    seed: int = 0,
    size_range: tuple[float, float] = (1.0, 4.0),
    name: str | None = None,
) -> dict[str, Any]:
    """A map dictionary with random obstacles (see module docstring)."""
    rng = np.random.default_rng(seed)
    lo, hi = size_range
    obstacles: list[dict[str, Any]] = []
    draws = 0
    while len(obstacles) < n_rotated:
        draws += 1
        if draws > DRAWS_PER_RECTANGLE * n_rotated:
            raise MapError(f"no rotated rectangle of sides {lo:g}..{hi:g} fits a {width} x "
                           f"{height} map in {draws - 1} draws; give smaller sizes")
        size = rng.uniform(lo, hi, size=2)
        r = 0.5 * float(np.hypot(*size))
        if 2 * r >= min(width, height):
            continue
        centre = rng.uniform([r, r], [width - r, height - r])
        verts = rotated_rectangle(centre, size, float(rng.uniform(0, np.pi)))
        obstacles.append({"vertices": np.round(verts, 6).tolist()})
    for _ in range(n_boxes):
        w, h = (int(v) for v in rng.integers(max(int(lo), 1), max(int(hi), 1) + 1, size=2))
        w, h = min(w, width), min(h, height)
        x = int(rng.integers(1, width - w + 2))
        y = int(rng.integers(1, height - h + 2))
        obstacles.append({"cells": {"lower_left": [x, y], "size": [w, h]}})
    return {
        "name": name or f"random_{width}x{height}_{n_rotated}r{n_boxes}b_{seed}",
        "width": width,
        "height": height,
        "obstacles": obstacles,
    }


def four_connected_components(free: np.ndarray) -> tuple[np.ndarray, int]:
    """Labels (``0`` = blocked, ``1..k`` = components) of a ``(W, H)`` free mask, 4-connected."""
    labels, k = label(free, structure=np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]]))
    return labels, int(k)


def largest_free_area(raw: dict[str, Any], footprint: Footprint = DEFAULT_FOOTPRINT
                      ) -> tuple[np.ndarray, np.ndarray]:
    """The 0-based ``x`` and ``y`` of the cells of the largest component of the robot's motion
    on the plan ``raw`` (module docstring), ordered by x, then y; empty without free cells.
    Ties go to the component of the first cell in that order."""
    from .maps import parse_map
    from .world import World

    world = World.from_spec(parse_map({k: v for k, v in raw.items() if k != "preference"}),
                            footprint)
    if not world.n_cells:
        return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
    order = np.lexsort((world.cells[:, 1], world.cells[:, 0]))
    labels = world.motion.components()[order]
    sizes = np.bincount(labels)
    biggest = labels[np.flatnonzero(sizes[labels] == sizes.max())[0]]
    cells = world.cells[order][labels == biggest] - 1
    return cells[:, 0].astype(int), cells[:, 1].astype(int)


def with_loop_preference(raw: dict[str, Any], footprint: Footprint = DEFAULT_FOOTPRINT
                         ) -> dict[str, Any]:
    """``raw`` plus a closed-route preference around the map (a loop through the free cells
    nearest to the four corners, all in the largest free area of :func:`largest_free_area`)."""
    from .maps import parse_map

    spec = parse_map(raw)
    xs, ys = largest_free_area(raw, footprint)
    corners = [(0, 0), (spec.width - 1, 0), (spec.width - 1, spec.height - 1),
               (0, spec.height - 1)]
    route = []
    for cx, cy in corners:
        k = int(np.argmin((xs - cx) ** 2 + (ys - cy) ** 2))
        route.append([int(xs[k]) + 1, int(ys[k]) + 1])
    return {**raw, "preference": {"route": route, "closed": True}}


def floor_plan(seed: int, route: str = "open", width: int = PLAN_DEFAULTS["width"],
               height: int = PLAN_DEFAULTS["height"], rotated: int = PLAN_DEFAULTS["rotated"],
               boxes: int = PLAN_DEFAULTS["boxes"],
               size_range: tuple[float, float] = PLAN_DEFAULTS["size_range"],
               name: str | None = None, description: str | None = None,
               footprint: Footprint = DEFAULT_FOOTPRINT) -> dict[str, Any]:
    """A floor plan with a preferred route from ``seed`` for a robot of ``footprint`` (module
    docstring); ``description``, when given, is the plan's. Raises :class:`MapError` for a
    plan too fragmented for a route and ValueError for an unknown ``route``."""
    if route not in ROUTE_KINDS:
        raise ValueError(f"route must be one of {ROUTE_KINDS}, got {route!r}")
    check_plan_request(width, height, rotated, size_range)
    raw = random_floor_plan(width, height, rotated, n_boxes=boxes, seed=seed,
                            size_range=size_range, name=name)
    check_plan_size(raw)
    xs, ys = largest_free_area(raw, footprint)
    cells = len(xs)
    if cells < MIN_ROUTE_CELLS:
        raise MapError(
            f"the plan of seed {seed} is too fragmented to place a route: its largest free area "
            f"has {cells} cells, fewer than {MIN_ROUTE_CELLS}; try another seed or fewer or "
            "smaller obstacles")
    about = {} if description is None else {"description": description}
    if route == "loop":
        return {**with_loop_preference(raw, footprint), **about}
    rng = np.random.default_rng(seed)
    pick = rng.choice(len(xs), size=4, replace=False)
    waypoints = [[int(xs[i]) + 1, int(ys[i]) + 1] for i in pick]
    return {**raw, **about, "preference": {"route": waypoints, "closed": False}}
