"""Study trials on the same physics as every other door: per-trial ``physics`` and ``robot``
(pathpref/study/plan.py), recorded in the trial rows, grouped by the report, replayed; study
databases written before the columns existed still open, replay and take new trials."""

from __future__ import annotations

import csv
import json
import shutil
import sqlite3
from pathlib import Path

import numpy as np
import pytest

from pathpref.apps.cli import main
from pathpref.episode.physics import Physics
from pathpref.errors import ConfigError
from pathpref.experiments.trials import LATE_TRIAL_COLUMNS, TRIAL_COLUMNS, study_sql
from pathpref.study.plan import parse_study

ROOT = Path(__file__).resolve().parents[1]
STUDY = ROOT / "examples" / "study_demo.json"
PUSHES = ROOT / "examples" / "pushes_demo.json"


def two_conditions() -> dict:
    """The demo's two trials: "left" with realistic sensing named explicitly (an ideal-sensing
    variant would be ``{"sensor": "ideal"}``), "right" on the arm (``carry``)."""
    raw = json.loads(STUDY.read_text())
    raw["order"] = "fixed"
    raw["trials"][0]["physics"] = {"sensor": "realistic"}
    raw["trials"][1]["robot"] = "carry"
    return raw


@pytest.fixture(scope="module")
def physics_db(tmp_path_factory):
    """The two-condition study run unattended from the command line (scripted pushes)."""
    folder = tmp_path_factory.mktemp("physics")
    study = folder / "two.json"
    study.write_text(json.dumps(two_conditions()))
    db = folder / "study.sqlite"
    assert main(["study", "run", str(study), "--participant", "p1", "--db", str(db),
                 "--script", str(PUSHES)]) == 0
    return db


def test_trials_run_the_physics_and_robot_their_condition_names():
    """The runner's body is built from the trial's setting: the arm's tray is what the
    participant pushes on a carry trial; the sensor model is the named preset."""
    from pathpref.sim.arm import ArmBase
    from pathpref.sim.sensing import SensorModel
    from pathpref.study.session import TrialRunner

    raw = two_conditions()
    raw["trials"].append({**raw["trials"][0], "name": "ideal", "physics": {"sensor": "ideal"}})
    raw["trials"].append({**raw["trials"][0], "name": "old", "physics": "legacy"})
    study = parse_study(raw)
    left, right, ideal, old = (TrialRunner(t, seed=0) for t in study.trials)
    assert left.spec.physics == Physics().to_json() == study.trials[0].physics
    assert left.base.sensing.sensor_model == SensorModel.realistic()
    # the ideal sensor is the raw one (no model), on the physical base (measured)
    assert ideal.base.sensing.sensor_model is None and ideal.base.measure
    assert old.spec.physics == "" and old.body.physics is None  # the legacy body
    assert old.base.sensing.sensor_model is None and not old.base.measure
    assert not isinstance(left.base, ArmBase)
    assert isinstance(right.base, ArmBase) and right.spec.robot == "carry"
    assert right.base.pushed_body == right.base.tray
    for r in (left, right, ideal, old):  # the participant is the only human
        assert r.continuous is False and r.body.human is None


def test_a_two_condition_study_records_its_settings(physics_db):
    c = sqlite3.connect(physics_db)
    rows = c.execute("SELECT name, status, outcome, physics, robot, pushes, time_s FROM trials "
                     "ORDER BY trial").fetchall()
    assert [(r[0], r[1], r[4]) for r in rows] == [("left", "done", "navigate"),
                                                  ("right", "done", "carry")]
    for name, _, outcome, physics, _, pushes, time_s in rows:
        assert json.loads(physics) == json.loads(Physics(sensor="realistic").to_json())
        assert outcome == "success"
        script = json.loads(PUSHES.read_text())["trials"][name]
        assert pushes == sum(p["t"] < time_s for p in script)  # every push that began


def test_replay_verifies_both_conditions(physics_db, tmp_path):
    from pathpref.apps.rollout import CARD_S, VIDEO_FPS
    from pathpref.study.replay import replay_trial

    held = int(round(CARD_S * VIDEO_FPS))  # the final frame, then the outcome card
    for k in (1, 2):
        frames = replay_trial(physics_db, "p1", k, tmp_path / f"t{k}.mp4", 32, 24)
        time_s = sqlite3.connect(physics_db).execute(
            "SELECT time_s FROM trials WHERE trial = ?", (k,)).fetchone()[0]
        assert abs(frames - (time_s * VIDEO_FPS + 1 + held)) <= 2


