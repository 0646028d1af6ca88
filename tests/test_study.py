"""Study mode (pathpref/study): study files, scripted participants through the front-end code
path, recording in the results store, resume, bad input."""

from __future__ import annotations

import json
import shutil
import sqlite3
from pathlib import Path

import pytest

from pathpref.apps.cli import main
from pathpref.errors import ConfigError
from pathpref.study.controls import MAX_FORCE_N, Controls
from pathpref.study.plan import latin_rows, load_study, parse_study

ROOT = Path(__file__).resolve().parents[1]
STUDY = ROOT / "examples" / "study_demo.json"
PUSHES = ROOT / "examples" / "pushes_demo.json"
HEADING = {(-1, 0): 6, (1, 0): 2, (0, 1): 0, (0, -1): 4}  # W, E, N, S sectors


def one_trial(**over):
    t = {"name": "a", "map": "simple", "start": [5, 2], "goal": [5, 9],
         "candidates": [[2, 9], [5, 9], [9, 9]], "route": [[5, 2], [2, 2], [2, 9], [5, 9]],
         "time_limit_s": 10}
    return {"trials": [{**t, **over}]}


@pytest.mark.parametrize("over, message", [
    ({"map": "nowhere"}, r"trials\[0\]\.map"),
    ({"goal": [5, 5], "candidates": [[5, 5], [2, 9]]}, r"trials\[0\]\.goal \(5, 5\) lies on an "
                                                       "obstacle"),
    ({"route": [[5, 2], [5, 14], [5, 9]]}, r"trials\[0\]\.route\[1\] \(5, 14\) is outside"),
    ({"route": [[5, 2], [2, 9]]}, r"route must run from the start"),
    ({"method": "oracle"}, r"trials\[0\]\.method must be one of"),
    ({"time_limit_s": 0}, r"time_limit_s must be"),
    ({"colour": "red"}, r"trials\[0\]\.colour is not a trial field"),
    ({"goal": [1, 1]}, r"goal \(1, 1\) is not among the candidates"),
    ({"condition": {"belief": "maybe"}}, r"condition\.belief must be shown or hidden"),
])
def test_bad_study_files_one_line_naming_the_field(over, message):
    with pytest.raises(ConfigError, match=message) as e:
        parse_study(one_trial(**over))
    assert "\n" not in str(e.value)


def test_toml_and_json_give_the_same_study(tmp_path):
    (tmp_path / "s.toml").write_text(
        'order = "fixed"\n[[trials]]\nname = "a"\nmap = "simple"\nstart = [5, 2]\n'
        'goal = [5, 9]\ncandidates = [[2, 9], [5, 9], [9, 9]]\n'
        'route = [[5, 2], [2, 2], [2, 9], [5, 9]]\ntime_limit_s = 10\n')
    (tmp_path / "s.json").write_text(json.dumps({"order": "fixed", **one_trial()}))
    a, b = load_study(tmp_path / "s.toml"), load_study(tmp_path / "s.json")
    assert a.trials == b.trials and a.hash == b.hash


@pytest.mark.parametrize("n", [2, 3, 4, 5])
def test_latin_square_is_balanced(n):
    """Every trial once per position per row set; every ordered pair adjacent equally often
    (Williams design; worked out by counting, not from the construction)."""
    rows = latin_rows(n)
    assert len(rows) == (n if n % 2 == 0 else 2 * n)
    for row in rows:
        assert sorted(row) == list(range(n))
    per_position = {(p, row[p]) for row in rows for p in range(n)}
    assert len(per_position) == n * n
    pairs: dict[tuple[int, int], int] = {}
    for row in rows:
        for a, b in zip(row[:-1], row[1:]):
            pairs[(a, b)] = pairs.get((a, b), 0) + 1
    assert len(pairs) == n * (n - 1) and len(set(pairs.values())) == 1


def test_controls_cap_and_ignore_bad_messages(caplog):
    c = Controls()
    assert c.handle('{"type": "push", "fx": 300, "fy": 400}')
    assert abs(float((c.force() ** 2).sum()) ** 0.5 - MAX_FORCE_N) < 1e-9  # capped at 60 N
    for bad in ("nonsense", "[1, 2]", '{"type": "push", "fx": "a", "fy": 1}',
                '{"type": "push", "fx": NaN, "fy": 1}', '{"type": "fly"}', "x" * 5000):
        assert not c.handle(bad)
    # logged one line each up to LOG_FIRST (5), then rate-limited (tests/test_study_server.py)
    assert c.ignored == 6 and len([r for r in caplog.records if "ignored" in r.message]) == 5
    assert c.force()[0] == pytest.approx(36.0)  # the last good push stands
    c.handle('{"type": "release"}')
    assert not c.force().any()


def _db(path):
    return sqlite3.connect(path)


