"""Convex polygons in the plane: H-representation, clipping and non-redundant rows.

An H-polytope is ``{x in R^2 : A x <= b}`` with one row per half-plane. The functions here
convert a vertex list into that form (checking convexity), clip the map box by a set of
half-planes (Sutherland-Hodgman, exact for convex inputs, compiled), and find the *essential*
rows of a polytope: the rows on which a facet of positive length lies. A row that is not
essential can be dropped without changing the set.

Two routes to the essential rows are offered: :func:`essential_rows` clips the box and reads the
facets off the polygon (O(n) per row, used everywhere), and :func:`essential_rows_lp` is the
SPEC's reference method, one HiGHS linear programme per row (row i is essential iff maximising
``a_i . x`` over the other rows and the box exceeds ``b_i``). The test-suite checks that both agree.
"""

from __future__ import annotations

import numba as nb
import numpy as np
from scipy.optimize import linprog

EPS = 1e-9


def box_polygon(width: float, height: float) -> np.ndarray:
    """Counter-clockwise vertices of the map box ``[0, width] x [0, height]``."""
    return np.array([[0.0, 0.0], [width, 0.0], [width, height], [0.0, height]])


def box_rows(width: float, height: float) -> tuple[np.ndarray, np.ndarray]:
    """The map box as ``A x <= b`` (rows: x <= W, -x <= 0, y <= H, -y <= 0)."""
    A = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])
    b = np.array([width, 0.0, height, 0.0])
    return A, b


