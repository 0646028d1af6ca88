"""End-to-end tests of every user command, and their one-line errors with exit status 2."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from pathpref.apps.cli import main


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pathpref", *args], capture_output=True,
                          text=True, timeout=600)


def test_map_info_json(capsys):
    assert main(["map", "info", "office", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert {k: info[k] for k in ("name", "polytopes", "edges", "free_cells")} == {
        "name": "office", "polytopes": 56, "edges": 73, "free_cells": 75}


def test_map_draw_builtin_and_rotated_user_file(tmp_path, capsys):
    out = tmp_path / "m.png"
    assert main(["map", "draw", "classroom", "--out", str(out)]) == 0
    assert out.stat().st_size > 10_000
    capsys.readouterr()
    user = tmp_path / "rotated.json"
    user.write_text(json.dumps({"name": "rotated", "width": 12, "height": 9, "obstacles": [
        {"vertices": [[3.0, 2.0], [5.5, 3.2], [4.3, 5.7], [1.8, 4.5]]},
        {"vertices": [[8, 2], [10.5, 4], [7.5, 6]]}],
        "preference": {"route": [[1, 1], [12, 1], [12, 9], [1, 9]]}}))
    assert main(["map", "info", str(user), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["polytopes"] > 10 and info["has_preference"]
    out2 = tmp_path / "r.png"
    assert main(["map", "draw", str(user), "--out", str(out2)]) == 0
    assert out2.stat().st_size > 10_000


@pytest.mark.parametrize("args,msg", [
    (["map", "info", "nowhere.json"], "no map named"),
    (["map", "draw", "simple", "--out", "/nonexistent/dir/m.png"], "does not exist"),
    (["map", "draw", "simple", "--out", "m.txt"], ".png"),
    (["evaluate", "--methods", "telepathy", "--db", "x.sqlite"], "unknown method"),
    (["evaluate", "--delta-t", "0", "--db", "x.sqlite"], "delta-t"),
    (["evaluate", "--t-max", "0", "--db", "x.sqlite"], "t-max"),
    (["evaluate", "--goals", "500", "--db", "x.sqlite", "--instances", "1", "--runs", "1"],
     "too few candidate"),
    (["report", "missing.sqlite"], "no results database"),
    (["evaluate", "--preset", "turbo", "--db", "x.sqlite"], "invalid choice: 'turbo'"),
    (["evaluate", "--runs", "abc", "--db", "x.sqlite"], "--runs must be an integer"),
    (["evaluate", "--runs", "0", "--db", "x.sqlite"], "in 1..1000000, got 0"),
    (["evaluate", "--workers", "0", "--db", "x.sqlite", "--runs", "1", "--instances", "1"],
     "--workers"),
    (["evaluate", "--backend", "cloud", "--db", "x.sqlite", "--runs", "1", "--instances", "1"],
     "unknown backend"),
    (["evaluate", "--ucb-c", "0", "--db", "x.sqlite"], "--ucb-c"),
    (["evaluate", "--time-budget-ms", "0", "--db", "x.sqlite"], "--time-budget-ms"),
    (["evaluate", "--time-budget-ms", "-5", "--db", "x.sqlite"], "--time-budget-ms"),
    (["evaluate", "--human", "friendly", "--db", "x.sqlite"], "invalid choice: 'friendly'"),
    (["evaluate", "--episode-timeout", "-1", "--db", "x.sqlite"], "--episode-timeout"),
    (["evaluate", "--queries", "0", "--db", "x.sqlite"], "--queries"),
    (["evaluate", "--map", "nomap.json", "--db", "x.sqlite"], "no map named"),
    (["evaluate", "--db", "/nonexistent/dir/x.sqlite", "--runs", "1", "--instances", "1"],
     "does not exist"),
    (["map", "info"], "the following arguments are required"),
    (["frobnicate"], "invalid choice"),
    (["timing", "--maps", "nomap", "--instances", "1"], "no map named"),
    (["belief-curves", "--out", "/nonexistent/f.png", "--runs", "1"], "does not exist"),
])
def test_bad_input_exits_2_with_one_line(tmp_path, args, msg):
    p = subprocess.run([sys.executable, "-m", "pathpref", *args], capture_output=True,
                       text=True, cwd=tmp_path, timeout=300)
    assert p.returncode == 2, p.stderr
    lines = [ln for ln in p.stderr.strip().splitlines() if ln]
    assert len(lines) == 1 and msg in lines[0] and "Traceback" not in p.stderr
    assert not (tmp_path / "x.sqlite").exists()


def one_line_error(p: subprocess.CompletedProcess, msg: str) -> None:
    assert p.returncode == 2, p.stderr
    lines = [ln for ln in p.stderr.strip().splitlines() if ln]
    assert len(lines) == 1 and msg in lines[0] and "Traceback" not in p.stderr


def test_databases_from_elsewhere_are_refused_and_untouched(tmp_path):
    notes = tmp_path / "notes.sqlite"
    notes.write_text("not a database")
    one_line_error(run("report", str(notes)), "not SQLite")
    one_line_error(run("evaluate", "--db", str(notes), "--runs", "1", "--instances", "1"),
                   "not SQLite")
    assert notes.read_text() == "not a database"
    import sqlite3

    from pathpref.experiments.store import ResultStore

    old = tmp_path / "old.sqlite"
    ResultStore(old).close()
    with sqlite3.connect(old) as c:
        c.execute("UPDATE meta SET value = '99' WHERE key = 'schema_version'")
    before = old.read_bytes()
    one_line_error(run("evaluate", "--db", str(old), "--runs", "1", "--instances", "1"),
                   "incompatible")
    one_line_error(run("report", str(old)), "incompatible")
    assert old.read_bytes() == before


def test_map_without_preference_and_no_partial_outputs(tmp_path):
    m = tmp_path / "nopref.json"
    m.write_text(json.dumps({"name": "nopref", "width": 6, "height": 6, "obstacles": []}))
    p = subprocess.run([sys.executable, "-m", "pathpref", "evaluate", "--map", str(m),
                        "--db", "r.sqlite", "--runs", "1", "--instances", "1"],
                       capture_output=True, text=True, cwd=tmp_path, timeout=300)
    one_line_error(p, "has no 'preference'")
    assert not (tmp_path / "r.sqlite").exists()
    p = subprocess.run([sys.executable, "-m", "pathpref", "evaluate", "--map", str(m),
                        "--methods", "oracle", "--db", "r.sqlite", "--runs", "1",
                        "--instances", "1"], capture_output=True, text=True, cwd=tmp_path,
                       timeout=300)
    one_line_error(p, "has no 'preference'")
    assert not (tmp_path / "r.sqlite").exists()
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        import os

        if os.access(ro, os.W_OK):  # running as root: permissions do not bind
            return
        one_line_error(run("map", "draw", "simple", "--out", str(ro / "m.png")), "not writable")
        assert list(ro.iterdir()) == []
    finally:
        ro.chmod(0o700)


def test_bad_map_file_exits_2(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"width": 5, "height": 5, "obstacles": [
        {"vertices": [[1, 1], [4, 1], [2, 2], [4, 3], [1, 3]]}]}))
    p = run("map", "info", str(bad))
    assert p.returncode == 2 and "obstacle 1 is not convex" in p.stderr


def test_evaluate_report_end_to_end(tmp_path):
    db = tmp_path / "r.sqlite"
    p = run("evaluate", "--map", "simple", "--methods", "all", "--delta-t", "1", "10",
            "--instances", "2", "--runs", "2", "--queries", "300", "--db", str(db),
            "--workers", "2", "--no-progress")
    assert p.returncode == 0, p.stderr
    assert "| path preference |" in p.stdout and "32 episodes run" in p.stdout
    p = run("report", str(db), "--figure", str(tmp_path / "t1.png"))
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "t1.png").exists() and db.with_suffix(".csv").exists()
    rows = db.with_suffix(".csv").read_text().splitlines()
    assert len(rows) == 1 + 4 * 2


def test_timing_and_belief_curves(tmp_path):
    p = run("timing", "--maps", "simple", "classroom", "--instances", "3", "--queries", "300",
            "--json", "--no-progress")
    assert p.returncode == 0, p.stderr
    res = json.loads(p.stdout)
    assert [r["map"] for r in res] == ["simple", "classroom"] and res[1]["depth"] == 60
    assert all(r["solve_path_pref_ms"] > 0 and r["update_path_pref_ms"] > 0 for r in res)
    out = tmp_path / "fig4.png"
    p = run("belief-curves", "--out", str(out), "--runs", "3", "--queries", "300",
            "--no-progress", "--workers", "2")
    assert p.returncode == 0, p.stderr
    assert out.exists() and Path(str(out.with_suffix(".sqlite"))).exists()
    assert "path_preference" in p.stdout


def test_demo_grid(tmp_path):
    p = run("demo", "--out", str(tmp_path / "out"), "--sim", "grid", "--runs", "4")
    assert p.returncode == 0, p.stderr
    for f in ("map_simple.png", "trajectories.png", "belief.png", "summary.csv", "rates.csv"):
        assert (tmp_path / "out" / f).stat().st_size > 0
    assert "| path_preference |" in p.stdout
    import csv

    rates = {r["method"]: r for r in csv.DictReader(open(tmp_path / "out" / "rates.csv"))}
    assert rates["oracle"]["success"] == "1.0"  # the demo's human is consistent by design
    for m, r in rates.items():
        wins = round(float(r["success"]) * 4)
        assert wins + int(r["other_route"]) + int(r["not_reached"]) == 4
        line = next(ln for ln in p.stdout.splitlines() if ln.startswith(f"- {m}: "))
        assert f"by the preferred route in {wins}/4 runs" in line


def test_report_puts_grid_and_physics_side_by_side(tmp_path):
    db = tmp_path / "both.sqlite"
    for sim in ("grid", "mujoco"):
        p = run("evaluate", "--map", "simple", "--methods", "compliant", "--delta-t", "2",
                "--instances", "1", "--runs", "2", "--db", str(db), "--sim", sim,
                "--workers", "2", "--no-progress")
        assert p.returncode == 0, p.stderr
    p = run("report", str(db))
    assert p.returncode == 0, p.stderr
    assert "grid / mujoco side by side" in p.stdout
    row = next(ln for ln in p.stdout.splitlines() if ln.startswith("| compliant |") and "/" in ln)
    assert len(row.split("/")) == 2


def _subparsers(parser, prefix=()):
    import argparse

    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield (*prefix, name), sub
                yield from _subparsers(sub, (*prefix, name))


def test_every_option_has_help_and_its_default():
    """Every listed option of every command has help text; one with a default (not None, not
    a switch) shows it in --help; ``render --help`` lists no sweep-only option."""
    import argparse

    from pathpref.apps.cli import build_parser

    missing = []
    for names, sub in _subparsers(build_parser()):
        text = " ".join(sub.format_help().split())
        for a in sub._actions:
            if not a.option_strings or a.help == argparse.SUPPRESS or a.dest == "help":
                continue
            if not a.help:
                missing.append(f"{' '.join(names)} {a.option_strings[0]}: no help")
            elif (a.default is not None and not isinstance(a, argparse._StoreTrueAction)
                  and "default" not in " ".join(a.help.split())):
                shown = " ".join(map(str, a.default)) if isinstance(a.default, list) \
                    else str(a.default)
                if f"(default: {shown})" not in text:
                    missing.append(f"{' '.join(names)} {a.option_strings[0]}: no default")
    assert not missing, missing
    render = build_parser()._subparsers._group_actions[0].choices["render"].format_help()
    assert "--workers" not in render and "--episode-timeout" not in render
    assert "--size WxH" in render
    evaluate = " ".join(build_parser()._subparsers._group_actions[0].choices["evaluate"]
                        .format_help().split())
    assert "(default: 50)" in evaluate and "6000" in evaluate


def test_version(capsys):
    """``pathpref --version`` prints the package's version (the one pathpref.__version__ and
    the installed metadata carry)."""
    import pytest

    import pathpref
    from pathpref.apps.cli import main

    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0
    assert capsys.readouterr().out.strip() == f"pathpref {pathpref.__version__}"
    import tomllib
    from pathlib import Path

    pyproject = Path(__file__).resolve().parents[1] / "pyproject.toml"
    wanted = tomllib.loads(pyproject.read_text())["project"]["version"]
    assert pathpref.__version__ == wanted, \
        "the installed metadata is older than pyproject.toml: run make install again"


def test_examples_are_copied_out_and_never_overwritten(tmp_path, capsys):
    """``pathpref examples DEST`` (source checkout) copies examples/*.py, *.json and
    maps/*.json byte for byte; a second copy into the same folder is one line and writes
    nothing; a file as DEST is one line."""
    from pathlib import Path

    from pathpref.apps.cli import main

    root = Path(__file__).resolve().parents[1] / "examples"
    want = sorted(p.relative_to(root).as_posix() for p in [*root.glob("*.py"),
                  *root.glob("*.json"), *root.glob("maps/*.json")] if p.name != "__init__.py")
    dest = tmp_path / "ex"
    assert main(["examples", str(dest)]) == 0
    got = sorted(p.relative_to(dest).as_posix() for p in dest.rglob("*") if p.is_file())
    assert got == want and "maps/hall.json" in got
    assert all((dest / f).read_bytes() == (root / f).read_bytes() for f in got)
    capsys.readouterr()
    (dest / "tutorial.py").write_text("# mine\n")
    assert main(["examples", str(dest)]) == 2
    err = capsys.readouterr().err
    assert "exists already" in err and err.count("\n") == 1
    assert (dest / "tutorial.py").read_text() == "# mine\n"
    assert main(["examples", str(dest / "tutorial.py")]) == 2
    assert "is a file" in capsys.readouterr().err


def test_map_generate_writes_a_plan_that_loads_and_refuses_a_fragmented_one(tmp_path, capsys):
    from pathpref.episode.instances import sample_instance
    from pathpref.geometry.world import load_world

    out = tmp_path / "plan.json"
    assert main(["map", "generate", "--seed", "9001", "--out", str(out)]) == 0
    plan = json.loads(out.read_text())
    assert (plan["width"], plan["height"], plan["preference"]["closed"]) == (24, 16, False)
    # the defaults are the held-out plans': the same obstacles as the stored one; its route
    # is drawn in the robot's free area (the stored one was drawn for a point robot)
    stored = json.loads(Path("docs/results/heldout_plans/heldout_9001.json").read_text())
    assert plan["obstacles"] == stored["obstacles"] and plan["preference"] != stored["preference"]
    world = load_world(str(out))
    assert world.preference is not None
    inst = sample_instance(world, 3, 10, consistent=True, t_max=world.spec.t_max)
    assert len(set(inst.goals)) == 10 and inst.start not in inst.goals
    capsys.readouterr()
    assert main(["map", "generate", "--seed", "5", "--route", "loop", "--rotated", "3",
                 "--boxes", "1", "--width", "12", "--height", "10"]) == 0
    loop = json.loads(capsys.readouterr().out)  # no --out: the JSON on stdout
    assert loop["preference"]["closed"] is True and len(loop["obstacles"]) == 4
    assert (loop["width"], loop["height"]) == (12, 10)
    load_world(loop)
    p = run("map", "generate", "--seed", "1", "--width", "8", "--height", "6", "--rotated",
            "10", "--boxes", "3", "--sizes", "2", "4")
    assert p.returncode == 2 and p.stderr.count("\n") == 1
    assert "too fragmented to place a route: its largest free area has 7 cells" in p.stderr
    p = run("map", "generate", "--width", "2")
    assert p.returncode == 2 and "--width must be an integer in 4..200, got 2" in p.stderr


def test_study_run_refuses_the_tidybot_with_the_study_files_reason(capsys, tmp_path):
    """``study run --robot-model tidybot`` is one line giving the reason a study file's
    ``robot_model`` gets (one message, :func:`pathpref.study.plan.disk_only`), exit 2, nothing
    created; the simulated human's flags get the study file's reason too."""
    import pytest

    from pathpref.apps.cli import main
    from pathpref.errors import ConfigError
    from pathpref.study.plan import NOT_THE_PARTICIPANT, disk_only, parse_study

    db = tmp_path / "s.sqlite"
    base = ["study", "run", "examples/study_demo.json", "--participant", "p", "--db", str(db)]
    with pytest.raises(SystemExit) as e:
        main([*base, "--robot-model", "tidybot"])
    err = capsys.readouterr().err
    assert e.value.code == 2 and err.count("\n") == 1 and "Traceback" not in err
    assert disk_only("tidybot") in err and "episodes, the tasks and the videos" in err
    t = {"name": "a", "map": "simple", "start": [5, 2], "goal": [5, 9],
         "candidates": [[2, 9], [5, 9], [9, 9]], "route": [[5, 2], [5, 9]],
         "physics": {"robot_model": "tidybot"}}
    with pytest.raises(ConfigError) as f:
        parse_study({"trials": [t]})
    assert str(f.value).endswith(disk_only("tidybot"))
    for extra, says in ((["--gamma-h", "2"], NOT_THE_PARTICIPANT),
                        (["--sensor", "ideal"], '"physics": {"sensor": ...}'),
                        (["--use-strength"], '"physics": {"use_strength": ...}')):
        with pytest.raises(SystemExit) as e:
            main([*base, *extra])
        err = capsys.readouterr().err
        assert e.value.code == 2 and err.count("\n") == 1 and says in err, (extra, err)
    assert not db.exists()


def test_a_sensor_override_states_its_default_as_the_presets():
    """The sensor's fault overrides are stored as -1 ("the --sensor preset's"); their help says
    that, never "default -1"."""
    from pathpref.apps.cli import build_parser

    sub = build_parser()._subparsers._group_actions[0].choices["evaluate"]
    text = " ".join(sub.format_help().split())
    for name in ("--sensor-noise-n", "--sensor-bias-n", "--sensor-drift-n"):
        assert re.search(re.escape(name) + r" X \d+\.\.\d+, default: the --sensor preset's",
                         text), name
    assert "default -1" not in text
