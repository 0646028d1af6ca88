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
    """The promise of docs/experiments.md: a row's stored configuration and seeds reproduce
    the episode."""
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
    from pathpref.geometry.following import human_route
    from pathpref.geometry.world import load_world

    spec = EpisodeSpec.single("simple", "compliant", 1, seed=4, queries=50, t_max=12)
    world = load_world("simple")
    res = run_episode(spec)
    res.metrics = {"b": 2.0, "a": 1.0}
    row = result_row(res)
    want = {"map": "simple", "method": "compliant", "delta_t": 1, "instance": 0, "run": 0,
            "instance_seed": spec.instance_seed, "run_seed": spec.run_seed,
            "preset": "robust-slack",
            "queries": 50, "t_max": 12, "n_goals": 10, "normalize": True, "coupling": False,
            "sim": "grid", "fixed": "", "task": "navigate", "ucb_c": 1.0,
            "time_budget_ms": 0.0, "human": "map", "physics": "", "prior": "routes",
            "push_rule": "", "timeout_s": 0.0, "record_path_hz": 0.0,
            "homotopy_success": int(res.goal_reached and res.homotopic),
            "key": spec.key(), "map_hash": spec.map_hash,
            "start": json.dumps(res.instance_cells["start"]),
            "goals": json.dumps(res.instance_cells["goals"]),
            "true_goal": res.instance.true_goal, "status": "ok", "reason": "",
            "goal_reached": int(res.goal_reached), "pref_followed": int(res.violations == 0),
            "success": int(res.goal_reached and res.violations == 0), "steps": res.steps,
            "inputs": res.steps,  # Delta_T = 1: one input before every step
            "violations": res.violations, "back_crossings": res.back_crossings,
            "wall_s": res.wall_s, "metrics": '{"a": 1.0, "b": 2.0}',
            # T_max minus the moves of the human's route (the map's preference here)
            "slack": 12 - (len(human_route(world, world.require_preference(),
                                           res.instance.start, res.instance.goal_cell)) - 1)}
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


TWO_SWEEPS = """
import json, os, sys, time
from pathpref.experiments import backends
from pathpref.experiments.sweep import run_sweep, sweep_specs

folder, tag, other = sys.argv[1], sys.argv[2], sys.argv[3]
real = backends.safe_run
ran = []

def run(spec):  # the first episode waits until the other sweep runs one too: they overlap
    open(os.path.join(folder, "started-" + tag), "w").close()
    for _ in range(6000):
        if os.path.exists(os.path.join(folder, "started-" + other)):
            break
        time.sleep(0.01)
    ran.append(spec.key())
    return real(spec)

backends.safe_run = run
specs = sweep_specs("simple", ["compliant", "goal_only"], [1, 10], instances=3, runs=2,
                    queries=50)
counts = run_sweep(specs, os.path.join(folder, "r.sqlite"), workers=int(sys.argv[4]),
                   progress=False)
print(json.dumps({"ran": ran, "counts": counts}))
"""


