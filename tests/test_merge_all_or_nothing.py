"""``pathpref db merge`` is all or nothing (issue 63): a refused merge (a damaged or tampered
input, two copies of an episode that disagree, a full disk) leaves an existing output byte for
byte as it was and creates no file; step rows survive whatever the order of the inputs, and a
merge of databases with and without steps names the episodes without."""

from __future__ import annotations

import os
import shutil
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

from pathpref.apps.cli import main
from pathpref.errors import ConfigError
from pathpref.experiments import merge
from pathpref.experiments.merge import merge_databases

from .store_helpers import corrupt_page, leaf_page_of, snapshot, synthetic_db


def _sql(db, query, params=()):
    with sqlite3.connect(f"file:{db}?mode=ro&immutable=1", uri=True) as c:
        rows = c.execute(query, params).fetchall()
    c.close()
    return rows


def _change(db, statement):
    c = sqlite3.connect(db)
    c.execute("PRAGMA journal_mode=DELETE")
    c.execute(statement)
    c.commit()
    c.close()


@pytest.fixture
def dbs(tmp_path):
    """``out`` (1 episode), ``a`` (4 other episodes with steps), ``nosteps`` (a copy of
    ``a`` without step rows), in a folder of their own; the inputs in rollback-journal mode."""
    folder = tmp_path / "w"
    folder.mkdir()
    out = synthetic_db(folder / "out.sqlite", {("compliant", 1): (1, 1)})
    a = synthetic_db(tmp_path / "a.sqlite", {("goal_only", 5): (2, 4)})
    nosteps = tmp_path / "nosteps.sqlite"
    shutil.copy(a, nosteps)
    for db in (out, a):
        _change(db, "SELECT 1")
    _change(nosteps, "DELETE FROM steps")
    return folder, out, a, nosteps


def _run(argv, capsys):
    rc = main([str(x) for x in argv])
    cap = capsys.readouterr()
    return rc, [ln for ln in cap.err.splitlines() if ln], cap.out


def _refused(folder, argv, capsys, *words):
    """Exit 2, one stderr line holding ``words``, the folder byte for byte as it was."""
    before = snapshot(folder)
    rc, err, _ = _run(argv, capsys)
    assert rc == 2 and len(err) == 1, err
    assert err[0].startswith("pathpref: error: ")
    for w in words:
        assert w in err[0], err[0]
    assert snapshot(folder) == before  # no new file, the output unchanged
    return err[0]


def test_a_damaged_input_after_a_good_one_changes_nothing(dbs, tmp_path, capsys):
    """It used to copy the first input's episodes (1 -> 5) and then stop on the second."""
    folder, out, a, _ = dbs
    bad = tmp_path / "bad.sqlite"
    shutil.copy(a, bad)
    corrupt_page(bad, leaf_page_of(bad, "steps", 0))
    other = synthetic_db(tmp_path / "other.sqlite", {("oracle", 5): (1, 1)})
    _refused(folder, ["db", "merge", out, other, bad], capsys, str(bad), "damaged")
    assert _sql(out, "SELECT COUNT(*) FROM episodes") == [(1,)]
    _refused(folder, ["db", "merge", folder / "new.sqlite", other, bad], capsys, "damaged")


@pytest.mark.parametrize("table, change, words", [
    ("episodes", "UPDATE episodes SET success = 'x' WHERE rowid = 2", ("success = 'x'",)),
    ("episodes", "UPDATE episodes SET goals = '[[1, 1' WHERE rowid = 3",
     ("episodes row 3", "goals")),
    ("episodes", "UPDATE episodes SET true_goal = 7 WHERE rowid = 1", ("true_goal = 7",)),
    ("steps", "UPDATE steps SET x = 'x' WHERE rowid = 9", ("steps row 9", "x = 'x'")),
    ("steps", "UPDATE steps SET heading = 99 WHERE rowid = 4", ("steps row 4", "heading = 99")),
    ("steps", "DELETE FROM steps WHERE rowid = 8", ("step rows", "steps = 5")),
    ("steps", "UPDATE steps SET p_true_goal = 1e400 WHERE rowid = 2", ("p_true_goal = inf",)),
])
def test_a_tampered_input_is_one_line_naming_row_and_column(dbs, tmp_path, capsys, table,
                                                             change, words):
    folder, out, a, _ = dbs
    _change(a, change)
    line = _refused(folder, ["db", "merge", out, a], capsys, str(a), *words)
    assert "changed outside pathpref" in line


def test_disagreeing_copies_name_the_episode_and_the_field(dbs, tmp_path, capsys):
    """It used to exit 2 with nothing on stderr, after writing the rest."""
    folder, out, a, _ = dbs
    b = tmp_path / "b.sqlite"
    shutil.copy(a, b)
    _change(b, "UPDATE episodes SET inputs = 4 WHERE instance = 2")
    line = _refused(folder, ["db", "merge", out, a, b], capsys, f"{a} and {b} disagree",
                    "goal_only ΔT=5 instance 2 run 0 on simple (grid, navigate)",
                    "inputs = 1 in", "but 4 in", "nothing was written")
    assert line.count("pathpref: error") == 1
    # the output's own copy disagrees with an input: named as the output
    assert main(["db", "merge", str(out), str(a)]) == 0
    capsys.readouterr()
    _refused(folder, ["db", "merge", out, b], capsys, f"{out} and {b} disagree", "inputs")


