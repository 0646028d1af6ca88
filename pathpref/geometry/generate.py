"""Random floor plans for tests and benchmarks: rotated rectangles and axis-aligned boxes.

:func:`random_floor_plan` places ``n_rotated`` rectangles at random angles and ``n_boxes``
cell-aligned boxes in a ``width x height`` map, all inside the map box, from a seed. Obstacles may
overlap (valid in the map format). The result is a map dictionary (see :mod:`.maps`).

:func:`four_connected_components` labels free cells by 4-connectivity, the reference the motion
rule must match (:mod:`.grid`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.ndimage import label


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
    while len(obstacles) < n_rotated:
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


def with_loop_preference(raw: dict[str, Any]) -> dict[str, Any]:
    """``raw`` plus a closed-route preference around the map (a loop through the free cells
    nearest to the four corners, all in the largest 4-connected part of free space)."""
    from .maps import free_cell_mask, parse_map

    spec = parse_map(raw)
    labels, _ = four_connected_components(free_cell_mask(spec))
    biggest = np.bincount(labels[labels > 0]).argmax()
    xs, ys = np.nonzero(labels == biggest)
    corners = [(0, 0), (spec.width - 1, 0), (spec.width - 1, spec.height - 1),
               (0, spec.height - 1)]
    route = []
    for cx, cy in corners:
        k = int(np.argmin((xs - cx) ** 2 + (ys - cy) ** 2))
        route.append([int(xs[k]) + 1, int(ys[k]) + 1])
    return {**raw, "preference": {"route": route, "closed": True}}
