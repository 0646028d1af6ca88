"""Scale and reliability: the Ray backend, worker crashes and freezes, recorded failures,
kill-and-resume. (The crash test proper, single processes killed by PID, is test_crash.py.)"""

from __future__ import annotations

import contextlib
import os
import random
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

from pathpref.errors import ConfigError
from pathpref.experiments import backends
from pathpref.experiments.backends import iter_local, iter_ray
from pathpref.experiments.store import ResultStore
from pathpref.experiments.sweep import run_sweep, sweep_specs
from pathpref.planning import policies
from pathpref.planning.policies import CompliantPolicy

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
from crash_test import children, gone  # noqa: E402

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
    """SIGKILL the coordinator or a worker (single processes, by PID) 10 times at random moments,
    then finish: exactly one row per episode, no gaps, an intact database, and no worker left
    behind by a killed coordinator."""
    db = tmp_path / "k.sqlite"
    cmd = [sys.executable, "-m", "pathpref", "evaluate", "--map", "simple", "--methods",
           "compliant", "goal_only", "--delta-t", "1", "5", "10", "20", "30", "--instances", "4",
           "--runs", "5", "--queries", "100", "--db", str(db), "--workers", "2", "--no-progress"]
    total = 2 * 5 * 4 * 5
    rng = random.Random(7)
    for k in range(10):
        p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        time.sleep(rng.uniform(1.0, 3.0))
        if k % 2 and p.poll() is None and (kids := children(p.pid)):
            with contextlib.suppress(ProcessLookupError):  # ended since children() looked
                os.kill(rng.choice(kids), signal.SIGKILL)  # a worker
            time.sleep(rng.uniform(0.3, 1.0))
        kids = children(p.pid)
        p.kill()  # the coordinator alone
        p.wait()
        t = time.monotonic()
        while not all(gone(w) for w in kids) and time.monotonic() - t < 5:
            time.sleep(0.05)
        assert all(gone(w) for w in kids), f"workers {kids} outlived their coordinator"
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


def _patch_episodes(monkeypatch, target, action):
    """Workers (forked) run ``action(spec)`` before the episode of ``target``."""
    real = backends.run_episode

    def run(spec):
        if spec.key() == target.key():
            action(spec)
        return real(spec)

    monkeypatch.setattr(backends, "run_episode", run)


def test_only_the_dying_episode_is_charged(monkeypatch):
    """An episode that kills its worker every time fails after max_crashes deaths; the episodes
    in flight on the other worker meanwhile are not charged."""
    s = specs(methods=["compliant"], delta_ts=[1])
    real = backends.run_episode

    def run(spec):
        if spec.key() == s[0].key():
            time.sleep(0.2)
            os.kill(os.getpid(), signal.SIGKILL)
        time.sleep(0.5)  # in flight when the other worker dies
        return real(spec)

    monkeypatch.setattr(backends, "run_episode", run)
    out = {r.spec.key(): r for r in iter_local(s, workers=2, max_crashes=3)}
    assert sorted(out) == sorted(x.key() for x in s)
    assert out[s[0].key()].reason == "worker process died 3 times (last: killed by SIGKILL)"
    assert all(out[x.key()].status == "ok" for x in s[1:])


def test_frozen_worker_is_killed_and_its_episode_rerun(tmp_path, monkeypatch):
    s = specs(methods=["compliant"], delta_ts=[1])
    marker = tmp_path / "stopped"

    def freeze_once(spec):
        if not marker.exists():
            marker.write_text(str(os.getpid()))
            os.kill(os.getpid(), signal.SIGSTOP)

    _patch_episodes(monkeypatch, s[0], freeze_once)
    t = time.monotonic()
    out = list(iter_local(s, workers=2, limit=lambda spec: 3.0))
    assert marker.exists() and gone(int(marker.read_text()))
    assert sorted(r.spec.key() for r in out) == sorted(x.key() for x in s)
    assert all(r.status == "ok" for r in out)
    assert time.monotonic() - t < 20


def test_episode_timeout_is_enforced_by_the_coordinator(monkeypatch):
    """A step that never returns (so the episode's own check never runs) is killed at
    1.1 x --episode-timeout + 1 s and recorded as a timeout; the others are unaffected."""
    from dataclasses import replace

    s = [replace(x, timeout_s=2.0) for x in specs(methods=["compliant"], delta_ts=[1])]
    _patch_episodes(monkeypatch, s[0], lambda spec: time.sleep(600))
    t = time.monotonic()
    out = {r.spec.key(): r for r in iter_local(s, workers=2)}
    assert time.monotonic() - t < 15
    assert out[s[0].key()].reason.startswith(
        "timeout: episode exceeded 2 s (its worker was killed after 3.")
    assert all(out[x.key()].status == "ok" for x in s[1:])


