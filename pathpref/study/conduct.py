"""Conducting a study: a participant's trials in order, each run, recorded and resumable.

:func:`run_study` opens the results database (the same store as sweeps, schema 4), refuses a
participant id that already has trials unless ``resume`` (then the trial a killed session left
unfinished is deleted and run again, and finished trials are skipped), and runs the
participant's trials (:meth:`~.plan.Study.order_for`) through a :class:`FrontEnd`: the browser
(:mod:`.server`), the MuJoCo viewer (:mod:`.viewer`) or a scripted participant
(:mod:`.script`). Every trial gets a rerun file beside the database:
``DB_STEM.rerun/PARTICIPANT-K-NAME.rrd``.
"""

from __future__ import annotations

import re
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import Protocol

from ..episode import cached_map
from ..errors import ConfigError
from ..experiments.store import ResultStore
from ..experiments.trials import TrialWriter, dumps
from .plan import Study, Trial
from .record import TrialRecorder
from .session import TrialRunner

PARTICIPANT_RE = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}")


class FrontEnd(Protocol):
    """What shows a trial to the participant and carries their pushes to the physics."""

    name: str

    def begin_trial(self, position: int, total: int, runner: TrialRunner) -> None:
        """Show the trial and wait until the participant is ready; attach physics hooks
        (the push source is given to the runner by :meth:`source`)."""

    def source(self):
        """The :class:`~.session.PushSource` of the trials (None: the front end writes
        ``xfrc_applied`` itself, as the MuJoCo viewer does)."""

    def after_decision(self, runner: TrialRunner) -> None:
        """After every decision step (refresh what is shown)."""

    def end_trial(self, runner: TrialRunner, outcome: dict) -> None:
        """Show the trial's outcome."""

    def close(self) -> None:
        """The study is over (or aborted): release windows and sockets."""


def check_participant(pid: str) -> str:
    """A participant id: 1..64 letters, digits, ``_``, ``.``, ``-`` (it names files)."""
    if not isinstance(pid, str) or not PARTICIPANT_RE.fullmatch(pid):
        raise ConfigError(f"--participant must be 1..64 letters, digits, '_', '.' or '-' "
                          f"starting with a letter or digit, got {str(pid)[:40]!r}")
    return pid


def rerun_path(db: str | Path, participant: str, position: int, trial: Trial) -> Path:
    """Where the rerun file of a trial goes (module docstring)."""
    db = Path(db)
    name = re.sub(r"[^A-Za-z0-9_.-]", "_", trial.name)[:40]
    return db.with_name(db.stem + ".rerun") / f"{participant}-{position:02d}-{name}.rrd"


def run_study(study: Study, participant: str, db: str | Path, front: FrontEnd,
              resume: bool = False, log=print) -> list[dict]:
    """Run (or resume) ``participant``'s trials of ``study`` into ``db``; the trial rows."""
    check_participant(participant)
    store = ResultStore(db)
    try:
        writer = TrialWriter(store.conn, participant)
        existing = writer.trials()
        if existing and not resume:
            raise ConfigError(
                f"participant {participant!r} already has {len(existing)} trial(s) in {db}; "
                "give --resume to continue them, or another --participant")
        if existing and existing[0]["study_hash"] != study.hash:
            raise ConfigError(f"participant {participant!r} in {db} ran another study file "
                              f"({existing[0]['study']}); resume with that file")
        lost = writer.discard_unfinished()
        if lost:
            log(f"trial {', '.join(map(str, lost))} of {participant!r} did not finish; "
                "running it again")
        done = {r["trial"] for r in writer.trials()}
        order = study.order_for(participant)
        for position, trial in enumerate(order, start=1):
            if position in done:
                continue
            run_trial(study, trial, position, len(order), participant, db, writer, front, log)
        return writer.trials()
    finally:
        front.close()
        store.close()


def run_trial(study: Study, trial: Trial, position: int, total: int, participant: str,
              db: str | Path, writer: TrialWriter, front: FrontEnd, log=print) -> dict:
    """Run one trial through ``front`` and record it (row written first as ``running``)."""
    runner = TrialRunner(trial, study.seed, front.source())
    front.begin_trial(position, total, runner)
    rerun = rerun_path(db, participant, position, trial)
    rerun.parent.mkdir(parents=True, exist_ok=True)
    writer.begin(position, {
        "name": trial.name, "study_index": trial.index, "study": study.path,
        "study_hash": study.hash,
        "condition": dumps(trial.condition), "show_belief": int(trial.show_belief),
        "front_end": front.name, "map": trial.map,
        "map_hash": cached_map(trial.map).content_hash, "method": trial.method,
        "preset": trial.preset, "queries": trial.queries, "start": dumps(trial.start),
        "goal": dumps(trial.goal), "candidates": dumps(trial.candidates),
        "route": dumps(trial.route), "time_limit_s": trial.time_limit_s, "seed": study.seed,
        "rerun": str(rerun), "started_utc": datetime.now(UTC).isoformat(timespec="seconds")})
    recorder = TrialRecorder(writer, position, runner, rerun)
    wall = time.perf_counter()
    while not runner.done:
        runner.decide()
        recorder.after_decision()
        front.after_decision(runner)
    outcome = recorder.finish() | {"wall_s": time.perf_counter() - wall}
    writer.finish(position, outcome)
    front.end_trial(runner, outcome)
    log(f"{participant} trial {position}/{total} ({trial.name}): {outcome['outcome']} in "
        f"{outcome['time_s']:.1f} s, {outcome['pushes']} pushes, {outcome['cues']} cues, "
        f"effort {outcome['effort_ns']:.1f} N s")
    return outcome