ARGV = ["study", "run", str(STUDY), "--participant", "demo", "--script", str(PUSHES)]


@pytest.fixture(scope="module")
def demo_db(tmp_path_factory):
    """The shipped example run once, as a user would (the command line)."""
    db = tmp_path_factory.mktemp("demo") / "study.sqlite"
    assert main([*ARGV, "--db", str(db)]) == 0
    return db


def test_scripted_demo_records_everything(demo_db, capsys):
    """The shipped example completes unattended; every push of the script is in the database
    with a cue in its direction, effort = sum |F| dt of the script's pushes, rerun files."""
    db = demo_db
    argv = [*ARGV, "--db", str(db)]
    script = json.loads(PUSHES.read_text())["trials"]
    c = _db(db)
    trials = c.execute("SELECT trial, name, status, outcome, pushes, cues, effort_ns, rerun, "
                       "show_belief, time_s FROM trials WHERE participant = 'demo' "
                       "ORDER BY trial").fetchall()
    assert [t[2] for t in trials] == ["done", "done"]
    assert {t[1] for t in trials} == {"left", "right"}
    for k, name, _, outcome, pushes, cues, effort, rerun, show, time_s in trials:
        assert outcome == "success" and time_s < 25
        assert show == (name == "left")
        hom, violations = c.execute("SELECT homotopy_success, violations FROM trials WHERE "
                                    "participant = 'demo' AND trial = ?", (k,)).fetchone()
        # no preference violated: the route's way round every obstacle
        assert hom == 1 if violations == 0 else hom in (0, 1)
        # the script's pushes that began before the robot reached the goal
        pushes_in = [p for p in script[name] if p["t"] < time_s]
        # every push released (and past the detector's 0.4 s release window) before the end
        # gave its cue; one the goal cut short may not have
        done = [p for p in pushes_in if p["t"] + p["duration"] + 0.4 <= time_s]
        assert pushes == len(pushes_in) and len(done) <= cues <= pushes and cues >= 3
        # effort: each scripted push is |F| x the time it acted (held constant, one physics
        # step late; a push under way when the trial ended acted until then)
        expected = sum((p["fx"] ** 2 + p["fy"] ** 2) ** 0.5 * min(p["duration"], time_s - p["t"])
                       for p in pushes_in)
        assert effort == pytest.approx(expected, rel=0.01)
        rows = c.execute("SELECT t_start, peak_n FROM trial_pushes WHERE trial = ? ORDER BY k",
                         (k,)).fetchall()
        assert [round(r[0], 1) for r in rows] == [round(p["t"], 1) for p in pushes_in]
        headings = [r[0] for r in c.execute(
            "SELECT heading FROM trial_cues WHERE trial = ? ORDER BY k", (k,))]
        want = [HEADING[(int(p["fx"] > 0) - int(p["fx"] < 0), int(p["fy"] > 0) - int(p["fy"] < 0))]
                for p in pushes_in]
        assert headings == want[:cues]  # the cues, in order, of the pushes that gave one
        n_forces = c.execute("SELECT count(*), max(time_s) FROM trial_forces WHERE trial = ?",
                             (k,)).fetchone()
        assert n_forces[0] == pytest.approx(n_forces[1] / 0.002, abs=2)  # every control step
        beliefs = c.execute("SELECT count(*) FROM trial_beliefs WHERE trial = ? AND cause = "
                            "'cue'", (k,)).fetchone()[0]
        assert beliefs == cues
        assert Path(rerun).is_file() and Path(rerun).stat().st_size > 1000
    # a second run of the same participant is refused, nothing written
    before = c.execute("SELECT count(*) FROM trial_forces").fetchone()[0]
    assert main(argv) == 2
    assert "already has 2 trial(s)" in capsys.readouterr().err
    assert c.execute("SELECT count(*) FROM trial_forces").fetchone()[0] == before


class Killed(Exception):
    pass


