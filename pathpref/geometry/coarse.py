"""A coarser decomposition: obstacle edges extended only until they hit an obstacle or the wall.

The paper's arrangement extends every obstacle edge to an infinite line, so on a floor plan with
many rotated obstacles each line cuts far-away free space into thin polytopes (about 1000 for
1400 free cells on a 40 x 40 map with 32 rotated rectangles), each with its own unknown
preference. Here each edge ``p -> q`` of an obstacle is extended from both ends as a ray that
stops where it enters another obstacle or reaches the map border; the *active cuts* are the
edges with their extensions. Free space cut by the active cuts falls into regions that are still
convex (at each obstacle vertex, a reflex corner of free space, both incident edges are
extended, which splits the reflex angle into angles of at most 180 degrees), so a route's region
sequence still tells its homotopy class.

Construction on top of the arrangement: two polytopes joined by a graph edge are merged when the
crossing between them lies on no active cut (for a facet edge: the facet's midpoint; a facet of
the arrangement lies wholly on or off a cut, since every cut ends at an arrangement vertex; for
a move edge: every line crossing of some straight move realising it). The regions are the
classes of this merge; their graph joins two regions when an arrangement edge joins members of
both (line of the first such facet edge, or -1 when only moves join them). Moves are the
arrangement's (so the corner rule for diagonals is the arrangement's: stricter than needed inside
a region, which costs at most a detour of straight moves); a move records a crossing only when it
changes region. The map field ``"decomposition": "coarse"`` selects it.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .arrangement import Arrangement
from .graph import PolytopeGraph
from .grid import GridMotion
from .maps import MapSpec
from .polygon import convex_vertices_to_h

ON_LINE = 1e-7


def _ray_stop(start: np.ndarray, u: np.ndarray, spec: MapSpec, own: int) -> float:
    """Length along ``u`` from ``start`` to the first obstacle interior (other than ``own``) or
    the map border."""
    W, H = spec.width, spec.height
    t_border = np.inf
    for k in range(2):
        if u[k] > 1e-12:
            t_border = min(t_border, ((W, H)[k] - start[k]) / u[k])
        elif u[k] < -1e-12:
            t_border = min(t_border, -start[k] / u[k])
    best = max(t_border, 0.0)
    for j, o in enumerate(spec.obstacles):
        if j == own:
            continue
        au, gap = o.A @ u, o.b - o.A @ start  # inside: gap - t au > 0 for every row
        if np.any((np.abs(au) <= 1e-12) & (gap <= ON_LINE)):
            continue  # parallel to a row and outside (or on) it: never inside
        enter = np.where(au < -1e-12, gap / np.where(au < -1e-12, au, 1.0), -np.inf).max()
        leave = np.where(au > 1e-12, gap / np.where(au > 1e-12, au, 1.0), np.inf).min()
        if enter < leave - ON_LINE and leave > ON_LINE:
            best = min(best, max(enter, 0.0))
    return best


def active_intervals(spec: MapSpec, arr: Arrangement) -> list[list[tuple[float, float]]]:
    """Per arrangement line, the intervals (in ``x . d`` with ``d`` the line's direction) that
    carry an active cut."""
    n, c = arr.normals, arr.offsets
    d = np.stack([-n[:, 1], n[:, 0]], axis=1)
    out: list[list[tuple[float, float]]] = [[] for _ in range(len(n))]
    for k, o in enumerate(spec.obstacles):
        v = o.vertices
        for p, q in zip(v, np.roll(v, -1, axis=0), strict=True):
            on = (np.abs(n @ p - c) < ON_LINE) & (np.abs(n @ q - c) < ON_LINE)
            if not on.any():
                continue
            j = int(np.argmax(on))
            u = (q - p) / np.linalg.norm(q - p)
            fwd = _ray_stop(q, u, spec, k)
            back = _ray_stop(p, -u, spec, k)
            s = sorted([float((p - back * u) @ d[j]), float((q + fwd * u) @ d[j])])
            out[j].append((s[0], s[1]))
    return out


def _is_active(point: np.ndarray, j: int, arr: Arrangement,
               intervals: list[list[tuple[float, float]]]) -> bool:
    s = float(point @ np.array([-arr.normals[j, 1], arr.normals[j, 0]]))
    return any(lo - ON_LINE <= s <= hi + ON_LINE for lo, hi in intervals[j])


def coarse_labels(spec: MapSpec, arr: Arrangement, graph: PolytopeGraph,
                  motion: GridMotion) -> np.ndarray:
    """Region of each arrangement polytope (see module docstring), numbered by first cell."""
    intervals = active_intervals(spec, arr)
    parent = np.arange(arr.n_polytopes)

    def find(x: int) -> int:
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for e, ((u, w), h) in enumerate(zip(graph.edges, graph.edge_hyperplane, strict=True)):
        if h >= 0:
            poly = arr.polygons[u]
            on = np.abs(poly @ arr.normals[h] - arr.offsets[h]) < 1e-6
            if on.sum() < 2:
                continue
            mid = poly[on].mean(axis=0)
            merge = not _is_active(mid, int(h), arr, intervals)
        else:
            merge = False
            for i, a in zip(*np.nonzero(motion.crossed_edge == e), strict=True):
                p0 = arr.cells[i] - 0.5
                p1 = arr.cells[motion.next_cell[i, a]] - 0.5
                lines = np.flatnonzero(arr.signs[u] != arr.signs[w])
                f0 = p0 @ arr.normals[lines].T - arr.offsets[lines]
                f1 = p1 @ arr.normals[lines].T - arr.offsets[lines]
                ts = f0 / (f0 - f1)
                pts = p0 + ts[:, None] * (p1 - p0)
                if not any(_is_active(x, int(j), arr, intervals)
                           for x, j in zip(pts, lines, strict=True)):
                    merge = True
                    break
        if merge:
            parent[find(int(u))] = find(int(w))
    roots = np.array([find(v) for v in range(arr.n_polytopes)])
    first = np.full(arr.n_polytopes, arr.n_cells)
    np.minimum.at(first, roots[arr.cell_polytope], np.arange(arr.n_cells))
    keep = np.unique(roots)
    order = keep[np.argsort(first[keep])]
    rank = np.empty(arr.n_polytopes, dtype=int)
    rank[order] = np.arange(len(order))
    return rank[roots]


def coarsen(spec: MapSpec, arr: Arrangement, graph: PolytopeGraph, motion: GridMotion
            ) -> tuple[Arrangement, PolytopeGraph, GridMotion]:
    """The coarse decomposition's arrangement view, graph and motion (see module docstring).

    The returned :class:`Arrangement` keeps the lines and cells; ``cell_polytope`` gives the
    region; ``polygons`` are the convex hulls of the members' polygons, ``A``/``b`` their
    H-representations; ``signs`` and ``rows`` are empty (a region is no single sign vector)."""
    label = coarse_labels(spec, arr, graph, motion)
    R = int(label.max()) + 1 if len(label) else 0
    pair_line: dict[tuple[int, int], int] = {}
    for (u, w), h in zip(graph.edges, graph.edge_hyperplane, strict=True):
        a, b = int(label[u]), int(label[w])
        if a == b:
            continue
        key = (min(a, b), max(a, b))
        if key not in pair_line or (pair_line[key] < 0 <= h):
            pair_line[key] = int(h)
    edges = np.array(sorted(pair_line), dtype=int).reshape(-1, 2)
    hyper = np.array([pair_line[tuple(e)] for e in edges.tolist()], dtype=int)
    nbrs: list[list[int]] = [[] for _ in range(R)]
    nbr_e: list[list[int]] = [[] for _ in range(R)]
    for e, (u, w) in enumerate(edges.tolist()):
        nbrs[u].append(w)
        nbr_e[u].append(e)
        nbrs[w].append(u)
        nbr_e[w].append(e)
    keys = np.concatenate([edges[:, 0] * R + edges[:, 1], edges[:, 1] * R + edges[:, 0]])
    eid = np.arange(len(edges))
    order = np.argsort(keys, kind="stable")
    cgraph = PolytopeGraph(
        edges=edges, edge_hyperplane=hyper,
        neighbors=tuple(np.array(n, dtype=int) for n in nbrs),
        neighbor_edges=tuple(np.array(n, dtype=int) for n in nbr_e),
        pair_keys=keys[order].astype(np.int64), pair_edge=np.concatenate([eid, eid])[order],
    )
    polys, As, bs = [], [], []
    for r in range(R):
        pts = np.concatenate([arr.polygons[v] for v in np.flatnonzero(label == r)
                              if len(arr.polygons[v])])
        hull = _hull(pts)
        polys.append(hull)
        try:
            A, b, _ = convex_vertices_to_h(hull)
        except ValueError:  # a degenerate region (no area): no H-representation
            A, b = np.zeros((0, 2)), np.zeros(0)
        As.append(A)
        bs.append(b)
    carr = dataclasses.replace(
        arr, cell_polytope=label[arr.cell_polytope], signs=np.zeros((R, 0), dtype=bool),
        A=tuple(As), b=tuple(bs), rows=tuple(np.zeros(0, dtype=int) for _ in range(R)),
        polygons=tuple(polys))
    cp = carr.cell_polytope
    src = np.repeat(np.arange(arr.n_cells)[:, None], 8, axis=1)
    change = cp[src] != cp[motion.next_cell]
    crossed = -np.ones_like(motion.crossed_edge)
    crossed[change] = cgraph.edges_between(cp[src][change], cp[motion.next_cell][change])
    cmotion = dataclasses.replace(motion, crossed_edge=crossed)
    return carr, cgraph, cmotion


def _turn(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> float:
    """z of ``(b - a) x (c - a)``: positive for a left turn."""
    return float((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))


def _hull(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise convex hull (monotone chain); collinear points dropped."""
    pts = np.unique(np.round(points, 9), axis=0)
    if len(pts) < 3:
        return pts

    def half(ps):
        out: list[np.ndarray] = []
        for p in ps:
            while len(out) >= 2 and _turn(out[-2], out[-1], p) <= 1e-12:
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])
