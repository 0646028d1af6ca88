"""Recording a trial as it happens: the study tables of the results store
(:mod:`pathpref.experiments.trials`) and a rerun file per trial.

Per physics step (the control rate, 2 ms) the applied force and the sensed force; a push is a
maximal run of steps with applied force above :data:`PUSH_ON_N`; effort is the integral of
``|F| dt`` of the applied force (N s). Every
:data:`~pathpref.experiments.trials.PATH_EVERY`-th physics step (100 Hz at 2 ms) the base's
position and the end effector's (``trial_path``). Per cue: time, cell, heading, magnitude; per
belief update (start, each cue, each decision): the goal probabilities. Rows are flushed to the
database in one transaction after every decision step.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from ..episode import Felt
from ..experiments.trials import PATH_EVERY, TrialWriter
from ..sim.mobile_base import MobileBase
from ..viz.rerun_log import RerunLogger
from .session import TrialRunner

PUSH_ON_N = 0.5  # applied force (N) above which the participant is pushing
RERUN_EVERY = 10  # physics steps between rerun frames (50 Hz)


class TrialRecorder:
    """Records ``runner``'s trial at position ``trial`` through ``writer`` (module docstring);
    ``rerun`` is the trial's ``.rrd`` path (None: no rerun file)."""

    def __init__(self, writer: TrialWriter, trial: int, runner: TrialRunner,
                 rerun: Path | None = None, lsl=None, live=None):
        self.writer, self.trial, self.runner = writer, trial, runner
        self.lsl = lsl  # LslOutlets (:mod:`.lsl`) or None
        self.live = live  # LiveView (:mod:`.live`) or None
        self.rows: dict[str, list[tuple]] = {t: [] for t in (
            "trial_steps", "trial_forces", "trial_pushes", "trial_cues", "trial_beliefs",
            "trial_path")}
        self.k_path = 0
        self.k_force = self.k_belief = self.k_push = self.n_cues = 0
        self.effort = 0.0
        self.push: list[float] | None = None  # [t_start, peak, impulse_x, impulse_y]
        self.dt = float(runner.base.model.opt.timestep)
        self.rerun = RerunLogger(runner.world, np.array(runner.trial.candidates),
                                 runner.trial.goal_index, rerun,
                                 cell_size=runner.base.scene.cell_size) if rerun else None
        if self.rerun:
            self.rerun.log_route(np.array(runner.trial.route))
        runner.base.on_substep.insert(0, self._substep)  # first: the force of this step
        runner.on_cue.append(self._cue)
        runner.on_belief.append(self._belief)
        if self.lsl:
            self.lsl.event("trial_start", trial)
        if self.live:
            t = runner.trial
            self.live.show(time.time_ns(), runner.world, t.start, t.candidates, t.goal, t.route)
        self._belief("start")
        self._step_row()

    def _substep(self, base: MobileBase, push) -> None:
        r = self.runner
        t = r.time_s
        f = r.body.felt_force()
        sensed = base.sensing.sensor.force_xy(base.data)
        self.rows["trial_forces"].append((self.k_force, t, float(f[0]), float(f[1]),
                                          float(sensed[0]), float(sensed[1])))
        if self.lsl:
            self.lsl.force(*self.rows["trial_forces"][-1][2:])
        if self.k_force % PATH_EVERY == 0:
            self._path_row(t, base)
        self.k_force += 1
        n = float(np.hypot(*f))
        self.effort += n * self.dt
        if n > PUSH_ON_N:
            if self.push is None:
                self.push = [t - self.dt, 0.0, 0.0, 0.0]
            self.push[1] = max(self.push[1], n)
            self.push[2] += float(f[0]) * self.dt
            self.push[3] += float(f[1]) * self.dt
        elif self.push is not None:
            self._end_push(t)
        if self.rerun and self.k_force % RERUN_EVERY == 0:
            self.rerun.log_frame(float(base.data.time), base.position.copy())

    def _path_row(self, t: float, base: MobileBase) -> None:
        x, y = (float(v) for v in base.position[:2])
        ee = base.end_effector
        e = (None, None, None) if ee is None else tuple(float(v) for v in ee[:3])
        self.rows["trial_path"].append((self.k_path, t, x, y, *e))
        if self.lsl:
            self.lsl.pose(x, y, e)
        if self.live:
            self.live.pose(time.time_ns(), x, y, float(base.data.qpos[base.yaw]))
        self.k_path += 1

    def _end_push(self, t: float) -> None:
        s, peak, jx, jy = self.push
        self.rows["trial_pushes"].append((self.k_push, s, t, peak, jx, jy))
        if self.lsl:
            self.lsl.event("push", self.trial, k=self.k_push, t_start=s, t_end=t, peak_n=peak)
        self.k_push += 1
        self.push = None

    def _cue(self, cue: Felt) -> None:
        x, y = self.runner.world.cells[self.runner.base.cell]
        self.rows["trial_cues"].append((
            self.n_cues, self.runner.time_s, int(x), int(y), int(cue.heading),
            float(cue.peak_n), float(cue.impulse[0]), float(cue.impulse[1]),
            float(cue.duration_s)))
        if self.lsl:
            self.lsl.event("cue", self.trial, k=self.n_cues, time_s=self.runner.time_s,
                           heading=int(cue.heading))
        self.n_cues += 1

    def _belief(self, cause: str) -> None:
        p = self.runner.policy.belief.goal_marginal()
        self.rows["trial_beliefs"].append((self.k_belief, self.runner.time_s, cause,
                                           json.dumps([round(float(v), 6) for v in p])))
        if self.lsl:
            self.lsl.event("belief", self.trial, k=self.k_belief, cause=cause,
                           p=[round(float(v), 6) for v in p])
        if self.live:
            self.live.belief(time.time_ns(), p)
        self.k_belief += 1

    def _step_row(self) -> None:
        r = self.runner
        s = r.result.log[-1]
        self.rows["trial_steps"].append((s.t, r.time_s, s.x, s.y, s.action, s.p_true_goal,
                                         s.goal_entropy))
        if self.rerun:
            last = r.cues[-1][2] if r.cues and r.cues[-1][0] >= r.time_s - 3.5 else None
            arrow = None if last is None else (
                last.impulse / max(np.linalg.norm(last.impulse), 1e-9) * last.peak_n / 60.0)
            self.rerun.log_step(s.t, r.base.position.copy(),
                                r.policy.belief.goal_marginal(), s.p_true_goal,
                                s.goal_entropy, arrow)

    def flush(self) -> None:
        """Write what was recorded since the last flush (one transaction)."""
        self.writer.write(self.trial, self.rows)
        for v in self.rows.values():
            v.clear()

    def after_decision(self) -> None:
        """Record the decision step just taken and flush."""
        self._step_row()
        self.flush()

    def finish(self) -> dict:
        """End the trial: close a push in progress, flush, close the rerun file; the trial's
        outcome columns."""
        r = self.runner
        if self.push is not None:
            self._end_push(r.time_s)
        self.flush()
        if self.rerun:
            self.rerun.close()
        res = r.result
        if self.lsl:
            self.lsl.event("trial_end", self.trial, goal_reached=bool(res.goal_reached))
        return {"outcome": "success" if res.goal_reached else "timeout",
                "success": int(res.goal_reached), "time_s": r.time_s, "steps": res.steps,
                "pushes": self.k_push, "cues": self.n_cues, "effort_ns": self.effort,
                "violations": res.violations,
                "homotopy_success": int(res.homotopy_success)}
