"""Lab Streaming Layer outlets of a live study (``study run --lsl``), read back through inlets
on the same machine: the force samples are a contiguous run of the recorded ``trial_forces``
rows (float32), the pose samples of ``trial_path``, and the markers name the recorded
pushes."""

from __future__ import annotations

import json
import sqlite3
import threading
from pathlib import Path

import numpy as np
import pytest

from pathpref.apps.cli import main

ROOT = Path(__file__).resolve().parents[1]


def _pylsl():
    try:
        import pylsl

        pylsl.local_clock()
    except (ImportError, RuntimeError, OSError) as e:
        pytest.skip(f"pylsl/liblsl unavailable: {e}")
    return pylsl


def _contiguous_run(got: np.ndarray, stored: np.ndarray) -> bool:
    """``got`` equals ``stored[i:i + len(got)]`` for some ``i`` (row-wise)."""
    n = len(got)
    return any(np.array_equal(stored[i:i + n], got) for i in range(len(stored) - n + 1))


def test_lsl_outlets_stream_force_pose_and_events(tmp_path):
    lsl = _pylsl()
    db = tmp_path / "s.sqlite"
    done: list[int] = []
    run = threading.Thread(target=lambda: done.append(main([
        "study", "run", str(ROOT / "examples" / "study_demo.json"), "--participant", "lab",
        "--db", str(db), "--script", str(ROOT / "examples" / "pushes_demo.json"), "--lsl"])))
    run.start()
    try:
        inlets = {}
        for kind in ("force", "pose", "events"):
            found = lsl.resolve_byprop("source_id", f"pathpref-lab-{kind}", 1, 30.0)
            assert found, kind
            inlets[kind] = lsl.StreamInlet(found[0], max_buflen=360)
            inlets[kind].open_stream(timeout=10.0)
        got: dict[str, list] = {k: [] for k in inlets}
        for _ in range(2000):  # bounded: 2000 x 50 ms
            for kind, inlet in inlets.items():
                samples, _ = inlet.pull_chunk(timeout=0.0)
                got[kind].extend(samples)
            if not run.is_alive():
                break
            run.join(0.05)
        for kind, inlet in inlets.items():  # what was sent before the run ended
            samples, _ = inlet.pull_chunk(timeout=1.0)
            got[kind].extend(samples)
    finally:
        run.join(120)
    assert done == [0]
    c = sqlite3.connect(db)
    forces = np.array(c.execute("SELECT fx, fy, sensed_fx, sensed_fy FROM trial_forces "
                                "ORDER BY trial, k").fetchall(), np.float32)
    assert len(got["force"]) > 500
    assert _contiguous_run(np.array(got["force"], np.float32), forces)
    path = np.array(c.execute("SELECT x, y FROM trial_path ORDER BY trial, k").fetchall(),
                    np.float32)
    pose = np.array(got["pose"], np.float32)
    assert len(pose) > 100 and np.isnan(pose[:, 2:]).all()  # the plain base: no end effector
    assert _contiguous_run(pose[:, :2], path)
    events = [json.loads(s[0]) for s in got["events"]]
    pushes = [(e["trial"], e["k"]) for e in events if e["event"] == "push"]
    stored = c.execute("SELECT trial, k FROM trial_pushes ORDER BY trial, k").fetchall()
    assert pushes and _contiguous_run(np.array(pushes), np.array(stored))
    assert events[-1] == {"event": "trial_end", "trial": 2, "goal_reached": True}
