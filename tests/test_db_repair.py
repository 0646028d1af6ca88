"""``pathpref db check`` reports damage without changing anything; ``pathpref db salvage``
copies every intact episode of a damaged database into a new one that passes check and report."""

from __future__ import annotations

import shutil
import sqlite3
from pathlib import Path

import pytest

from pathpref.apps.cli import main
from pathpref.experiments.migrate import check_database

from .store_helpers import corrupt_page, leaf_page_of, snapshot, synthetic_db

CELLS = {("compliant", 1): (10, 60), ("goal_only", 5): (3, 40)}  # 100 episodes, 21 steps each


@pytest.fixture(scope="module")
def intact(tmp_path_factory) -> Path:
    return synthetic_db(tmp_path_factory.mktemp("intact") / "r.sqlite", CELLS, steps=20)


def damaged_copy(intact: Path, folder: Path, table: str) -> Path:
    db = folder / "r.sqlite"
    shutil.copy(intact, db)
    corrupt_page(db, leaf_page_of(intact, table, 3 if table == "steps" else 1))
    return db


def test_check_intact_database(intact, capsys):
    assert main(["db", "check", str(intact)]) == 0
    out = capsys.readouterr().out
    assert f"{intact}: intact" in out and "schema 4" in out
    assert "episodes: 100 readable, 0 unreadable" in out and "step rows: 2100 readable" in out


@pytest.mark.parametrize("table", ["steps", "episodes"])
def test_check_reports_damage_and_salvage_saves_the_rest(intact, table, tmp_path, capsys):
    db = damaged_copy(intact, tmp_path, table)
    before = snapshot(tmp_path)
    assert main(["db", "check", str(db)]) == 2
    out = capsys.readouterr().out
    assert f"{db}: DAMAGED" in out and "malformed" in out and "db salvage" in out
    assert snapshot(tmp_path) == before
    r = check_database(db)
    if table == "steps":  # three episodes lost step rows, their episode rows read
        assert (r["episodes"], r["episodes_lost"], len(r["incomplete"])) == (100, 0, 3)
        assert r["steps_lost"] > 0 and r["orphans"] == 0
    else:  # a page of episode rows is gone: their step rows belong to no episode
        assert r["episodes_lost"] > 0 and r["incomplete"] == []
        assert r["orphans"] == 21 * r["episodes_lost"] and r["steps_lost"] == 0

    out_db = tmp_path / "saved.sqlite"
    assert main(["db", "salvage", str(db), str(out_db)]) == 0
    msg = capsys.readouterr().out
    saved = 100 - (len(r["incomplete"]) or r["episodes_lost"])
    assert f"saved {saved} episodes and {21 * saved} step rows" in msg
    assert f"lost {100 - saved} episodes" in msg
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.sqlite", "saved.sqlite"]
    assert main(["db", "check", str(out_db)]) == 0
    assert f"episodes: {saved} readable, 0 unreadable" in capsys.readouterr().out
    assert main(["report", str(out_db), "--csv", str(tmp_path / "t.csv")]) == 0
    assert "| compliant |" in capsys.readouterr().out
    with sqlite3.connect(f"file:{intact}?mode=ro&immutable=1", uri=True) as a, \
            sqlite3.connect(f"file:{out_db}?mode=ro&immutable=1", uri=True) as b:
        kept = b.execute("SELECT * FROM episodes ORDER BY key").fetchall()
        assert set(kept) <= set(a.execute("SELECT * FROM episodes").fetchall())
        assert set(b.execute("SELECT * FROM steps").fetchall()) <= set(
            a.execute("SELECT * FROM steps").fetchall())
    a.close()
    b.close()


def test_salvage_refuses_an_existing_output_and_foreign_files(intact, tmp_path, capsys):
    out_db = tmp_path / "out.sqlite"
    out_db.write_text("keep me")
    assert main(["db", "salvage", str(intact), str(out_db)]) == 2
    assert "exists" in capsys.readouterr().err and out_db.read_text() == "keep me"
    foreign = tmp_path / "f.sqlite"
    shutil.copy(intact, foreign)
    with sqlite3.connect(foreign) as c:
        c.execute("CREATE VIEW v AS SELECT 1")
    c.close()
    before = snapshot(tmp_path)
    assert main(["db", "salvage", str(foreign), str(tmp_path / "new.sqlite")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "view 'v'" in err
    assert main(["db", "check", str(foreign)]) == 2
    assert "pathpref database: no:" in capsys.readouterr().out
    assert snapshot(tmp_path) == before


def test_check_of_an_old_schema_points_at_upgrade(capsys):
    fixture = Path(__file__).parent / "data" / "schema2" / "schema2.sqlite"
    assert main(["db", "check", str(fixture)]) == 0
    out = capsys.readouterr().out
    assert "schema 2" in out and "pathpref db upgrade" in out


@pytest.mark.parametrize("make, message", [
    (lambda p: p.mkdir(), "is a directory"),
    (lambda p: p.write_text("notes"), "not SQLite"),
    (lambda p: None, "no results database"),
])
def test_check_of_non_databases_is_one_line(make, message, tmp_path, capsys):
    path = tmp_path / "x.sqlite"
    make(path)
    assert main(["db", "check", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err