def test_steps_are_kept_whatever_the_order_and_the_bare_episodes_are_named(dbs, tmp_path,
                                                                            capsys):
    """``--no-steps`` first used to leave 0 step rows of 24, silently."""
    folder, out, a, nosteps = dbs
    whole = _sql(a, "SELECT * FROM steps ORDER BY key, t")
    assert len(whole) == 24
    for order in ([nosteps, a], [a, nosteps]):
        target = folder / f"m{len(os.listdir(folder))}.sqlite"
        rc, err, text = _run(["db", "merge", target, *order], capsys)
        assert rc == 0 and not err
        assert _sql(target, "SELECT * FROM steps ORDER BY key, t") == whole
        assert "note" not in text  # every finished episode has its steps
    # with and without steps: the note names the episodes without, and where they came from
    rc, err, text = _run(["db", "merge", folder / "mixed.sqlite", out, nosteps], capsys)
    assert rc == 0 and not err
    note = [ln for ln in text.splitlines() if ln.startswith("note:")]
    assert len(note) == 1
    assert f"4 of its 5 finished episodes have no step rows (run with --no-steps; from " \
           f"{nosteps}: 4)" in note[0]
    assert "goal_only ΔT=5 instance 0 run 0 on simple (grid, navigate)" in note[0]
    assert "goal_only ΔT=5 instance 3 run 0" in note[0]


def test_a_full_disk_leaves_the_output_unchanged(dbs, tmp_path, capsys, monkeypatch):
    """SQLite's own "database or disk is full", made by a page limit on the temporary
    database (a real small file system: the next test, as root)."""
    folder, out, _, _ = dbs
    a = synthetic_db(tmp_path / "big.sqlite", {("goal_only", 5): (20, 60)})
    real = merge.open_staging

    def small(path):
        store = real(path)
        pages = store.conn.execute("PRAGMA page_count").fetchone()[0]
        store.conn.execute(f"PRAGMA max_page_count = {pages}")
        return store

    monkeypatch.setattr(merge, "open_staging", small)
    _refused(folder, ["db", "merge", out, a], capsys, f"cannot write {out}: no space left",
             f"{out} is unchanged")
    _refused(folder, ["db", "merge", folder / "new.sqlite", a], capsys, "no space left",
             "was not created")
    with pytest.raises(ConfigError, match="no space left"):
        merge_databases(out, [a])


def _can_mount() -> bool:
    if os.geteuid() != 0 or not shutil.which("unshare"):
        return False
    probe = subprocess.run(["unshare", "-m", "true"], capture_output=True)
    return probe.returncode == 0


@pytest.mark.skipif(not _can_mount(), reason="needs root and a private mount namespace")
def test_a_real_full_file_system(dbs, tmp_path):
    """A 200 KiB tmpfs in a private mount namespace (``unshare -m``; nothing outside it sees
    the mount): merging an input larger than the free room is refused in one line; the
    output, already there, is unchanged and no other file is left."""
    folder, out, _, _ = dbs
    big = synthetic_db(tmp_path / "big.sqlite", {("goal_only", 5): (50, 400)}, steps=20)
    mnt = tmp_path / "mnt"
    mnt.mkdir()
    script = (f"mount -t tmpfs -o size=200k tmpfs {mnt} && cp {out} {mnt}/out.sqlite && "
              f"sha1sum {mnt}/out.sqlite && ({sys.executable} -m pathpref db merge "
              f"{mnt}/out.sqlite {big}; echo rc=$?) && sha1sum {mnt}/out.sqlite && ls -a {mnt}")
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).parents[1])}
    r = subprocess.run(["unshare", "-m", "sh", "-c", script], capture_output=True, text=True,
                       env=env, timeout=120)
    lines = r.stdout.split()
    assert "rc=2" in lines, r.stdout + r.stderr
    assert lines[0] == lines[lines.index("rc=2") + 1]  # the same SHA-1 before and after
    assert lines[-3:] == [".", "..", "out.sqlite"]  # nothing else left
    err = [ln for ln in r.stderr.splitlines() if ln]
    assert len(err) == 1 and "no space left on device" in err[0], r.stderr


def test_an_output_in_use_or_unwritable_is_refused_before_any_work(dbs, capsys):
    folder, out, a, _ = dbs
    wal = Path(f"{out}-wal")
    wal.write_bytes(b"x" * 100)  # a sweep writes to it (or one was killed)
    _refused(folder, ["db", "merge", out, a], capsys, "write-ahead log")
    wal.unlink()
    if os.geteuid() != 0:  # root writes into a read-only folder
        folder.chmod(0o555)
        try:
            _refused(folder, ["db", "merge", folder / "new.sqlite", a], capsys,
                     "is not writable")
        finally:
            folder.chmod(0o755)