def test_workers_are_capped(tmp_path):
    import multiprocessing as mp

    s = specs(methods=["compliant"], delta_ts=[1])[:2]
    results = iter_local(s, workers=50)
    next(results)
    assert len(mp.active_children()) <= 2
    results.close()
    assert mp.active_children() == []
    with pytest.raises(ConfigError, match="--workers 100000 is too many"):
        run_sweep(s, str(tmp_path / "w.sqlite"), workers=100_000, progress=False)


def test_ray_address_that_refuses_connections_is_a_config_error():
    pytest.importorskip("ray")
    import socket

    with socket.socket() as sock:  # a port nobody listens on
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    t = time.monotonic()
    with pytest.raises(ConfigError, match="cannot reach Ray"):
        list(iter_ray(specs()[:1], address=f"127.0.0.1:{port}"))
    with pytest.raises(ConfigError, match="is not host:port"):
        list(iter_ray(specs()[:1], address="nowhere"))
    assert time.monotonic() - t < backends.RAY_CONNECT_S


FROZEN_SWEEP = """
import ctypes, sys, time
from pathpref.experiments import backends
from pathpref.experiments.sweep import sweep_specs
if sys.argv[1] == "no-prctl":
    def no_prctl(*args, **kwargs):
        raise OSError("no prctl here")
    ctypes.CDLL = no_prctl
backends.run_episode = lambda spec: time.sleep(600)
list(backends.iter_local(sweep_specs("simple", ["compliant"], [1], 1, 2, queries=200), 2))
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.parametrize("mode", ["prctl", "no-prctl"])
def test_workers_die_with_a_killed_coordinator(mode):
    """SIGKILL of the coordinator alone: its workers follow, by PR_SET_PDEATHSIG or else by
    their watchdog thread (within about a second)."""
    p = subprocess.Popen([sys.executable, "-c", FROZEN_SWEEP, mode],
                         cwd=Path(__file__).resolve().parents[1])
    t = time.monotonic()
    while len(kids := children(p.pid)) < 2 and time.monotonic() - t < 60:
        time.sleep(0.05)
    assert len(kids) == 2
    p.kill()
    p.wait()
    t = time.monotonic()
    while not all(gone(w) for w in kids) and time.monotonic() - t < 5:
        time.sleep(0.02)
    assert all(gone(w) for w in kids)
    assert time.monotonic() - t < (0.5 if mode == "prctl" else 2.5)


def test_a_swallowed_sigterm_still_ends_the_sweep():
    """Python drops an exception raised in a fork hook or a finalizer; the SIGTERM is then
    raised again when the sweep leaves its block."""
    from pathpref.experiments.sweep import _sigterm_exits

    before = signal.getsignal(signal.SIGTERM)
    with pytest.raises(SystemExit) as e, _sigterm_exits():
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(1)
        except SystemExit:
            pass  # swallowed
    assert e.value.code == 143
    assert signal.getsignal(signal.SIGTERM) == before


@pytest.mark.parametrize("created", [False, True])
def test_dead_ray_address_leaves_no_database(tmp_path, capsys, created):
    """`--backend ray --address` at a dead port (or without Ray) is refused before the database
    is created: no empty file is left behind, an existing one is not touched."""
    import socket

    from pathpref.apps.cli import main

    from .store_helpers import snapshot

    with socket.socket() as sock:  # a port nobody listens on
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    db = tmp_path / "r.sqlite"
    if created:
        run_sweep(specs()[:1], str(db), workers=1, progress=False)
    before = snapshot(tmp_path)
    argv = ["evaluate", "--db", str(db), "--runs", "1", "--instances", "1", "--methods",
            "goal_only", "--delta-t", "5", "--backend", "ray", "--no-progress"]
    assert main([*argv, "--address", f"127.0.0.1:{port}"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "cannot reach Ray" in err[0]
    assert snapshot(tmp_path) == before
    try:
        import ray  # noqa: F401
    except ImportError:
        assert main(argv) == 2
        assert "needs Ray" in capsys.readouterr().err
        assert snapshot(tmp_path) == before