def polygon_area(vertices: np.ndarray) -> float:
    """Signed area (shoelace formula); positive for counter-clockwise order."""
    x, y = vertices[:, 0], vertices[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def convex_vertices_to_h(vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Turn a convex polygon's vertex list into ``(A, b, ccw_vertices)``.

    Accepts clockwise or counter-clockwise order; drops repeated and collinear vertices.
    Rows are normalised (``|a_i| = 1``), one per edge, outward normals.

    Raises ``ValueError`` with a short reason when the polygon has fewer than three distinct
    vertices, zero area, turns both ways (not convex) or winds more than once
    (self-intersecting).
    """
    v = np.asarray(vertices, dtype=float)
    if v.ndim != 2 or v.shape[1] != 2:
        raise ValueError("vertices must be a list of [x, y] pairs")
    if len(v) < 3:
        raise ValueError(f"has {len(v)} vertices; a polygon needs at least 3")
    if not np.all(np.isfinite(v)):
        raise ValueError("has a NaN or infinite coordinate")
    # drop consecutive duplicates (including last == first)
    keep = np.linalg.norm(v - np.roll(v, 1, axis=0), axis=1) > EPS
    v = v[keep]
    if len(v) < 3:
        raise ValueError("has fewer than 3 distinct vertices")
    area = polygon_area(v)
    if np.linalg.svd(v - v.mean(axis=0), compute_uv=False)[1] <= EPS:
        raise ValueError("has zero area (all vertices on one line)")
    if abs(area) <= EPS:
        raise ValueError("is self-intersecting (its edges cross; signed area is zero)")
    if area < 0:
        v = v[::-1]
    # drop collinear vertices, then check every turn is a left turn
    def turns(p: np.ndarray) -> np.ndarray:
        e1 = p - np.roll(p, 1, axis=0)
        e2 = np.roll(p, -1, axis=0) - p
        return e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]

    t = turns(v)
    scale = max(1.0, float(np.abs(v).max()))
    v = v[np.abs(t) > EPS * scale * scale]
    t = turns(v)
    if np.any(t < 0):
        k = int(np.argmax(t < 0))
        raise ValueError(f"is not convex (vertex {k + 1} turns the other way)")
    # total turning angle must be exactly 2*pi (a pentagram turns 4*pi)
    e = np.roll(v, -1, axis=0) - v
    ang = np.arctan2(e[:, 1], e[:, 0])
    dturn = np.mod(np.roll(ang, -1) - ang, 2 * np.pi)
    if abs(dturn.sum() - 2 * np.pi) > 1e-6:
        raise ValueError("is self-intersecting (its boundary winds more than once)")
    normals = np.stack([e[:, 1], -e[:, 0]], axis=1)
    norms = np.linalg.norm(normals, axis=1)
    A = normals / norms[:, None]
    b = np.einsum("ij,ij->i", A, v)
    return A, b, v


@nb.njit(cache=True)
def _clip_box(A, b, start):
    """Sutherland-Hodgman: clip the convex polygon ``start`` by every row of ``A x <= b``.

    Vertices within ``EPS`` of a line count as inside; near-duplicate consecutive vertices
    produced by clipping through a vertex are merged.
    """
    cap = len(start) + len(A) + 2
    poly = np.empty((cap, 2))
    nxt = np.empty((cap, 2))
    n = len(start)
    poly[:n] = start
    d = np.empty(cap)
    for r in range(len(A)):
        if n == 0:
            break
        a0, a1, br = A[r, 0], A[r, 1], b[r]
        n_in = 0
        for i in range(n):
            d[i] = poly[i, 0] * a0 + poly[i, 1] * a1 - br
            if d[i] <= EPS:
                n_in += 1
        if n_in == n:
            continue
        if n_in == 0:
            n = 0
            break
        m = 0
        for i in range(n):
            j = (i + 1) % n
            ins_i, ins_j = d[i] <= EPS, d[j] <= EPS
            if ins_i:
                nxt[m] = poly[i]
                m += 1
            if ins_i != ins_j:
                t = d[i] / (d[i] - d[j])
                nxt[m, 0] = poly[i, 0] + t * (poly[j, 0] - poly[i, 0])
                nxt[m, 1] = poly[i, 1] + t * (poly[j, 1] - poly[i, 1])
                m += 1
        # merge near-duplicate consecutive points (clipping through a vertex)
        n = 0
        for i in range(m):
            p = (i - 1) % m
            dx, dy = nxt[i, 0] - nxt[p, 0], nxt[i, 1] - nxt[p, 1]
            if m == 1 or dx * dx + dy * dy > 1e-24:
                poly[n] = nxt[i]
                n += 1
    return poly[:n].copy()


def h_polygon(A: np.ndarray, b: np.ndarray, width: float, height: float) -> np.ndarray:
    """Vertices (CCW) of ``{A x <= b}`` intersected with the map box; empty if degenerate.

    Compiled Sutherland-Hodgman over all rows (``O(rows x vertices)``, microseconds for the
    hundreds of lines of a large floor plan).
    """
    A = np.ascontiguousarray(A, dtype=float).reshape(-1, 2)
    b = np.ascontiguousarray(b, dtype=float).reshape(-1)
    return _clip_box(A, b, box_polygon(width, height))


def essential_rows(
    A: np.ndarray, b: np.ndarray, width: float, height: float, min_length: float = 1e-7
) -> np.ndarray:
    """Indices of the rows of ``A x <= b`` that carry a facet of positive length in the box.

    A row is essential iff some edge of the clipped polygon lies on its line with length
    greater than ``min_length`` and that edge is not part of the map border (the border bounds
    every polytope but is not a face: a row that coincides with it is redundant given the box,
    exactly as the LP reference judges it). Requires unit-norm rows.
    """
    return facet_rows(h_polygon(A, b, width, height), A, b, width, height, min_length)


def facet_rows(
    poly: np.ndarray, A: np.ndarray, b: np.ndarray, width: float, height: float,
    min_length: float = 1e-7,
) -> np.ndarray:
    """The rows of ``A x <= b`` on which an edge of ``poly`` (its clipped polygon) lies with
    length above ``min_length``, map-border edges excluded (see :func:`essential_rows`)."""
    if len(poly) < 3:
        return np.zeros(0, dtype=int)
    p0 = poly
    p1 = np.roll(poly, -1, axis=0)
    lengths = np.linalg.norm(p1 - p0, axis=1)
    on_border = (
        ((p0[:, 0] < 1e-7) & (p1[:, 0] < 1e-7))
        | ((p0[:, 0] > width - 1e-7) & (p1[:, 0] > width - 1e-7))
        | ((p0[:, 1] < 1e-7) & (p1[:, 1] < 1e-7))
        | ((p0[:, 1] > height - 1e-7) & (p1[:, 1] > height - 1e-7))
    )
    lengths = np.where(on_border, 0.0, lengths)
    # residual of both edge endpoints on each row: |a.p - b| small for both => edge lies on row
    r0 = np.abs(p0 @ A.T - b)  # (edges, rows)
    r1 = np.abs(p1 @ A.T - b)
    on = (r0 < 1e-7) & (r1 < 1e-7) & (lengths[:, None] > min_length)
    return np.flatnonzero(on.any(axis=0))


def essential_rows_lp(A: np.ndarray, b: np.ndarray, width: float, height: float) -> np.ndarray:
    """Reference method (SPEC 2): one HiGHS LP per row.

    Row i is essential when ``max a_i . x`` subject to the other rows and the map box exceeds
    ``b_i``. A row that coincides with the map border is therefore redundant (the box
    already bounds the set there).
    """
    Abox, bbox = box_rows(width, height)
    keep = []
    for i in range(len(A)):
        others = np.delete(np.arange(len(A)), i)
        A_ub = np.vstack([A[others], Abox])
        b_ub = np.concatenate([b[others], bbox])
        # relax row i slightly so the LP is bounded by something near b_i
        A_ub = np.vstack([A_ub, A[i]])
        b_ub = np.concatenate([b_ub, [b[i] + 1.0]])
        res = linprog(-A[i], A_ub=A_ub, b_ub=b_ub, bounds=[(None, None)] * 2, method="highs")
        if res.status == 0 and -res.fun > b[i] + 1e-7:
            keep.append(i)
    return np.asarray(keep, dtype=int)
