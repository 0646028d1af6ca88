"""Convex polygons in the plane: H-representation, clipping and non-redundant rows.

An H-polytope is ``{x in R^2 : A x <= b}`` with one row per half-plane. The functions here
convert a vertex list into that form (checking convexity), clip the map box by a set of
half-planes (Sutherland-Hodgman, exact for convex inputs), and find the *essential* rows of a
polytope: the rows on which a facet of positive length lies. A row that is not essential can be
dropped without changing the set.

Two routes to the essential rows are offered: :func:`essential_rows` clips the box and reads the
facets off the polygon (O(n) per row, used everywhere), and :func:`essential_rows_lp` is the
SPEC's reference method, one HiGHS linear programme per row (row i is essential iff maximising
``a_i . x`` over the other rows and the box exceeds ``b_i``). The test-suite checks that both agree.
"""

from __future__ import annotations

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


def clip_polygon(poly: np.ndarray, a: np.ndarray, b: float) -> np.ndarray:
    """Clip a convex polygon (CCW vertices) by the half-plane ``a . x <= b``."""
    if len(poly) == 0:
        return poly
    d = poly @ a - b
    inside = d <= EPS
    if inside.all():
        return poly
    if not inside.any():
        return poly[:0]
    out = []
    n = len(poly)
    for i in range(n):
        j = (i + 1) % n
        pi, pj, di, dj = poly[i], poly[j], d[i], d[j]
        if inside[i]:
            out.append(pi)
        if inside[i] != inside[j]:
            t = di / (di - dj)
            out.append(pi + t * (pj - pi))
    res = np.array(out)
    # remove near-duplicate consecutive points produced by clipping through a vertex
    if len(res) > 1:
        keep = np.linalg.norm(res - np.roll(res, 1, axis=0), axis=1) > 1e-12
        res = res[keep]
    return res


def h_polygon(A: np.ndarray, b: np.ndarray, width: float, height: float) -> np.ndarray:
    """Vertices (CCW) of ``{A x <= b}`` intersected with the map box; empty if degenerate."""
    poly = box_polygon(width, height)
    for a_i, b_i in zip(A, b, strict=True):
        poly = clip_polygon(poly, a_i, b_i)
        if len(poly) == 0:
            break
    return poly


def essential_rows(
    A: np.ndarray, b: np.ndarray, width: float, height: float, min_length: float = 1e-7
) -> np.ndarray:
    """Indices of the rows of ``A x <= b`` that carry a facet of positive length in the box.

    A row is essential iff some edge of the clipped polygon lies on its line with length
    greater than ``min_length`` and that edge is not part of the map border (the border bounds
    every polytope but is not a face: a row that coincides with it is redundant given the box,
    exactly as the LP reference judges it). Requires unit-norm rows.
    """
    poly = h_polygon(A, b, width, height)
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
