"""Circulations: a one-way flow round a centre, the way people keep to one direction round a
building's core, an island of desks or a ring of aisles.

A circulation ``f = (c, sigma)`` has a centre ``c`` in the plane and a sense ``sigma = +1``
(counter-clockwise, ``y`` up) or ``-1`` (clockwise). Its flow gives each polytope ``v`` the
neighbour whose step turns most round ``c`` in that sense::

    f(v) = argmax_{u in N(v)}  sigma * ((x_v - c) x (x_u - x_v)) / (|x_v - c| |x_u - x_v|)

(``x_v``: the polytope's point, :func:`~.ways.polytope_points`; ``a x b`` the 2-D cross
product; the lowest slot of :meth:`~.graph.PolytopeGraph.neighbor_table` among equals; ``-1``
for a polytope with no neighbour). Round an obstacle the flow of a centre inside it goes one
way round; a centre away from the obstacles gives a flow that circles the free space round it.

The centres are the ``CENTRES x CENTRES`` lattice ``lo + (hi - lo) (i + 1/2) / CENTRES`` over
the bounding box ``[lo, hi]`` of the polytopes' points, each with both senses; flows that come
out the same are kept once. Elementwise IEEE arithmetic only (no reductions), so every machine
draws the same flows.
"""

from __future__ import annotations

import numpy as np

from .ways import polytope_points
from .world import World

#: the centres form a CENTRES x CENTRES lattice over the polytopes' bounding box
CENTRES = 3


def circulations(world: World, centres: int = CENTRES) -> np.ndarray:
    """``(F, P)`` the distinct flows of the module docstring, one row per circulation, in
    lexicographic order of the rows (``np.unique``)."""
    if centres < 1:
        raise ValueError("centres must be at least 1")
    pt = polytope_points(world)
    nbr = world.graph.neighbor_table()
    P = len(pt)
    if P == 0:
        return np.zeros((0, 0), dtype=np.int64)
    valid = nbr >= 0
    lo, hi = pt.min(axis=0), pt.max(axis=0)
    step = pt[np.maximum(nbr, 0)] - pt[:, None, :]  # (P, K, 2)
    step_len = np.sqrt(step[..., 0] * step[..., 0] + step[..., 1] * step[..., 1])
    flows = []
    for i in range(centres):
        for j in range(centres):
            c = lo + (hi - lo) * np.array([(i + 0.5) / centres, (j + 0.5) / centres])
            rel = pt - c
            rel_len = np.sqrt(rel[:, 0] * rel[:, 0] + rel[:, 1] * rel[:, 1])
            cross = rel[:, None, 0] * step[..., 1] - rel[:, None, 1] * step[..., 0]
            turn = cross / (rel_len[:, None] * step_len + 1e-12)
            for sense in (1.0, -1.0):
                score = np.where(valid, sense * turn, -np.inf)
                k = score.argmax(axis=1)
                flows.append(np.where(valid.any(axis=1), nbr[np.arange(P), k], -1))
    return np.unique(np.array(flows, dtype=np.int64), axis=0)
