"""Grid motion (SPEC 3): costs, blocked moves, the corner rule, heading bins."""

from __future__ import annotations

import numpy as np
import pytest

from pathpref.geometry.grid import ACTION_NAMES, heading_to_action


def act(name: str) -> int:
    return ACTION_NAMES.index(name)


def test_costs_and_walls(simple):
    m = simple.motion
    s = simple.cell((1, 1))
    assert m.blocked[s, act("S")] and m.blocked[s, act("W")] and m.blocked[s, act("SW")]
    assert m.cost[s, act("S")] == 1.0 and m.next_cell[s, act("S")] == s
    assert m.cost[s, act("NE")] == pytest.approx(np.sqrt(2))
    assert m.next_cell[s, act("NE")] == simple.cell((2, 2))


def test_obstacle_blocks(simple):
    s = simple.cell((4, 5))
    assert simple.motion.blocked[s, act("E")]  # (5,5) is the table


def test_corner_rule(simple):
    """(4,5) -> SE -> (5,4) passes through the corner (4,4) of two lines: blocked."""
    s = simple.cell((4, 5))
    assert simple.motion.blocked[s, act("SE")]
    assert simple.motion.next_cell[s, act("SE")] == s
    # (4,3) -> NE -> (5,4) crosses only x = 4: allowed, and crosses an edge
    s = simple.cell((4, 3))
    assert not simple.motion.blocked[s, act("NE")]
    assert simple.motion.crossed_edge[s, act("NE")] >= 0


def test_moves_are_reversible(worlds):
    for w in worlds.values():
        m = w.motion
        opposite = (np.arange(8) + 4) % 8
        for s in range(w.n_cells):
            for a in range(8):
                if not m.blocked[s, a]:
                    t = m.next_cell[s, a]
                    assert m.next_cell[t, opposite[a]] == s


@pytest.mark.parametrize(
    "deg,name", [(0, "E"), (45, "NE"), (90, "N"), (135, "NW"), (180, "W"), (-90, "S"),
                 (22.4, "E"), (22.6, "NE"), (-22.6, "SE"), (359, "E"), (250, "S")]
)
def test_heading_bins(deg, name):
    assert ACTION_NAMES[heading_to_action(np.deg2rad(deg))] == name
