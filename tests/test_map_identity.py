"""A map is its content: episodes keyed by a hash of the canonical map, mission time from the
map file, schema-2 databases migrated by ``pathpref db upgrade``, big maps refused up front."""

from __future__ import annotations

import json
import shutil
import sqlite3
from pathlib import Path

import numpy as np
import pytest

from pathpref.apps.cli import main
from pathpref.episode import EpisodeSpec, cached_map, run_episode
from pathpref.errors import ConfigError, MapError
from pathpref.experiments.store import ResultStore, row_spec
from pathpref.geometry.maps import load_map, parse_map

FIXTURE = Path(__file__).parent / "data" / "schema2"


def lab(**extra) -> dict:
    raw = json.loads((FIXTURE / "lab.json").read_text())
    raw.update(extra)
    return raw


def test_hash_ignores_path_name_order_and_form_but_not_geometry(tmp_path):
    a = parse_map(lab())
    renamed = parse_map({**lab(), "name": "other", "description": "x", "t_max": 99})
    assert a.content_hash == renamed.content_hash
    # the same rectangle as cells or as clockwise vertices from another corner
    raw = lab()
    raw["obstacles"][0] = {"vertices": [[5, 2], [3, 2], [3, 4], [5, 4]]}
    assert parse_map(raw).content_hash == a.content_hash
    moved = lab()
    moved["obstacles"][0]["cells"]["lower_left"] = [4, 2]
    assert parse_map(moved).content_hash != a.content_hash
    band = lab(goal_band={"x": [1, 8], "y": [5, 6]})
    assert parse_map(band).content_hash != a.content_hash


def test_t_max_is_a_map_field_with_a_size_rule():
    assert [load_map(m).t_max for m in ("simple", "office", "classroom")] == [30, 30, 60]
    assert parse_map(lab()).t_max == 24  # 3 x max(8, 6)
    assert parse_map(lab(t_max=41)).t_max == 41
    for bad in (0, -3, 2.5, True, "30"):
        with pytest.raises(MapError, match="t_max"):
            parse_map(lab(t_max=bad))


def test_same_t_max_by_name_and_by_path(tmp_path, capsys):
    from pathpref.geometry.maps import builtin_map_path

    copy = tmp_path / "classroom_copy.json"
    shutil.copy(builtin_map_path("classroom"), copy)
    assert cached_map(str(copy)).t_max == cached_map("classroom").t_max == 60


def evaluate(map_path: str, db: Path) -> str:
    return (f"evaluate --map {map_path} --methods compliant --delta-t 5 --instances 1 --runs 2 "
            f"--queries 50 --db {db} --workers 1 --no-progress").split()


def test_changed_map_runs_new_episodes_and_other_path_reuses(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "sub").mkdir()
    (tmp_path / "lab.json").write_text(json.dumps(lab()))
    db = tmp_path / "e.sqlite"
    assert main(evaluate("lab.json", db)) == 0
    assert "2 episodes run" in capsys.readouterr().out
    # the same file under another path: reused
    monkeypatch.chdir(tmp_path / "sub")
    assert main(evaluate("../lab.json", db)) == 0
    assert "0 episodes run (0 failed), 2 already" in capsys.readouterr().out
    # an obstacle moved: new episodes, and the report shows the new map's rows only
    moved = lab()
    moved["obstacles"][0]["cells"]["lower_left"] = [4, 2]
    (tmp_path / "lab.json").write_text(json.dumps(moved))
    cached_map.cache_clear()
    assert main(evaluate("../lab.json", db)) == 0
    out = capsys.readouterr().out
    assert "2 episodes run" in out and "n = 2 per cell" in out
    with ResultStore(db) as st:
        rows = st.episodes()
    assert len(rows) == 4 and len({r["map_hash"] for r in rows}) == 2
    assert {r["t_max"] for r in rows} == {24}


def test_schema2_database_is_refused_with_the_upgrade_command(tmp_path):
    db = tmp_path / "old.sqlite"
    shutil.copy(FIXTURE / "schema2.sqlite", db)
    before = db.read_bytes()
    with pytest.raises(ConfigError, match=r"pathpref db upgrade"):
        ResultStore(db)
    assert db.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old.sqlite"]