def test_report_separates_conditions_by_physics_and_robot(physics_db, capsys):
    assert main(["report", str(physics_db)]) == 0
    out = capsys.readouterr().out
    assert "| path_preference, belief=hidden, robot=carry | 1 |" in out
    assert "| path_preference, belief=shown | 1 |" in out  # the default physics: no suffix
    from pathpref.experiments.report import condition_label

    row = {"method": "compliant", "condition": "{}", "robot": "navigate"}
    assert condition_label(row | {"physics": None}) == "compliant"
    assert condition_label(row | {"physics": ""}) == "compliant, legacy physics"
    assert condition_label(row | {"physics": Physics(sensor="ideal").to_json()}) == \
        "compliant, physics sensor=ideal"


def test_report_fits_the_participants_rationality(physics_db, tmp_path, capsys):
    """gamma_h from every recorded cue (its cell and heading) under each trial's own goal and
    route; shown by the report and in the study CSV; a tampered heading is one line."""
    from pathpref.study.plan import trial_from_row
    from pathpref.study.rationality import fit_gamma, heading_log_probs, participant_fits

    c = sqlite3.connect(physics_db)
    c.row_factory = sqlite3.Row
    logp, heads = [], []
    for r in c.execute("SELECT * FROM trials ORDER BY trial"):
        cues = c.execute("SELECT x, y, heading FROM trial_cues WHERE trial = ? ORDER BY k",
                         (r["trial"],)).fetchall()
        logp.append(heading_log_probs(trial_from_row(dict(r)), [(q[0], q[1]) for q in cues]))
        heads += [q[2] for q in cues]
    want = fit_gamma(np.concatenate(logp), np.array(heads))
    fits = participant_fits(physics_db)
    assert list(fits) == ["p1"] and fits["p1"] == want and want.n == len(heads) >= 6
    assert main(["report", str(physics_db), "--csv", str(tmp_path / "r.csv")]) == 0
    assert f"| p1 | {len(heads)} | {want.text()} |" in capsys.readouterr().out
    with open(tmp_path / "r.csv") as f:
        first = next(csv.DictReader(f))
    assert first["group"] == "p1" and float(first["gamma_h"]) == want.gamma
    bad = tmp_path / "bad.sqlite"
    shutil.copy(physics_db, bad)
    with sqlite3.connect(bad) as b:
        b.execute("UPDATE trial_cues SET heading = 9 WHERE k = 0 AND trial = 2")
    b.close()
    with pytest.raises(ConfigError, match=r"trial 2 of 'p1' has a cue heading outside 0\.\.7"):
        participant_fits(bad)


def _strip_late_columns(db: Path) -> None:
    """Make ``db`` what a study database written before the columns looked like: its
    ``trials`` table as the older pathpref created it, the same rows."""
    old = TRIAL_COLUMNS[:-len(LATE_TRIAL_COLUMNS)]
    with sqlite3.connect(db) as c:
        c.execute("ALTER TABLE trials RENAME TO t_new")
        c.execute(study_sql("trials", old))
        c.execute(f"INSERT INTO trials SELECT {', '.join(old)} FROM t_new")
        c.execute("DROP TABLE t_new")
    c.close()


def test_a_study_database_from_before_the_columns_opens_replays_and_grows(
        physics_db, tmp_path, capsys):
    """An older study file is read as it is (check, report, replay: the trials ran the
    default physics on the navigate robot), and opened for writing gets the columns in place
    (old rows NULL) and keeps every row; salvage keeps its trials."""
    db = tmp_path / "old.sqlite"
    shutil.copy(physics_db, db)
    with sqlite3.connect(db) as c:  # its trials ran the defaults (left) before the columns
        c.execute("DELETE FROM trials WHERE trial = 2")
        for t in ("trial_steps", "trial_forces", "trial_pushes", "trial_cues",
                  "trial_beliefs"):
            c.execute(f"DELETE FROM {t} WHERE trial = 2")
    c.close()
    _strip_late_columns(db)
    raw = db.read_bytes()
    assert main(["db", "check", str(db)]) == 0
    assert main(["report", str(db), "--csv", str(tmp_path / "r.csv")]) == 0
    assert "| path_preference, belief=shown | 1 |" in capsys.readouterr().out
    from pathpref.study.replay import replay_trial

    assert replay_trial(db, "p1", 1, tmp_path / "t1.mp4", 32, 24) > 0
    assert db.read_bytes() == raw  # readers never write
    out = tmp_path / "salvaged.sqlite"
    assert main(["db", "salvage", str(db), str(out)]) == 0
    s = sqlite3.connect(out)
    assert s.execute("SELECT trial, physics, robot FROM trials").fetchall() == [(1, None, None)]
    # a new participant's session on the old file: the columns are added in place
    one = json.loads(STUDY.read_text())
    one["trials"] = one["trials"][:1]
    one["trials"][0]["robot"] = "carry"
    (tmp_path / "one.json").write_text(json.dumps(one))
    pushes = json.loads(PUSHES.read_text())
    pushes["trials"] = {"left": pushes["trials"]["left"]}
    (tmp_path / "one_pushes.json").write_text(json.dumps(pushes))
    assert main(["study", "run", str(tmp_path / "one.json"), "--participant", "p2", "--db",
                 str(db), "--script", str(tmp_path / "one_pushes.json")]) == 0
    c = sqlite3.connect(db)
    assert c.execute("SELECT participant, robot, physics IS NULL FROM trials ORDER BY "
                     "participant").fetchall() == [("p1", None, 1), ("p2", "carry", 0)]
    assert [r[1] for r in c.execute("PRAGMA table_xinfo(trials)")] == list(TRIAL_COLUMNS)
    assert main(["db", "check", str(db)]) == 0


