"""The hyperplane arrangement of free space (paper Sec. IV-A, SPEC 2).

Every obstacle row ``a . x <= b`` contributes the line ``a . x = b``; repeated lines (a row
equal to an earlier row or to its negation) are kept once. The lines cut the map box into
convex cells; a cell is identified by its *sign vector* ``alpha_j = [a_j . x > b_j]``. A
*free polytope* is a cell that lies in no obstacle and holds at least one free grid cell.

Each free grid cell's centre gives the sign vector of the polytope it lies in, so grouping the
free cells by sign vector yields exactly the free polytopes that hold a cell (also in free
components that a breadth-first search from one cell would not reach). Each polytope is then
reduced to its essential rows (:func:`pathpref.geometry.polygon.essential_rows`: the rows
carrying a facet of its polygon).

Polytope ids are 0-based, ordered by their first free cell in ``(x, y)`` lexicographic order.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import MapError
from .maps import MapSpec, cell_pair, free_cell_mask
from .polygon import facet_rows, h_polygon

SIDE_EPS = 1e-9
#: free cells per block of the sign computation in :func:`build_arrangement`
SIGN_CHUNK = 4096
#: polytope pairs per block of :meth:`Arrangement.lines_between`
PAIR_CHUNK = 4096
#: free cells x lines above which a map is refused before any allocation (the sign-vector table
#: has one byte per pair; temporaries take a few times that)
MAX_CELL_LINES = 400_000_000
#: most free polytopes an arrangement may have (the bound of :func:`arrangement_size`) before
#: building is refused unless forced: 100 000 is about half a minute (a 500 x 500 map with 100
#: rotated rectangles, 400 lines, bound 80 201, builds in about 20 s)
MAX_POLYTOPES = 100_000


def arrangement_size(spec: MapSpec) -> tuple[int, int, int]:
    """A cheap estimate before building: ``(lines, free_cells, polytope_bound)``.

    ``lines`` counts the obstacle lines with equal (rounded) lines once; ``polytope_bound`` is
    ``min(free cells, 1 + m + m (m - 1) / 2)``, the most faces ``m`` lines cut a plane into,
    and no more than the free cells (every free polytope holds one).
    """
    rows = [np.column_stack([o.A, o.b]) for o in spec.obstacles]
    if rows:
        ab = np.concatenate(rows)
        flip = (ab[:, 0] < -1e-12) | ((np.abs(ab[:, 0]) <= 1e-12) & (ab[:, 1] < 0))
        ab[flip] *= -1
        m = len(np.unique(np.round(ab, 6) + 0.0, axis=0))
    else:
        m = 0
    n = int(free_cell_mask(spec).sum())
    return m, n, min(n, 1 + m + m * (m - 1) // 2)


def check_arrangement_size(spec: MapSpec, force: bool = False) -> tuple[int, int, int]:
    """:func:`arrangement_size`, and a MapError when the polytope bound exceeds
    :data:`MAX_POLYTOPES` (unless ``force``): refused before any long build."""
    m, n, bound = arrangement_size(spec)
    if bound > MAX_POLYTOPES and not force:
        raise MapError(
            f"map '{spec.name}' may have up to {bound:,} polytopes ({m} distinct obstacle "
            f"lines, {n:,} free cells), above the limit {MAX_POLYTOPES:,} (building could take "
            "many minutes); use fewer or axis-aligned obstacles, or pass --force (Python: "
            "force=True) to build it anyway")
    return m, n, bound


def unique_hyperplanes(spec: MapSpec) -> tuple[np.ndarray, np.ndarray]:
    """All obstacle lines ``n . x = c`` (unit normals), each once, in first-seen order.

    A line is canonically oriented (first non-zero normal component positive) so that a row and
    its negation map to the same line.
    """
    rows = [(np.asarray(a, dtype=float), float(b)) for o in spec.obstacles
            for a, b in zip(o.A, o.b, strict=True)]
    normals = np.zeros((len(rows), 2))
    offsets = np.zeros(len(rows))
    m = 0
    for a, b in rows:
        if a[0] < -1e-12 or (abs(a[0]) <= 1e-12 and a[1] < 0):
            a, b = -a, -b
        # the same test as np.allclose(a, n, atol=1e-9) and |b - c| <= 1e-9, against all kept
        close = np.abs(a - normals[:m]) <= 1e-9 + 1e-5 * np.abs(normals[:m])
        if not (close.all(axis=1) & (np.abs(b - offsets[:m]) <= 1e-9)).any():
            normals[m], offsets[m] = a, b
            m += 1
    return normals[:m].copy(), offsets[:m].copy()


@dataclass(frozen=True)
class Arrangement:
    """Free polytopes of a map and the cell -> polytope look-up.

    Attributes:
        width, height: map size in cells.
        normals, offsets: the arrangement's lines ``normals[j] . x = offsets[j]``.
        cells: ``(n, 2)`` 1-based free cells, ordered by x then y; row i is cell index i.
        cell_index: ``(W, H)`` array, ``cell_index[x-1, y-1]`` = cell index or -1.
        cell_polytope: ``(n,)`` polytope id of each free cell.
        signs: ``(P, m)`` bool sign vector of each polytope.
        A, b: per polytope, its essential rows as ``A x <= b``.
        rows: per polytope, the hyperplane index of each essential row.
        polygons: per polytope, its vertices (CCW) clipped to the map box.
    """

    width: int
    height: int
    normals: np.ndarray
    offsets: np.ndarray
    cells: np.ndarray
    cell_index: np.ndarray
    cell_polytope: np.ndarray
    signs: np.ndarray
    A: tuple[np.ndarray, ...]
    b: tuple[np.ndarray, ...]
    rows: tuple[np.ndarray, ...]
    polygons: tuple[np.ndarray, ...]

    @property
    def n_polytopes(self) -> int:
        """Number of free polytopes."""
        return len(self.signs)

    @property
    def n_cells(self) -> int:
        """Number of free cells."""
        return len(self.cells)

    def free_cell(self, value: Any, where: str = "cell") -> int:
        """Index of the free cell ``value = (x, y)`` (1-based); MapError naming ``where`` when
        it is not a pair of whole numbers, lies off the map or on an obstacle."""
        x, y = cell_pair(value, where)
        if not (1 <= x <= self.width and 1 <= y <= self.height):
            raise MapError(f"{where} ({x}, {y}) is outside the {self.width} x {self.height} map")
        i = int(self.cell_index[x - 1, y - 1])
        if i < 0:
            raise MapError(f"{where} ({x}, {y}) lies on an obstacle; name a free cell")
        return i

    def polytope_cells(self, v: int) -> np.ndarray:
        """Cell indices of polytope ``v``."""
        return np.flatnonzero(self.cell_polytope == v)

    def lines_between(self, v: np.ndarray, w: np.ndarray, chunk: int | None = None
                      ) -> np.ndarray:
        """``|{j : signs[v_i, j] != signs[w_i, j]}|`` for each pair ``(v_i, w_i)``: the number
        of lines separating the two polytopes (integers, exact).

        Each distinct pair is counted once, ``chunk`` (:data:`PAIR_CHUNK` when None) pairs at
        a time, so the ``pairs x lines`` comparison never exceeds ``chunk x lines`` bytes
        (many moves share a pair: a polytope boundary is crossed from every cell along it)."""
        v, w = np.asarray(v, dtype=np.int64), np.asarray(w, dtype=np.int64)
        chunk = PAIR_CHUNK if chunk is None else int(chunk)
        key = v * max(self.n_polytopes, 1) + w
        uniq, inverse = np.unique(key, return_inverse=True)
        uv, uw = np.divmod(uniq, max(self.n_polytopes, 1))
        count = np.empty(len(uniq), dtype=np.int64)
        for lo in range(0, len(uniq), chunk):
            hi = lo + chunk
            count[lo:hi] = (self.signs[uv[lo:hi]] != self.signs[uw[lo:hi]]).sum(axis=1)
        return count[inverse.ravel()]

    def constraint_rows(self, v: int) -> tuple[np.ndarray, np.ndarray]:
        """All rows (one per line) whose intersection is polytope ``v``: ``A x <= b``."""
        flip = np.where(self.signs[v], -1.0, 1.0)
        return self.normals * flip[:, None], self.offsets * flip


def build_arrangement(spec: MapSpec) -> Arrangement:
    """Compute the free polytopes of ``spec`` (see module docstring)."""
    normals, offsets = unique_hyperplanes(spec)
    free = free_cell_mask(spec)
    size = int(free.sum()) * len(normals)
    if size > MAX_CELL_LINES:
        raise MapError(
            f"map '{spec.name}' is too large to build: {int(free.sum())} free cells x "
            f"{len(normals)} distinct obstacle lines = {size:,} exceeds the limit "
            f"{MAX_CELL_LINES:,}; use fewer or simpler obstacles, or a coarser grid")
    xs, ys = np.nonzero(free)  # x-major order
    cells = np.stack([xs + 1, ys + 1], axis=1)
    cell_index = -np.ones((spec.width, spec.height), dtype=int)
    cell_index[xs, ys] = np.arange(len(cells))
    centres = cells - 0.5
    # each cell's sign vector (which side of every line its centre lies on), bit-packed: rows
    # of bytes group the cells the same way and sort far faster; computed SIGN_CHUNK cells
    # at a time, so the float temporaries are SIGN_CHUNK x m, not n x m (~17 bytes a pair)
    packed = np.empty((len(cells), -(-len(normals) // 8)), dtype=np.uint8)
    for lo in range(0, len(cells), SIGN_CHUNK):
        side = centres[lo: lo + SIGN_CHUNK] @ normals.T - offsets > SIDE_EPS
        packed[lo: lo + SIGN_CHUNK] = np.packbits(side, axis=1)
    # group cells by sign vector; number groups by their first cell
    _, first, inverse = np.unique(packed, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.ravel()
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    cell_polytope = rank[inverse]
    signs = np.unpackbits(packed[first[order]], axis=1, count=len(normals)).astype(bool)
    As, bs, rows, polys = [], [], [], []
    for v in range(len(signs)):
        flip = np.where(signs[v], -1.0, 1.0)
        A_all, b_all = normals * flip[:, None], offsets * flip
        poly = h_polygon(A_all, b_all, spec.width, spec.height)
        ess = facet_rows(poly, A_all, b_all, spec.width, spec.height)
        As.append(A_all[ess])
        bs.append(b_all[ess])
        rows.append(ess)
        polys.append(poly)
    return Arrangement(
        width=spec.width, height=spec.height, normals=normals, offsets=offsets, cells=cells,
        cell_index=cell_index, cell_polytope=cell_polytope, signs=signs, A=tuple(As),
        b=tuple(bs), rows=tuple(rows), polygons=tuple(polys),
    )
