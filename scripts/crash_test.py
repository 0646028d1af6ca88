"""Crash test of a local sweep: kill single processes of it by PID, then compare its database
with a clean run's.

A sweep (``pathpref evaluate``, 2 workers, ``--episode-timeout``) is run to completion once
cleanly, then again into a second database while this script

* SIGKILLs a random worker ``--worker-kills`` times, each after the sweep stored a new row;
* kills the coordinator ``--coordinator-kills`` times (SIGKILL and SIGTERM by turns) and starts
  the same command again: the coordinator must exit (143 after SIGTERM), its output pipes must
  close and every worker it had must be gone (or a zombie) within 5 s;
* SIGSTOPs a worker early in the last run (before that run's worker kills, which spare it): the
  coordinator must kill it past the episode timeout and finish, recording that one episode as a
  failed "timeout", which ``--retry-failed`` then re-runs.

Then both databases must hold the same episodes (key, status, success, goal_reached,
violations, steps, inputs) and the same per-step logs: 0 rows lost, duplicated or changed, and
no episode charged with a worker death it did not have. Linux only (reads ``/proc``).

    python scripts/crash_test.py --worker-kills 20 --coordinator-kills 4
"""

from __future__ import annotations

import argparse
import json
import os
import random
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ROWS = "key, status, success, goal_reached, violations, steps, inputs"
STEPS = "key, t, x, y, action, heading"
GRACE_S = 5.0  # a killed coordinator's workers must be gone within this


def sweep_cmd(db: Path, instances: int, queries: int, *extra: str) -> list[str]:
    return [sys.executable, "-m", "pathpref", "evaluate", "--map", "simple", "--methods",
            "goal_only", "path_preference", "--delta-t", "1", "5", "--instances", str(instances),
            "--runs", "2", "--queries", str(queries), "--db", str(db), "--workers", "2",
            "--no-progress", *extra]


