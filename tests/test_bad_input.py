"""Hostile and out-of-range input: one line, exit status 2 (a ValueError subclass from the
Python API), and the working folder left exactly as it was. Nothing big is ever built: every
case is refused before work."""

from __future__ import annotations

import errno
import importlib.util
import json
import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from pathpref.apps import checks
from pathpref.apps.cli import main
from pathpref.episode import EpisodeSpec
from pathpref.errors import ConfigError, MapError, PathprefError
from pathpref.geometry.maps import MAX_NAME, load_map, parse_map

ROOT = Path(__file__).resolve().parents[1]


def snapshot(folder: Path) -> dict[str, bytes | None]:
    """Names and bytes of everything in ``folder`` (None for non-regular entries)."""
    out = {}
    for p in sorted(folder.rglob("*")):
        out[str(p.relative_to(folder))] = p.read_bytes() if p.is_file() and not \
            p.is_symlink() and p.suffix != "" and p.stat().st_size < 2**22 else None
    return out


def refuse(tmp_path, capsys, argv, msg, *, chdir=True, monkeypatch=None) -> str:
    """Run the CLI in-process in ``tmp_path``; assert exit 2, one stderr line holding ``msg``,
    and an unchanged folder."""
    before = snapshot(tmp_path)
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        try:
            rc = main(argv)
        except SystemExit as e:  # argparse errors
            rc = e.code
    finally:
        os.chdir(cwd)
    err = capsys.readouterr().err
    lines = [ln for ln in err.strip().splitlines() if ln]
    assert rc == 2, err
    assert len(lines) == 1, err
    assert lines[0].startswith("pathpref: error: ") and msg in lines[0], err
    assert snapshot(tmp_path) == before
    return lines[0]


def write(path: Path, raw) -> str:
    path.write_text(raw if isinstance(raw, str) else json.dumps(raw))
    return str(path)


# --- 1. map loading -------------------------------------------------------------------------
@pytest.mark.parametrize("make, msg", [
    (lambda d: write(d / "deep.json", "[" * 100_000 + "]" * 100_000), "nests lists/objects"),
    (lambda d: write(d / "deep2.json", {"width": 5, "height": 5,
                                        "description": "", "preference": json.loads(
                                            "[" * 100 + "]" * 100)}), "more than 32 levels"),
    (lambda d: write(d / "int.json", '{"width": ' + "9" * 5000 + ', "height": 5}'),
     "an integer of 5000 digits"),
    (lambda d: write(d / "cells.json", {"width": 5, "height": 5, "obstacles": [
        {"cells": {"lower_left": [1, 1], "size": [10**20, 1]}}]}), "an integer of 21 digits"),
    (lambda d: write(d / "cells2.json", {"width": 5, "height": 5, "obstacles": [
        {"cells": {"lower_left": [1, 1], "size": [10**17, 1]}}]}), "do not fit in the 5 x 5 map"),
    (lambda d: write(d / "cells3.json", {"width": 5, "height": 5, "obstacles": [
        {"cells": {"lower_left": [0, 1], "size": [1, 1]}}]}), "do not fit in the 5 x 5 map"),
    (lambda d: write(d / "huge.json", {"width": 5, "height": 5, "obstacles": [
        {"vertices": [[1e308, 1], [2, 1], [2, 2]]}]}), "x = 1e+308 is out of range"),
    (lambda d: write(d / "huge2.json", {"width": 5, "height": 5, "obstacles": [
        {"vertices": [[1, 1], [2, 1], [2, -1e300]]}]}), "vertex 3 y = -1e+300 is out of range"),
    (lambda d: write(d / "outside.json", {"width": 5, "height": 5, "obstacles": [
        {"vertices": [[1, 1], [7, 1], [2, 2]]}]}), "extends outside the map (vertex at (7, 1)"),
    (lambda d: write(d / "inf.json", '{"width": 5, "height": 5, "obstacles": [{"vertices": '
                     '[[1, 1], [Infinity, 1], [2, 2]]}]}'), "coordinates must be finite"),
    (lambda d: write(d / "side.json", {"width": 501, "height": 5}), "between 1 and 500"),
    (lambda d: write(d / "float.json", {"width": 5.5, "height": 5}), "whole number of cells"),
    (lambda d: write(d / "name.json", {"name": "x" * 1_000_000, "width": 5, "height": 5}),
     f"at most {MAX_NAME} are allowed"),
    (lambda d: write(d / "ctl.json", {"name": "a\nb", "width": 5, "height": 5}),
     "must be printable text"),
    (lambda d: write(d / "many.json", {"width": 5, "height": 5, "obstacles": [
        {"cells": {"lower_left": [1, 1], "size": [1, 1]}}] * 10_001}), "at most 10000 are"),
    (lambda d: write(d / "verts.json", {"width": 5, "height": 5, "obstacles": [
        {"vertices": [[1, 1]] * 1001}]}), "1001 vertices"),
    (lambda d: ((d / "bad.bin").write_bytes(b"\xff\xfe{}"), str(d / "bad.bin"))[1],
     "not UTF-8 text"),
    (lambda d: str(d), "is a folder"),
    (lambda d: "/dev/zero", "is not a regular file"),
    (lambda d: "x" * 5000, "no map named"),
])
def test_bad_map_files_refused(tmp_path, capsys, make, msg):
    src = make(tmp_path)
    refuse(tmp_path, capsys, ["map", "info", src], msg)
    with pytest.raises(MapError) as e:
        load_map(src)
    assert isinstance(e.value, ValueError) and msg in str(e.value)


