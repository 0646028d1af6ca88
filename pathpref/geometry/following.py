"""Paths that follow a preference: the shortest route to a goal that leaves each polytope ``v``
only toward its preferred neighbour ``p_v`` (any way out of a polytope without one, except the
goal's: see below), and the consistent human's preference for a goal (the map's, completed into
a tree of routes that all lead to the goal's polytope: :func:`consistent_preference`).

**The goal's polytope is held.** When the goal's polytope ``r`` has no preference (``p_r =
-1``: always for the consistent human, for the map's human when the map leaves it free), a
route that has reached a cell of ``r`` from which the goal can be reached without leaving ``r``
(a *held* cell, :func:`goal_polytope_hold`) stays in ``r``: from a held cell, only moves inside
``r`` are allowed. Every exit of the goal's polytope is a non-preferred one (the planner's reward
pays ``R_n`` for it), and a grid path may leave a convex polytope and enter it again where its
cells are joined across a corner or a thin region (``examples/maps/hall.json``: ``... 10, 12,
10, 12`` with ``r = 12``). A cell of ``r`` with no path inside ``r`` (``r``'s cells in pieces)
leaves it as before. The consistent human's pushes in ``r`` follow the same rule
(:class:`~pathpref.inference.human.SimulatedHuman` with ``hold``).

Used by the ``oracle`` reference method (it follows this path) and by the ``consistent`` human
of the instance sampler (a goal the preference can lead to, and the preference it pushes along).
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from .grid import STAY
from .world import World


def goal_polytope_distance(world: World, goal: int) -> np.ndarray:
    """``(n,)`` length of the shortest path from each cell to ``goal`` by moves between cells of
    the goal's polytope ``r`` (both ends in ``r``); inf outside ``r`` and at the cells of ``r``
    that no such path joins to the goal."""
    m = world.motion
    n = world.n_cells
    r = world.cell_polytope[goal]
    inside = np.flatnonzero(world.cell_polytope == r)
    src = np.repeat(inside, 8)
    dst = m.next_cell[inside].ravel()
    ok = ~m.blocked[inside].ravel() & (world.cell_polytope[dst] == r)
    rev = csr_matrix((m.cost[inside].ravel()[ok], (dst[ok], src[ok])), shape=(n, n))
    return dijkstra(rev, directed=True, indices=goal)


def goal_polytope_hold(world: World, pref: np.ndarray, goal: int) -> np.ndarray:
    """``(n,)`` bool: the held cells (module docstring): the cells of the goal's polytope ``r``,
    when ``pref[r] < 0``, from which a path inside ``r`` reaches ``goal``; none when ``r`` has a
    preference."""
    if pref[world.cell_polytope[goal]] >= 0:
        return np.zeros(world.n_cells, dtype=bool)
    return np.isfinite(goal_polytope_distance(world, goal))


def preference_following_distance(world: World, pref: np.ndarray, goal: int,
                                  steps: bool = False) -> np.ndarray:
    """``(n,)`` length of the shortest path from each cell to ``goal`` that leaves each polytope
    ``v`` only toward ``pref[v]`` (any way when ``pref[v] < 0``) and never leaves the goal's
    polytope from a held cell (:func:`goal_polytope_hold`); inf where none exists.
    ``steps``: count moves (each 1) instead of the moves' costs."""
    m = world.motion
    n = world.n_cells
    src = np.repeat(np.arange(n), 8)
    dst = m.next_cell.ravel()
    v, w = world.cell_polytope[src], world.cell_polytope[dst]
    held = goal_polytope_hold(world, pref, goal)[src]
    ok = ~m.blocked.ravel() & ((v == w) | ((pref[v] < 0) & ~held) | (pref[v] == w))
    # reversed graph: an edge t -> s for every allowed move s -> t, so one search from the goal
    weight = np.ones(ok.sum()) if steps else m.cost.ravel()[ok]
    rev = csr_matrix((weight, (dst[ok], src[ok])), shape=(n, n))
    return dijkstra(rev, directed=True, indices=goal)


def preferred_move(world: World, pref: np.ndarray, togo: np.ndarray, cell: int) -> int:
    """The move along the preference from ``cell``: among the moves not blocked that leave
    ``v = v(cell)`` only toward ``pref[v]`` (any when ``pref[v] < 0``), the one minimising
    ``c(cell, a) + togo[next(cell, a)]`` (the lowest index among equals), ``togo`` being
    :func:`preference_following_distance` to the goal; ``STAY`` when every such score is
    infinite. The ``oracle`` acts by it and :func:`preference_route` walks it.

    The goal's polytope is held (module docstring): in the goal's polytope ``r`` (the cell
    where ``togo = 0``) with ``pref[r] < 0``, when a move inside ``r`` scores exactly
    ``togo[cell]`` (the cell is held: ``togo`` was computed without ``r``'s exits there), the
    move is the best of the moves inside ``r``."""
    m = world.motion
    poly = world.cell_polytope
    v, w = poly[cell], poly[m.next_cell[cell]]
    p = pref[v]
    allowed = ~m.blocked[cell] & ((w == v) | (p < 0) | (w == p))
    score = np.where(allowed, m.cost[cell] + togo[m.next_cell[cell]], np.inf)
    if not np.isfinite(score).any():
        return STAY
    if p < 0 and np.isfinite(togo[cell]) and poly[int(np.argmin(togo))] == v:
        inside = np.where(w == v, score, np.inf)
        if inside.min() == togo[cell]:
            return int(np.argmin(inside))
    return int(np.argmin(score))