def test_killed_session_resumes_at_the_unfinished_trial(tmp_path, capsys):
    """A session dying in trial 2 keeps trial 1 whole; --resume deletes trial 2's partial rows
    and runs it again, giving the same rows as an uninterrupted run."""
    from pathpref.study.conduct import run_study
    from pathpref.study.script import PushScript, ScriptedFrontEnd

    study = load_study(STUDY)
    script = PushScript.load(PUSHES)

    class Dying(ScriptedFrontEnd):
        def after_decision(self, runner):
            if runner.trial.name == study.order_for("p1")[1].name and runner.t == 4:
                raise Killed

    db = tmp_path / "s.sqlite"
    with pytest.raises(Killed):
        run_study(study, "p1", db, Dying(script), log=lambda m: None)
    c = _db(db)
    assert c.execute("SELECT trial, status FROM trials ORDER BY trial").fetchall() == [
        (1, "done"), (2, "running")]
    assert c.execute("SELECT count(*) FROM trial_steps WHERE trial = 2").fetchone()[0] == 5
    assert main(["db", "check", str(db)]) == 0  # not damage: a trial to run again
    assert "study trials: 1 finished, 1 unfinished" in capsys.readouterr().out
    with pytest.raises(ConfigError, match="--resume"):
        run_study(study, "p1", db, ScriptedFrontEnd(script), log=lambda m: None)
    rows = run_study(study, "p1", db, ScriptedFrontEnd(script), resume=True,
                     log=lambda m: None)
    assert [r["status"] for r in rows] == ["done", "done"]
    clean = tmp_path / "clean.sqlite"
    run_study(study, "p1", clean, ScriptedFrontEnd(script), log=lambda m: None)
    for table in ("trial_steps", "trial_cues", "trial_pushes", "trial_forces"):
        q = f"SELECT * FROM {table} ORDER BY trial, {'t' if table == 'trial_steps' else 'k'}"
        assert c.execute(q).fetchall() == _db(clean).execute(q).fetchall(), table


def test_schema3_database_gets_the_study_tables_and_keeps_its_episodes(tmp_path):
    from pathpref.experiments.report import load_records

    db = tmp_path / "old.sqlite"
    shutil.copy(ROOT / "tests" / "data" / "saved_sweep.sqlite", db)
    before = load_records(db)
    version = _db(db).execute("SELECT value FROM meta").fetchone()[0]
    assert version == "3"
    assert main(["study", "run", str(STUDY), "--participant", "x", "--db", str(db),
                 "--script", str(PUSHES)]) == 0
    c = _db(db)
    assert c.execute("SELECT value FROM meta").fetchone()[0] == "5"
    assert c.execute("SELECT count(*) FROM trials").fetchone()[0] == 2
    assert load_records(db) == before


