"""A results database saved before the house was rebuilt (issue 11) replays exactly.

``tests/data/saved_sweep.sqlite`` holds 39 episodes written by the code of commit 7410427:
a Table I style sweep under ``--preset paper`` (simple: the four methods at Delta_T 1 and 5,
three instances; office: the four methods at Delta_T 5, two instances; 1000 queries), two
``--preset robust`` episodes, and three MuJoCo episodes (``navigate`` and ``carry``). Every
stored outcome, count, physical metric and per-step log (cells, actions, headings, P(true goal)
and goal entropy) must come out the same from today's code: discrete values exactly, floats to
``tests/close.py``'s tolerance (they differ in the last bits between CPU classes;
docs/experiments.md, "Replays exactly").

The robust search has changed on purpose since the save (each violation costs its own factor
``rho``; the root breaks statistical ties by the rollout heuristic), so its four episodes are
replayed for what does not depend on the planner: the key, the instance (start, goals, true
goal) and the status. Every other row must match in full.

The Jaco's carrying posture has changed on purpose too (moved within the disk's footprint, the
tray 0.1 m ahead and 0.8 m up): the ``carry`` episode replays its outcome and per-step log
exactly and its metrics but four, which the posture sets and :data:`REPINNED` holds as the
replay gave them (the saved ones: ``ik_solves`` 401, ``sim_time_s`` 4.008, ``tilt_max_deg``
1.565, ``tilt_rms_deg`` 0.845).
"""

from __future__ import annotations

import json
import shutil
import sqlite3

import pytest

from pathpref.episode import run_episode
from pathpref.experiments.store import row_spec
from tests.close import REL, REL_PHYSICS, assert_same

SAVED = "tests/data/saved_sweep.sqlite"
OUTCOME = ("goal_reached", "pref_followed", "success", "steps", "inputs", "violations",
           "back_crossings", "true_goal", "start", "goals", "status")


def _rows(tmp_path):
    db = tmp_path / "saved.sqlite"
    shutil.copy(SAVED, db)  # the stored file stays as it is
    conn = sqlite3.connect(db)
    conn.row_factory = sqlite3.Row
    eps = [dict(r) for r in conn.execute("SELECT * FROM episodes ORDER BY key")]
    steps = {}
    for r in conn.execute("SELECT * FROM steps ORDER BY key, t"):
        steps.setdefault(r["key"], []).append(tuple(r)[1:])
    conn.close()
    return eps, steps


PLANNER_FREE = ("true_goal", "start", "goals", "status")
#: the saved ``carry`` episode's metrics that the Jaco's carrying posture sets, as the
#: replay at the current posture gives them (module docstring); by the episode's map, method
#: and task
REPINNED = {("simple", "path_preference", "carry"): {
    "ik_solves": 459.0, "sim_time_s": 4.588, "tilt_max_deg": 2.4984174252360623,
    "tilt_rms_deg": 0.7091182692556912}}


def _replay(row, steps):
    if row["sim"] == "mujoco":
        pytest.importorskip("mujoco")
        import pathpref.sim  # noqa: F401 - registers the MuJoCo bodies
    res = run_episode(row_spec(row))
    assert res.spec.key() == row["key"]
    got = {"goal_reached": int(res.goal_reached), "pref_followed": int(res.pref_followed),
           "success": int(res.success), "steps": res.steps, "inputs": res.inputs,
           "violations": res.violations, "back_crossings": res.back_crossings,
           "true_goal": res.instance.true_goal, "status": res.status,
           "start": json.dumps(res.instance_cells["start"]),
           "goals": json.dumps(res.instance_cells["goals"])}
    if row["preset"] == "robust":  # changed on purpose (module docstring)
        assert {k: got[k] for k in PLANNER_FREE} == {k: row[k] for k in PLANNER_FREE}
        return
    assert got == {k: row[k] for k in OUTCOME}, row["key"]
    want = {**json.loads(row["metrics"]),
            **REPINNED.get((row["map"], row["method"], row["task"]), {})}
    assert_same(res.metrics, want, row["key"],
                rel=REL_PHYSICS if row["sim"] == "mujoco" else REL)
    log = [(s.t, s.x, s.y, s.action, s.heading, s.p_true_goal, s.goal_entropy)
           for s in res.log]
    assert [r[:5] for r in log] == [r[:5] for r in steps[row["key"]]], row["key"]
    assert_same(log, steps[row["key"]], row["key"])


@pytest.mark.cross_cpu
def test_saved_grid_sweep_replays_exactly(tmp_path):
    eps, steps = _rows(tmp_path)
    grid = [r for r in eps if r["sim"] == "grid"]
    assert len(grid) == 36 and {r["preset"] for r in grid} == {"paper", "robust"}
    assert sum(r["success"] for r in grid) > 0 and sum(not r["success"] for r in grid) > 0
    for row in grid:
        _replay(row, steps)


@pytest.mark.cross_cpu
def test_saved_physics_episodes_replay_exactly(tmp_path):
    eps, steps = _rows(tmp_path)
    phys = [r for r in eps if r["sim"] == "mujoco"]
    assert sorted(r["task"] for r in phys) == ["carry", "navigate", "navigate"]
    for row in phys:
        _replay(row, steps)
