"""Ways round the obstacles: a few routes from a start to a goal, one per homotopy class.

A person choosing a route chooses a way round the obstacles (left or right of the desk, through
which door), not an exit per polytope. This module finds, for a start polytope ``s`` and a goal
polytope ``r``, the shortest route of each of the few shortest *classes* (their *ways*), and a
potential per way that says how far the goal is "along that way" from any polytope.

**The sketch of the polytope graph.** Each polytope ``v`` is drawn at the mean ``x_v`` of its
cells' centres (inside ``v``: its cells are those of a convex region of the arrangement), and
each directed edge ``v -> u`` as the polyline ``x_v -> a -> b -> x_u`` through the crossing
grid move ``a -> b`` (``a`` in ``v``, ``b`` in ``u``) that makes it shortest. Its length
``w(v, u)`` is the polyline's, and its *signature* ``sigma(v, u)`` the vector of its signed
crossings of the ray from each obstacle's point toward ``+x``
(:func:`~.homotopy.crossings`). The signature of a route is the sum over its edges; two routes
from ``s`` to ``r`` are in the same class exactly when their signatures are equal (the loop
one makes with the other reversed then winds zero times round every obstacle, the rule of
:mod:`.homotopy`).

**Via routes** (the via-node method of road-network route planning). With the shortest-path
trees from ``s`` and from ``r`` (Dijkstra on ``w``), every polytope ``m`` gives the route
``s -> m -> r`` of length ``d(s, m) + d(m, r)`` and signature ``sigma(s ~> m) - sigma(r ~> m)``
(the tree paths; a reversed path's crossings negate). Grouped by signature, each class keeps
its shortest via route; the ways are the :data:`K_WAYS` shortest classes no longer than
:data:`STRETCH` times the shortest route. Cost: two Dijkstras and ``O(P m)`` for ``m``
obstacles, whatever the number of classes. A via route is two shortest paths joined at one
polytope, so a class that needs two turns of its own (weaving above one obstacle and below
the next) is not among the ways; the route prior's share of the mixture
(:mod:`pathpref.inference.homotopy_prior`) keeps such routes possible.

**A way's potential.** For a way ``c = (c_0 = s, ..., c_n = r)`` with remaining lengths
``l_i = sum_{j >= i} w(c_j, c_{j+1})``::

    phi_c(u) = min_i ( LEAVE * d(u, c_i) + l_i )

(one Dijkstra from a virtual source joined to each ``c_i`` at ``l_i``, every edge weighing
``LEAVE`` times its length): the length to the goal along the way, where the distance to rejoin
it counts :data:`LEAVE` times, so that a shortcut round an obstacle the other way is rarely
shorter than following the way.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra

from .homotopy import crossings, obstacle_points
from .world import World

#: the most ways (classes) kept per start and goal
K_WAYS = 6
#: a way is kept when its length is at most this many times the shortest route's
STRETCH = 2.0
#: how many times a step away from the way counts in its potential (module docstring)
LEAVE = 2.0


@dataclass(frozen=True)
class Sketch:
    """The polytope graph drawn in the plane (module docstring).

    Attributes:
        point: ``(P, 2)`` each polytope's point ``x_v``.
        src, dst: ``(D,)`` every directed edge ``v -> u`` (both orientations of each edge).
        length: ``(D,)`` its polyline's length ``w(v, u)``.
        signature: ``(D, m)`` its signed crossings of the ``m`` obstacles' rays.
    """

    point: np.ndarray
    src: np.ndarray
    dst: np.ndarray
    length: np.ndarray
    signature: np.ndarray

    def edge_index(self, v: np.ndarray, u: np.ndarray) -> np.ndarray:
        """The index (into ``src``, ``dst``, ...) of each directed edge ``v[i] -> u[i]`` (all
        must be edges)."""
        P = len(self.point)
        key = self.src * P + self.dst
        by_key = np.argsort(key)
        return by_key[np.searchsorted(key, np.asarray(v) * P + np.asarray(u), sorter=by_key)]

    def matrix(self, scale: float = 1.0) -> sp.csr_matrix:
        """``(P, P)`` the edge lengths times ``scale`` (a sparse graph for Dijkstra)."""
        P = len(self.point)
        return sp.csr_matrix((self.length * scale, (self.src, self.dst)), shape=(P, P))


def polytope_points(world: World) -> np.ndarray:
    """``(P, 2)`` each polytope's point ``x_v``: the mean of its cells' centres (inside ``v``:
    its cells are those of a convex region)."""
    P = world.n_polytopes
    centre = world.cells.astype(float) - 0.5
    cp = world.cell_polytope.astype(np.int64)
    count = np.bincount(cp, minlength=P).astype(float)
    return np.stack([np.bincount(cp, weights=centre[:, i], minlength=P) for i in (0, 1)],
                    axis=1) / np.maximum(count, 1.0)[:, None]


def sketch(world: World) -> Sketch:
    """The :class:`Sketch` of ``world``'s polytope graph (module docstring)."""
    P = world.n_polytopes
    centre = world.cells.astype(float) - 0.5
    cp = world.cell_polytope.astype(np.int64)
    point = polytope_points(world)
    m = world.motion
    a, k = np.nonzero(m.crossed_edge >= 0)  # every crossing move a -> b
    b = m.next_cell[a, k]
    v, u = cp[a], cp[b]
    keep = v != u
    a, b, v, u = a[keep], b[keep], v[keep], u[keep]
    pa, pb = centre[a], centre[b]
    cost = (np.linalg.norm(pa - point[v], axis=1) + np.linalg.norm(pb - pa, axis=1)
            + np.linalg.norm(point[u] - pb, axis=1))
    key = v * P + u
    order = np.lexsort((cost, key))  # per directed pair, its shortest crossing first
    first = order[np.r_[True, key[order][1:] != key[order][:-1]]] if len(order) else order
    v, u, a, b, cost = v[first], u[first], a[first], b[first], cost[first]
    pts = obstacle_points(world.spec)
    sig = (crossings(point[v], centre[a], pts) + crossings(centre[a], centre[b], pts)
           + crossings(centre[b], point[u], pts))
    return Sketch(point=point, src=v, dst=u, length=cost, signature=sig)


