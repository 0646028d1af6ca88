"""The demo's outcome card, its choice of the rendered episode and its statement of where
inferring the preference matters, on hand-made inputs."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np

from pathpref.apps.demo import (
    FILM_MIN_CROSSINGS,
    FILM_MIN_SLACK,
    FILM_MIN_STEPS,
    differ_counts,
    film_candidates,
    film_index,
    route_crossings,
    sweep_header,
    sweep_statement,
)
from pathpref.viz.video import outcome_card, outcome_lines


def _res(success, reached, followed, homotopy, pushes=3, steps=12):
    return SimpleNamespace(success=success, goal_reached=reached, pref_followed=followed,
                           homotopy_success=homotopy, inputs=pushes, steps=steps)


def test_outcome_lines_name_every_outcome():
    texts = [t for t, _ in outcome_lines(_res(True, True, True, True))]
    assert texts == ["SUCCESS: goal reached by the preferred route",
                     "preferred route followed: yes", "homotopy-level success: yes",
                     "pushes: 3   steps: 12"]
    assert outcome_lines(_res(False, True, False, True))[0][0] == \
        "FAILURE: goal reached by another route"
    assert outcome_lines(_res(False, True, False, True))[2][0] == "homotopy-level success: yes"
    assert outcome_lines(_res(False, False, False, False, 0, 30))[0][0] == \
        "FAILURE: goal not reached"
    # success is red only when it failed
    assert outcome_lines(_res(True, True, True, True))[0][1] != \
        outcome_lines(_res(False, False, False, False))[0][1]


def test_outcome_card_fades_the_frame_and_boxes_the_text():
    frame = np.zeros((270, 480, 3), np.uint8)
    card = outcome_card(frame, outcome_lines(_res(False, True, False, False)))
    assert card.shape == frame.shape and card.dtype == np.uint8
    assert (card[0, 0] == int(0.55 * 255)).all()  # 0.45 * 0 + 0.55 * 255, faded black
    assert card[135, 30:450].max() == 255  # the white box crosses the centre row


def _route(xs: list[tuple[int, int]], t_max: int = 30):
    """A hand-made oracle result on ``simple`` whose logged path is ``xs``."""
    log = [SimpleNamespace(x=x, y=y) for x, y in xs]
    return SimpleNamespace(steps=len(xs) - 1, log=log, spec=SimpleNamespace(map="simple"))


def test_film_index_reads_the_route_only():
    """The rule: run 0, >= FILM_MIN_STEPS steps, >= FILM_MIN_CROSSINGS polytope crossings,
    >= FILM_MIN_SLACK steps spare; each candidate below fails exactly one condition."""
    assert (FILM_MIN_STEPS, FILM_MIN_CROSSINGS, FILM_MIN_SLACK) == (8, 2, 10)
    along_south = [(x, 1) for x in range(1, 11)]  # 9 steps along the bottom row
    assert route_crossings(_route(along_south)) >= FILM_MIN_CROSSINGS
    inside = [(1, 1), (1, 2), (1, 1), (1, 2), (1, 1), (1, 2), (1, 1), (1, 2), (1, 1)]
    assert route_crossings(_route(inside)) == 0  # 8 steps inside one polytope
    specs = [SimpleNamespace(run=r, t_max=t) for r, t in ((1, 30), (0, 30), (0, 17), (0, 30),
                                                          (0, 30))]
    oracle = [_route(along_south), _route(inside), _route(along_south),
              _route(along_south[:8]), _route(along_south)]
    # 0: run 1; 1: no crossing; 2: 17 - 9 = 8 spare; 3: 7 steps; 4: every condition holds
    assert film_index(specs, oracle) == 4
    assert film_index(specs[:4], oracle[:4]) == 0  # none qualifies: the first


def test_film_candidates_are_where_path_preference_alone_succeeds():
    """The film rule's candidates: episodes where path preference is a strict success and goal
    only is not, those with a route worth filming first; none when they never so differ."""
    ok = SimpleNamespace(success=True)
    no = SimpleNamespace(success=False)
    along_south = [(x, 1) for x in range(1, 11)]
    inside = [(1, 1), (1, 2)] * 4 + [(1, 1)]
    specs = [SimpleNamespace(run=0, t_max=30)] * 5
    oracle = [_route(along_south), _route(inside), _route(along_south), _route(inside),
              _route(along_south)]
    pp = [ok, ok, no, ok, ok]
    go = [ok, no, no, no, no]
    # 0: both succeed; 2: both fail; 1 and 3 differ, route not worth filming; 4 differs, worth it
    assert film_candidates(specs, oracle, pp, go) == [4, 1, 3]
    assert film_candidates(specs, oracle, pp, pp) == []
    assert differ_counts(pp, go) == (3, 0) and differ_counts(go, pp) == (0, 3)


def _cell(setting, method, k, lo, hi):
    return {"setting": setting, "method": method, "success": k, "n": 30,
            "success_ci": [lo, hi]}


def test_sweep_statement_says_where_it_matters(tmp_path):
    cells = [_cell("A", "path_preference", 29, 0.83, 0.99), _cell("A", "goal_only", 12, 0.25, 0.58),
             _cell("A", "compliant", 14, 0.30, 0.64), _cell("A", "oracle", 30, 0.89, 1.0),
             _cell("B", "path_preference", 27, 0.74, 0.97), _cell("B", "goal_only", 19, 0.46, 0.78),
             _cell("B", "compliant", 7, 0.12, 0.41)]
    path = tmp_path / "s.json"
    path.write_text(json.dumps({"cells": cells}))
    a, b = sweep_statement(path)
    assert a.startswith("- A: path_preference 29/30 [0.83, 0.99]; goal_only 12/30 [0.25, 0.58]")
    assert "oracle 30/30 [0.89, 1.00] (knows the preference)" in a
    assert a.endswith("-> inferring the preference MATTERS")
    assert b.endswith("no measurable gain over goal only / compliant at this n")  # 0.74 < 0.78
    assert "oracle" not in b
    assert sweep_statement(tmp_path / "missing.json")[0].startswith("(the stored sweep")


def test_sweep_header_names_command_and_preset_and_a_mismatch():
    sweep = {"command": "sh scripts/demo_sweep.sh db robust", "preset": "robust",
             "episodes": 60, "cells": [{"n": 30, "preset": "robust"}] * 2}
    head = sweep_header(sweep, "robust")
    assert head == ["stored sweep demo_sweep.json (shipped with pathpref): 60 grid episodes, "
                    "30 per cell, preset robust, made by `sh scripts/demo_sweep.sh db robust`"]
    note = sweep_header(sweep, "paper")
    assert len(note) == 2 and note[1].startswith("NOTE: the stored sweep was made with preset "
                                                 "robust; this demo runs preset paper")
