"""The robot's footprint, and which straight moves it can sweep without touching an obstacle.

A robot whose footprint is a disc of radius ``r`` (map units, cells) that must keep a clearance
``c`` from every obstacle and from the map's walls can make the straight move from point ``p``
to point ``q`` exactly when the segment ``[p, q]`` keeps a distance of at least ``r + c`` (the
*reach*) from every obstacle polygon and from the four walls: the disc swept along the segment
is the segment's ``r``-neighbourhood (a capsule), and it misses an obstacle ``O`` iff
``dist([p, q], O) >= r`` (Minkowski sum: the capsule meets ``O`` iff the segment meets
``O ⊕ disc(r)``). The distance is computed exactly, per obstacle:

* ``dist([p, q], O) = 0`` when ``p`` lies in ``O`` (``A p <= b``);
* otherwise it is the least distance between the segment and an edge ``[e0, e1]`` of ``O``
  (a segment entering ``O`` crosses its boundary). Two segments that cross properly (the
  orientations of each one's ends about the other differ in sign) are at distance 0; else the
  distance is the least of the four point-to-segment distances of their ends,
  ``|x - a - clip(((x - a) . (b - a)) / |b - a|^2, 0, 1) (b - a)|``.

For the walls of the ``W x H`` map the capsule stays inside iff both ends do (the box is
convex): ``r_c <= x <= W - r_c`` and the same in ``y``.

:data:`DEFAULT_FOOTPRINT` is the mobile base of ``mjcf/navigate.xml`` at the default scale of
0.5 m per cell: radius 0.15 m (0.3 cells) and a clearance of 0.05 m (0.1 cells), reach 0.4
cells. On maps whose obstacles are cell rectangles (the paper's) every move the corner rule of
:mod:`.grid` allows keeps 0.5 cells (straight moves) or ``sqrt(2)/2`` (diagonal moves past a
corner) from every obstacle, more than the reach, so the footprint removes none of their moves.
A reach of 0.5 or more would.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numba as nb
import numpy as np

if TYPE_CHECKING:
    from .maps import MapSpec

#: segments per block of :meth:`Clearance.distance` (bounds its temporaries)
CHUNK = 65536


@dataclass(frozen=True)
class Footprint:
    """A disc robot: ``radius`` and the ``clearance`` it keeps, both in map units (cells)."""

    radius: float
    clearance: float

    @property
    def reach(self) -> float:
        """``radius + clearance``: the least distance the robot's centre keeps from obstacles."""
        return self.radius + self.clearance

    def describe(self, cell_size_m: float | None = None) -> str:
        """``radius 0.3 + clearance 0.1 cells`` (and metres when ``cell_size_m`` is given)."""
        text = f"radius {self.radius:g} + clearance {self.clearance:g} cells"
        if cell_size_m:
            text += (f" ({self.radius * cell_size_m:g} m + {self.clearance * cell_size_m:g} m "
                     f"at {cell_size_m:g} m per cell)")
        return text


#: the mobile base's footprint (module docstring): 0.15 m radius and 0.05 m clearance at
#: 0.5 m per cell
DEFAULT_FOOTPRINT = Footprint(radius=0.3, clearance=0.1)
#: a point robot: no move is removed (the grid's corner rule alone)
POINT_ROBOT = Footprint(radius=0.0, clearance=0.0)


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