@pytest.mark.parametrize("over, message", [
    ({"physics": {"timing": "rate"}},
     r"trials\[0\]\.physics\.timing must be decision or guidance \(decision: the "
     r"participant's pushes are read as cues; guidance: the base also complies to them\), "
     r"got 'rate'"),
    ({"physics": {"gamma_h": 2}},
     r"trials\[0\]\.physics\.gamma_h is the simulated human's; a trial's human is the "
     "participant"),
    ({"physics": {"sensor": "perfect"}},
     r"trials\[0\]\.physics sensor \(--sensor\) must be one of ideal, ft300s, realistic"),
    ({"physics": {"colour": 1}}, r"trials\[0\]\.physics has unknown field 'colour'"),
    ({"physics": "fast"}, r"trials\[0\]\.physics must be an object of physics fields"),
    ({"physics": {"robot_model": "tidybot"}},
     r"trials\[0\]\.physics\.robot_model must be disk: a study's exports place its cells at "
     r"the disk's 0\.5 m; got 'tidybot'"),
    ({"robot": "fly"}, r"trials\[0\]\.robot must be navigate or carry, got 'fly'"),
    ({"robot": "carry", "physics": {"base": "diffdrive"}},
     r"trials\[0\]: physics base diffdrive runs the navigate task only"),
])
def test_bad_physics_or_robot_one_line_naming_the_field(over, message):
    t = {"name": "a", "map": "simple", "start": [5, 2], "goal": [5, 9],
         "candidates": [[2, 9], [5, 9], [9, 9]], "route": [[5, 2], [2, 2], [2, 9], [5, 9]],
         "time_limit_s": 10, **over}
    with pytest.raises(ConfigError, match=message) as e:
        parse_study({"trials": [t]})
    assert "\n" not in str(e.value)


def test_a_scripted_study_with_guidance_trials_completes(tmp_path):
    """A guidance trial: the participant's sustained drag moves the compliant base (the
    recorded path goes west under a 25 N westward drag of 1.5 s: the admittance's 0.31 m/s
    gives about 0.4 m) and the scripted study runs to its end with its outcome recorded."""
    study = json.loads(STUDY.read_text())
    study["trials"] = study["trials"][:1]
    study["trials"][0]["physics"] = {"timing": "guidance"}
    (tmp_path / "g.json").write_text(json.dumps(study))
    drags = {"trials": {"left": [
        {"t": 0.3, "fx": -25, "fy": 0, "duration": 1.5},
        {"t": 4.0, "fx": 0, "fy": 25, "duration": 2.0},
        {"t": 9.0, "fx": 0, "fy": 25, "duration": 2.0},
        {"t": 14.0, "fx": 25, "fy": 0, "duration": 1.5}]}}
    (tmp_path / "drags.json").write_text(json.dumps(drags))
    db = tmp_path / "g.sqlite"
    assert main(["study", "run", str(tmp_path / "g.json"), "--participant", "p1", "--db",
                 str(db), "--script", str(tmp_path / "drags.json")]) == 0
    c = sqlite3.connect(db)
    status, outcome, physics = c.execute(
        "SELECT status, outcome, physics FROM trials").fetchone()
    assert status == "done" and outcome in ("success", "timeout")
    assert json.loads(physics)["timing"] == "guidance"
    path = c.execute("SELECT time_s, x FROM trial_path ORDER BY k").fetchall()
    x0 = path[0][1]
    x_after = min(x for t, x in path if 0.3 <= t <= 2.5)
    assert x0 - x_after > 0.25
    assert main(["db", "check", str(db)]) == 0