def start(cmd: list[str]) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=str(ROOT), MUJOCO_GL="disable")
    return subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def _stat(pid: int) -> tuple[str, int] | None:
    """(state, parent pid) of a process, None if there is none."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    state, ppid = text[text.rindex(")") + 2:].split()[:2]
    return state, int(ppid)


def children(pid: int) -> list[int]:
    """Live (not zombie) child processes of ``pid``."""
    kids = []
    for d in os.listdir("/proc"):
        if d.isdigit() and (st := _stat(int(d))) and st[1] == pid and st[0] != "Z":
            kids.append(int(d))
    return kids


def gone(pid: int) -> bool:
    st = _stat(pid)
    return st is None or st[0] == "Z"


def count(db: Path) -> int:
    """Finished episodes stored in ``db`` (claims of running ones, a chunk at a time, left
    out)."""
    if not db.exists():
        return 0
    try:
        with sqlite3.connect(db, timeout=5) as c:
            return c.execute("SELECT COUNT(*) FROM episodes WHERE status != 'running'"
                             ).fetchone()[0]
    except sqlite3.OperationalError:  # not created yet
        return 0


def wait_for(cond, timeout: float, what: str) -> None:
    t = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > t:
            raise AssertionError(f"timed out after {timeout:g} s waiting for {what}")
        time.sleep(0.05)


def kill_worker(p: subprocess.Popen, db: Path, rng: random.Random, sig: int,
                spare: int | None = None) -> int | None:
    """After the sweep stores a new row, send ``sig`` to one of its workers (not ``spare``); its
    PID, or None if the sweep ended first."""
    n = count(db)
    wait_for(lambda: count(db) > n or p.poll() is not None, 120, "a new row")
    time.sleep(rng.uniform(0.1, 0.6))
    while p.poll() is None:
        kids = [k for k in children(p.pid) if k != spare]
        if kids:
            pid = rng.choice(kids)
            try:
                os.kill(pid, sig)
                return pid
            except ProcessLookupError:  # it ended since children() looked: pick again
                pass
        time.sleep(0.05)
    return None


def kill_coordinator(p: subprocess.Popen, db: Path, sig: int) -> float | None:
    """Send ``sig`` to the coordinator once it has workers; check that it exits, that its pipes
    close and that its workers are gone within GRACE_S. Seconds until the last one was gone, or
    None when the sweep finished before it could be killed."""
    wait_for(lambda: children(p.pid) or p.poll() is not None, 120, "workers")
    workers = children(p.pid)
    if p.poll() is not None:  # the sweep finished before it could be killed
        p.communicate()
        return None
    try:
        os.kill(p.pid, sig)
    except ProcessLookupError:  # it finished between poll() and kill()
        p.communicate()
        return None
    t0 = time.monotonic()
    try:
        _, err = p.communicate(timeout=30)  # EOF only once no process holds its pipes
    except subprocess.TimeoutExpired:
        raise AssertionError(f"the sweep's output pipes stayed open after {sig!r}") from None
    expected = 128 + signal.SIGTERM if sig == signal.SIGTERM else -signal.SIGKILL
    assert p.returncode == expected, (p.returncode, err[-2000:])
    wait_for(lambda: all(gone(w) for w in workers), GRACE_S, f"workers {workers} to die")
    return time.monotonic() - t0


def rows(db: Path, what: str, table: str) -> list[tuple]:
    with sqlite3.connect(db) as c:
        return c.execute(f"SELECT {what} FROM {table} ORDER BY {what}").fetchall()


def crash_test(workdir: Path, worker_kills: int = 10, coordinator_kills: int = 3,
               instances: int = 5, queries: int = 10000, timeout_s: float = 6.0,
               seed: int = 1, log=print) -> dict:
    """Run the crash test in ``workdir``; raises AssertionError on a violated rule, else returns
    what happened."""
    rng = random.Random(seed)
    clean_db, db = workdir / "clean.sqlite", workdir / "crash.sqlite"
    t = time.monotonic()
    clean = start(sweep_cmd(clean_db, instances, queries))
    out, err = clean.communicate(timeout=600)
    assert clean.returncode == 0, err[-2000:]
    total = count(clean_db)
    log(f"clean run: {total} episodes in {time.monotonic() - t:.1f} s")
    # the timeout must catch only the frozen worker: at least 4x the slowest clean episode
    # (a loaded machine slows every episode alike)
    with sqlite3.connect(clean_db) as c:
        slowest = float(c.execute("SELECT MAX(wall_s) FROM episodes").fetchone()[0] or 0.0)
    timeout_s = max(timeout_s, 4.0 * slowest)

    cmd = sweep_cmd(db, instances, queries, "--episode-timeout", f"{timeout_s:g}")
    t = time.monotonic()
    done = {"worker_kills": 0, "coordinator_kills": 0, "starts": 0, "stopped": 0}
    worst = 0.0
    per_run = [worker_kills // (coordinator_kills + 1)] * (coordinator_kills + 1)
    per_run[-1] += worker_kills - sum(per_run)
    for run, kills in enumerate(per_run):
        p = start(cmd)
        done["starts"] += 1
        last = run == coordinator_kills
        stopped = kill_worker(p, db, rng, signal.SIGSTOP) if last else None
        for _ in range(kills):
            if kill_worker(p, db, rng, signal.SIGKILL, spare=stopped) is not None:
                done["worker_kills"] += 1
        if not last:
            sig = signal.SIGKILL if run % 2 == 0 else signal.SIGTERM
            took = kill_coordinator(p, db, sig)
            if took is None:  # a fast machine finished the sweep first: nothing left to kill
                log(f"run {run}: the sweep finished before its coordinator kill")
                break
            worst = max(worst, took)
            done["coordinator_kills"] += 1
            log(f"run {run}: {kills} worker kills, coordinator {sig.name}: "
                f"{count(db)}/{total} rows")
            continue
        if stopped is not None:
            done["stopped"] = 1
            wait_for(lambda pid=stopped: gone(pid), 1.1 * timeout_s + 11, "the frozen worker's end")
        _, err = p.communicate(timeout=600)
        assert p.returncode == 0, err[-2000:]
        log(f"run {run}: {kills} worker kills, 1 worker SIGSTOP, finished: {count(db)}/{total}")
    with sqlite3.connect(db) as c:
        failures = c.execute("SELECT reason FROM episodes WHERE status != 'ok'").fetchall()
    assert len(failures) <= done["stopped"], failures
    assert all(r.startswith("timeout") for (r,) in failures), failures
    retry = start(cmd + ["--retry-failed"])
    _, err = retry.communicate(timeout=600)
    assert retry.returncode == 0, err[-2000:]
    crash_s = time.monotonic() - t

    # a fast machine may finish the sweep before the planned kills; what happened is reported
    assert done["worker_kills"] >= 1, f"the sweep ended before any worker kill: {done}"
    assert done["coordinator_kills"] >= 1, f"the sweep ended before any coordinator kill: {done}"
    assert rows(db, ROWS, "episodes") == rows(clean_db, ROWS, "episodes"), "episodes differ"
    assert rows(db, STEPS, "steps") == rows(clean_db, STEPS, "steps"), "step logs differ"
    with sqlite3.connect(db) as c:
        assert c.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
    return {**done, "episodes": total, "timeouts_recorded_then_retried": len(failures),
            "rows_lost_duplicated_or_changed": 0,
            "slowest_worker_cleanup_after_coordinator_kill_s": round(worst, 2),
            "crash_runs_s": round(crash_s, 1)}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--worker-kills", type=int, default=20)
    ap.add_argument("--coordinator-kills", type=int, default=4)
    ap.add_argument("--instances", type=int, default=10, help="x 8 episodes")
    ap.add_argument("--queries", type=int, default=10000)
    ap.add_argument("--episode-timeout", type=float, default=6.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--dir", default=None, help="work folder (default: a temporary one)")
    a = ap.parse_args()
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        workdir = Path(a.dir or tmp)
        workdir.mkdir(parents=True, exist_ok=True)
        summary = crash_test(workdir, a.worker_kills, a.coordinator_kills, a.instances,
                             a.queries, a.episode_timeout, a.seed)
    print(json.dumps(summary, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
