"""The physics step's Python changes no result: a few physical episodes (navigate with the
realistic, ideal and legacy sensing, pushes at any time, the differential drive, carry) and
control-rate task runs replay ``tests/data/physics_traces.json`` (written by
``scripts/physics_traces.py`` with the per-step code of 23bd330, before the step was cut;
the carry row re-pinned when the physical arm's IK went from 100 to 20 Hz: the same steps,
cues, cells and counts, ``ik_solves`` 922 -> 185, the tilt within 4e-4 and every other float
within 5e-7 relative; the "navigate any time" row re-pinned when the safety filter came to
act on every move that starts off its cell's centre, as moves after a yield do: the same
steps, cues, cells and counts, no contact, the felt pushes' peaks within 1.3e-4 relative;
the carry row re-pinned again when the Jaco's carrying posture moved within the disk's
footprint, the tray 0.1 m ahead and 0.8 m up: the same steps, cues, cells and counts, the
felt push's peak within 2e-4 relative, ``tip_force_n`` 240.3 -> 227.3 N (the tray 0.05 m
higher), ``tilt_max_deg`` 1.01 -> 1.67, ``tilt_rms_deg`` 0.51 -> 0.40):
decision steps, cue headings and cells, counts exactly; times, forces,
impulses and the base's final ``qpos`` to ``tests/close.py``'s ``REL_PHYSICS``."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

import pytest  # noqa: E402

from tests.close import REL_PHYSICS, assert_same  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))

from physics_traces import EPISODES, TASKS, episode, task_run  # noqa: E402

WANT = json.loads((ROOT / "tests/data/physics_traces.json").read_text())


def _effort_apart(got: dict) -> None:
    """The person's effort measures (added after the traces were written: the metrics are
    otherwise the pinned ones) taken out of ``got``'s metrics, checked present and sane."""
    from pathpref.experiments.report import EFFORT

    m = got.get("metrics")
    if not isinstance(m, dict) or "pushes" not in m:
        return
    effort = {k: m.pop(k) for k in EFFORT}
    assert all(v >= 0 for v in effort.values())
    assert effort["person_impulse_ns"] <= effort["person_peak_n"] * \
        effort["person_contact_s"] + 1e-9


@pytest.mark.cross_cpu
@pytest.mark.parametrize("row", EPISODES, ids=[r[0] for r in EPISODES])
def test_episode_replays(row):
    """One physical episode (module docstring); the effort measures apart
    (:func:`_effort_apart`)."""
    got, want = episode(row), WANT[row[0]]
    _effort_apart(got)
    assert [s[:5] for s in got["steps"]] == want["steps"]
    assert [f[:2] for f in got["felt"]] == [f[:2] for f in want["felt"]]
    for k in ("pushes", "pushes_missed", "pushes_misread", "collisions", "cues_felt"):
        assert got["metrics"].get(k) == want["metrics"].get(k), k
    assert_same(got, want, row[0], rel=REL_PHYSICS)


@pytest.mark.cross_cpu
@pytest.mark.parametrize("row", TASKS, ids=[r[0] for r in TASKS])
def test_control_task_replays(row):
    """A control-rate task run by its own policy (module docstring); the effort measures
    apart (:func:`_effort_apart`)."""
    got, want = task_run(row), WANT[row[0]]
    _effort_apart(got)
    assert got["rewards"] == want["rewards"] and got["cells"] == want["cells"]
    assert [f[:2] for f in got["felt"]] == [f[:2] for f in want["felt"]]
    assert_same(got, want, row[0], rel=REL_PHYSICS)
