"""Gamepad calibrations and NASA-TLX answers in the database (``study_calibrations``,
``study_tlx``): a scripted study that calibrates and answers stores the rows, the report shows
the raw TLX with an interval clipped to 0..100, the export writes ``calibration.csv`` and
``tlx.csv``, ``db salvage`` keeps them, and an older database whose answers are JSON lines
beside it still reports (and a session imports them)."""

from __future__ import annotations

import csv
import json
import math
import shutil
import sqlite3
from pathlib import Path

import pytest

from pathpref.apps.cli import main
from pathpref.study.controls import TLX_SCALES

ROOT = Path(__file__).resolve().parents[1]
STUDY = ROOT / "examples" / "study_demo.json"
PUSHES = ROOT / "examples" / "pushes_demo.json"
#: every scale answered v: the raw TLX (the mean of the six) is v
RAW = {"left0": 90, "right1": 95, "left2": 100, "right3": 100}
#: Student's t 0.975 quantile with 3 degrees of freedom (tables: 3.182446)
T3 = 3.182446


def _study(tmp_path: Path):
    from pathpref.study.plan import parse_study

    raw = json.loads(STUDY.read_text())
    base = raw["trials"]
    raw["trials"] = [{**base[k % 2], "name": f"{base[k % 2]['name']}{k}"} for k in range(4)]
    return parse_study(raw, "four.json"), raw


def _script(raw) -> dict:
    pushes = json.loads(PUSHES.read_text())["trials"]
    return {"trials": {t["name"]: pushes[t["name"].rstrip("0123456789")]
                       for t in raw["trials"]},
            "gamepad": {"rest": [0.1, -0.05], "reach": 0.9},
            "tlx": {name: dict.fromkeys(TLX_SCALES, v) for name, v in RAW.items()}}


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """A four-trial scripted study of participant s1: a simulated gamepad calibrated once,
    the NASA-TLX answered after every trial."""
    from pathpref.study.conduct import run_study
    from pathpref.study.script import PushScript, ScriptedFrontEnd

    tmp = tmp_path_factory.mktemp("answers")
    study, raw = _study(tmp)
    db = tmp / "s.sqlite"
    rows = run_study(study, "s1", db, ScriptedFrontEnd(PushScript(_script(raw))),
                     log=lambda m: None)
    assert [r["status"] for r in rows] == ["done"] * 4
    return db, rows


def _table(db, table: str, order: str) -> list[tuple]:
    return sqlite3.connect(db).execute(f"SELECT * FROM {table} ORDER BY {order}").fetchall()


def test_scripted_calibration_and_answers_are_rows(recorded):
    db, rows = recorded
    cal = _table(db, "study_calibrations", "participant, k")
    assert [c[:2] + c[3:] for c in cal] == [("s1", 0, 1, "simulated gamepad", 0.1, -0.05,
                                             0.9, 0.15, 60.0)]
    tlx = _table(db, "study_tlx", "participant, trial")
    names = {r["trial"]: r["name"] for r in rows}
    assert [(t[1], t[2]) for t in tlx] == sorted(names.items())
    for t in tlx:
        v = RAW[t[2]]
        assert t[4:10] == (v,) * 6 and t[10] == v  # raw TLX: the six scales' mean
    assert not list(db.parent.glob("*.jsonl"))


def test_report_shows_raw_tlx_with_a_range_respecting_interval(recorded, capsys):
    """Per participant: 90, 95, 100, 100 -> mean 96.25, s = sqrt(68.75 / 3), the t interval
    96.25 -+ 3.182446 s / 2 = [88.63, 103.87] clipped to [88.63, 100]. Per condition (left:
    belief shown, right: hidden) two answers each: a mean and no interval."""
    from pathpref.experiments.report import load_trials
    from pathpref.study.answers import load_answers, tlx_records

    db, _ = recorded
    recs = tlx_records(load_answers(db)[1], load_trials(db))
    person = [r for r in recs if r["by"] == "participant"]
    assert [(r["group"], r["n"]) for r in person] == [("s1", 4)]
    s = math.sqrt(68.75 / 3)
    assert abs(person[0]["raw_tlx"] - 96.25) < 1e-12
    assert abs(person[0]["raw_tlx_low"] - (96.25 - T3 * s / 2)) < 1e-4
    assert person[0]["raw_tlx_high"] == 100.0
    cond = {r["group"]: r for r in recs if r["by"] == "condition"}
    assert {g: (r["n"], r["raw_tlx"]) for g, r in cond.items()} == {
        "path_preference, belief=shown": (2, 95.0), "path_preference, belief=hidden": (2, 97.5)}
    assert all(math.isnan(r["raw_tlx_low"]) for r in cond.values())
    assert main(["report", str(db), "--csv", str(db.parent / "r.csv")]) == 0
    out = capsys.readouterr().out
    assert "NASA-TLX (raw, 0..100)" in out
    line = next(x for x in out.splitlines() if x.startswith("| participant | s1 | 4 |"))
    assert line.endswith(", 100.0] |")
    assert "| condition | path_preference, belief=shown | 2 | 95.0 (n < 3) |" in out