@pytest.mark.parametrize("workers", [1, 2])
def test_two_sweeps_on_one_database_never_run_an_episode_twice(tmp_path, workers):
    """Two sweeps of the same 24 episodes started together on one database: every episode is
    run exactly once (each claims an episode before running it); they used to compute most of
    them twice."""
    import json
    import os
    import subprocess
    import sys

    script = tmp_path / "sweep.py"
    script.write_text(TWO_SWEEPS)
    env = dict(os.environ, MUJOCO_GL="egl")
    procs = [subprocess.Popen([sys.executable, str(script), str(tmp_path), a, b,
                               str(workers)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True, env=env) for a, b in (("a", "b"), ("b", "a"))]
    outs = []
    for p in procs:
        out, err = p.communicate(timeout=600)
        assert p.returncode == 0, err
        outs.append(json.loads(out.strip().splitlines()[-1]))
    a, b = outs
    if workers == 1:  # in-process: the keys each sweep ran
        assert not set(a["ran"]) & set(b["ran"])
        assert len(a["ran"]) + len(b["ran"]) == 24
    assert a["counts"]["ran"] + b["counts"]["ran"] == 24
    assert a["counts"]["ran"] > 0 and b["counts"]["ran"] > 0
    with ResultStore(tmp_path / "r.sqlite") as st:
        rows = st.episodes()
    assert len(rows) == 24 and {r["status"] for r in rows} == {"ok"}


def test_a_sweep_that_finds_the_tables_made_does_not_reopen_the_file(tmp_path, monkeypatch):
    """When two sweeps create one new file at once, the second finds the first one's tables
    and checks them on its own connection: opening the file again (even to read its header)
    and closing it would drop the process's POSIX locks, the first sweep would fold and delete
    the WAL on closing, and this sweep's later episodes would be lost (seen as a claim left
    'running' after both sweeps ended, one run in 25). Also: a refused schema is one line."""
    from pathpref.experiments import store as store_mod

    with ResultStore(tmp_path / "r.sqlite") as st:
        def no_reopen(*args, **kwargs):
            raise AssertionError("the database file was opened again while connected")

        monkeypatch.setattr(store_mod, "require_sqlite_file", no_reopen)
        monkeypatch.setattr(store_mod, "open_readonly", no_reopen)
        st._create_schema()  # the tables are there: checked on st.conn, nothing reopened
        st.conn.execute("UPDATE meta SET value = '999' WHERE key = 'schema_version'")
        st.conn.commit()
        with pytest.raises(ConfigError, match="schema 999"):
            st._create_schema()


def test_a_second_store_on_a_held_file_does_not_reopen_it(tmp_path, monkeypatch):
    """A second store on a file this process already holds (and ``inspect_results_file``,
    ``report``'s check) reads no header through a new descriptor, whose closing would drop
    the first store's POSIX locks (:data:`store._HELD`); once every store of the file is
    closed (or collected unclosed) the header is read again, and a file that is not SQLite is
    still refused."""
    import builtins

    from pathpref.experiments import store as store_mod

    path = tmp_path / "r.sqlite"
    real_open = builtins.open
    opened = []

    def watch(file, *args, **kwargs):
        if str(file) == str(path):
            opened.append(file)
        return real_open(file, *args, **kwargs)

    monkeypatch.setattr(builtins, "open", watch)
    first = ResultStore(path)
    with ResultStore(path) as second, ResultStore(path, create=False) as reader:
        assert store_mod.inspect_results_file(path) == store_mod.SCHEMA_VERSION
        assert second.episodes() == [] and reader.episodes() == []
    assert opened == []
    key = store_mod._file_id(path)
    assert store_mod._HELD[key] == 1
    first.close()
    first.close()  # closing twice releases the file once
    assert key not in store_mod._HELD
    assert store_mod.inspect_results_file(path) == store_mod.SCHEMA_VERSION
    assert opened == [path]
    forgotten = ResultStore(path)  # a store never closed releases the file when collected
    assert store_mod._HELD[key] == 1
    del forgotten
    import gc
    gc.collect()
    assert key not in store_mod._HELD
    other = tmp_path / "x.sqlite"
    other.write_bytes(b"not a database at all, 40 bytes long...")
    with pytest.raises(ConfigError, match="not SQLite"):
        ResultStore(other)


def test_stale_claims_are_taken_over_and_live_ones_left(tmp_path):
    """A claim of a process that is gone (a crashed sweep) is run on resume; a claim of a
    live sweep is left to it; a finished sweep leaves no claim behind; reports skip claims."""
    import json
    import subprocess
    import sys

    from pathpref.experiments.backends import failed
    from pathpref.experiments.report import load_records
    from pathpref.experiments.store import RUNNING, claim_is_live, this_owner

    db = tmp_path / "r.sqlite"
    specs = small_specs(methods=["compliant"], delta_ts=[1], instances=1, runs=3)
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    live = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)"])
    try:
        me = this_owner()
        gone = {**me, "pid": dead.pid, "start": "1"}
        alive = {**me, "pid": live.pid, "start": None}
        assert not claim_is_live({**gone, "at": 0}, 1e9) and claim_is_live({**alive, "at": 0},
                                                                          1e9)
        assert not claim_is_live({**me, "host": "elsewhere", "at": 0.0}, 60.0)
        with ResultStore(db) as st:
            assert st.claim(failed(specs[0], ""), owner=gone) == "claimed"
            assert st.claim(failed(specs[1], ""), owner=alive) == "claimed"
            assert st.claim(failed(specs[1], ""), owner=me) == "busy"
        assert load_records(db) == []  # claims are not results
        counts = run_sweep(specs, str(db), workers=1, progress=False)
        assert counts["ran"] == 2 and counts["busy"] == 1  # the dead one's claim retaken
        with ResultStore(db) as st:
            rows = {r["key"]: r for r in st.episodes()}
        assert rows[specs[0].key()]["status"] == "ok"
        assert rows[specs[1].key()]["status"] == RUNNING
        assert json.loads(rows[specs[1].key()]["reason"])["pid"] == live.pid
    finally:
        live.kill()
        live.wait()
    counts = run_sweep(specs, str(db), workers=2, progress=False)  # the live one died
    assert counts["ran"] == 1
    with ResultStore(db) as st:
        assert {r["status"] for r in st.episodes()} == {"ok"}


def test_an_interrupted_sweep_releases_its_claims(tmp_path, monkeypatch):
    from pathpref.experiments import sweep

    db = tmp_path / "r.sqlite"
    specs = small_specs(methods=["compliant"], delta_ts=[1], instances=1, runs=3)
    real = sweep.iter_results

    def interrupted(todo, *a, **k):
        for i, res in enumerate(real(todo, *a, **k)):
            if i == 1:
                raise KeyboardInterrupt
            yield res

    monkeypatch.setattr(sweep, "iter_results", interrupted)
    with pytest.raises(KeyboardInterrupt):
        run_sweep(specs, str(db), workers=1, progress=False)
    with ResultStore(db) as st:
        assert [r["status"] for r in st.episodes()] == ["ok"]


def test_asking_for_wal_journaling_is_bounded(monkeypatch):
    """``PRAGMA journal_mode=WAL`` refused as "locked" (another sweep opening the file) is
    asked again, then succeeds; refused for good it is asked exactly WAL_TRIES times and the
    refusal raised (no endless wait); any other error is raised at once."""
    from pathpref.experiments import store as store_mod

    class Conn:
        def __init__(self, refusals, message="database is locked"):
            self.calls, self.refusals, self.message = 0, refusals, message

        def execute(self, sql):
            self.calls += 1
            if self.calls <= self.refusals:
                raise sqlite3.OperationalError(self.message)

    class Fake:
        pass

    monkeypatch.setattr(store_mod.time, "sleep", lambda s: None)
    f = Fake()
    f.conn = Conn(2)
    ResultStore._wal(f)
    assert f.conn.calls == 3
    f.conn = Conn(10**6)
    with pytest.raises(sqlite3.OperationalError, match="locked"):
        ResultStore._wal(f)
    assert f.conn.calls == store_mod.WAL_TRIES
    f.conn = Conn(10**6, "disk I/O error")
    with pytest.raises(sqlite3.OperationalError, match="disk"):
        ResultStore._wal(f)
    assert f.conn.calls == 1
