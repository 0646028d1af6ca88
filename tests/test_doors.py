"""Every door builds the same episode: the CLI, ``EpisodeSpec``, ``pathpref_tasks.load`` and a
study plan resolve the planner, the mission time and the physics from one home (the preset's
defaults, the map's ``t_max``, ``Physics()``), so a study, a task and a sweep see the same
robot unless told otherwise."""

from __future__ import annotations

import os
import subprocess
import sys

os.environ.setdefault("MUJOCO_GL", "egl")

from pathpref_tasks import load  # noqa: E402

from pathpref.episode import EpisodeSpec, Physics  # noqa: E402
from pathpref.experiments.store import ResultStore, row_spec  # noqa: E402
from pathpref.planning.pomdp import DEFAULT_PRESET, get_preset  # noqa: E402

SETTINGS = ("preset", "queries", "t_max", "physics", "coupling", "prior", "ucb_c",
            "normalize", "human", "time_budget_ms", "sim", "robot")


def _settings(spec: EpisodeSpec) -> dict:
    return {k: getattr(spec, k) for k in SETTINGS}


def test_every_door_resolves_the_same_settings(tmp_path):
    from pathpref.study.plan import parse_study
    from pathpref.study.session import TrialRunner

    spec = EpisodeSpec.single("classroom", "path_preference", 5, sim="mujoco")
    want = _settings(spec)
    # worked out independently: the default preset, its queries, classroom's own t_max
    # (3 x its longer side: 60), the default physics of a physical body
    assert want["preset"] == DEFAULT_PRESET == "robust-slack"
    assert want["queries"] == get_preset("robust-slack").queries
    assert want["t_max"] == 60 and want["physics"] == Physics().to_json()
    db = tmp_path / "one.sqlite"
    done = subprocess.run(
        [sys.executable, "-m", "pathpref", "evaluate", "--map", "classroom", "--methods",
         "path_preference", "--delta-t", "5", "--instances", "1", "--runs", "1", "--sim",
         "mujoco", "--db", str(db), "--workers", "1", "--no-progress", "--t-max", "2"],
        capture_output=True, text=True, timeout=600, env={**os.environ, "MUJOCO_GL": "egl"})
    assert done.returncode == 0, done.stderr
    with ResultStore(db, create=False) as st:
        cli = _settings(row_spec(st.episodes()[0]))
    assert cli == {**want, "t_max": 2}  # everything but the mission time given on the line
    task = load("navigate", map="classroom", method="path_preference", delta_t=5)
    assert _settings(task.task.template) == want
    study = parse_study({"trials": [{"name": "one", "map": "classroom", "start": [2, 2],
                                     "goal": [20, 20], "candidates": [[20, 20], [2, 20]],
                                     "route": [[2, 2], [20, 20]]}]}, "one.json")
    trial = TrialRunner(study.trials[0], seed=0)
    # a trial has no simulated human and one decision per cue: delta_t 1, its own candidates
    assert _settings(trial.spec) == want