def test_fifo_map_does_not_block(tmp_path, capsys):
    fifo = tmp_path / "pipe.json"
    os.mkfifo(fifo)
    refuse(tmp_path, capsys, ["map", "info", str(fifo)], "is not a regular file")


def test_oversized_map_file(tmp_path, capsys):
    big = tmp_path / "big.json"
    with open(big, "wb") as f:
        f.truncate(10 * 2**20 + 1)  # sparse: nothing is written
    refuse(tmp_path, capsys, ["map", "info", str(big)], "above the limit of 10,485,760")


def test_huge_coordinates_no_numpy_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(MapError, match="out of range"):
            parse_map({"width": 5, "height": 5, "obstacles": [
                {"vertices": [[1e308, 1e308], [-1e308, 1e308], [0, -1e308]]}]})


def test_dict_maps_with_huge_python_ints():
    with pytest.raises(MapError, match="integer of"):
        parse_map({"width": 10**5000, "height": 5})
    with pytest.raises(MapError, match="out of range"):
        parse_map({"width": 5, "height": 5, "obstacles": [{"vertices": [[10**400, 1], [2, 1],
                                                                         [2, 2]]}]})
    with pytest.raises(MapError, match="goal_band.x"):
        parse_map({"width": 5, "height": 5, "goal_band": {"x": [1, 10**5000]}})


def test_evaluate_with_bad_map_leaves_no_database(tmp_path, capsys):
    m = write(tmp_path / "deep.json", "[" * 100_000 + "]" * 100_000)
    refuse(tmp_path, capsys, ["evaluate", "--map", m, "--db", "r.sqlite", "--runs", "1",
                              "--instances", "1"], "nests lists/objects")


# --- 2. size of the arrangement and of the tables -------------------------------------------
def tiny_obstacles(n: int, side: int = 500) -> dict:
    rng = np.random.default_rng(0)
    obs = []
    for x, y in rng.integers(0, side - 1, size=(n, 2)):
        ang = rng.uniform(0, np.pi)
        c, s = np.cos(ang) * 0.2, np.sin(ang) * 0.2
        cx, cy = x + 0.5, y + 0.5
        obs.append({"vertices": [[cx + c, cy + s], [cx - s, cy + c], [cx - c, cy - s]]})
    return {"name": "tiny", "width": side, "height": side, "obstacles": obs}


@pytest.mark.parametrize("n", [200, 3000])
def test_many_tiny_obstacles_refused_before_building(tmp_path, capsys, n):
    m = write(tmp_path / "tiny.json", tiny_obstacles(n))
    line = refuse(tmp_path, capsys, ["map", "info", m], "above the limit 100,000")
    assert "--force" in line
    refuse(tmp_path, capsys, ["map", "draw", m, "--out", "m.png"], "above the limit 100,000")
    refuse(tmp_path, capsys, ["evaluate", "--map", m, "--db", "r.sqlite", "--runs", "1",
                              "--instances", "1"], "above the limit 100,000")


