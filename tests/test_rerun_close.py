"""Closing a rerun recording is bounded: rerun's flush and disconnect wait without end when
the disk is full (a study run on a 2.75 MB file system hung in its disconnect), so the
recording waits at most its timeout, then reports (``close``) or gives up quietly
(``abandon``)."""

from __future__ import annotations

import errno
import threading
import time

import numpy as np
import pytest

from pathpref.episode.cache import cached_world
from pathpref.viz.rerun_log import RerunLogger


class StuckStream:
    """A recording stream whose file never drains: the flush times out as rerun's does
    (RuntimeError after ``timeout_sec``), the disconnect never returns."""

    def __init__(self):
        self.never = threading.Event()

    def flush(self, timeout_sec: float = 1e38) -> None:
        time.sleep(timeout_sec)
        raise RuntimeError("flush timed out")

    def disconnect(self) -> None:
        self.never.wait()


@pytest.fixture
def stuck(tmp_path):
    world = cached_world("simple")
    log = RerunLogger(world, np.array([[2, 2], [8, 8]]), 0, tmp_path / "e.rrd")
    log.rec.disconnect()  # the real stream is done with; the stuck one replaces it
    log.rec = StuckStream()
    yield log
    log.rec.never.set()


def test_abandon_returns_within_its_bound(stuck):
    t = time.monotonic()
    stuck.abandon(timeout_s=0.2)
    assert time.monotonic() - t < 3.0  # two waits of 0.2 s, with room for a loaded machine


def test_close_reports_an_unwritten_file_within_its_bound(stuck, tmp_path):
    t = time.monotonic()
    with pytest.raises(OSError) as e:
        stuck.close(timeout_s=0.2)
    assert time.monotonic() - t < 3.0
    assert e.value.errno == errno.EIO  # tmp_path's file system has room: not ENOSPC
    assert str(tmp_path / "e.rrd") in str(e.value) and "flush timed out" in str(e.value)


def test_a_stuck_disconnect_alone_is_reported(stuck, tmp_path):
    stuck.rec.flush = lambda timeout_sec=1e38: None  # flushed; the disconnect never returns
    with pytest.raises(OSError, match="not closed within 0.2 s"):
        stuck.close(timeout_s=0.2)


def test_render_abandons_its_recording_when_a_write_fails(tmp_path, capsys, monkeypatch):
    """A full disk mid-episode (rerun's error at a log call): ``render --rerun`` abandons the
    recording, so rerun's exit hook cannot wait on it (a render on a 450 KB tmpfs hung there),
    and ends in one line naming the file, leaving none."""
    from pathpref.apps.cli import main

    abandoned = []

    def full(self, *a, **k):
        raise RuntimeError("Failed to write: No space left on device (os error 28)")

    real_abandon = RerunLogger.abandon
    monkeypatch.setattr(RerunLogger, "log_step", full)
    monkeypatch.setattr(RerunLogger, "abandon",
                        lambda self, *a, **k: (abandoned.append(self), real_abandon(self, 0.5)))
    out = tmp_path / "e.rrd"
    assert main(["render", "--rerun", str(out), "--map", "simple"]) == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln]
    assert len(err) == 1 and f"cannot write {out}: no space left on device" in err[0], err
    assert len(abandoned) == 1 and not out.exists()
    assert list(tmp_path.iterdir()) == []


def test_the_command_ends_at_once_when_it_holds_a_failed_recording():
    """``console_main`` (the ``pathpref`` command) ends a process holding a failed recording
    with its exit status at once, output flushed: nothing after it runs, no exit hook (rerun's
    destructor of that stream would wait on a full disk without end)."""
    import subprocess
    import sys

    code = ("import atexit, sys\n"
            "from pathpref.viz import rerun_log\n"
            "rerun_log._FAILED.append(object())\n"
            "atexit.register(lambda: print('EXIT HOOK RAN'))\n"
            "sys.argv = ['pathpref', 'map', 'info', 'simple', '--json']\n"
            "from pathpref.apps.cli import console_main\n"
            "console_main()\n"
            "print('AFTER')\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert '"name": "simple"' in r.stdout
    assert "AFTER" not in r.stdout and "EXIT HOOK RAN" not in r.stdout
