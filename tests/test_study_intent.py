"""The robot's planned path (pathpref/study/intent.py) for the study's observers, against
paths worked out by hand on the ``simple`` map and an independent Dijkstra.

The ``simple`` map (10 x 10 cells, a table on cells x 5..6, y 5..6) has 8 polytopes::

    2222447777
    2222447777
    2222447777
    2222447777
    1111##6666
    1111##6666
    0000335555
    0000335555
    0000335555
    0000335555
"""

from __future__ import annotations

import heapq
import math

import numpy as np

from pathpref.study.plan import parse_study
from pathpref.study.session import TrialRunner

TRIAL = {"name": "a", "map": "simple", "start": [5, 2], "goal": [5, 9],
         "candidates": [[2, 9], [5, 9], [9, 9]], "route": [[5, 2], [2, 2], [2, 9], [5, 9]],
         "time_limit_s": 10, "queries": 30}
WEST = 6


def runner(**over) -> TrialRunner:
    return TrialRunner(parse_study({"trials": [{**TRIAL, **over}]}).trials[0], seed=0)


def dijkstra(world, src: int, allowed) -> np.ndarray:
    """Shortest path costs from ``src`` over the moves ``allowed(v, w)`` permits (v, w the
    polytopes of the move's two cells): a plain heap Dijkstra over the grid's moves."""
    m = world.motion
    dist = np.full(world.n_cells, np.inf)
    dist[src] = 0.0
    heap = [(0.0, src)]
    while heap:
        d, s = heapq.heappop(heap)
        if d > dist[s]:
            continue
        for a in range(8):
            if m.blocked[s, a]:
                continue
            t = int(m.next_cell[s, a])
            if not allowed(int(world.cell_polytope[s]), int(world.cell_polytope[t])):
                continue
            if d + m.cost[s, a] < dist[t]:
                dist[t] = d + m.cost[s, a]
                heapq.heappush(heap, (dist[t], t))
    return dist


def path_cost(world, cells: list[int]) -> float:
    total = 0.0
    for a, b in zip(cells, cells[1:]):
        (xa, ya), (xb, yb) = world.cells[a], world.cells[b]
        assert max(abs(xa - xb), abs(ya - yb)) == 1, (a, b)  # grid neighbours
        total += math.hypot(xa - xb, ya - yb)
    return total


def test_pushes_west_plan_left_round_the_table_to_the_likely_goal():
    """Three west pushes at the start: the belief's likely goal is (9, 9) and its likely
    route 3 -> 0 -> 1 -> 2 -> 4 -> 7 (left of the table, across the top). By hand the
    shortest path along it: (5,2) to (4,5) 2 + sqrt2, up to (4,7) 2 (polytope 1 may be left
    only into 2), (4,7) to (9,9) 3 + 2 sqrt2: 7 + 3 sqrt2; an independent Dijkstra over the
    moves that route allows agrees, and the path is the one drawn."""
    r = runner()
    w = r.world
    for _ in range(3):
        r.policy.belief.update(r.cell, WEST)
    probs = r.policy.belief.goal_marginal()
    assert int(np.argmax(probs)) == 2  # (9, 9)
    path = r.planned_path()
    assert path[0] == r.cell == w.cell((5, 2)) and path[-1] == w.cell((9, 9))
    cost = path_cost(w, path)
    assert abs(cost - (7 + 3 * math.sqrt(2))) < 1e-9
    route = {(3, 0), (0, 1), (1, 2), (2, 4), (4, 7)}
    ref = dijkstra(w, path[0], lambda v, u: v == u or (v, u) in route)
    assert abs(ref[path[-1]] - cost) < 1e-9
    xy = w.cells[path].tolist()
    assert all(x <= 4 for x, y in xy if y in (5, 6))  # left of the table
    assert r.planned_path() is path  # cached until the belief or the move changes


def test_a_move_under_way_comes_first_and_a_cue_replans():
    """While a move is under way the path is the robot's cell, the cell it drives to, then the
    plan from there; a cue reaching the belief drops the cached plan."""
    r = runner()
    w = r.world
    north = 0
    r.intended_action = north
    path = r.planned_path()
    assert w.cells[path[:2]].tolist() == [[5, 2], [5, 3]]
    # uniform goal belief: the likely goal is the first candidate, (2, 9)
    assert path[-1] == w.cell((2, 9))
    ref = dijkstra(w, w.cell((5, 3)), lambda v, u: True)
    # the route belief's likely exits never lengthen this one: the plain shortest path
    assert abs(path_cost(w, path[1:]) - ref[w.cell((2, 9))]) < 1e-9
    from pathpref.episode import Felt

    before = path
    r.observe(Felt(cell=r.cell, heading=WEST))
    assert r.planned_path() is not before


def test_goal_only_and_compliant_policies():
    """A goal-only belief has no preference: the plain shortest path to the likely goal
    (hand: (5,2) to (2,9) is 3 diagonal + 4 straight moves, 4 + 3 sqrt2). The compliant
    policy plans nothing: its cell and its decided move only."""
    r = runner(method="goal_only")
    w = r.world
    path = r.planned_path()
    assert path[-1] == w.cell((2, 9)) and len(path) == 8
    assert abs(path_cost(w, path) - (4 + 3 * math.sqrt(2))) < 1e-9
    c = runner(method="compliant")
    assert c.planned_path() == [c.cell]
    c.intended_action, c._plan = WEST, None
    assert c.world.cells[c.planned_path()].tolist() == [[5, 2], [4, 2]]


def test_path_is_bounded_and_in_bounds_from_every_cell():
    """Worst case of the route walk: from every free cell the path has at most n_cells + 2
    cells, each a free cell, consecutive ones grid neighbours, ending at the likely goal."""
    from pathpref.study.intent import intended_path

    r = runner()
    w = r.world
    goals = r.model.goals
    for cell in range(w.n_cells):
        p = intended_path(w, goals, r.policy.belief, cell)
        assert p[0] == cell and len(p) <= w.n_cells + 2
        assert all(0 <= c < w.n_cells for c in p)
        path_cost(w, p)
        assert p[-1] == goals[0]
