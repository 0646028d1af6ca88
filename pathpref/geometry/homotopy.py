"""Whether two paths with the same ends go the same way round every obstacle (winding numbers).

A path is the polyline through the centres ``(x - 1/2, y - 1/2)`` of its cells. For two paths
``a`` and ``b`` from the same start to the same end, the closed loop ``L = a + reverse(b)`` is
drawn, and for every obstacle ``O_j`` its representative point ``c_j`` is the mean of its
vertices (inside ``O_j``, which is convex). The winding number of ``L`` around ``c``::

    w(L, c) = sum over the edges (p, q) of L of
                +1  if p_y <= c_y < q_y and c lies strictly left of p -> q   (an upward crossing)
                -1  if q_y <= c_y < p_y and c lies strictly right of p -> q  (a downward one)
                 0  otherwise

(the signed count of the loop's crossings of the ray from ``c`` toward ``+x``, with each edge
taken half-open in ``y``, so a vertex on the ray counts once; Sunday's rule). ``a`` and ``b``
are *in the same class* when ``w(L, c_j) = 0`` for every obstacle ``j``:

* ``a`` passes an obstacle on the other side from ``b``: ``L`` encircles it once, ``w = +-1``;
* ``a`` loops once more round an obstacle than ``b``: ``w = +-1`` as well;
* obstacles that overlap form one blocked region, and a loop in free space has the same winding
  number round all of their points; an obstacle touching the map's border cannot be encircled
  (``w = 0`` always), nor can a point outside every loop.

This is equality in the first homology of the plane minus the points ``c_j``: it tells paths
apart by the number of times (with sign) they go round each obstacle, which is the homotopy
class for paths that go round obstacles one at a time; two paths that differ by a commutator
loop (round ``A``, round ``B``, back round ``A``, back round ``B``) have equal winding numbers
and are not told apart. A grid path is a cell-centre polyline: a straight move may cut the
corner of a thin obstacle whose centre it does not pass, and only the points ``c_j`` count.
A point ``c_j`` lying exactly on the loop is counted by the same half-open rule, so the test is
deterministic. Cell centres are half-integers, so the loop's own coordinates and their
differences are exact in floating point; only the side test's products with ``c_j`` round.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .following import human_route
from .maps import MapSpec
from .world import World


def obstacle_points(spec: MapSpec) -> np.ndarray:
    """``(m, 2)`` the representative point of each obstacle: the mean of its vertices."""
    if not spec.obstacles:
        return np.zeros((0, 2))
    return np.array([o.vertices.mean(axis=0) for o in spec.obstacles], dtype=float)


def crossings(p: np.ndarray, q: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``(k, m)`` signed crossings of the segments ``p[i] -> q[i]`` (``(k, 2)`` each) with the
    ray from each of ``points`` (``(m, 2)``) toward ``+x``: +1 for an upward crossing, -1 for a
    downward one, 0 otherwise (the rule of the module docstring, each segment half-open in
    ``y``). A closed loop's winding number is the sum over its edges; reversing a segment
    negates its crossing, so the crossings of a path are additive along it."""
    p = np.asarray(p, dtype=float).reshape(-1, 2)
    q = np.asarray(q, dtype=float).reshape(-1, 2)
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    px, py = p[:, 0][:, None], p[:, 1][:, None]
    qx, qy = q[:, 0][:, None], q[:, 1][:, None]
    cx, cy = points[:, 0][None, :], points[:, 1][None, :]
    side = (qx - px) * (cy - py) - (cx - px) * (qy - py)  # > 0: c left of p -> q
    up = (py <= cy) & (cy < qy) & (side > 0)
    down = (qy <= cy) & (cy < py) & (side < 0)
    return up.astype(np.int64) - down.astype(np.int64)


def winding_numbers(loop: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``(m,)`` integer winding number of the closed polyline ``loop`` (``(k, 2)``, the last
    vertex joined back to the first) round each of ``points`` (``(m, 2)``), by the rule of the
    module docstring: the sum of its edges' :func:`crossings`."""
    loop = np.asarray(loop, dtype=float).reshape(-1, 2)
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    if len(loop) < 2 or len(points) == 0:
        return np.zeros(len(points), dtype=np.int64)
    return crossings(loop, np.roll(loop, -1, axis=0), points).sum(axis=0).astype(np.int64)


def cell_centres(cells: np.ndarray) -> np.ndarray:
    """Centres ``(x - 1/2, y - 1/2)`` of 1-based cells ``(k, 2)``."""
    return np.asarray(cells, dtype=float).reshape(-1, 2) - 0.5


def same_class(spec: MapSpec, path_a: Sequence, path_b: Sequence) -> bool:
    """Whether the cell paths ``path_a`` and ``path_b`` (1-based ``(x, y)`` each, same first
    and same last cell) go the same way round every obstacle of ``spec``: the loop
    ``a + reverse(b)`` winds zero times round every obstacle (module docstring). Paths with
    different ends are in no common class (False)."""
    a, b = np.asarray(path_a, dtype=float).reshape(-1, 2), \
        np.asarray(path_b, dtype=float).reshape(-1, 2)
    if len(a) == 0 or len(b) == 0 or (a[0] != b[0]).any() or (a[-1] != b[-1]).any():
        return False
    loop = cell_centres(np.concatenate([a, b[::-1]]))
    return not winding_numbers(loop, obstacle_points(spec)).any()


def route_homotopic(world: World, pref: np.ndarray, start: int, goal: int,
                    path: Sequence) -> bool:
    """Whether the cell path ``path`` (1-based ``(x, y)``, from ``start``'s cell to ``goal``'s)
    is in the class of the human's route from ``start`` to ``goal`` under ``pref``
    (:func:`~pathpref.geometry.following.human_route`); False when there is no route."""
    route = human_route(world, pref, start, goal)
    return bool(route) and same_class(world.spec, path, world.cells[route])
