"""Path preferences as preferred transitions (paper Sec. IV-B).

A preference ``theta = {p_v}`` gives each polytope ``v`` one preferred neighbour ``p_v``
(stored as an int array, ``-1`` for "no preference": the human then goes straight for the goal
inside ``v``). A map file states it in a numbering-free way, by cells:

``{"table": [{"from": [x, y], "to": [x, y]}, ...]}``
    the polytope holding cell ``from`` prefers the neighbouring polytope holding cell ``to``.

``{"route": [[x, y], ...], "closed": true}``
    a drawn route (waypoints, e.g. a clockwise loop around the desks), turned into a table by
    the rule of :func:`preference_from_route`.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from typing import Any

import numpy as np
from scipy.sparse.csgraph import dijkstra

from ..errors import MapError
from .arrangement import Arrangement
from .graph import PolytopeGraph
from .grid import GridMotion

#: ``explain(a, b)``: one sentence on why the robot cannot go from cell ``a`` to cell ``b``
#: (:func:`~.grid.blocked_passage`), added to the errors of a preference it cannot follow
Explain = Callable[[int, int], str]


def _because(explain: Explain | None, a: int, b: int) -> str:
    return f": {explain(a, b)}" if explain is not None else ""


def preference_from_table(
    arr: Arrangement, graph: PolytopeGraph, table: list[dict[str, Any]],
    explain: Explain | None = None,
) -> np.ndarray:
    """Preference array from ``[{"from": cell, "to": cell}, ...]`` (see module docstring)."""
    if not isinstance(table, list):
        raise MapError("preference.table must be a list of {'from': [x, y], 'to': [x, y]}")
    pref = -np.ones(arr.n_polytopes, dtype=int)
    for k, entry in enumerate(table):
        where = f"preference.table[{k}]"
        if not isinstance(entry, dict) or set(entry) != {"from", "to"}:
            raise MapError(f"{where} must be {{'from': [x, y], 'to': [x, y]}}, got {entry!r}")
        a, b = arr.free_cell(entry["from"], f"{where}.from"), arr.free_cell(entry["to"],
                                                                             f"{where}.to")
        v, w = int(arr.cell_polytope[a]), int(arr.cell_polytope[b])
        if v == w:
            raise MapError(
                f"{where}: cells {entry['from']} and {entry['to']} lie in the same polytope "
                f"({v}); 'to' must lie in a neighbouring one (see 'pathpref map draw')")
        if graph.edge_between(v, w) < 0:
            raise MapError(
                f"{where}: polytope {v} (cell {entry['from']}) and polytope {w} (cell "
                f"{entry['to']}) are not neighbours; 'to' must lie in a polytope next to 'from'"
                + _because(explain, a, b))
        if pref[v] >= 0 and pref[v] != w:
            raise MapError(
                f"{where} conflicts with an earlier entry: polytope {v} already prefers {pref[v]}"
            )
        pref[v] = w
    return pref


def preference_from_route(
    arr: Arrangement,
    graph: PolytopeGraph,
    motion: GridMotion,
    waypoints: list[list[int]],
    closed: bool = True,
    explain: Explain | None = None,
) -> np.ndarray:
    """Turn a drawn route into a preference table.

    Rule:
      1. Consecutive waypoints (and the last to the first when ``closed``) are joined by a
         shortest grid path (SPEC 3 motion; ties broken by SciPy's Dijkstra, deterministic).
      2. Along the resulting cell path, each polytope change ``u -> w`` sets ``p_u = w`` unless
         ``u`` already has a preference (the first visit wins).
      3. A polytope off the route prefers the neighbour one step closer to the route in the
         polytope graph (breadth-first from the route's polytopes; ties to the lower id), so the
         human always steers toward the route and then along it.
      4. A route polytope with no outgoing change (the end of an open route) has no preference.
    """
    if not isinstance(waypoints, list) or len(waypoints) < 2:
        raise MapError("preference.route must list at least 2 waypoints [x, y]")
    idx = [arr.free_cell(w, f"preference.route[{k}]") for k, w in enumerate(waypoints)]
    legs = list(zip(idx[:-1], idx[1:], strict=True))
    if closed:
        legs.append((idx[-1], idx[0]))
    adj = motion.adjacency()
    path: list[int] = [idx[0]]
    for k, (a, b) in enumerate(legs):
        dist, pred = dijkstra(adj, indices=a, return_predecessors=True)
        if not np.isfinite(dist[b]):
            raise MapError(f"preference.route: waypoint {k + 2} cannot be reached from {k + 1}"
                           + _because(explain, a, b))
        leg = [b]
        while leg[-1] != a:
            leg.append(int(pred[leg[-1]]))
        path.extend(reversed(leg[:-1]))
    pref = -np.ones(arr.n_polytopes, dtype=int)
    verts = arr.cell_polytope[np.array(path)]
    on_route = set(int(v) for v in verts)
    for u, w in zip(verts[:-1], verts[1:], strict=True):
        if u != w and pref[u] < 0:
            pref[u] = w
    # breadth-first from the route outward: off-route polytopes point to their parent
    seen = set(on_route)
    queue = deque(sorted(on_route))
    while queue:
        u = queue.popleft()
        for w in sorted(int(x) for x in graph.neighbors[u]):
            if w not in seen:
                seen.add(w)
                pref[w] = u
                queue.append(w)
    return pref


def parse_preference(
    arr: Arrangement, graph: PolytopeGraph, motion: GridMotion, raw: dict[str, Any] | None,
    explain: Explain | None = None,
) -> np.ndarray | None:
    """The map file's ``preference`` field as an array, or None when absent; ``explain``
    adds why the robot cannot make a transition the preference needs."""
    if raw is None:
        return None
    if set(raw) == {"table"}:
        return preference_from_table(arr, graph, raw["table"], explain)
    if "route" in raw and set(raw) <= {"route", "closed"}:
        closed = raw.get("closed", True)
        if not isinstance(closed, bool):
            raise MapError("preference.closed must be true or false")
        return preference_from_route(arr, graph, motion, raw["route"], closed, explain)
    raise MapError(
        "preference must be {'table': [{'from': [x, y], 'to': [x, y]}, ...]} or "
        "{'route': [[x, y], ...], 'closed': true}"
    )


def preference_to_table(arr: Arrangement, pref: np.ndarray) -> list[dict[str, list[int]]]:
    """Inverse of :func:`preference_from_table`, one entry per polytope with a preference."""
    first = [arr.cells[arr.polytope_cells(v)[0]].tolist() for v in range(arr.n_polytopes)]
    return [{"from": first[v], "to": first[int(w)]} for v, w in enumerate(pref) if w >= 0]