@dataclass(frozen=True)
class Ways:
    """The ways from polytope ``start`` to polytope ``goal`` (module docstring).

    Attributes:
        routes: per way, its polytopes ``c_0 = start, ..., c_n = goal``.
        lengths: ``(K,)`` each route's length.
        signatures: ``(K, m)`` each route's signature (distinct rows).
    """

    start: int
    goal: int
    routes: tuple[np.ndarray, ...]
    lengths: np.ndarray
    signatures: np.ndarray

    def __len__(self) -> int:
        return len(self.routes)


def _tree(sk: Sketch, matrix: sp.csr_matrix, root: int, reverse: bool = False):
    """Distances, predecessors and tree-path signatures from ``root`` (Dijkstra on
    ``matrix``). ``reverse``: ``matrix`` is the reversed graph, so a tree edge ``p -> x`` is the
    sketch's edge ``x -> p`` and ``sig[x]`` is the signature of the path ``x ~> root``."""
    P = len(sk.point)
    dist, pred = dijkstra(matrix, directed=True, indices=root, return_predecessors=True)
    sig = np.zeros((P, sk.signature.shape[1]), dtype=np.int64)
    reached = np.flatnonzero(np.isfinite(dist) & (pred >= 0))
    order = reached[np.argsort(dist[reached], kind="stable")]  # parents before children
    parent = pred[order].astype(np.int64)
    edge = sk.edge_index(order, parent) if reverse else sk.edge_index(parent, order)
    for x, p, e in zip(order.tolist(), parent.tolist(), edge.tolist(), strict=True):
        sig[x] = sig[p] + sk.signature[e]
    return dist, pred, sig


def _path(pred: np.ndarray, x: int) -> list[int]:
    """The tree path from the root to ``x`` (``len(pred)`` steps at most)."""
    out = [x]
    for _ in range(len(pred)):
        if pred[out[-1]] < 0:
            break
        out.append(int(pred[out[-1]]))
    return out[::-1]


def find_ways(sk: Sketch, start: int, goal: int, k: int = K_WAYS,
              stretch: float = STRETCH) -> Ways:
    """The ways from ``start`` to ``goal`` (module docstring, "Via routes"): at most ``k``
    classes, each by its shortest via route, no longer than ``stretch`` times the shortest
    route, shortest first. One way (the shortest route) when there is only one class, none when
    ``goal`` cannot be reached."""
    mat = sk.matrix()
    d_s, pred_s, sig_s = _tree(sk, mat, start)
    d_r, pred_r, sig_r = _tree(sk, mat.T.tocsr(), goal, reverse=True)  # d(m, r)
    total = d_s + d_r
    ok = np.flatnonzero(np.isfinite(total))
    if not np.isfinite(d_s[goal]) or not len(ok):
        return Ways(start, goal, (), np.zeros(0), np.zeros((0, sk.signature.shape[1]), np.int64))
    sig = sig_s[ok] + sig_r[ok]
    best = total[ok]
    order = np.lexsort((ok, best))
    classes, first = np.unique(sig[order], axis=0, return_index=True)
    picks = order[np.sort(first)]  # each class's shortest via polytope, shortest first
    picks = picks[np.argsort(best[picks], kind="stable")]
    picks = picks[best[picks] <= stretch * d_s[goal] + 1e-9][:k]
    routes = []
    for i in picks:
        m_ = int(ok[i])
        tail = _path(pred_r, m_)[::-1]  # m ~> r along the reversed tree
        routes.append(np.array(_path(pred_s, m_) + tail[1:], dtype=np.int64))
    return Ways(start, goal, tuple(routes), best[picks].astype(float), sig[picks])


def way_potential(sk: Sketch, route: np.ndarray, leave: float = LEAVE) -> np.ndarray:
    """``(P,)`` ``phi_c(u) = min_i (leave * d(u, c_i) + l_i)`` of the way ``route``
    (module docstring; ``inf`` where the way cannot be reached)."""
    P = len(sk.point)
    route = np.asarray(route, dtype=np.int64)
    step = sk.length[sk.edge_index(route[:-1], route[1:])]
    remaining = np.concatenate([np.cumsum(step[::-1])[::-1], [0.0]]) if len(step) else \
        np.zeros(1)
    at = np.full(P, np.inf)
    np.minimum.at(at, route, remaining)  # a route may pass a polytope twice: its least
    on = np.flatnonzero(np.isfinite(at))
    # reversed edges (distances *to* the way) and a virtual source P joined to each c_i at
    # 1 + l_i (scipy's sparse graphs drop explicit zeros: the 1 is taken off after)
    g = sp.vstack([sp.hstack([sk.matrix(leave).T, sp.csr_matrix((P, 1))]),
                   sp.csr_matrix((at[on] + 1.0, (np.zeros(len(on), np.int64), on)),
                                 shape=(1, P + 1))]).tocsr()
    return dijkstra(g, directed=True, indices=P)[:P] - 1.0