def point_segment_distance(x: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance from points ``x`` to segments ``[a, b]`` (broadcast over leading axes)."""
    d = b - a
    dd = np.einsum("...i,...i->...", d, d)
    t = np.einsum("...i,...i->...", x - a, d) / np.where(dd > 0, dd, 1.0)
    t = np.clip(np.where(dd > 0, t, 0.0), 0.0, 1.0)
    return np.linalg.norm(x - (a + t[..., None] * d), axis=-1)


def segment_segment_distance(p: np.ndarray, q: np.ndarray, a: np.ndarray,
                             b: np.ndarray) -> np.ndarray:
    """Distance between segments ``[p, q]`` and ``[a, b]`` (broadcast; module docstring)."""
    o1, o2 = _cross(q - p, a - p), _cross(q - p, b - p)
    o3, o4 = _cross(b - a, p - a), _cross(b - a, q - a)
    proper = (o1 * o2 < 0) & (o3 * o4 < 0)
    ends = np.minimum(np.minimum(point_segment_distance(p, a, b), point_segment_distance(q, a, b)),
                      np.minimum(point_segment_distance(a, p, q), point_segment_distance(b, p, q)))
    return np.where(proper, 0.0, ends)


class Clearance:
    """Distances from segments (and points) to a map's obstacles and walls (module docstring).

    ``Clearance(spec).distance(P, Q)`` is the least distance from each segment ``[P_i, Q_i]``
    to any obstacle polygon, and ``wall_distance`` the least distance of either end to the
    map's box; ``clear(P, Q, reach)`` both at least ``reach``."""

    def __init__(self, spec: MapSpec):
        self.width, self.height = spec.width, spec.height
        self.obstacles = spec.obstacles
        # every obstacle's edges and rows at once, for the point check of :meth:`clear_at`
        vs = [o.vertices for o in spec.obstacles]
        self._e0 = np.concatenate(vs) if vs else np.zeros((0, 2))
        self._e1 = np.concatenate([np.roll(v, -1, axis=0) for v in vs]) if vs else self._e0
        self._A = np.concatenate([o.A for o in spec.obstacles]) if vs else np.zeros((0, 2))
        self._b = np.concatenate([o.b for o in spec.obstacles]) if vs else np.zeros(0)
        self._row_starts = np.cumsum([0] + [len(o.b) for o in spec.obstacles[:-1]])
        self._edge_starts = np.cumsum([0] + [len(v) for v in vs[:-1]]) if vs else \
            np.zeros(0, dtype=np.int64)
        if not vs:
            self._row_starts = np.zeros(0, dtype=np.int64)
        #: the map as the compiled point checks take it (:func:`near_into`'s ``clr``)
        self.arrays = (float(self.width), float(self.height), self._A, self._b,
                       self._row_starts.astype(np.int64), self._e0, self._e1,
                       self._edge_starts.astype(np.int64))
        #: :func:`near_into`'s rows, one per wall and obstacle
        self.near_rows = np.empty((4 + len(self._edge_starts), 3))

    def distance(self, P: np.ndarray, Q: np.ndarray, within: float = np.inf) -> np.ndarray:
        """``(N,)`` least distance from segment ``[P_i, Q_i]`` to any obstacle (``inf``
        without obstacles). Obstacles whose bounding box lies farther than ``within`` from a
        segment's bounding box are skipped for it (their distance exceeds ``within``)."""
        P, Q = np.asarray(P, float).reshape(-1, 2), np.asarray(Q, float).reshape(-1, 2)
        out = np.full(len(P), np.inf)
        for s in range(0, len(P), CHUNK):
            p, q, o = P[s:s + CHUNK], Q[s:s + CHUNK], out[s:s + CHUNK]
            lo, hi = np.minimum(p, q), np.maximum(p, q)
            for obs in self.obstacles:
                v = obs.vertices
                vlo, vhi = v.min(axis=0), v.max(axis=0)
                near = np.all((lo <= vhi + within) & (hi >= vlo - within), axis=1)
                idx = np.flatnonzero(near)
                if not len(idx):
                    continue
                pi, qi = p[idx], q[idx]
                a, b = v[None, :, :], np.roll(v, -1, axis=0)[None, :, :]
                d = segment_segment_distance(pi[:, None, :], qi[:, None, :], a, b).min(axis=1)
                d = np.where(obs.contains(pi, eps=0.0), 0.0, d)
                o[idx] = np.minimum(o[idx], d)
        return out

    def wall_distance(self, P: np.ndarray, Q: np.ndarray) -> np.ndarray:
        """``(N,)`` least distance from either end of each segment to the map's four walls
        (negative: outside the map)."""
        P, Q = np.asarray(P, float).reshape(-1, 2), np.asarray(Q, float).reshape(-1, 2)
        ends = np.stack([P, Q], axis=1)
        return np.minimum(ends.min(axis=(1, 2)),
                          np.minimum(self.width - ends[..., 0], self.height - ends[..., 1]
                                     ).min(axis=1))

    def clear(self, P: np.ndarray, Q: np.ndarray, reach: float) -> np.ndarray:
        """``(N,)`` whether a disc of radius ``reach`` swept from ``P_i`` to ``Q_i`` touches no
        obstacle and stays inside the map (distance ``>= reach``)."""
        return (self.wall_distance(P, Q) >= reach) & (self.distance(P, Q, within=reach) >= reach)

    def clear_at(self, xy: np.ndarray, reach: float) -> bool:
        """Whether a disc of radius ``reach`` centred at ``xy`` (map units) touches no
        obstacle and lies inside the map: the point case of :meth:`clear`, over all
        obstacles' edges (a physics step's check; compiled, :func:`_clear_at`)."""
        p = np.asarray(xy, float)
        return bool(_clear_at(float(p[0]), float(p[1]), float(self.width), float(self.height),
                              float(reach), self._A, self._b, self._row_starts, self._e0,
                              self._e1))

    def near(self, xy: np.ndarray, within: float) -> list[tuple[float, np.ndarray]]:
        """The obstacles and walls within ``within`` of the point ``xy`` (map units): per
        obstacle (and wall), its distance ``d`` and the unit vector from its nearest point to
        ``xy`` (the direction that leads away from it). A point inside an obstacle is at
        distance 0 from it, with the direction of its nearest edge's outward normal (compiled,
        :func:`_near`)."""
        p = np.asarray(xy, float)
        out = self.near_rows
        n = near_into(float(p[0]), float(p[1]), float(within), self.arrays, out)
        return [(float(out[i, 0]), out[i, 1:3].copy()) for i in range(n)]


@nb.njit(cache=True)
def _inside(x, y, A, b, start, end):
    """Whether ``(x, y)`` satisfies rows ``start..end-1`` of ``A p <= b`` (one obstacle)."""
    for r in range(start, end):
        if A[r, 0] * x + A[r, 1] * y - b[r] > 0.0:
            return False
    return True


@nb.njit(cache=True)
def _to_edge(x, y, e0, e1, j):
    """``(distance, closest x, closest y)`` from ``(x, y)`` to edge ``j``: ``t = clip((p -
    a) . e / e . e, 0, 1)``, the closest point ``a + t e``."""
    ex, ey = e1[j, 0] - e0[j, 0], e1[j, 1] - e0[j, 1]
    t = ((x - e0[j, 0]) * ex + (y - e0[j, 1]) * ey) / (ex * ex + ey * ey)
    t = min(max(t, 0.0), 1.0)
    cx, cy = e0[j, 0] + t * ex, e0[j, 1] + t * ey
    return math.sqrt((x - cx) * (x - cx) + (y - cy) * (y - cy)), cx, cy


@nb.njit(cache=True)
def _clear_at(x, y, width, height, reach, A, b, row_starts, e0, e1):
    """:meth:`Clearance.clear_at` on plain arrays: inside the map by ``reach``, inside no
    obstacle (every row of ``A p <= b``), and at least ``reach`` from every edge."""
    if min(min(x, y), min(width - x, height - y)) < reach:
        return False
    k_n = len(row_starts)
    for k in range(k_n):
        end = row_starts[k + 1] if k + 1 < k_n else len(b)
        if _inside(x, y, A, b, row_starts[k], end):
            return False
    for j in range(len(e0)):
        if _to_edge(x, y, e0, e1, j)[0] < reach:
            return False
    return True


@nb.njit(cache=True)
def near_into(x, y, within, clr, out):
    """:meth:`Clearance.near` on plain arrays (``clr``: :attr:`Clearance.arrays`, ``(width,
    height, A, b, row_starts, e0, e1, edge_starts)``), written into ``out`` (at least ``4 +``
    obstacles rows; allocates nothing): the count ``n``, row ``i < n`` = ``(d, nx, ny)``;
    walls first (x = 0, y = 0, x = width, y = height), then per obstacle with an edge within
    ``within`` its nearest edge (the first of equals)."""
    width, height, A, b, row_starts, e0, e1, edge_starts = clr
    k_n = len(edge_starts)
    n = 0
    walls = ((x, 1.0, 0.0), (y, 0.0, 1.0), (width - x, -1.0, 0.0), (height - y, 0.0, -1.0))
    for d, nx, ny in walls:
        if d < within:
            out[n, 0], out[n, 1], out[n, 2] = max(d, 0.0), nx, ny
            n += 1
    for k in range(k_n):
        end = edge_starts[k + 1] if k + 1 < k_n else len(e0)
        best, bj, bx, by = np.inf, -1, 0.0, 0.0
        for j in range(edge_starts[k], end):
            d, cx, cy = _to_edge(x, y, e0, e1, j)
            if d < best:
                best, bj, bx, by = d, j, cx, cy
        if bj < 0 or not best < within:
            continue
        r_end = row_starts[k + 1] if k + 1 < k_n else len(b)
        if _inside(x, y, A, b, row_starts[k], r_end):
            ex, ey = e1[bj, 0] - e0[bj, 0], e1[bj, 1] - e0[bj, 1]
            length = math.sqrt(ex * ex + ey * ey)
            out[n, 0], out[n, 1], out[n, 2] = 0.0, ey / length, -ex / length  # CCW: outward
            n += 1
        elif best > 0:
            out[n, 0], out[n, 1], out[n, 2] = best, (x - bx) / best, (y - by) / best
            n += 1
    return n