@pytest.mark.parametrize("argv, message", [
    (["--participant", "a/b"], "--participant must be"),
    (["--script", "missing.json"], "cannot read push file"),
])
def test_bad_command_line_writes_nothing(tmp_path, capsys, argv, message):
    db = tmp_path / "s.sqlite"
    assert main(["study", "run", str(STUDY), "--db", str(db), *(
        [] if "--participant" in argv else ["--participant", "p"]), *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not db.exists()


def test_replay_runs_the_recorded_forces_again(demo_db, tmp_path, capsys):
    """The replay feeds the recorded forces through the same physics and planner: it matches
    the recorded steps and writes a real-time video; with the forces removed it departs from
    the recording and writes nothing."""
    import imageio.v2 as imageio

    out = tmp_path / "t1.mp4"
    assert main(["replay", str(demo_db), "--participant", "demo", "--trial", "1", "--out",
                 str(out), "--width", "96", "--height", "72"]) == 0
    time_s = _db(demo_db).execute("SELECT time_s FROM trials WHERE trial = 1").fetchone()[0]
    n = imageio.get_reader(str(out)).count_frames()
    assert abs(n - (time_s * 25 + 1 + 25)) <= 2  # + the final frame, the 1 s outcome card
    assert main(["replay", str(demo_db), "--participant", "demo", "--trial", "9", "--out",
                 str(tmp_path / "x.mp4")]) == 2
    assert "no trial 9" in capsys.readouterr().err
    from pathpref.study import replay

    spec, seed, forces, steps = replay.load_recorded_trial(demo_db, "demo", 1)
    assert len(forces) == pytest.approx(time_s / 0.002, abs=2) and forces.any()
    quiet = tmp_path / "quiet.sqlite"
    shutil.copy(demo_db, quiet)
    with sqlite3.connect(quiet) as c:  # no forces, and a row that agrees: only a replay
        c.execute("UPDATE trial_forces SET fx = 0, fy = 0")  # can tell
        c.execute("UPDATE trials SET pushes = 0, effort_ns = 0")
        c.execute("DELETE FROM trial_pushes")
    with pytest.raises(ConfigError, match="departs from the recording"):
        replay.replay_trial(quiet, "demo", 1, tmp_path / "q.mp4", 32, 24)
    assert not (tmp_path / "q.mp4").exists()


def test_replay_on_a_full_disk_exits_2_and_keeps_no_file(demo_db, tmp_path, capsys,
                                                         monkeypatch):
    """`replay --out` used to exit 0 and print "wrote" over an unplayable MP4; the database
    is not changed either (a reader never writes)."""
    from pathpref.sim import render

    from .test_render import fake_ffmpeg

    monkeypatch.setenv("IMAGEIO_FFMPEG_EXE", fake_ffmpeg(tmp_path, read_all=True))
    monkeypatch.setattr(render, "free_bytes", lambda folder: 0)
    (tmp_path / "out").mkdir()
    out = tmp_path / "out" / "t1.mp4"
    raw = demo_db.read_bytes()
    rc = main(["replay", str(demo_db), "--participant", "demo", "--trial", "1", "--out",
               str(out), "--width", "32", "--height", "24"])
    cap = capsys.readouterr()
    assert rc == 2 and "wrote" not in cap.out
    assert cap.err.splitlines() == [f"pathpref: error: cannot write {out}: no space left on "
                                    "device; free some space and run again (no partial file "
                                    "was kept)"]
    assert list((tmp_path / "out").iterdir()) == [] and demo_db.read_bytes() == raw


def test_report_has_study_tables(demo_db, capsys):
    assert main(["report", str(demo_db)]) == 0
    out = capsys.readouterr().out
    # two successes of two: Wilson 95% interval [0.34, 1.00]
    assert "| demo | 2 | 1.00 [0.34, 1.00] |" in out
    # pushes: every scripted push that began before the trial ended; their mean, and no
    # interval at n = 2 (a t interval there spans 12.7 s.d. either side)
    script = json.loads(PUSHES.read_text())["trials"]
    db = _db(demo_db)
    counts = [sum(p["t"] < time_s for p in script[name])
              for name, time_s in db.execute("SELECT name, time_s FROM trials ORDER BY trial")]
    assert [r[0] for r in db.execute("SELECT pushes FROM trials ORDER BY trial")] == counts
    mean = sum(counts) / 2
    row = next(line for line in out.splitlines() if line.startswith("| demo |"))
    assert f"| {mean:.1f} (n < 3) |" in row and "-" not in row
    assert "| path_preference, belief=hidden | 1 | 1.00 [0.21, 1.00] |" in out


def test_scripted_ten_trial_study_within_three_minutes(tmp_path):
    """Ten trials (the demo's two, five times each, counterbalanced) run unattended well
    within 3 minutes, and every scripted push is recorded as a push and felt as a cue."""
    import time

    from pathpref.study.conduct import run_study
    from pathpref.study.script import PushScript, ScriptedFrontEnd

    raw = json.loads(STUDY.read_text())
    base = raw["trials"]
    raw["trials"] = [{**base[k % 2], "name": f"{base[k % 2]['name']}{k}"} for k in range(10)]
    script = json.loads(PUSHES.read_text())["trials"]
    pushes = {f"{t['name']}": script[t["name"].rstrip("0123456789")] for t in raw["trials"]}
    study = parse_study(raw, "ten.json")
    t0 = time.process_time()  # CPU time: a scripted trial is not paced to the wall clock
    rows = run_study(study, "p10", tmp_path / "ten.sqlite",
                     ScriptedFrontEnd(PushScript({"trials": pushes})), log=lambda m: None)
    assert time.process_time() - t0 < 180 and len(rows) == 10
    for r in rows:  # a trial that ends early (goal reached) ends its script there
        made = [p for p in pushes[r["name"]] if p["t"] < r["time_s"]]
        felt = [p for p in made if p["t"] + p["duration"] + 0.1 < r["time_s"]]
        assert r["pushes"] == len(made) and r["cues"] == len(felt)
    assert sum(r["pushes"] for r in rows) >= 40


def test_resume_with_another_study_file_is_refused(demo_db, tmp_path, capsys):
    other = tmp_path / "other.json"
    raw = json.loads(STUDY.read_text())
    raw["defaults"]["time_limit_s"] = 20
    other.write_text(json.dumps(raw))
    before = _db(demo_db).execute("SELECT count(*) FROM trial_steps").fetchone()[0]
    assert main(["study", "run", str(other), "--participant", "demo", "--db", str(demo_db),
                 "--script", str(PUSHES), "--resume"]) == 2
    assert "ran another study file" in capsys.readouterr().err
    assert _db(demo_db).execute("SELECT count(*) FROM trial_steps").fetchone()[0] == before


def test_the_robot_is_not_told_the_goal_or_the_route():
    from pathpref.study.session import TrialRunner

    trial = parse_study(one_trial()).trials[0]
    r = TrialRunner(trial, seed=0)
    assert r.policy.ctx.true_goal == -1 and r.policy.ctx.true_preference is None
    # no simulated human input: the heading the policy sees comes from cues only
    r.begin()
    assert r.pending_heading is None and r.result.inputs == 0
    # driving over a wrong candidate rules nothing out (the paper's protocol would)
    before = r.policy.belief.goal_marginal().copy()
    r._arrive(trial.world.cell(trial.candidates[0]))
    assert not r.result.goal_reached
    assert (r.policy.belief.goal_marginal() == before).all()
    r._arrive(trial.world.cell(trial.goal))
    assert r.result.goal_reached
