"""A results database is pathpref's only if it holds exactly pathpref's tables and columns, the
right schema row and nothing else (no view, no trigger); anything else, and a damaged file, is
refused in one line and left exactly as it was, with no side file created."""

from __future__ import annotations

import os
import shutil
import sqlite3

import pytest

from pathpref.errors import ConfigError
from pathpref.experiments.report import load_records
from pathpref.experiments.store import ResultStore
from pathpref.experiments.sweep import run_sweep, sweep_specs


@pytest.fixture(scope="module")
def good_db(tmp_path_factory):
    db = tmp_path_factory.mktemp("good") / "r.sqlite"
    specs = sweep_specs("simple", ["compliant"], [1, 5], instances=3, runs=1, queries=50)
    run_sweep(specs, str(db), workers=1, progress=False)
    with sqlite3.connect(db) as c:  # one self-contained file: no -wal beside it
        c.execute("PRAGMA wal_checkpoint(TRUNCATE)")
        c.execute("PRAGMA journal_mode=DELETE")
    return db


def _snapshot(folder):
    return {n: (os.path.getsize(folder / n), os.path.getmtime(folder / n))
            for n in sorted(os.listdir(folder))}


def _refused(path, match):
    folder = path.parent
    before = _snapshot(folder)
    data = path.read_bytes() if path.is_file() else None
    with pytest.raises(ConfigError, match=match) as e:
        ResultStore(path)
    assert "\n" not in str(e.value)
    with pytest.raises(ConfigError):
        load_records(path)
    assert _snapshot(folder) == before  # no -wal, -shm or -journal, nothing modified
    if data is not None:
        assert path.read_bytes() == data


def _doctored(good_db, tmp_path, sql):
    p = tmp_path / "doctored.sqlite"
    shutil.copy(good_db, p)
    with sqlite3.connect(p) as c:
        c.executescript(sql)
    return p


def test_a_planted_trigger_is_refused(good_db, tmp_path):
    p = _doctored(good_db, tmp_path, "CREATE TRIGGER lie AFTER INSERT ON episodes BEGIN "
                                     "UPDATE episodes SET success = 1; END;")
    _refused(p, "trigger 'lie'")


def test_episodes_replaced_by_a_view_is_refused(good_db, tmp_path):
    p = _doctored(good_db, tmp_path, "ALTER TABLE episodes RENAME TO e2; CREATE VIEW episodes "
                                     "AS SELECT * FROM e2;")
    _refused(p, "view 'episodes'")


def test_a_recursive_view_is_refused_before_it_is_read(good_db, tmp_path):
    p = _doctored(good_db, tmp_path, "CREATE VIEW big AS WITH RECURSIVE n(i) AS (SELECT 1 "
                                     "UNION ALL SELECT i + 1 FROM n) SELECT i FROM n;")
    _refused(p, "view 'big'")


def test_another_applications_file_is_refused(tmp_path):
    p = tmp_path / "other.sqlite"
    with sqlite3.connect(p) as c:
        c.executescript("CREATE TABLE t (x); CREATE VIEW v AS SELECT x FROM t;")
    _refused(p, "not write")
    q = tmp_path / "meta.sqlite"
    with sqlite3.connect(q) as c:  # a meta table that claims schema 2, foreign tables
        c.executescript("CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT); INSERT INTO "
                        "meta VALUES ('schema_version', '2'); CREATE TABLE notes (x);")
    _refused(q, "not write")


def test_a_damaged_page_is_refused(good_db, tmp_path):
    p = tmp_path / "damaged.sqlite"
    data = bytearray(good_db.read_bytes())
    page = 4096
    assert len(data) > 4 * page
    data[3 * page: 4 * page] = b"\xde\xad\xbe\xef" * (page // 4)
    p.write_bytes(bytes(data))
    _refused(p, "damaged|cannot read")


def test_folders_and_devices_are_refused(tmp_path):
    d = tmp_path / "dir.sqlite"
    d.mkdir()
    _refused(d, "not a regular file")
    fifo = tmp_path / "fifo.sqlite"
    os.mkfifo(fifo)
    _refused(fifo, "not a regular file")  # and does not block
    with pytest.raises(ConfigError, match="not a regular file"):
        ResultStore("/dev/null")
    assert not os.path.exists("/dev/null-journal")


def test_a_good_database_still_opens_and_reports(good_db):
    assert len(load_records(good_db)) > 0
    with ResultStore(good_db) as st:
        assert len(st.done_keys()) == 6


def test_db_check_and_salvage(good_db, tmp_path, capsys):
    """A damaged page: check reports it (exit 2), salvage copies the rest into a new file that
    checks intact and reports; an intact file checks 0."""
    from pathpref.apps.cli import main

    assert main(["db", "check", str(good_db)]) == 0
    assert "intact" in capsys.readouterr().out
    bad = tmp_path / "damaged.sqlite"
    data = bytearray(good_db.read_bytes())
    n_pages = len(data) // 4096
    data[(n_pages - 1) * 4096:] = b"\x00\xff" * 2048  # the last page: some step rows
    bad.write_bytes(bytes(data))
    before = bad.read_bytes()
    assert main(["db", "check", str(bad)]) == 2
    assert "problem" in capsys.readouterr().out
    out = tmp_path / "saved.sqlite"
    assert main(["db", "salvage", str(bad), str(out)]) == 0
    msg = capsys.readouterr().out
    assert bad.read_bytes() == before and not (tmp_path / "damaged.sqlite-wal").exists()
    with sqlite3.connect(good_db) as c:
        total = c.execute("SELECT COUNT(*) FROM episodes").fetchone()[0]
    with sqlite3.connect(out) as c:
        saved = c.execute("SELECT COUNT(*) FROM episodes").fetchone()[0]
        assert c.execute("SELECT COUNT(*) FROM steps WHERE key NOT IN "
                         "(SELECT key FROM episodes)").fetchone()[0] == 0
    assert 0 < saved <= total and f"saved {saved} episodes" in msg
    assert main(["db", "check", str(out)]) == 0
    assert load_records(out)  # the report reads it
    with ResultStore(out) as st:
        assert len(st.episodes()) == saved
    assert main(["db", "salvage", str(bad), str(out)]) == 2  # never overwrites
