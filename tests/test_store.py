"""Results store and sweeps: resume, no duplicates, kill-and-resume, refusing foreign files."""

from __future__ import annotations

import sqlite3

import pytest

from pathpref.errors import ConfigError
from pathpref.experiments.store import ResultStore
from pathpref.experiments.sweep import run_sweep, sweep_specs


def small_specs(**kw):
    d = dict(map_name="simple", methods=["compliant", "path_preference"], delta_ts=[1, 10],
             instances=2, runs=2, queries=200)
    d.update(kw)
    return sweep_specs(**d)


def test_sweep_resumes(tmp_path):
    db = tmp_path / "r.sqlite"
    specs = small_specs()
    first = run_sweep(specs[:5], str(db), workers=1, progress=False)
    assert first["ran"] == 5
    again = run_sweep(specs, str(db), workers=2, progress=False)
    assert again["skipped"] == 5 and again["ran"] == len(specs) - 5
    with ResultStore(db) as st:
        rows = st.episodes()
        assert len(rows) == len(specs) == len({r["key"] for r in rows})
        assert all(st.steps(r["key"]) for r in rows)


def test_any_stored_row_replays_exactly(tmp_path):
    """The README's promise: a row's stored configuration and seeds reproduce the episode."""
    from pathpref.episode import run_episode
    from pathpref.experiments.store import row_spec

    db = tmp_path / "r.sqlite"
    run_sweep(small_specs(instances=1, runs=2), str(db), workers=2, progress=False)
    with ResultStore(db) as st:
        for row in st.episodes():
            res = run_episode(row_spec(row))
            assert res.spec.key() == row["key"]
            stored = [(s["x"], s["y"], s["action"], s["heading"]) for s in st.steps(row["key"])]
            assert [(s.x, s.y, s.action, s.heading) for s in res.log] == stored
            assert int(res.success) == row["success"]


def test_backends_identical_rows(tmp_path):
    """In-process and pool runs write the same results (seeds are per episode)."""
    specs = small_specs(instances=1)
    a, b = tmp_path / "a.sqlite", tmp_path / "b.sqlite"
    run_sweep(specs, str(a), workers=1, progress=False)
    run_sweep(specs, str(b), workers=2, progress=False)
    cols = "key, success, goal_reached, violations, steps, start, goals"
    with ResultStore(a) as sa, ResultStore(b) as sb:
        ra = sa.conn.execute(f"SELECT {cols} FROM episodes ORDER BY key").fetchall()
        rb = sb.conn.execute(f"SELECT {cols} FROM episodes ORDER BY key").fetchall()
    assert ra == rb


def test_refuses_foreign_and_incompatible_files(tmp_path):
    text = tmp_path / "notes.sqlite"
    text.write_text("my notes")
    with pytest.raises(ConfigError, match="not SQLite"):
        ResultStore(text)
    assert text.read_text() == "my notes"
    other = tmp_path / "other.sqlite"
    with sqlite3.connect(other) as c:
        c.execute("CREATE TABLE t (x)")
    with pytest.raises(ConfigError, match="not written by pathpref"):
        ResultStore(other)
    old = tmp_path / "old.sqlite"
    ResultStore(old).close()
    with sqlite3.connect(old) as c:
        c.execute("UPDATE meta SET value = '0' WHERE key = 'schema_version'")
    before = old.read_bytes()
    with pytest.raises(ConfigError, match="incompatible"):
        ResultStore(old)
    assert old.read_bytes() == before



def test_the_stored_row_of_an_episode_is_exact():
    """Every column of ``result_row``, worked out from the episode itself."""
    import json

    from pathpref.episode import EpisodeSpec, result_row, run_episode

    spec = EpisodeSpec.single("simple", "compliant", 1, seed=4, queries=50, t_max=12)
    res = run_episode(spec)
    res.metrics = {"b": 2.0, "a": 1.0}
    row = result_row(res)
    want = {"map": "simple", "method": "compliant", "delta_t": 1, "instance": 0, "run": 0,
            "instance_seed": spec.instance_seed, "run_seed": spec.run_seed, "preset": "paper",
            "queries": 50, "t_max": 12, "n_goals": 10, "normalize": True, "coupling": True,
            "sim": "grid", "fixed": "", "task": "navigate", "ucb_c": 1.0,
            "time_budget_ms": 0.0, "human": "map", "physics": "", "prior": "independent",
            "timeout_s": 0.0,
            "key": spec.key(), "map_hash": spec.map_hash,
            "start": json.dumps(res.instance_cells["start"]),
            "goals": json.dumps(res.instance_cells["goals"]),
            "true_goal": res.instance.true_goal, "status": "ok", "reason": "",
            "goal_reached": int(res.goal_reached), "pref_followed": int(res.violations == 0),
            "success": int(res.goal_reached and res.violations == 0), "steps": res.steps,
            "inputs": res.steps,  # Delta_T = 1: one input before every step
            "violations": res.violations, "back_crossings": res.back_crossings,
            "wall_s": res.wall_s, "metrics": '{"a": 1.0, "b": 2.0}'}
    assert row == want
    assert [res.log[0].x, res.log[0].y] == json.loads(row["start"])
    assert len(json.loads(row["goals"])) == 10 and row["inputs"] > 0


def test_readers_never_change_a_rollback_journal_database(tmp_path, capsys):
    """`report` and `replay` read a rollback-journal file as it is: same bytes, same journal
    mode, no side file (they used to switch it to WAL)."""
    from pathpref.apps.cli import main
    from pathpref.experiments.report import load_records

    from .store_helpers import snapshot, synthetic_db

    (tmp_path / "d").mkdir()
    db = synthetic_db(tmp_path / "d" / "r.sqlite", {("compliant", 1): (2, 4)})
    c = sqlite3.connect(db)
    assert c.execute("PRAGMA journal_mode=DELETE").fetchone() == ("delete",)
    c.close()
    out = tmp_path / "out"
    out.mkdir()
    before = snapshot(db.parent)
    raw = db.read_bytes()
    assert raw[18:20] == b"\x01\x01"  # the header's read/write versions: rollback journal
    assert main(["report", str(db), "--csv", str(out / "r.csv")]) == 0
    assert main(["replay", str(db), "--participant", "p1", "--trial", "1", "--out",
                 str(out / "v.mp4")]) == 2
    assert "no trial 1 of participant" in capsys.readouterr().err
    assert load_records(db)[0]["n"] == 4
    assert db.read_bytes() == raw and snapshot(db.parent) == before
    with ResultStore(db, create=False) as st:
        with pytest.raises(sqlite3.OperationalError, match="readonly"):
            st.conn.execute("DELETE FROM episodes")
    with pytest.raises(ConfigError, match="holds no episodes yet"):
        (tmp_path / "empty.sqlite").write_bytes(b"")
        ResultStore(tmp_path / "empty.sqlite", create=False)
