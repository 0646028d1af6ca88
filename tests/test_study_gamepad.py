"""Gamepad input: the calibrated stick rule (worked out by hand), its refusals, and a
10-trial scripted study driven by a simulated gamepad through the front-end code path."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from pathpref.study.controls import (
    MAX_FORCE_N,
    STICK_DEADZONE,
    Controls,
    StickCalibration,
    stick_axes,
    stick_force,
)

ROOT = Path(__file__).resolve().parents[1]
STUDY = ROOT / "examples" / "study_demo.json"
PUSHES = ROOT / "examples" / "pushes_demo.json"
CAL = StickCalibration((0.1, -0.05), 0.9, "pad")


def test_stick_rule_by_hand():
    assert STICK_DEADZONE == 0.15 and MAX_FORCE_N == 60.0
    # 0.6 of the reach east of rest: g = (0.6 - 0.15) / 0.85 = 0.5294118, F = 31.764706 N east
    f = stick_force(0.1 + 0.9 * 0.6, -0.05, CAL)
    assert f[0] == pytest.approx(60 * 0.45 / 0.85, abs=1e-12) and f[1] == 0.0
    # the browser's axis 1 points down: pushing the stick up (ay < rest) pushes north
    f = stick_force(0.1, -0.05 - 0.9, CAL)
    assert f.tolist() == [0.0, 60.0]
    # inside the dead zone (0.1 of the reach) and at rest: no force
    assert not stick_force(0.1 + 0.09, -0.05, CAL).any()
    assert not stick_force(0.1, -0.05, CAL).any()
    # beyond the reach: capped at 60 N, in the stick's direction (NE: 45 degrees)
    f = stick_force(1.0, -1.0, StickCalibration((0.0, 0.0), 0.5))
    assert math.hypot(*f) == pytest.approx(60.0, abs=1e-12) and f[0] == pytest.approx(f[1])


@pytest.mark.parametrize("f", [(35.0, 0.0), (0.0, -35.0), (-20.0, 20.0), (12.5, -3.0)])
def test_simulated_stick_gives_back_the_force(f):
    ax, ay = stick_axes(np.array(f), CAL)
    assert np.allclose(stick_force(ax, ay, CAL), f, rtol=0, atol=1e-9)


def test_stick_needs_a_calibration_and_sane_values():
    c = Controls()
    assert not c.handle('{"type": "stick", "ax": 0.5, "ay": 0}')
    for bad in ('{"type": "calibrate", "rest": [0, 0], "reach": 0.05}',  # did not move it
                '{"type": "calibrate", "rest": [2, 0], "reach": 0.9}',
                '{"type": "calibrate", "rest": [0], "reach": 0.9}'):
        assert not c.handle(bad)
    got = []
    c.on_calibration.append(got.append)
    assert c.handle('{"type": "calibrate", "rest": [0.1, -0.05], "reach": 0.9, '
                    '"device": "pad"}')
    assert got == [CAL] and c.calibration == CAL
    assert not c.handle('{"type": "stick", "ax": NaN, "ay": 0}')
    assert c.handle(json.dumps({"type": "stick", "ax": 0.1 + 0.9 * 0.6, "ay": -0.05}))
    assert c.force()[0] == pytest.approx(60 * 0.45 / 0.85, abs=1e-12)
    assert c.handle('{"type": "stick", "ax": 0.1, "ay": -0.05}')  # back at rest: a release
    assert not c.force().any() and c.released_at is not None
    assert c.ignored == 5


def test_ten_trial_study_with_a_simulated_gamepad(tmp_path):
    """Ten trials, the pushes sent as stick axes of a calibrated simulated gamepad, complete
    unattended: every push recorded with the scripted force as its peak, felt as a cue; the
    calibration is recorded once, before trial 1."""
    from pathpref.study.conduct import run_study
    from pathpref.study.plan import parse_study
    from pathpref.study.script import PushScript, ScriptedFrontEnd

    raw = json.loads(STUDY.read_text())
    base = raw["trials"]
    raw["trials"] = [{**base[k % 2], "name": f"{base[k % 2]['name']}{k}"} for k in range(10)]
    script = json.loads(PUSHES.read_text())["trials"]
    pushes = {t["name"]: script[t["name"].rstrip("0123456789")] for t in raw["trials"]}
    study = parse_study(raw, "ten.json")
    db = tmp_path / "pad.sqlite"
    pad = {"rest": [0.1, -0.05], "reach": 0.9}
    rows = run_study(study, "g1", db, ScriptedFrontEnd(PushScript({"trials": pushes,
                                                                   "gamepad": pad})),
                     log=lambda m: None)
    assert [r["status"] for r in rows] == ["done"] * 10
    import sqlite3

    c = sqlite3.connect(db)
    for r in rows:
        made = [p for p in pushes[r["name"]] if p["t"] < r["time_s"]]
        felt = [p for p in made if p["t"] + p["duration"] + 0.1 < r["time_s"]]
        assert r["pushes"] == len(made) and r["cues"] == len(felt)
        peaks = [p for (p,) in c.execute("SELECT peak_n FROM trial_pushes WHERE trial = ? "
                                         "ORDER BY k", (r["trial"],))]
        assert peaks == pytest.approx([math.hypot(p["fx"], p["fy"]) for p in made], abs=1e-9)
    cal = c.execute("SELECT participant, k, trial, rest_x, rest_y, reach, deadzone, "
                    "max_force_n FROM study_calibrations").fetchall()
    assert cal == [("g1", 0, 1, 0.1, -0.05, 0.9, 0.15, 60.0)]
    assert not list(tmp_path.glob("*.jsonl"))  # the database holds it, nothing beside it


def test_tlx_answers_are_checked():
    from pathpref.study.controls import TLX_SCALES

    c = Controls()
    got = []
    c.on_tlx.append(lambda k, scores: got.append((k, scores)))
    good = dict(zip(TLX_SCALES, (10, 20, 30, 40, 50, 60), strict=True))
    for bad in ({**good, "mental": 101}, {**good, "mental": 2.5},
                {k: v for k, v in good.items() if k != "effort"}, {**good, "fun": 3}):
        assert not c.handle(json.dumps({"type": "tlx", "trial": 1, "scores": bad}))
    assert not c.handle(json.dumps({"type": "tlx", "trial": 0, "scores": good}))
    # issue 47: nothing is accepted before the question is asked, nor about another trial
    assert not c.handle(json.dumps({"type": "tlx", "trial": 2, "scores": good}))
    c.ask_tlx(2)
    assert not c.handle(json.dumps({"type": "tlx", "trial": 3, "scores": good}))
    assert c.handle(json.dumps({"type": "tlx", "trial": 2, "scores": good}))
    assert not c.handle(json.dumps({"type": "tlx", "trial": 2,
                                    "scores": {**good, "effort": 0}}))
    assert got == [(2, good)] and c.tlx == {2: good}  # the first answer stands
    assert c.ignored == 8
    c.ask_tlx(3)
    c.reset()  # the next trial began: the question is closed
    assert not c.handle(json.dumps({"type": "tlx", "trial": 3, "scores": good}))
    assert got == [(2, good)]


def test_study_file_questionnaire_field():
    from pathpref.errors import ConfigError
    from pathpref.study.plan import parse_study

    raw = json.loads(STUDY.read_text())
    assert parse_study(raw).questionnaire is None
    assert parse_study({**raw, "questionnaire": "nasa-tlx"}).questionnaire == "nasa-tlx"
    with pytest.raises(ConfigError, match="questionnaire must be nasa-tlx"):
        parse_study({**raw, "questionnaire": "sus"})
