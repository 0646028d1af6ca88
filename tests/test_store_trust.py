"""A results database is pathpref's only when its tables, columns and schema row are pathpref's
and it has no views or triggers; anything else, and any damaged file, is refused with one line
and left untouched (no side file appears, no byte or mtime changes)."""

from __future__ import annotations

import os
import shutil
import sqlite3
from pathlib import Path

import pytest

from pathpref.apps.cli import main
from pathpref.errors import ConfigError
from pathpref.experiments import store as store_mod
from pathpref.experiments.store import ResultStore

from .store_helpers import corrupt_page, leaf_page_of, snapshot, synthetic_db

CELLS = {("compliant", 1): (1, 5), ("goal_only", 1): (2, 5)}


def tamper(path: Path, *statements: str) -> Path:
    """Run ``statements`` on ``path`` (created if missing), left in rollback-journal mode."""
    c = sqlite3.connect(path)
    c.execute("PRAGMA journal_mode=DELETE")
    for s in statements:
        c.execute(s)
    c.commit()
    c.close()
    return path


def valid(tmp_path: Path) -> Path:
    return synthetic_db(tmp_path / "r.sqlite", CELLS)


def trigger(tmp_path):
    return tamper(valid(tmp_path), "CREATE TRIGGER fix AFTER INSERT ON episodes BEGIN "
                  "UPDATE episodes SET success = 1, goal_reached = 1; END")


def view_named_episodes(tmp_path):
    return tamper(valid(tmp_path), "DROP TABLE episodes", """CREATE VIEW episodes AS
        WITH RECURSIVE i(n) AS (SELECT 1 UNION ALL SELECT n + 1 FROM i WHERE n < 100)
        SELECT 'k' || n AS key, 'simple' AS map, 'h' AS map_hash, 1 AS success FROM i""")


def extra_view(tmp_path):
    return tamper(valid(tmp_path), "CREATE VIEW summary AS SELECT count(*) FROM episodes")


def recursive_view(tmp_path):
    return tamper(valid(tmp_path), "CREATE VIEW grow AS WITH RECURSIVE c(x) AS "
                  "(SELECT randomblob(1000) UNION ALL SELECT randomblob(1000) FROM c) "
                  "SELECT x FROM c")


def other_app_view_only(tmp_path):
    return tamper(tmp_path / "app.db", "CREATE VIEW v AS SELECT 1 AS one")


def meta_schema2_foreign_tables(tmp_path):
    return tamper(tmp_path / "app.db", "CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT)",
                  "INSERT INTO meta VALUES ('schema_version', '2')",
                  "CREATE TABLE accounts (id INTEGER PRIMARY KEY, owner TEXT)")


def extra_index(tmp_path):
    return tamper(valid(tmp_path), "CREATE INDEX by_method ON episodes (method)")


def generated_column(tmp_path):
    db = valid(tmp_path)
    cols = ", ".join(f"{k} {t}" for k, t in store_mod.EPISODE_COLUMNS.items()
                     if k != "success")
    return tamper(db, "DROP TABLE episodes",
                  f"CREATE TABLE episodes ({cols}, success INTEGER GENERATED ALWAYS AS (1))")


def bad_schema_row(tmp_path):
    return tamper(valid(tmp_path), "UPDATE meta SET value = 'three'")


def corrupt(tmp_path):
    db = synthetic_db(tmp_path / "r.sqlite", {("compliant", 1): (10, 60)}, steps=20)
    corrupt_page(db, leaf_page_of(db, "steps", 3))
    return db


def directory(tmp_path):
    (tmp_path / "results.sqlite").mkdir()
    return tmp_path / "results.sqlite"


def fifo(tmp_path):
    os.mkfifo(tmp_path / "pipe.sqlite")
    return tmp_path / "pipe.sqlite"


CASES = {
    trigger: "trigger 'fix'",
    view_named_episodes: "view 'episodes'",
    extra_view: "view 'summary'",
    recursive_view: "view 'grow'",
    other_app_view_only: "view 'v'",
    meta_schema2_foreign_tables: "table 'accounts'",
    extra_index: "index 'by_method'",
    generated_column: "table episodes is not defined as pathpref defines it",
    bad_schema_row: "no schema version",
    corrupt: "is damaged",
    directory: "is a directory",
    fifo: "not a regular file",
}


@pytest.mark.parametrize("make", list(CASES), ids=[f.__name__ for f in CASES])
def test_refused_untouched_with_one_line(make, tmp_path, capsys):
    db = make(tmp_path)
    before = snapshot(tmp_path)
    with pytest.raises(ConfigError, match=CASES[make]) as e:
        ResultStore(db)
    assert str(db) in str(e.value) and "\n" not in str(e.value)
    for argv in (["report", str(db)], ["db", "upgrade", str(db)],
                 ["evaluate", "--db", str(db), "--methods", "compliant", "--delta-t", "1",
                  "--instances", "1", "--runs", "1", "--workers", "1", "--no-progress"]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and str(db) in err, err
    assert snapshot(tmp_path) == before


def test_damaged_file_names_the_repair_commands(tmp_path):
    db = corrupt(tmp_path)
    with pytest.raises(ConfigError, match=r"pathpref db check .*pathpref db salvage"):
        ResultStore(db)


def test_dev_null_is_refused_without_a_journal():
    if os.path.exists("/dev/null-journal"):
        pytest.skip("/dev/null-journal exists already")
    with pytest.raises(ConfigError, match="not a regular file"):
        ResultStore("/dev/null")
    assert main(["report", "/dev/null"]) == 2
    assert not os.path.exists("/dev/null-journal")


def test_read_error_after_opening_is_one_line(tmp_path, monkeypatch, capsys):
    """A page that breaks after the check (here: the check is skipped) is one line too."""
    db = synthetic_db(tmp_path / "r.sqlite", {("compliant", 1): (10, 200)})
    corrupt_page(db, leaf_page_of(db, "episodes", 2))
    monkeypatch.setattr(store_mod, "check_results_file", lambda path, create: True)
    assert main(["report", str(db)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is damaged" in err and "db salvage" in err


def test_interrupted_sweep_with_wal_is_read_whole(tmp_path):
    """A killed sweep leaves its last episodes in the -wal file: they count, nothing is lost."""
    live = synthetic_db(tmp_path / "live.sqlite", CELLS)
    writer = sqlite3.connect(live)
    writer.execute("PRAGMA journal_mode=WAL")
    n = writer.execute("SELECT count(*) FROM episodes").fetchone()[0]
    writer.execute("DELETE FROM episodes WHERE method = 'goal_only'")
    writer.commit()
    killed = tmp_path / "killed"
    killed.mkdir()
    for side in ("", "-wal", "-shm"):
        shutil.copy(f"{live}{side}", killed / f"r.sqlite{side}")
    writer.close()
    with ResultStore(killed / "r.sqlite") as st:
        assert len(st.episodes()) == n - 5


def test_new_and_empty_files_are_created(tmp_path):
    (tmp_path / "empty.sqlite").write_bytes(b"")
    for name in ("new.sqlite", "empty.sqlite"):
        with ResultStore(tmp_path / name) as st:
            assert st.episodes() == []
        with ResultStore(tmp_path / name) as st:  # and reopened as pathpref's
            assert st.done_keys() == set()
    with pytest.raises(ConfigError, match="no results database"):
        ResultStore(tmp_path / "missing.sqlite", create=False)
