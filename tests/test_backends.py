"""Scale and reliability: the Ray backend, worker crashes, recorded failures, kill-and-resume."""

from __future__ import annotations

import os
import random
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

from pathpref.experiments.backends import iter_local
from pathpref.experiments.store import ResultStore
from pathpref.experiments.sweep import run_sweep, sweep_specs
from pathpref.planning import policies
from pathpref.planning.policies import CompliantPolicy

ROWS = "key, status, success, goal_reached, violations, steps, start, goals"


def specs(**kw):
    d = dict(map_name="simple", methods=["compliant", "goal_only"], delta_ts=[1, 10],
             instances=2, runs=2, queries=200)
    d.update(kw)
    return sweep_specs(**d)


def rows(db):
    with ResultStore(db) as st:
        return st.conn.execute(f"SELECT {ROWS} FROM episodes ORDER BY key").fetchall()


def test_ray_backend_gives_identical_rows(tmp_path):
    pytest.importorskip("ray")
    s = specs()
    run_sweep(s, str(tmp_path / "local.sqlite"), workers=2, progress=False)
    run_sweep(s, str(tmp_path / "ray.sqlite"), workers=2, progress=False, backend="ray")
    a, b = rows(tmp_path / "local.sqlite"), rows(tmp_path / "ray.sqlite")
    assert a == b and len(a) == len(s)


class Crashy(CompliantPolicy):
    def act(self, t, cell, heading):
        if t == 1:
            raise RuntimeError("boom at step 1")
        return super().act(t, cell, heading)


class Killer(CompliantPolicy):
    """Kills its own worker process once per marker file (simulates a segfault/OOM kill)."""

    def act(self, t, cell, heading):
        marker = Path(os.environ["PATHPREF_TEST_MARKER"])
        if t == 1 and not marker.exists():
            marker.write_text("killed")
            os.kill(os.getpid(), signal.SIGKILL)
        return super().act(t, cell, heading)


def test_failures_are_recorded_and_retried(tmp_path, monkeypatch):
    db = str(tmp_path / "f.sqlite")
    monkeypatch.setitem(policies.METHODS, "crashy", Crashy)
    s = specs(methods=["crashy"], delta_ts=[1])
    counts = run_sweep(s, db, workers=2, progress=False)
    assert counts["failed"] == len(s)
    with ResultStore(db) as st:
        reasons = {r["reason"].split(" | ")[0] for r in st.episodes()}
    assert reasons == {"RuntimeError: boom at step 1"}
    # the failure is fixed: --retry-failed re-runs exactly those
    monkeypatch.setitem(policies.METHODS, "crashy", CompliantPolicy)
    assert run_sweep(s, db, workers=2, progress=False)["ran"] == 0
    again = run_sweep(s, db, workers=2, progress=False, retry_failed=True)
    assert again["ran"] == len(s) and again["failed"] == 0
    assert all(r[1] == "ok" for r in rows(db)) and len(rows(db)) == len(s)


def test_timeout_is_a_recorded_failure(tmp_path):
    from dataclasses import replace

    s = [replace(x, timeout_s=1e-9) for x in specs(methods=["goal_only"], delta_ts=[1])]
    counts = run_sweep(s, str(tmp_path / "t.sqlite"), workers=1, progress=False)
    assert counts["failed"] == len(s)
    with ResultStore(tmp_path / "t.sqlite") as st:
        assert all("timeout" in r["reason"] for r in st.episodes())


def test_killed_worker_is_rerun(tmp_path, monkeypatch):
    monkeypatch.setitem(policies.METHODS, "killer", Killer)
    monkeypatch.setenv("PATHPREF_TEST_MARKER", str(tmp_path / "marker"))
    s = specs(methods=["killer"], delta_ts=[1])
    out = list(iter_local(s, workers=2))
    assert (tmp_path / "marker").exists()  # one worker really died
    assert sorted(r.spec.key() for r in out) == sorted(x.key() for x in s)
    assert all(r.status == "ok" for r in out)


def test_ten_random_kills_during_200_episode_sweep(tmp_path):
    """SIGKILL the coordinator or a worker 10 times at random moments, then finish: exactly one
    row per episode, no gaps, an intact database."""
    db = tmp_path / "k.sqlite"
    cmd = [sys.executable, "-m", "pathpref", "evaluate", "--map", "simple", "--methods",
           "compliant", "goal_only", "--delta-t", "1", "5", "10", "20", "30", "--instances", "4",
           "--runs", "5", "--queries", "100", "--db", str(db), "--workers", "2", "--no-progress"]
    total = 2 * 5 * 4 * 5
    rng = random.Random(7)
    for k in range(10):
        p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                             start_new_session=True)
        time.sleep(rng.uniform(1.0, 3.0))
        if k % 2 and p.poll() is None:
            kids = subprocess.run(["pgrep", "-P", str(p.pid)], capture_output=True,
                                  text=True).stdout.split()
            if kids:
                os.kill(int(rng.choice(kids)), signal.SIGKILL)  # a worker
                time.sleep(rng.uniform(0.3, 1.0))
        try:
            os.killpg(p.pid, signal.SIGKILL)  # the coordinator (and its pool)
        except ProcessLookupError:
            pass
        p.wait()
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    with sqlite3.connect(db) as c:
        keys = [r[0] for r in c.execute("SELECT key FROM episodes")]
        assert c.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
        assert c.execute("SELECT COUNT(*) FROM episodes WHERE status != 'ok'").fetchone()[0] == 0
        orphans = c.execute(
            "SELECT COUNT(*) FROM steps WHERE key NOT IN (SELECT key FROM episodes)").fetchone()
    assert len(keys) == len(set(keys)) == total
    assert orphans[0] == 0
