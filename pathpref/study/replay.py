"""``pathpref replay``: a recorded trial rendered to a video by running it again in physics.

The recorded force of every physics step (``trial_forces``: what the participant's front end
applied to the handle) is fed back through the same :class:`~.session.TrialRunner`, so the
robot senses, detects, updates its belief and plans exactly as it did; the planner is seeded
from the trial's row and plans by query count (no wall-time budget), so on the same machine
and library versions the replay reproduces the trial step for step (checked against the
recorded ``trial_steps``, and reported). Re-running beats drawing stored states because the
database then needs no per-frame robot state, and the video shows the physics itself (the
base yielding to the push, the arrow of the applied force, the goals tinted by the belief).

**Verified.** Before rendering, the trial row's ``pushes`` and ``effort_ns`` must be what its
``trial_forces`` give (a push a maximal run of steps above
:data:`~.record.PUSH_ON_N`; effort the sum of ``|F| dt``, to 1e-9 relative), and the
``trial_pushes`` and ``trial_cues`` tables must hold that many rows; after the run, the
replay's outcome (``success``/``timeout``), step count and cue count must equal the row's and
its trial time the row's ``time_s`` (to 1e-6 s). A row changed after the trial (a timeout
relabelled a success) is refused with one line naming the column, and no video is kept.

**The video** shows the base's trail (a point each time it has moved
:data:`TRAIL_STEP_M` since the last, the latest :data:`TRAIL_MAX` drawn) and ends, like a
rollout's, with the final frame and then the outcome card
(:func:`pathpref.viz.video.outcome_card`, :func:`study_outcome_lines`) held for
:data:`~pathpref.viz.video.CARD_S` seconds.

**Bounded memory.** Frames go to the encoder as they are drawn
(:class:`~pathpref.sim.render.VideoWriter`); nothing holds the frames of a trial (a 3600 s
trial is 90000 frames).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import ConfigError
from ..experiments.store import ResultStore
from ..experiments.trial_rows import check_trial_row, checked
from ..experiments.trials import has_study_tables, participants_hint, read_rows
from ..sim.render import Overlay, RolloutRenderer, VideoWriter
from ..viz.video import CARD_S, PanelInfo, belief_rgba, compose, info_panel, outcome_card
from .plan import Trial, trial_from_row
from .record import PUSH_ON_N
from .session import TrialRunner

VIDEO_FPS = 25
#: the trail gains a point when the base has moved this far (m) since the last one
TRAIL_STEP_M = 0.05
#: trail points drawn (the latest; each is a line segment in the scene)
TRAIL_MAX = 400


def study_outcome_lines(row: dict) -> list[tuple[str, tuple[int, int, int]]]:
    """The outcome card's lines (text, colour) for a study trial's row: the outcome and
    time, the route (followed, or its violations), pushes, cues, effort and steps."""
    good, bad, ink = (20, 140, 60), (190, 30, 30), (30, 30, 30)
    head = (f"SUCCESS: goal reached in {row['time_s']:.1f} s", good) \
        if row["outcome"] == "success" else (
        f"TIMEOUT: goal not reached in {row['time_s']:.1f} s", bad)
    v = row["violations"]
    route = "preferred route followed" if v == 0 else f"preferred route: {v} violation(s)"
    return [head, (route, good if v == 0 else bad),
            (f"pushes: {row['pushes']}   cues: {row['cues']}   effort: "
             f"{row['effort_ns']:.1f} N s", ink),
            (f"decision steps: {row['steps']}", ink)]


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
    t, seed, forces, steps, _ = load_trial(db, participant, trial)
    return t, seed, forces, steps


def forces_summary(forces: np.ndarray, dt: float) -> tuple[int, float]:
    """Pushes (maximal runs of steps with ``|F| > PUSH_ON_N``) and effort ``sum |F| dt``
    (N s) of per-step forces, as :class:`~.record.TrialRecorder` counts them."""
    n = np.hypot(forces[:, 0], forces[:, 1]) if len(forces) else np.zeros(0)
    on = n > PUSH_ON_N
    starts = int(on[0]) + int(np.count_nonzero(on[1:] & ~on[:-1])) if len(on) else 0
    return starts, float(n.sum() * dt)


def verify_row(row: dict, forces: np.ndarray, dt: float) -> None:
    """The row's push count and effort agree with its forces (``dt`` the physics step) and
    its tables (``row["rows_pushes"]``, ``row["rows_cues"]``: module docstring); else one line
    naming the column."""
    n_pushes, n_cues = row["rows_pushes"], row["rows_cues"]
    pushes, effort = forces_summary(forces, dt)
    where = f"trial {row['trial']} of {row['participant']!r}"
    if row["pushes"] != pushes or n_pushes != pushes:
        raise ConfigError(f"{where}: trials.pushes is {row['pushes']} and trial_pushes has "
                          f"{n_pushes} rows, but its recorded forces make {pushes} pushes; "
                          "the rows were changed after the trial: not replayed")
    if not abs((row["effort_ns"] or 0.0) - effort) <= 1e-9 * max(1.0, abs(effort)):
        raise ConfigError(f"{where}: trials.effort_ns is {row['effort_ns']}, but its recorded "
                          f"forces give {effort:.6g} N s; the rows were changed after the "
                          "trial: not replayed")
    if row["cues"] != n_cues:
        raise ConfigError(f"{where}: trials.cues is {row['cues']} but trial_cues has {n_cues} "
                          "rows; the rows were changed after the trial: not replayed")


def verify_outcome(row: dict, runner: TrialRunner) -> None:
    """The replay ends as the row says (module docstring); else one line naming the column."""
    res = runner.result
    got = {"outcome": "success" if res.goal_reached else "timeout",
           "success": int(res.goal_reached), "steps": res.steps, "cues": len(runner.cues)}
    for col, v in got.items():
        if row[col] != v:
            raise ConfigError(
                f"trial {row['trial']} of {row['participant']!r}: trials.{col} is "
                f"{row[col]!r} but the replay gives {v!r}; the row was changed after the "
                "trial: no video written")
    if not abs(row["time_s"] - runner.time_s) <= 1e-6:
        raise ConfigError(
            f"trial {row['trial']} of {row['participant']!r}: trials.time_s is "
            f"{row['time_s']} but the replay ends at {runner.time_s:.6f} s; the row was "
            "changed after the trial: no video written")


def load_trial(db: str | Path, participant: str, trial: int
               ) -> tuple[Trial, int, np.ndarray, list[tuple[int, int, int]], dict]:
    """:func:`load_recorded_trial` and the trial's row (with the row counts of its
    ``trial_pushes`` and ``trial_cues``: ``rows_pushes``, ``rows_cues``)."""
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
                   f" (no trials of that participant; {participants_hint(c, db)})"))
        r = check_trial_row(rows[0], db)
        if r["status"] != "done":
            raise ConfigError(f"trial {trial} of {participant!r} did not finish; there is "
                              "nothing whole to replay")
        forces = np.array([(f["fx"], f["fy"]) for f in checked("trial_forces", read_rows(
            c, "trial_forces", "WHERE participant = ? AND trial = ? ORDER BY k",
            (participant, trial)), db)], float).reshape(-1, 2)
        steps = [(s["t"], s["x"], s["y"]) for s in checked("trial_steps", read_rows(
            c, "trial_steps", "WHERE participant = ? AND trial = ? ORDER BY t",
            (participant, trial)), db)]
        n_pushes, n_cues = (c.execute(
            f"SELECT count(*) FROM {t} WHERE participant = ? AND trial = ?",
            (participant, trial)).fetchone()[0] for t in ("trial_pushes", "trial_cues"))
    return (trial_from_row(r), int(r["seed"]), forces, steps,
            r | {"rows_pushes": n_pushes, "rows_cues": n_cues})



def replay_trial(db: str | Path, participant: str, trial: int, out: str | Path,
                 width: int = 960, height: int = 540) -> int:
    """Render trial ``trial`` of ``participant`` to ``out`` (MP4, real time); the number of
    frames. A replay that departs from the recorded steps, or a row that does not hold what
    the replay gives, is a ConfigError naming the step or column (module docstring)."""
    spec, seed, forces, recorded, row = load_trial(db, participant, trial)
    runner = TrialRunner(spec, seed, RecordedPushes(forces))
    base, world = runner.base, runner.world
    verify_row(row, forces, float(base.model.opt.timestep))
    renderer = RolloutRenderer(base.scene, width, height)
    every = max(1, int(round(1.0 / VIDEO_FPS / base.dt)))
    video = VideoWriter(out, VIDEO_FPS, sample_every=VIDEO_FPS)
    goals = np.array(spec.candidates)
    route = np.array(spec.route)
    polygons = world.arrangement.polygons
    k = {"n": 0}
    trail = [base.position.copy()]

    def frame(b) -> np.ndarray:
        o = Overlay(goal_cells=goals, goal_rgba=belief_rgba(runner.policy.belief.goal_marginal()),
                    true_goal=spec.goal_index, polygons=polygons,
                    current=int(world.cell_polytope[b.cell]), robot_xy=b.position.copy(),
                    push_origin=b.data.xpos[b.pushed_body].copy(),
                    push_force=np.array([*runner.body.applied, 0.0]), route=route,
                    trail=np.array(trail[-TRAIL_MAX:] + [b.position[:2].copy()]))
        top, persp = renderer.views(b.data, o)
        panel = None
        if renderer.column >= 16 and height - renderer.persp_h >= 16:
            f = float(np.hypot(*runner.body.applied))
            cue = runner.cues[-1] if runner.cues and runner.time_s - runner.cues[-1][0] <= 1.0 \
                else None
            panel = info_panel(renderer.column, height - renderer.persp_h, PanelInfo(
                title=f"{participant} trial {trial}: {spec.name} ({spec.method})",
                step=runner.t, t_max=runner.spec.t_max, sim_time=runner.time_s,
                belief=runner.policy.belief.goal_marginal(), true_goal=spec.goal_index,
                pushes=len(runner.cues), push_n=f if f > PUSH_ON_N else None,
                cue_heading=None if cue is None else int(cue[2].heading),
                extra=[f"time limit {spec.time_limit_s:g} s",
                       f"recorded: {row['outcome']} in {row['time_s']:.1f} s"]))
        return compose(top, persp, panel, width, height)

    def hook(b, push) -> None:
        if np.hypot(*(b.position[:2] - trail[-1][:2])) >= TRAIL_STEP_M:
            trail.append(b.position[:2].copy())
            if len(trail) > 2 * TRAIL_MAX:
                del trail[:-TRAIL_MAX]  # bounded: only the latest TRAIL_MAX are drawn
        k["n"] += 1
        if k["n"] % every:
            return
        video.append(frame(b))

    def departs(at: int) -> ConfigError:
        return ConfigError(f"the replay departs from the recording at decision step {at} "
                           "(another machine or library version?); no video written")

    base.on_substep.append(hook)
    try:
        try:
            while not runner.done:
                runner.decide()
                s = runner.result.log[-1]
                if s.t >= len(recorded) or recorded[s.t] != (s.t, s.x, s.y):
                    raise departs(s.t)
            if len(runner.result.log) != len(recorded):
                raise departs(len(runner.result.log))
            verify_outcome(row, runner)
            last = frame(base)
            video.append(last)
            card = outcome_card(last, study_outcome_lines(row))
            for _ in range(int(round(CARD_S * VIDEO_FPS))):
                video.append(card)
        finally:
            renderer.close()
    except BaseException:
        try:
            video.close()
        except (OSError, ConfigError):
            pass
        Path(out).unlink(missing_ok=True)
        raise
    video.close()
    return video.frames
