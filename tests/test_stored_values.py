"""Issue 63: every stored value a command reads is checked (a tampered or out-of-type value is
one line naming the row and the column), and ``dataset`` on a read-only or full file system is
one line that leaves nothing behind."""

from __future__ import annotations

import errno
import os
import shutil
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

from pathpref.apps.cli import main

from .store_helpers import snapshot, synthetic_db

pytest.importorskip("pyarrow")


def _change(db, *statements):
    c = sqlite3.connect(db)
    c.execute("PRAGMA journal_mode=DELETE")
    for s in statements:
        c.execute(s)
    c.commit()
    c.close()


@pytest.fixture
def physical(tmp_path):
    """A sweep database of 3 --sim mujoco episodes with steps and a recorded path at 100 Hz
    (rows as pathpref writes them; the values synthetic)."""
    db = synthetic_db(tmp_path / "m.sqlite", {("goal_only", 5): (2, 3)})
    c = sqlite3.connect(db)
    keys = [k for (k,) in c.execute("SELECT key FROM episodes")]
    c.close()
    _change(db, "UPDATE episodes SET sim = 'mujoco'",
            *(f"INSERT INTO episode_path VALUES ('{key}', {k}, {k / 100}, {0.1 * k}, 0.5, 0.0, "
              f"NULL, NULL, NULL, {3.0 * (k == 2)}, 0.0)" for key in keys for k in range(6)))
    return db


def _run(tmp_path, argv, capsys):
    before = snapshot(tmp_path)
    rc = main([str(a) for a in argv])
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln]
    return rc, err, before


@pytest.mark.parametrize("source", ["episodes", "paths"])
def test_the_rows_export_as_they_are(physical, tmp_path, capsys, source):
    rc, err, _ = _run(tmp_path, ["dataset", physical, "--source", source, "--out",
                                 tmp_path / source], capsys)
    assert rc == 0 and not err


@pytest.mark.parametrize("source, change, words", [
    ("episodes", "UPDATE episodes SET success = 'x' WHERE rowid = 2", ("success = 'x'",)),
    ("episodes", "UPDATE episodes SET goals = 'oops' WHERE rowid = 1",
     ("episodes row 1 has goals = 'oops'",)),
    ("episodes", "UPDATE episodes SET true_goal = 9 WHERE rowid = 3",
     ("episodes row 3 has true_goal = 9, not an index into its goals",)),
    ("episodes", "UPDATE steps SET x = 'far' WHERE rowid = 4", ("steps row 4 (t = 3)",
                                                                "x = 'far', not an integer")),
    ("episodes", "UPDATE steps SET heading = 12 WHERE rowid = 2", ("heading = 12",)),
    ("paths", "UPDATE episode_path SET fx = 'x' WHERE rowid = 3", ("episode_path row 3 (k = 2)",
                                                                  "fx = 'x'")),
    ("paths", "UPDATE episode_path SET time_s = 'later' WHERE rowid = 2", ("time_s = 'later'",)),
    ("paths", "UPDATE episode_path SET x = 1e300 WHERE rowid = 5", ("x = 1e+300",)),
])
def test_a_tampered_value_is_one_line_naming_row_and_column(physical, tmp_path, capsys, source,
                                                            change, words):
    _change(physical, change)
    rc, err, before = _run(tmp_path, ["dataset", physical, "--source", source, "--out",
                                      tmp_path / "ds"], capsys)
    assert rc == 2 and len(err) == 1, err
    for w in words:
        assert w in err[0], err[0]
    assert "changed outside pathpref" in err[0]
    assert snapshot(tmp_path) == before  # no dataset folder, no temporary one


def test_a_full_disk_leaves_no_dataset(physical, tmp_path, capsys, monkeypatch):
    from pathpref.study import lerobot

    def full(self, *a, **k):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(lerobot.LeRobotWriter, "finish", full)
    rc, err, before = _run(tmp_path, ["dataset", physical, "--source", "paths", "--out",
                                      tmp_path / "ds"], capsys)
    assert rc == 2 and err == [f"pathpref: error: cannot write --out {tmp_path / 'ds'}: no space "
                               "left on device; free some space and run again (no partial "
                               "dataset was kept)"]
    assert snapshot(tmp_path) == before


def _root_namespace() -> bool:
    if os.geteuid() != 0 or not shutil.which("unshare"):
        return False
    return subprocess.run(["unshare", "-m", "true"], capture_output=True).returncode == 0


@pytest.mark.skipif(not _root_namespace(), reason="needs root and a private mount namespace")
def test_a_read_only_file_system_is_one_line(physical, tmp_path):
    """A read-only bind mount in a private mount namespace (root writes into a folder of
    mode 0555, not into a read-only file system). It used to end in an OSError traceback."""
    ro = tmp_path / "ro"
    ro.mkdir()
    script = (f"mount --bind {ro} {ro} && mount -o remount,bind,ro {ro} && "
              f"{sys.executable} -m pathpref dataset {physical} --source paths --out {ro}/ds")
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).parents[1])}
    r = subprocess.run(["unshare", "-m", "sh", "-c", script], capture_output=True, text=True,
                       env=env, timeout=120)
    assert r.returncode == 2, r.stdout + r.stderr
    assert r.stderr.splitlines() == [f"pathpref: error: cannot write --out {ro}/ds: folder {ro} "
                                     "is not writable"]
    assert os.listdir(ro) == []


def test_report_names_a_tampered_row_by_its_rowid(physical, tmp_path, capsys):
    """A row whose key is not pathpref's is named by its rowid, not by its position among the
    rows read (row 1 deleted, so the tampered rowid 3 is the second row read)."""
    _change(physical, "DELETE FROM episodes WHERE rowid = 1",
            "UPDATE episodes SET key = 'not a key!', success = 'x' WHERE rowid = 3")
    rc, err, _ = _run(tmp_path, ["report", physical], capsys)
    assert rc == 2 and len(err) == 1, err
    assert "episodes row 3 has success = 'x'" in err[0], err[0]
    assert "WHERE rowid = 3" in err[0], err[0]