def preference_route(world: World, pref: np.ndarray, start: int, goal: int) -> list[int]:
    """The cells of the shortest path from ``start`` to ``goal`` that leaves each polytope
    ``v`` only toward ``pref[v]``: :func:`preferred_move` from ``start`` until ``goal``
    (the oracle's path); ``[]`` when the preference does not lead from ``start`` to ``goal``.

    ``togo`` decreases by the move's cost (at least 1) at every move of the walk, so it ends
    at the goal within ``togo[start] <= n_cells * sqrt(2)`` moves; the walk is bounded by
    ``n_cells`` moves all the same (a RuntimeError past it would be a bug here)."""
    togo = preference_following_distance(world, pref, goal)
    if not np.isfinite(togo[start]):
        return []
    route = [int(start)]
    for _ in range(world.n_cells):
        if route[-1] == goal:
            return route
        a = preferred_move(world, pref, togo, route[-1])
        if a == STAY:
            break
        route.append(int(world.motion.next_cell[route[-1], a]))
    if route[-1] == goal:
        return route
    raise RuntimeError("preference_route: the walk along a finite togo did not reach the goal")


def human_route(world: World, pref: np.ndarray, start: int, goal: int) -> list[int]:
    """The human's route from ``start`` to ``goal`` under the preference ``pref``:
    :func:`preference_route` with ``pref``, or, when ``pref`` does not lead there, with its
    completion :func:`consistent_preference` for the goal's polytope (the fewest departures
    from ``pref``); ``[]`` when the goal cannot be reached from the start at all."""
    route = preference_route(world, pref, start, goal)
    if route:
        return route
    q = consistent_preference(world, pref, int(world.cell_polytope[goal]))[0]
    return preference_route(world, q, start, goal)


def consistent_preference(world: World, pref: np.ndarray, goal_polytope: int
                          ) -> tuple[np.ndarray, np.ndarray]:
    """The consistent human's preference for a goal in polytope ``r = goal_polytope``: the
    map's preference ``p`` completed into an in-arborescence rooted at ``r``, and the number of
    departures from ``p`` each polytope needs to reach ``r``.

    Returns ``(q, departures)``: ``q`` per polytope (a neighbour, or -1), ``departures`` per
    polytope (``inf`` outside ``r``'s component ``A`` of the polytope graph).

    The rule. A move ``v -> u`` between neighbours ``u in N(v)`` departs from the map's
    preference when ``p_v >= 0`` and ``u != p_v`` (a polytope without a preference, ``p_v = -1``,
    such as the end of an open route, accepts every exit). Each polytope gets the lexicographic
    cost of its best polytope path ``v = x_0, x_1, ..., x_m = r``::

        kappa(v) = min_path ( sum_i [x_i -> x_{i+1} departs],  m )   (departures, then hops)

    (one Dijkstra from ``r`` over the polytope graph, with integer weights
    ``P * [departs] + 1`` so the order is exact), and then::

        q_r = -1
        q_v = p_v                                          if kappa(p_v) + c(v, p_v) = kappa(v)
        q_v = min { u in N(v) : kappa(u) + c(v, u) = kappa(v) }      otherwise, for v in A \\ {r}
        q_v = p_v                                          for v outside A

    with ``c(v, u) = ([v -> u departs], 1)``: every polytope takes the first move of a best path,
    the map's exit whenever it is one, else the lowest-numbered neighbour that is.

    Why. The hop count strictly decreases along ``q``, so following ``q`` from any polytope of
    ``A`` reaches ``r`` with no cycle, and ``r`` has no exit: ``q`` lies in the support of the
    route prior (:mod:`pathpref.inference.routes`), so it holds no mutual pair and the human
    never pushes the robot back along its own route. Where the map's preference leads to
    ``r`` (its walk ``v, p_v, p_{p_v}, ...`` reaches ``r``) that walk is the only path with no
    departure, so ``q = p`` there: the human keeps the map's route. A route's end (``p = -1``),
    the polytopes past the goal and those on loops that miss it get one exit each, the one that
    leaves the map's route least (then by the fewest polytope changes), instead of the
    goal-only push that led out of the route's end into polytopes pointing back along it.
    ``departures[v] = 0`` exactly when some path from ``v`` to ``r`` leaves every polytope
    toward ``p_v`` or anywhere where ``p_v = -1``: the map's preference leads from ``v`` to the
    goal, and ``q`` then takes such a path. Integers only: the same ``q`` on every machine.
    """
    P = world.n_polytopes
    r = int(goal_polytope)
    pref = np.asarray(pref, dtype=np.int64)
    nbr = world.graph.neighbors
    deg = np.array([len(nb) for nb in nbr], dtype=np.int64)
    src = np.repeat(np.arange(P, dtype=np.int64), deg)
    dst = (np.concatenate([np.asarray(nb, dtype=np.int64) for nb in nbr]) if deg.sum()
           else np.zeros(0, dtype=np.int64))
    departs = (pref[src] >= 0) & (pref[src] != dst)
    w = np.where(departs, float(P), 0.0) + 1.0  # hops < P: departures first, then hops
    # reversed graph (an edge u -> v for each move v -> u), one search from r
    rev = csr_matrix((w, (dst, src)), shape=(P, P))
    key = dijkstra(rev, directed=True, indices=r)
    tight = np.isfinite(key[src]) & (src != r) & (key[dst] + w == key[src])
    rank = np.where(dst == pref[src], -1, dst)  # the map's exit first, then the lowest index
    best = np.full(P, P, dtype=np.int64)
    np.minimum.at(best, src[tight], rank[tight])
    q = pref.copy()
    chosen = best < P
    q[chosen] = np.where(best[chosen] < 0, pref[chosen], best[chosen])
    q[r] = -1
    departures = np.full(P, np.inf)
    reach = np.isfinite(key)
    departures[reach] = key[reach].astype(np.int64) // P
    return q, departures