def test_db_upgrade_keeps_every_row_and_rows_replay(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    shutil.copy(FIXTURE / "schema2.sqlite", "old.sqlite")
    old = sqlite3.connect("old.sqlite")
    old_rows = old.execute("SELECT key, success, steps, goals FROM episodes").fetchall()
    old_steps = old.execute("SELECT COUNT(*) FROM steps").fetchone()[0]
    old.close()
    # the stored map 'lab.json' is not here: refused, nothing changed
    assert main(["db", "upgrade", "old.sqlite"]) == 2
    assert "--map 'lab.json=PATH'" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old.sqlite"]
    (tmp_path / "maps").mkdir()
    shutil.copy(FIXTURE / "lab.json", tmp_path / "maps" / "lab.json")
    assert main(["db", "upgrade", "old.sqlite", "--map", "lab.json=maps/lab.json"]) == 0
    assert "10 episodes, 113 steps" in capsys.readouterr().out
    assert (tmp_path / "old.sqlite.schema2.bak").exists()
    with ResultStore("old.sqlite") as st:
        rows = st.episodes()
        assert len(rows) == len(old_rows) == 10
        assert st.conn.execute("SELECT COUNT(*) FROM steps").fetchone()[0] == old_steps
        assert sorted((r["success"], r["steps"], r["goals"]) for r in rows) == sorted(
            (s, n, g) for _, s, n, g in old_rows)
        for row in rows:
            spec = row_spec(row)
            assert spec.key() == row["key"] and row["map_hash"] == spec.map_hash
            res = run_episode(spec)
            stored = [(s["x"], s["y"], s["action"]) for s in st.steps(row["key"])]
            assert [(s.x, s.y, s.action) for s in res.log] == stored
            assert int(res.success) == row["success"]
    # a second upgrade has nothing to do
    assert main(["db", "upgrade", "old.sqlite"]) == 0
    assert "nothing to do" in capsys.readouterr().out


def test_map_info_reports_components(tmp_path, capsys):
    split = {"name": "split", "width": 5, "height": 3,
             "obstacles": [{"cells": {"lower_left": [3, 1], "size": [1, 3]}}]}
    path = tmp_path / "split.json"
    path.write_text(json.dumps(split))
    assert main(["map", "info", str(path), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["components"] == 2 and info["largest_component_cells"] == 6
    assert info["free_cells"] == 12 and info["t_max"] == 15
    assert main(["map", "info", str(path)]) == 0
    assert "splits into 2 parts" in capsys.readouterr().out
    assert main(["map", "info", "simple", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert (info["polytopes"], info["edges"], info["components"]) == (8, 8, 1)
    assert info["largest_component_cells"] == info["free_cells"] == 96


def test_too_large_map_is_refused_before_building(monkeypatch):
    from pathpref.geometry import arrangement
    from pathpref.geometry.world import load_world

    monkeypatch.setattr(arrangement, "MAX_CELL_LINES", 1000)
    raw = {"name": "big", "width": 60, "height": 60, "obstacles": [
        {"cells": {"lower_left": [5 * i + 2, 5 * j + 2], "size": [2, 2]}}
        for i in range(3) for j in range(3)]}
    with pytest.raises(MapError, match=r"too large to build: \d+ free cells x \d+ distinct"):
        load_world(raw)


def test_too_large_tables_are_refused_before_allocating(monkeypatch):
    from pathpref.geometry.world import load_world
    from pathpref.inference import human

    monkeypatch.setattr(human, "MAX_TABLE_BYTES", 10_000)
    w = load_world("simple")
    with pytest.raises(ConfigError, match="likelihood tables for 96 cells x 3 goals"):
        human.ObservationModel.build(w, np.arange(3))


def test_episode_key_has_hash_not_path():
    spec = EpisodeSpec(map="simple", method="compliant", delta_t=5, instance=0, run=0,
                       instance_seed=1, run_seed=2)
    assert "map=" not in spec.key() and f"map_hash={load_map('simple').content_hash}" in spec.key()
