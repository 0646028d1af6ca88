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


def _children(pid: int) -> list[int]:
    out = subprocess.run(["pgrep", "-P", str(pid)], capture_output=True, text=True).stdout
    return [int(x) for x in out.split()]


def _gone(pid: int) -> bool:
    """The process no longer exists (or is a zombie waiting for its reaper)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] == "Z"
    except FileNotFoundError:
        return True


def _wait_gone(pids, seconds=5.0) -> list[int]:
    t = time.monotonic() + seconds
    while time.monotonic() < t and not all(_gone(p) for p in pids):
        time.sleep(0.1)
    return [p for p in pids if not _gone(p)]


def test_random_single_process_kills_during_200_episode_sweep(tmp_path):
    """SIGKILL (or SIGTERM) the coordinator or one worker by pid, 12 times at random moments,
    then finish: exactly one row per episode, the same rows as a clean run, an intact database,
    and no worker left 5 s after its coordinator died."""
    db = tmp_path / "k.sqlite"
    args = ["evaluate", "--map", "simple", "--methods", "compliant", "goal_only", "--delta-t",
            "1", "5", "10", "20", "30", "--instances", "4", "--runs", "5", "--queries", "100",
            "--no-progress"]
    cmd = [sys.executable, "-m", "pathpref", *args, "--db", str(db), "--workers", "2"]
    total = 2 * 5 * 4 * 5
    rng = random.Random(7)
    for k in range(12):
        p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                             start_new_session=True)
        time.sleep(rng.uniform(1.0, 3.0))
        kids = _children(p.pid)
        if k % 2 and kids:
            os.kill(rng.choice(kids), signal.SIGKILL)  # one worker
            time.sleep(rng.uniform(0.3, 1.0))
        kids = _children(p.pid)
        try:
            os.kill(p.pid, signal.SIGTERM if k % 3 == 0 else signal.SIGKILL)  # the coordinator
        except ProcessLookupError:
            pass
        p.wait()
        assert _wait_gone(kids) == [], f"workers outlived their coordinator (round {k})"
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
    clean = tmp_path / "clean.sqlite"
    subprocess.run([sys.executable, "-m", "pathpref", *args, "--db", str(clean), "--workers",
                    "2"], check=True, capture_output=True, timeout=600)
    assert rows(db) == rows(clean)


def test_a_frozen_worker_costs_its_timeout_only(tmp_path):
    """SIGSTOP one worker: the coordinator kills it after the episode's timeout and runs the
    episode again; the rows equal a clean run's."""
    args = ["evaluate", "--map", "simple", "--methods", "goal_only", "--delta-t", "1", "5",
            "--instances", "10", "--runs", "2", "--queries", "2000", "--no-progress",
            "--episode-timeout", "2"]
    db, clean = tmp_path / "s.sqlite", tmp_path / "clean.sqlite"
    p = subprocess.Popen([sys.executable, "-m", "pathpref", *args, "--db", str(db), "--workers",
                          "2"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    t = time.monotonic()
    while not _children(p.pid) and time.monotonic() - t < 30:
        time.sleep(0.02)
    victim = _children(p.pid)[0]
    os.kill(victim, signal.SIGSTOP)
    try:
        p.wait(timeout=120)
    finally:
        if p.poll() is None:
            p.kill()
    assert p.returncode == 0, p.stderr.read()
    assert time.monotonic() - t < 60
    subprocess.run([sys.executable, "-m", "pathpref", *args, "--db", str(clean)], check=True,
                   capture_output=True, timeout=300)
    assert rows(db) == rows(clean)