def test_force_builds_and_progress_line(tmp_path, capsys, monkeypatch):
    from pathpref.geometry import arrangement

    monkeypatch.setattr(arrangement, "MAX_POLYTOPES", 5)
    refuse(tmp_path, capsys, ["map", "info", "office"], "above the limit 5")
    assert main(["map", "info", "office", "--force", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["polytopes"] == 56


def test_model_tables_refused_up_front(tmp_path, capsys, monkeypatch):
    from pathpref.inference import human

    monkeypatch.setattr(human, "MAX_TABLE_BYTES", 10_000)
    refuse(tmp_path, capsys, ["evaluate", "--map", "simple", "--db", "r.sqlite", "--runs", "1",
                              "--instances", "1"], "likelihood tables for 96 cells")


def test_biggest_allowed_map_table_estimate():
    """A 500 x 500 map whose polytope has many neighbours needs hundreds of GiB: refused by
    the estimate, without allocating (a stand-in world with the counts)."""
    class Graph:
        max_degree = 1019

    class W:
        name, n_cells, graph = "big", 250_000, Graph()

    with pytest.raises(ConfigError, match="GiB, above the limit"):
        checks.check_model_size(W(), 10)


# --- 3. map names in figures ----------------------------------------------------------------
def test_mathtext_map_name_draws(tmp_path, capsys):
    m = write(tmp_path / "math.json", {"name": r"$\frac{", "width": 4, "height": 4})
    assert main(["map", "draw", m, "--out", str(tmp_path / "m.png")]) == 0
    assert (tmp_path / "m.png").stat().st_size > 1000


# --- 4. numbers on the command line ---------------------------------------------------------
@pytest.mark.parametrize("argv, msg", [
    (["evaluate", "--delta-t", str(10**30)], "--delta-t must be an integer in 1..100000, got 1"),
    (["evaluate", "--delta-t", "5", "0"], "--delta-t must be an integer in 1..100000, got 0"),
    (["evaluate", "--t-max", str(10**30)], "--t-max must be an integer in 1..100000"),
    (["evaluate", "--queries", str(2**64)],
     "--queries must be an integer in 1..10000000, got 18446744073709551616"),
    (["evaluate", "--queries", "0"], "--queries must be an integer in 1..10000000, got 0"),
    (["evaluate", "--seed", "-1"], "--seed must be an integer in 0..9223372036854775807, got -1"),
    (["evaluate", "--seed", str(2**63)], "--seed must be an integer in 0..9223372036854775807"),
    (["evaluate", "--runs", str(10**12)], "--runs must be an integer in 1..1000000"),
    (["evaluate", "--runs", "abc"], "--runs must be an integer in 1..1000000, got 'abc'"),
    (["evaluate", "--runs", "9" * 5000], "--runs must be an integer in 1..1000000"),
    (["evaluate", "--runs", "1000000", "--instances", "1000"],
     "above the limit of 10,000,000"),
    (["evaluate", "--instances", "0"], "--instances must be an integer in 1..1000000, got 0"),
    (["evaluate", "--goals", "0"], "--goals must be an integer in 1..1000, got 0"),
    (["evaluate", "--workers", "0"], "--workers must be an integer in 1..1024, got 0"),
    (["evaluate", "--ucb-c", "nan"], "--ucb-c must be a number in 1e-06..1e+06, got nan"),
    (["evaluate", "--ucb-c", "inf"], "--ucb-c must be a number"),
    (["evaluate", "--time-budget-ms", "-5"], "--time-budget-ms must be a number"),
    (["evaluate", "--episode-timeout", "-1"], "--episode-timeout must be 0 (none) or a number"),
    (["timing", "--instances", "0"], "--instances must be an integer in 1..1000000, got 0"),
    (["timing", "--queries", "0"], "--queries must be an integer in 1..10000000, got 0"),
    (["belief-curves", "--episode-timeout", "1e-9"],
     "--episode-timeout must be 0 (none) or a number in 1..1e+06, got 1e-09"),
    (["belief-curves", "--delta-t", "0"], "--delta-t must be an integer"),
    (["belief-curves", "--runs", "0"], "--runs must be an integer"),
    (["render", "--width", "100000", "--out", "v.mp4"], "--width must be an integer in 16..4096"),
    (["render", "--queries", str(2**64), "--out", "v.mp4"], "--queries must be an integer"),
    (["interact", "--seed", "-1"], "--seed must be an integer"),
    (["demo", "--runs", "0"], "--runs must be an integer in 1..1000000, got 0"),
    (["demo", "--seed", "-3"], "--seed must be an integer"),
])
def test_numbers_refused_at_parse_time(tmp_path, capsys, argv, msg):
    refuse(tmp_path, capsys, [*argv, *(["--db", "r.sqlite"] if argv[0] == "evaluate" else [])],
           msg)


def test_numbers_refused_in_a_subprocess(tmp_path):
    p = subprocess.run([sys.executable, "-m", "pathpref", "evaluate", "--queries", str(2**64),
                        "--db", "r.sqlite"], capture_output=True, text=True, cwd=tmp_path,
                       timeout=120, env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert p.returncode == 2 and "Traceback" not in p.stderr
    assert p.stderr.strip().splitlines() == [
        "pathpref: error: --queries must be an integer in 1..10000000, got "
        "18446744073709551616 (see 'pathpref evaluate --help')"]
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("field, value, msg", [
    ("delta_t", 10**30, "--delta-t must be an integer in 1..100000"),
    ("delta_t", "5", "--delta-t must be an integer in 1..100000, got '5'"),
    ("delta_t", 5.0, "--delta-t must be an integer"),
    ("t_max", 0, "--t-max must be an integer in 1..100000, got 0"),
    ("queries", 2**64, "--queries must be an integer in 1..10000000, got 18446744073709551616"),
    ("queries", True, "--queries must be an integer"),
    ("n_goals", 0, "--goals must be an integer in 1..1000"),
    ("run_seed", -1, "run_seed must be an integer in 0..9223372036854775807, got -1"),
    ("instance_seed", 2**64, "instance_seed must be an integer"),
    ("ucb_c", float("nan"), "--ucb-c must be a number"),
    ("timeout_s", float("inf"), "--episode-timeout must be a number in 0..1e+06"),
    ("timeout_s", -1.0, "--episode-timeout must be a number"),
    ("time_budget_ms", float("nan"), "--time-budget-ms must be a number"),
    ("map", {"width": 3}, "map must be a string"),
])
def test_episode_spec_validate_limits(field, value, msg):
    fields = {"map": "simple", "method": "goal_only", "delta_t": 5, "instance": 0, "run": 0,
              "instance_seed": 0, "run_seed": 0}
    spec = EpisodeSpec(**{**fields, field: value})
    with pytest.raises(ConfigError) as e:
        spec.validate()
    assert isinstance(e.value, ValueError) is isinstance(e.value, PathprefError)
    assert msg in str(e.value) and "\n" not in str(e.value)


def test_episode_spec_numpy_ints_pass():
    EpisodeSpec(map="simple", method="goal_only", delta_t=np.int64(5), instance=0, run=0,
                instance_seed=np.int64(3), run_seed=0, queries=np.int32(10)).validate()


# --- 5. outputs -----------------------------------------------------------------------------
@pytest.mark.parametrize("argv, msg", [
    (["evaluate", "--db", "sub", "--runs", "1", "--instances", "1"], "--db sub is a folder"),
    (["evaluate", "--db", "/dev/null", "--runs", "1", "--instances", "1"],
     "--db /dev/null is a device"),
    (["evaluate", "--db", "missing/r.sqlite", "--runs", "1", "--instances", "1"],
     "folder missing does not exist"),
    (["belief-curves", "--out", "sub", "--runs", "1"], "--out sub is a folder"),
    (["belief-curves", "--out", "sub.png", "--runs", "1"], "--out sub.png is a folder"),
    (["belief-curves", "--out", "f.png", "--db", "/dev/null", "--runs", "1"],
     "--db /dev/null is a device"),
    (["belief-curves", "--out", "fig.txt", "--runs", "1"], "unsupported file type '.txt'"),
    (["map", "draw", "simple", "--out", "sub"], "--out sub is a folder"),
    (["map", "draw", "simple", "--out", "sub/"], "--out 'sub/': give a file name, not a folder"),
    (["map", "draw", "simple", "--out", "sub.png"], "--out sub.png is a folder"),
    (["map", "draw", "simple", "--out", "fig.txt"],
     "--out fig.txt: unsupported file type '.txt'; use a file name ending in .png, .pdf, .svg"),
    (["map", "draw", "simple", "--out", "/dev/null"], "is a device"),
    (["report", "db.sqlite", "--figure", "fig.txt"], "--figure fig.txt: unsupported file type"),
    (["report", "db.sqlite", "--figure", "sub.png"], "--figure sub.png is a folder"),
    (["report", "db.sqlite", "--csv", "sub.csv"], "--csv sub.csv is a folder"),
    (["report", "db.sqlite", "--csv", "out.txt"], "--csv out.txt: unsupported file type"),
    (["report", "sub"], "database sub is a folder"),
    (["report", "/dev/null"], "database /dev/null is a device"),
    (["report", "none.sqlite"], "no results database at none.sqlite"),
    (["demo", "--out", "file.txt", "--sim", "grid"], "--out file.txt exists and is not a folder"),
    (["demo", "--out", "missing/out", "--sim", "grid"], "folder missing does not exist"),
    (["render", "--out", "v.avi"], "--out v.avi: unsupported file type"),
    (["render", "--out", "sub.mp4"], "--out sub.mp4 is a folder"),
    (["render", "--rerun", "r.txt"], "--rerun r.txt: unsupported file type"),
    (["render"], "give --out video.mp4 and/or --rerun"),
])
def test_outputs_checked_before_work(tmp_path, capsys, argv, msg):
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub.png").mkdir()
    (tmp_path / "sub.csv").mkdir()
    (tmp_path / "sub.mp4").mkdir()
    (tmp_path / "file.txt").write_text("keep me")
    (tmp_path / "db.sqlite").write_bytes(b"")  # checked as a path only
    refuse(tmp_path, capsys, argv, msg)


def test_check_writable_and_folder_helpers(tmp_path):
    (tmp_path / "d").mkdir()
    with pytest.raises(ConfigError, match="is a folder"):
        checks.check_writable(tmp_path / "d", "--out")
    with pytest.raises(ConfigError, match="give a file name, not a folder"):
        checks.check_writable(str(tmp_path) + os.sep, "--out")
    assert checks.check_output_folder(tmp_path / "new") == tmp_path / "new"
    assert not (tmp_path / "new").exists()


# --- 6. temporary files ---------------------------------------------------------------------
def test_staged_outputs_never_use_a_predictable_name(tmp_path):
    out = tmp_path / "x.mp4"
    victim = tmp_path / "victim.txt"
    victim.write_text("secret")
    (tmp_path / ".x.partial.mp4").symlink_to(victim)  # the old fixed name
    with checks.staged_outputs([out, None]) as (tmp, none):
        assert none is None and tmp.parent == tmp_path and tmp.name != ".x.partial.mp4"
        assert not tmp.is_symlink() and tmp.stat().st_size == 0
        tmp.write_bytes(b"video")
    assert out.read_bytes() == b"video" and victim.read_text() == "secret"
    assert sorted(p.name for p in tmp_path.iterdir()) == [".x.partial.mp4", "victim.txt",
                                                          "x.mp4"]


def test_render_does_not_write_through_a_planted_symlink(tmp_path):
    """The old fixed temp name, planted as a symlink to a victim file: render (end to end, a
    two-step MuJoCo episode) leaves the victim alone and writes its video."""
    victim = tmp_path / "victim.txt"
    victim.write_text("secret")
    (tmp_path / ".x.partial.mp4").symlink_to(victim)
    p = subprocess.run([sys.executable, "-m", "pathpref", "render", "--map", "simple",
                        "--method", "compliant", "--t-max", "2", "--queries", "10", "--width",
                        "64", "--height", "48", "--out", "x.mp4"], cwd=tmp_path,
                       capture_output=True, text=True, timeout=300,
                       env={**os.environ, "MUJOCO_GL": "egl", "PYTHONPATH": str(ROOT)})
    assert p.returncode == 0, p.stderr
    assert victim.read_text() == "secret"
    assert (tmp_path / "x.mp4").stat().st_size > 0


# --- 7. MUJOCO_GL ---------------------------------------------------------------------------
@pytest.mark.parametrize("argv", [["render", "--out", "v.mp4"],
                                  ["evaluate", "--sim", "mujoco", "--db", "r.sqlite",
                                   "--runs", "1", "--instances", "1"]])
def test_bogus_mujoco_gl(tmp_path, argv):
    env = {**os.environ, "MUJOCO_GL": "bogus", "PYTHONPATH": str(ROOT)}
    p = subprocess.run([sys.executable, "-m", "pathpref", *argv], capture_output=True,
                       text=True, cwd=tmp_path, timeout=300, env=env)
    assert p.returncode == 2 and "Traceback" not in p.stderr, p.stderr
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and "MUJOCO_GL='bogus' is not a rendering backend" in lines[0]
    assert "egl, osmesa, glfw or disable" in lines[0]
    assert os.listdir(tmp_path) == []


# --- 8. the dm_control tasks ----------------------------------------------------------------
@pytest.fixture(scope="module")
def tasks():
    """This tree's ``tasks`` package (the installed ``pathpref_tasks`` may be another tree's)."""
    spec = importlib.util.spec_from_file_location(
        "_pathpref_tasks_here", ROOT / "tasks" / "__init__.py",
        submodule_search_locations=[str(ROOT / "tasks")])
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


@pytest.mark.parametrize("kwargs, msg", [
    ({"delta_t": "5"}, "--delta-t must be an integer in 1..100000, got '5'"),
    ({"seed": -1}, "seed must be an integer in 0..9223372036854775807, got -1"),
    ({"seed": 2**70}, "seed must be an integer"),
    ({"t_max": 10**30}, "t_max must be an integer in 1..100000"),
    ({"queries": 0}, "--queries must be an integer"),
    ({"map": 3}, "map must be a built-in name, a JSON path or a map dictionary"),
    ({"map": {"width": 5}}, "map field 'height' is missing"),
    ({"map": "nomap.json"}, "no map named"),
])
def test_task_arguments(tasks, kwargs, msg):
    with pytest.raises(PathprefError) as e:
        tasks.load("navigate", **kwargs)
    assert isinstance(e.value, ValueError) and msg in str(e.value)


def test_task_dict_map_and_actions(tasks, tmp_path):
    before = sorted(os.listdir(tmp_path))
    raw = {"name": "room", "width": 6, "height": 5, "obstacles": [
        {"cells": {"lower_left": [3, 2], "size": [1, 2]}}],
        "preference": {"route": [[1, 1], [6, 1], [6, 5], [1, 5]]}}
    env = tasks.load("navigate", map=raw, queries=20, seed=1)
    assert env.task.world.spec.name == "room"
    ts = env.reset()
    assert ts.observation["goal_belief"].shape == (10,)
    for bad, msg in [(np.array([1, 2]), "an array of shape (2,)"), ("3", "'3'"),
                     (None, "None"), (2**70, "got"), (9, "got 9"), (-1, "got -1"),
                     (2.5, "2.5"), (float("nan"), "nan"), (True, "True")]:
        with pytest.raises(ConfigError, match="action must be 0..8") as e:
            env.step(bad)
        assert msg in str(e.value)
    for good in (np.array(3), np.int64(8), np.array([4]), 2.0, 8):
        env.step(good)
    assert sorted(os.listdir(tmp_path)) == before
    assert tasks.navigate.parse_action(np.int32(7)) == 7


DEEP = "[" * 100_000 + "]" * 100_000


def _deep_dict(levels: int) -> dict:
    d: dict = {}
    x = d
    for _ in range(levels):
        x["a"] = {}
        x = x["a"]
    return d


@pytest.mark.parametrize("kwargs, msg", [
    ({"physics": DEEP}, "physics nests lists/objects too deeply to read"),
    ({"physics": _deep_dict(100_000)}, "physics nests lists/objects too deeply to read"),
    ({"physics": '{"peak_n": ' + "9" * 400 + "}"},
     "physics peak_n (--peak-n) must be a number in 1..300, got 99999"),
    ({"physics": '{"peak_n": 1e400}'}, "physics peak_n (--peak-n) must be a number"),
    ({"physics": '{"peak_n": [1]}'}, "physics peak_n must be a number, a string or true/false"),
    ({"environment_kwargs": [1]}, "environment_kwargs must be a dict of argument names"),
    ({"task_kwargs": [1]}, "task_kwargs must be a dict of argument names"),
    ({"task_kwargs": {1: 2}}, "task_kwargs must have argument names (strings) as keys"),
])
def test_task_arguments_hostile(tasks, kwargs, msg):
    """RecursionError, OverflowError and TypeError used to escape: one ConfigError line."""
    with pytest.raises(ConfigError) as e:
        tasks.load("navigate", **{"map": "simple", **kwargs})
    assert msg in str(e.value) and "\n" not in str(e.value)


@pytest.mark.parametrize("size, msg", [
    ({"width": 5000}, "width must be at most"),
    ({"height": 5000}, "height must be at most"),
    ({"width": 0}, "width must be an integer in 1.."),
    ({"height": -3}, "height must be an integer in 1.."),
    ({"width": 2.5}, "width must be an integer"),
])
def test_gymnasium_render_size_refused(tasks, size, msg):
    """Width 5000 was dm_control's multi-line error at render(), width 0 an empty image."""
    with pytest.raises(ConfigError) as e:
        tasks.gym.PathprefEnv(task="navigate", render_mode="rgb_array", map="simple",
                              queries=20, **size)
    assert msg in str(e.value) and "\n" not in str(e.value)


def test_complex_actions_refused(tasks):
    """A complex action was accepted and its imaginary part dropped."""
    env = tasks.load("navigate_control", map="simple", queries=20)
    env.reset()
    for bad in (np.array([0.1 + 1j, 0.0]), [0.1 + 1j, 0.0], np.array([0.1, 0.0], complex)):
        with pytest.raises(ConfigError, match="real numbers, got .*a complex number"):
            env.step(bad)
    env.step(np.array([0.1, 0.0]))
    g = tasks.gym.PathprefEnv(task="navigate_control", map="simple", queries=20)
    g.reset(seed=0)
    with pytest.raises(ConfigError, match="a complex number"):
        g.step(np.array([0.1 + 1j, 0.0], complex))
    g.step(np.array([0.1, 0.0], np.float32))
    nav = tasks.gym.PathprefEnv(task="navigate", map="simple", queries=20)
    nav.reset(seed=0)
    with pytest.raises(ConfigError, match="action must be 0..8"):
        nav.step(3 + 1j)


# --- 9. a full disk -------------------------------------------------------------------------
def test_full_disk_while_writing_a_figure(tmp_path, capsys, monkeypatch):
    from pathpref.viz import mapdraw

    def full(world, out):
        Path(out).write_bytes(b"partial")
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(mapdraw, "save_map_figure", full)
    refuse(tmp_path, capsys, ["map", "draw", "simple", "--out", "m.png"],
           "cannot write m.png: no space left on device")


def test_full_disk_while_writing_the_report_csv(tmp_path, capsys, monkeypatch):
    from pathpref.experiments import report

    src = ROOT / "tests" / "data" / "saved_sweep.sqlite"
    if not src.exists():
        pytest.skip("no saved sweep")
    (tmp_path / "r.sqlite").write_bytes(src.read_bytes())

    def full(recs, out):
        Path(out).write_text("partial")
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(report, "write_csv", full)
    before = sorted(os.listdir(tmp_path))
    os.chdir(tmp_path)
    try:
        rc = main(["report", "r.sqlite"])
    finally:
        os.chdir(ROOT)
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and err[-1] == ("pathpref: error: cannot write r.csv: no space left on "
                                   "device; free some space and run again (no partial file "
                                   "was kept)")
    assert sorted(os.listdir(tmp_path)) == before  # no r.csv, no temporary file


def test_full_disk_during_a_sweep_removes_the_new_database(tmp_path, capsys, monkeypatch):
    from pathpref.experiments import sweep

    def full(specs, db, **kw):
        Path(db).write_bytes(b"partial")
        Path(f"{db}-journal").write_bytes(b"j")
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(sweep, "run_sweep", full)
    refuse(tmp_path, capsys, ["evaluate", "--db", "r.sqlite", "--runs", "1", "--instances", "1",
                              "--methods", "goal_only", "--delta-t", "5", "--workers", "1"],
           "cannot write r.sqlite: no space left on device")


def test_full_disk_anywhere_is_one_line(capsys, monkeypatch):
    from pathpref.apps import commands

    def boom(args):
        raise OSError(errno.ENOSPC, "No space left on device", "somewhere.bin")

    monkeypatch.setattr(commands, "cmd_map_info", boom)
    assert main(["map", "info", "simple"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["pathpref: error: cannot write somewhere.bin: no space left on device; free "
                   "some space and run again (no partial file was kept)"]


# --- 10. tampered episode rows --------------------------------------------------------------
TAMPERED = [("success = 'x'", "has success = 'x', not 0 or 1"),
            ("success = 5", "has success = 5, not 0 or 1"),
            ("ucb_c = NULL", "has ucb_c = NULL, not a finite number"),
            ("delta_t = 'x'", "has delta_t = 'x', not an integer >= 1"),
            ("map = NULL", "has map = NULL, not a string"),
            ("success = 1, goal_reached = 0", "has success = 1 but goal_reached = 0")]


def tampered_db(path: Path, change: str) -> Path:
    import sqlite3

    from .store_helpers import synthetic_db

    synthetic_db(path, {("goal_only", 5): (1, 3)})
    c = sqlite3.connect(path)
    c.execute("PRAGMA journal_mode=DELETE")
    c.execute(f"UPDATE episodes SET {change} WHERE rowid = 2")
    c.commit()
    c.close()
    return path


@pytest.mark.parametrize("change, msg", TAMPERED)
def test_report_on_tampered_rows_is_one_line(tmp_path, capsys, change, msg):
    tampered_db(tmp_path / "r.sqlite", change)
    line = refuse(tmp_path, capsys, ["report", "r.sqlite"], msg)
    assert "changed outside pathpref" in line and "DELETE FROM episodes WHERE key" in line
    from pathpref.experiments.report import load_records

    with pytest.raises(ConfigError, match=msg.replace("(", r"\(")):
        load_records(tmp_path / "r.sqlite")


@pytest.mark.parametrize("change, msg", TAMPERED[:3])
def test_evaluate_resume_into_tampered_rows_refuses_before_running(tmp_path, capsys,
                                                                   monkeypatch, change, msg):
    """It used to run its episodes, then crash in the report: now nothing runs, and the file
    (rollback journal) is not even switched to WAL."""
    from pathpref.experiments import sweep

    tampered_db(tmp_path / "r.sqlite", change)

    def never(*a, **k):
        raise AssertionError("an episode ran")

    monkeypatch.setattr(sweep, "iter_results", never)
    refuse(tmp_path, capsys, ["evaluate", "--db", "r.sqlite", "--runs", "1", "--instances",
                              "1", "--methods", "goal_only", "--delta-t", "5", "--workers", "1",
                              "--no-progress"], msg)


# --- 11. one line for a damaged database and a map too large --------------------------------
def test_sqlite_integrity_report_is_one_line(tmp_path, capsys):
    """SQLite's quick_check text spans lines (`*** in database main ***`, then one per
    problem): the refusal is still one line."""
    import random
    import sqlite3

    from .store_helpers import synthetic_db

    base = synthetic_db(tmp_path / "base.sqlite", {("compliant", 1): (1, 300)})
    c = sqlite3.connect(base)
    c.execute("PRAGMA journal_mode=DELETE")
    c.close()
    raw, rng = base.read_bytes(), random.Random(1)
    base.unlink()
    db = tmp_path / "r.sqlite"
    for _ in range(3000):  # flip one byte until the damage is one SQLite reports in lines
        b = bytearray(raw)
        b[rng.randrange(4096, len(b))] = rng.randrange(256)
        db.write_bytes(bytes(b))
        try:
            with sqlite3.connect(f"file:{db}?mode=ro&immutable=1", uri=True) as c:
                problems = [r[0] for r in c.execute("PRAGMA quick_check(3)")]
            c.close()
        except sqlite3.DatabaseError:
            continue
        if any("\n" in p for p in problems):
            break
    else:
        pytest.skip("no multi-line integrity report found")
    line = refuse(tmp_path, capsys, ["report", "r.sqlite"], "r.sqlite is damaged (")
    assert "***" not in line
    refuse(tmp_path, capsys, ["evaluate", "--db", "r.sqlite", "--runs", "1", "--instances",
                              "1", "--methods", "goal_only", "--delta-t", "5"], "is damaged (")


class _Terminal:
    """A stderr that says it is a terminal, keeping what is written."""

    def __init__(self):
        self.text = ""

    def write(self, s):
        self.text += s

    def flush(self):
        pass

    def isatty(self):
        return True


@pytest.mark.parametrize("tty", [False, True])
def test_map_too_large_for_the_tables_is_one_line(tmp_path, capsys, monkeypatch, tty):
    """The build's note came first, a line of its own, then the refusal: now a note is shown
    only on a terminal and erased when the build ends."""
    import sys
    import time

    import pathpref.episode as episode
    from pathpref.inference import human

    # simple: 96 cells x 10 goals; 368,640 bytes with one neighbour slot, 552,960 with its 2
    monkeypatch.setattr(human, "MAX_TABLE_BYTES", 500_000)
    monkeypatch.setattr(checks, "NOTE_POLYTOPES", 1)
    monkeypatch.setattr(checks, "NOTE_AFTER_S", 0.0)
    term = _Terminal()
    real = episode.cached_world

    def slow_build(source):  # the build ends once the note is out (on a terminal)
        for _ in range(3000):
            if not tty or "building map" in term.text:
                break
            time.sleep(0.01)
        return real(source)

    monkeypatch.setattr(episode, "cached_world", slow_build)
    if tty:
        monkeypatch.setattr(sys, "stderr", term)
    argv = ["evaluate", "--map", "simple", "--db", "r.sqlite", "--runs", "1", "--instances",
            "1", "--methods", "goal_only", "--delta-t", "5"]
    if not tty:
        refuse(tmp_path, capsys, argv, "likelihood tables for 96 cells x 10 goals x 2")
        return
    os.chdir(tmp_path)
    try:
        assert main(argv) == 2
    finally:
        os.chdir(ROOT)
    assert term.text.count("\n") == 1 and "building map" in term.text
    shown = term.text.split("\r\033[K")[-1]  # what the terminal shows after the erase
    assert shown.startswith("pathpref: error: ") and "likelihood tables" in shown
    assert os.listdir(tmp_path) == []


def test_map_too_large_is_refused_before_building(tmp_path, capsys, monkeypatch):
    import pathpref.episode as episode
    from pathpref.inference import human

    monkeypatch.setattr(human, "MAX_TABLE_BYTES", 300_000)  # below even one slot per cell

    def never(source):
        raise AssertionError("the map was built")

    monkeypatch.setattr(episode, "cached_world", never)
    refuse(tmp_path, capsys, ["evaluate", "--map", "simple", "--db", "r.sqlite", "--runs", "1",
                              "--instances", "1"], "likelihood tables for 96 cells x 10 goals x 1")


# --- 12. numerical trouble inside an episode --------------------------------------------------
def test_a_belief_that_breaks_is_one_line_not_a_warning_per_step(capfd, monkeypatch):
    """A belief table that underflows (as on a 500 x 500 map) made NumPy print its warnings at
    every step (1196 lines; the route prior's `catch_warnings` resets the registry each
    decision): now nothing is printed and the episode fails with one line."""
    from pathpref.episode import run_episode
    from pathpref.errors import EpisodeError
    from pathpref.experiments.backends import safe_run
    from pathpref.inference.belief import PreferenceBelief

    real = PreferenceBelief._multiply

    def underflow(self, v, factor):  # every entry of the table to 0 (a full underflow)
        real(self, v, factor * 0.0)

    monkeypatch.setattr(PreferenceBelief, "_multiply", underflow)
    spec = EpisodeSpec.single("simple", "path_preference", 1, seed=0, preset="paper",
                              queries=20)
    with warnings.catch_warnings():
        warnings.simplefilter("always")  # the worst case: every warning shown
        with pytest.raises(EpisodeError) as e:
            run_episode(spec)
        res = safe_run(spec)
    assert str(e.value).startswith("belief became non-finite at step ")
    assert "floating-point errors, the first: " in str(e.value) and "\n" not in str(e.value)
    assert res.status == "failed" and res.reason.startswith("EpisodeError: belief became")
    out = capfd.readouterr()
    assert out.err == "" and out.out == ""


# --- issue 47: --policy names a module, whatever the module does on import ----------------
@pytest.mark.parametrize("policy, source, msg", [
    ("./pol.py:act", None, "is not a module name"),
    ("/tmp/pol.py:act", None, "is not a module name"),
    ("pol.py:act", None, "is not a module name"),
    ("pol_raises_47:act", "raise RuntimeError('no GPU')\n",
     "module 'pol_raises_47' failed on import: RuntimeError: no GPU"),
    ("pol_exits_47:act", "raise SystemExit('bye')\n",
     "module 'pol_exits_47' failed on import: SystemExit: bye"),
])
def test_policy_module_problems_are_one_line(tmp_path, monkeypatch, policy, source, msg):
    import re
    import sys

    from pathpref.apps.film import load_policy

    if source is not None:
        (tmp_path / f"{policy.split(':')[0]}.py").write_text(source)
        monkeypatch.syspath_prepend(str(tmp_path))
    try:
        with pytest.raises(ConfigError, match=re.escape(msg)) as e:
            load_policy(policy)
    finally:
        sys.modules.pop(policy.split(":")[0], None)
    assert "\n" not in str(e.value) and str(e.value).startswith("--policy")


def test_render_with_a_path_as_policy_is_one_line(tmp_path, capsys):
    out = tmp_path / "v.mp4"
    assert main(["render", "--map", "simple", "--task", "navigate_control", "--out", str(out),
                 "--policy", "./my_policy.py:act", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is not a module name" in err and not out.exists()


def test_render_with_a_missing_or_bad_agent_is_one_line(tmp_path, capsys):
    """``--policy X.zip`` is a stable-baselines3 agent: a missing file, or a file that is no
    agent, is one line (or the rl extra's absence is)."""
    bad = tmp_path / "bad.zip"
    bad.write_bytes(b"not a zip")
    for agent, msg in ((tmp_path / "none.zip", "no agent checkpoint"),
                       (bad, "is not a stable-baselines3 agent")):
        out = tmp_path / "v.mp4"
        assert main(["render", "--map", "simple", "--task", "navigate", "--out", str(out),
                     "--policy", str(agent), "--no-progress"]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and not out.exists()
        assert msg in err or "needs stable-baselines3" in err


@pytest.mark.parametrize("width, height", [(1, 500), (500, 1), (4, 4)])
def test_map_draw_clamps_the_figure(tmp_path, width, height):
    """Issue 47: a 1 x 500 map drew a 1170 x 585,000 px PNG (4.5 GB); now every side is at
    most MAX_FIGURE_IN inches (1560 px) and at least MIN_FIGURE_IN."""
    from PIL import Image

    from pathpref.viz.mapdraw import MAX_FIGURE_IN, MIN_FIGURE_IN

    m = write(tmp_path / "thin.json", {"name": "thin", "width": width, "height": height})
    out = tmp_path / "thin.png"
    assert main(["map", "draw", m, "--out", str(out)]) == 0
    w, h = Image.open(out).size
    assert MIN_FIGURE_IN * 130 - 1 <= min(w, h) and max(w, h) <= MAX_FIGURE_IN * 130 + 1


@pytest.mark.parametrize("exists", [False, True])
def test_examples_on_a_full_disk_leave_nothing_and_the_retry_works(tmp_path, capsys,
                                                                   monkeypatch, exists):
    """Issue 47: ENOSPC halfway through a file (after two whole ones): one line naming the
    destination file (not the source), nothing left in DEST (a new DEST is gone), and the
    same command then copies everything."""
    import errno
    import shutil

    real = shutil.copyfile
    calls = {"n": 0}

    def copyfile(src, dst, *a, **k):
        calls["n"] += 1
        if calls["n"] == 3:
            Path(dst).write_bytes(b"half a fi")
            raise OSError(errno.ENOSPC, "No space left on device", str(src))
        return real(src, dst, *a, **k)

    dest = tmp_path / "ex"
    if exists:
        dest.mkdir()
    monkeypatch.setattr(shutil, "copyfile", copyfile)
    assert main(["examples", str(dest)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no space left on device" in err and str(dest) in err
    assert "nothing was copied" in err and "examples/" not in err.split(str(dest))[0]
    assert (list(dest.iterdir()) == []) if exists else not dest.exists()
    monkeypatch.setattr(shutil, "copyfile", real)
    assert main(["examples", str(dest)]) == 0
    assert (dest / "tutorial.py").is_file()