def test_export_writes_calibration_and_tlx_csv(recorded, tmp_path):
    from pathpref.study.export import export_participant

    db, _ = recorded
    counts = export_participant(db, "s1", tmp_path, mcap=False)
    assert counts["calibration.csv"] == 1 and counts["tlx.csv"] == 4
    for name, table, order in (("calibration.csv", "study_calibrations", "participant, k"),
                               ("tlx.csv", "study_tlx", "participant, trial")):
        with open(tmp_path / "s1" / name, newline="") as f:
            got = list(csv.reader(f))
        cur = sqlite3.connect(db).execute(f"SELECT * FROM {table} ORDER BY {order}")
        assert got[0] == [d[0] for d in cur.description]
        assert got[1:] == [["" if v is None else str(v) for v in r] for r in cur.fetchall()]


def test_salvage_keeps_them_and_a_lost_trial_takes_its_answer(recorded, tmp_path):
    from pathpref.experiments.migrate import salvage_database

    db, _ = recorded
    out = tmp_path / "saved.sqlite"
    r = salvage_database(db, out)
    assert r["trials"] == 4 and r["trials_lost"] == 0
    for table, order in (("study_calibrations", "k"), ("study_tlx", "trial")):
        assert _table(out, table, order) == _table(db, table, order)
    broken = tmp_path / "broken.sqlite"
    shutil.copy(db, broken)
    with sqlite3.connect(broken) as c:  # trial 2 loses a force row: it is left out whole
        c.execute("DELETE FROM trial_forces WHERE participant = 's1' AND trial = 2 AND k = 3")
    out2 = tmp_path / "saved2.sqlite"
    r = salvage_database(broken, out2)
    assert r["trials"] == 3 and r["trials_lost"] == 1
    assert [t[1] for t in _table(out2, "study_tlx", "trial")] == [1, 3, 4]
    assert _table(out2, "study_calibrations", "k") == _table(db, "study_calibrations", "k")


def _legacy_copy(db: Path, folder: Path) -> Path:
    """``db`` as a session before the tables left it: no study_calibrations / study_tlx, the
    records as JSON lines beside it (the old format)."""
    old = folder / "old.sqlite"
    shutil.copy(db, old)
    c = sqlite3.connect(old)
    cal = c.execute("SELECT utc, trial, device, rest_x, rest_y, reach, deadzone, max_force_n "
                    "FROM study_calibrations ORDER BY k").fetchall()
    tlx = c.execute(f"SELECT utc, trial, name, {', '.join(TLX_SCALES)}, raw_tlx FROM "
                    "study_tlx ORDER BY trial").fetchall()
    with c:
        c.execute("DROP TABLE study_calibrations")
        c.execute("DROP TABLE study_tlx")
    c.close()
    (folder / "old.sqlite.s1.calibration.jsonl").write_text("".join(json.dumps({
        "utc": u, "trial": t, "device": d, "rest": [x, y], "reach": r, "deadzone": z,
        "max_force_n": m}) + "\n" for u, t, d, x, y, r, z, m in cal))
    (folder / "old.sqlite.s1.tlx.jsonl").write_text("".join(json.dumps({
        "utc": row[0], "trial": row[1], "name": row[2],
        "scores": dict(zip(TLX_SCALES, row[3:9], strict=True)), "raw_tlx": row[9]}) + "\n"
        for row in tlx))
    return old


def test_an_older_database_with_json_lines_still_reports_and_imports(recorded, tmp_path,
                                                                     capsys):
    from pathpref.experiments.migrate import check_database
    from pathpref.experiments.store import ResultStore
    from pathpref.experiments.trials import TrialWriter, read_rows
    from pathpref.study.answers import import_legacy, load_answers

    db, _ = recorded
    new_cal, new_tlx = load_answers(db)
    old = _legacy_copy(db, tmp_path)
    assert check_database(old)["pathpref"] is None  # the late tables may be missing
    assert load_answers(old) == (new_cal, new_tlx)  # read from the files
    assert main(["report", str(old), "--csv", str(tmp_path / "r.csv")]) == 0
    assert "| participant | s1 | 4 |" in capsys.readouterr().out
    with ResultStore(old) as store:  # opened for writing: the tables are added, empty
        assert read_rows(store.conn, "study_tlx") == []
        assert import_legacy(TrialWriter(store.conn, "s1"), old) == (1, 4)
        assert import_legacy(TrialWriter(store.conn, "s1"), old) == (0, 0)  # once only
    assert load_answers(old) == (new_cal, new_tlx)  # from the tables: nothing counted twice
    (tmp_path / "old.sqlite.s1.tlx.jsonl").write_text('{"trial": 1, "scores": {}}\n')
    assert load_answers(old) == (new_cal, new_tlx)  # issue 47: a bad line is skipped, named
    assert "old.sqlite.s1.tlx.jsonl:1 skipped: not a NASA-TLX" in capsys.readouterr().err


