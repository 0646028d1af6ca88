"""``pathpref replay``: a recorded trial rendered to a video by running it again in physics.

The recorded force of every physics step (``trial_forces``: what the participant's front end
applied to the handle) is fed back through the same :class:`~.session.TrialRunner`, so the
robot senses, detects, updates its belief and plans exactly as it did; the planner is seeded
from the trial's row and plans by query count (no wall-time budget), so on the same machine
and library versions the replay reproduces the trial step for step (checked against the
recorded ``trial_steps``, and reported). Re-running beats drawing stored states because the
database then needs no per-frame robot state, and the video shows the physics itself (the
base yielding to the push, the arrow of the applied force, the goals tinted by the belief).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..errors import ConfigError
from ..experiments.store import ResultStore
from ..experiments.trials import has_study_tables, read_rows
from ..sim.render import Overlay, RolloutRenderer, write_video
from ..viz.video import belief_rgba, compose
from .plan import Trial
from .session import TrialRunner

VIDEO_FPS = 25


class RecordedPushes:
    """A push source that gives back the force recorded for each physics step."""

    def __init__(self, forces: np.ndarray):
        self.forces = np.asarray(forces, float).reshape(-1, 2)
        self.k = 0

    def force(self) -> np.ndarray:
        """The force recorded for the next physics step (zero after the recording ends)."""
        self.k += 1
        return self.forces[self.k] if self.k < len(self.forces) else np.zeros(2)


def load_recorded_trial(db: str | Path, participant: str, trial: int
                        ) -> tuple[Trial, int, np.ndarray, list[tuple[int, int, int]]]:
    """The trial (as run), its seed, its per-step forces and its recorded ``(t, x, y)``."""
    with ResultStore(db, create=False) as store:
        c = store.conn
        if not has_study_tables(c):
            raise ConfigError(f"{db} holds no study trials")
        rows = read_rows(c, "trials", "WHERE participant = ? AND trial = ?",
                         (participant, trial))
        if not rows:
            have = [r["trial"] for r in read_rows(c, "trials", "WHERE participant = ?",
                                                  (participant,))]
            raise ConfigError(
                f"{db} has no trial {trial} of participant {participant!r}"
                + (f" (it has trials {', '.join(map(str, have))})" if have else
                   " (no trials of that participant)"))
        r = rows[0]
        if r["status"] != "done":
            raise ConfigError(f"trial {trial} of {participant!r} did not finish; there is "
                              "nothing whole to replay")
        forces = np.array([(f["fx"], f["fy"]) for f in read_rows(
            c, "trial_forces", "WHERE participant = ? AND trial = ? ORDER BY k",
            (participant, trial))], float)
        steps = [(s["t"], s["x"], s["y"]) for s in read_rows(
            c, "trial_steps", "WHERE participant = ? AND trial = ? ORDER BY t",
            (participant, trial))]

    def cells(key: str) -> tuple:
        return tuple(tuple(c) for c in json.loads(r[key]))

    t = Trial(index=r["study_index"], name=r["name"], map=r["map"], method=r["method"],
              preset=r["preset"], queries=r["queries"], start=tuple(json.loads(r["start"])),
              goal=tuple(json.loads(r["goal"])), candidates=cells("candidates"),
              route=cells("route"), time_limit_s=r["time_limit_s"],
              condition=json.loads(r["condition"] or "{}"))
    return t, int(r["seed"]), forces, steps


def replay_trial(db: str | Path, participant: str, trial: int, out: str | Path,
                 width: int = 960, height: int = 540) -> int:
    """Render trial ``trial`` of ``participant`` to ``out`` (MP4, real time); the number of
    frames. A replay that departs from the recorded steps is a ConfigError naming the step."""
    spec, seed, forces, recorded = load_recorded_trial(db, participant, trial)
    runner = TrialRunner(spec, seed, RecordedPushes(forces))
    base, world = runner.base, runner.world
    renderer = RolloutRenderer(base.scene, width, height)
    every = max(1, int(round(1.0 / VIDEO_FPS / base.dt)))
    frames: list[np.ndarray] = []
    goals = np.array(spec.candidates)
    route = np.array(spec.route)
    polygons = world.arrangement.polygons
    k = {"n": 0}

    def hook(b, push) -> None:
        k["n"] += 1
        if k["n"] % every:
            return
        o = Overlay(goal_cells=goals, goal_rgba=belief_rgba(runner.policy.belief.goal_marginal()),
                    true_goal=spec.goal_index, polygons=polygons,
                    current=int(world.cell_polytope[b.cell]), robot_xy=b.position.copy(),
                    push_origin=b.data.xpos[b.pushed_body].copy(),
                    push_force=np.array([*runner.body.applied, 0.0]), route=route)
        top, persp = renderer.views(b.data, o)
        frames.append(compose(top, persp, None, width, height))

    def departs(at: int) -> ConfigError:
        return ConfigError(f"the replay departs from the recording at decision step {at} "
                           "(another machine or library version?); no video written")

    base.on_substep.append(hook)
    try:
        while not runner.done:
            runner.decide()
            s = runner.result.log[-1]
            if s.t >= len(recorded) or recorded[s.t] != (s.t, s.x, s.y):
                raise departs(s.t)
    finally:
        renderer.close()
    if len(runner.result.log) != len(recorded):
        raise departs(len(runner.result.log))
    write_video(frames, out, VIDEO_FPS)
    return len(frames)
