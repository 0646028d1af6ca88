"""The demo's outcome card, its choice of the rendered episode and its statement of where
inferring the preference matters, on hand-made inputs."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np

from pathpref.apps.demo import FILM_MIN_STEPS, film_index, sweep_statement
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


def test_film_index_reads_the_route_length_only():
    specs = [SimpleNamespace(run=r) for _ in range(3) for r in range(2)]
    steps = [2, 30, 5, FILM_MIN_STEPS, FILM_MIN_STEPS, 2]
    oracle = [SimpleNamespace(steps=s) for s in steps]
    assert film_index(specs, oracle) == 4  # index 1 and 3 are run 1, not run 0
    assert film_index(specs[:2], oracle[:2]) == 0  # none long enough: the first


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