BAD_LINES = [b'{"utc": "x", "trial": Infinity, "name": "a", "scores": {}}',
             b'{"utc": "x", "trial": 2, "name": "\xff\xfe", "scores": {}} \xff',
             b'{"utc": "x", "trial": 1e300, "name": "a", "scores": {"mental": 1}}',
             b'{"utc": "x", "trial": 2, "sco']


def test_bad_lines_of_old_answer_files_are_skipped_and_named(recorded, tmp_path, capsys):
    """Issue 47: ``"trial": Infinity``, invalid UTF-8, 1e300 and a truncated line in a
    participant's JSON-lines file: ``report``, ``study export`` and a resumed session go on,
    each bad line named once; another participant's bad file is not even read by s1's
    export."""
    from pathpref.study.conduct import run_study
    from pathpref.study.script import PushScript, ScriptedFrontEnd

    db, _ = recorded
    old = _legacy_copy(db, tmp_path)
    tlx_file = tmp_path / "old.sqlite.s1.tlx.jsonl"
    good = tlx_file.read_bytes()
    n_good = good.count(b"\n")
    tlx_file.write_bytes(good + b"\n".join(BAD_LINES))  # the last one truncated, no newline
    cal_file = tmp_path / "old.sqlite.s1.calibration.jsonl"
    cal_file.write_bytes(cal_file.read_bytes() + b'{"utc": "x", "trial": 1, "device": "d", '
                         b'"rest": [1e300, 0], "reach": 1, "deadzone": 0.15, '
                         b'"max_force_n": 60}\n')
    (tmp_path / "old.sqlite.p2.tlx.jsonl").write_bytes(b"\xff" * 10 + b"\n{]\n")

    def named(err: str) -> None:
        for n in range(n_good + 1, n_good + 5):
            assert f"old.sqlite.s1.tlx.jsonl:{n} skipped" in err
        assert "old.sqlite.s1.calibration.jsonl:2 skipped" in err
        assert "Traceback" not in err

    assert main(["report", str(old), "--csv", str(tmp_path / "r.csv")]) == 0
    out, err = capsys.readouterr()
    named(err)
    assert "old.sqlite.p2.tlx.jsonl:1 skipped" in err and "| participant | s1 | 4 |" in out
    assert main(["study", "export", str(old), "--participant", "s1", "--out",
                 str(tmp_path / "x"), "--no-mcap"]) == 0
    err = capsys.readouterr().err
    named(err)
    assert "p2" not in err
    with open(tmp_path / "x" / "s1" / "tlx.csv") as f:
        assert len(list(csv.DictReader(f))) == 4
    study, raw = _study(tmp_path)
    rows = run_study(study, "s1", old, ScriptedFrontEnd(PushScript(_script(raw))),
                     resume=True, log=lambda m: None)
    assert [r["status"] for r in rows] == ["done"] * 4
    named(capsys.readouterr().err)
    assert sqlite3.connect(old).execute("SELECT count(*) FROM study_tlx").fetchone() == (4,)


def test_push_file_tlx_is_checked(tmp_path):
    from pathpref.errors import ConfigError
    from pathpref.study.script import PushScript

    good = dict.fromkeys(TLX_SCALES, 50)
    assert PushScript({"pushes": [], "tlx": {"a": good}}).tlx == {"a": good}
    for bad in ({**good, "mental": 101}, {**good, "mental": 2.5}, {**good, "fun": 1},
                {k: v for k, v in good.items() if k != "effort"}, [good]):
        with pytest.raises(ConfigError, match="tlx") as e:
            PushScript({"pushes": [], "tlx": {"a": bad}})
        assert "\n" not in str(e.value)


def test_legacy_files_of_a_database_named_with_glob_characters(tmp_path):
    """A database named ``a[1].sqlite``: its legacy files are found by their literal name."""
    from pathpref.study.answers import _legacy_participants

    db = tmp_path / "a[1].sqlite"
    (tmp_path / "a[1].sqlite.p.1.tlx.jsonl").write_text("")
    (tmp_path / "a1.sqlite.q.tlx.jsonl").write_text("")  # what the unescaped pattern matches
    assert _legacy_participants(db, "tlx") == ["p.1"]
