"""Conducting a study: a participant's trials in order, each run, recorded and resumable.

:func:`run_study` opens the results database (the same store as sweeps, schema 4), refuses a
participant id that already has trials unless ``resume`` (then the trial a killed session left
unfinished is deleted and run again, and finished trials are skipped), and runs the
participant's trials (:meth:`~.plan.Study.order_for`) through a :class:`FrontEnd`: the browser
(:mod:`.server`), the MuJoCo viewer (:mod:`.viewer`) or a scripted participant
(:mod:`.script`). Every trial gets a rerun file beside the database:
``DB_STEM.rerun/PARTICIPANT-K-NAME.rrd``.

**One live session per participant.** :class:`Session` takes an exclusive ``flock`` on
``DB.PARTICIPANT.lock`` beside the database before it reads or deletes anything, and holds it
until the session ends (the operating system drops it when the process dies, so a killed
session never blocks its ``--resume``). A second session of the same participant, ``--resume``
or not, is refused with one line naming the process that holds the lock, and nothing is
deleted. All checks (participant, lock, existing trials, study file) run before a front end
is made, so a refused command serves no page and prints no URL.

**Gamepad calibration** (:class:`~.controls.StickCalibration`): every calibration the
participant's front end accepts is appended, as one JSON line (time, the trial it came
before, device, rest, reach, dead zone, maximum force), to ``DB.PARTICIPANT.calibration.jsonl``
beside the database (the database's schema is left as it is).

**Questionnaire** (the study's ``questionnaire``: ``nasa-tlx``): the front end asks it after
every trial; each answer is appended as one JSON line (time, trial position and name, the six
scales, and the raw TLX: their mean) to ``DB.PARTICIPANT.tlx.jsonl``.
"""

from __future__ import annotations

import fcntl
import json
import os
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


def calibration_path(db: str | Path, participant: str) -> Path:
    """The participant's gamepad calibrations: JSON lines beside the database (module
    docstring)."""
    db = Path(db)
    return db.with_name(f"{db.name}.{participant}.calibration.jsonl")


def tlx_path(db: str | Path, participant: str) -> Path:
    """The participant's NASA-TLX answers: JSON lines beside the database (module
    docstring)."""
    db = Path(db)
    return db.with_name(f"{db.name}.{participant}.tlx.jsonl")


def lock_path(db: str | Path, participant: str) -> Path:
    """The lock file of ``participant``'s sessions in ``db`` (module docstring)."""
    db = Path(db)
    return db.with_name(f"{db.name}.{participant}.lock")


class Session:
    """``participant``'s session of ``study`` in ``db``, checked and locked (module docstring);
    :meth:`run` runs it, :meth:`close` releases the lock (``run`` does, at its end)."""

    def __init__(self, study: Study, participant: str, db: str | Path, resume: bool = False):
        check_participant(participant)
        self.study, self.participant, self.db, self.resume = study, participant, Path(db), resume
        self.path = lock_path(db, participant)
        self.fd: int | None = None
        self._lock()
        try:
            self._check()
        except BaseException:
            self.close()
            raise

    def _lock(self) -> None:
        for _ in range(3):  # the holder may unlink the file between our open and our flock
            try:
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            except OSError as e:
                raise ConfigError(f"cannot create the session lock {self.path}: {e.strerror}; "
                                  "give a --db in a writable folder") from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = os.pread(fd, 32, 0).decode(errors="replace").strip() or "?"
                os.close(fd)
                raise ConfigError(
                    f"participant {self.participant!r} has a live session on {self.db} "
                    f"(process {holder}); let it end or stop it before --resume") from None
            try:
                same = os.fstat(fd).st_ino == os.stat(self.path).st_ino
            except FileNotFoundError:
                same = False
            if same:
                os.ftruncate(fd, 0)
                os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
                self.fd = fd
                return
            os.close(fd)
        raise ConfigError(f"cannot lock {self.path}: it keeps changing; try again")

    def _check(self) -> None:
        if not self.db.exists():
            return
        with ResultStore(self.db) as store:
            existing = TrialWriter(store.conn, self.participant).trials()
        if existing and not self.resume:
            raise ConfigError(
                f"participant {self.participant!r} already has {len(existing)} trial(s) in "
                f"{self.db}; give --resume to continue them, or another --participant")
        if existing and existing[0]["study_hash"] != self.study.hash:
            raise ConfigError(f"participant {self.participant!r} in {self.db} ran another "
                              f"study file ({existing[0]['study']}); resume with that file")

    def _record_calibration(self, cal) -> None:
        """Append a gamepad calibration to the participant's calibration file (one JSON line:
        when, before which trial, the device, rest, reach, and the rule's constants)."""
        from .controls import MAX_FORCE_N, STICK_DEADZONE

        line = json.dumps({"utc": datetime.now(UTC).isoformat(timespec="seconds"),
                           "trial": self.position, "device": cal.device,
                           "rest": list(cal.rest), "reach": cal.reach,
                           "deadzone": STICK_DEADZONE, "max_force_n": MAX_FORCE_N})
        with open(calibration_path(self.db, self.participant), "a") as f:
            f.write(line + "\n")

    def _record_tlx(self, k: int, scores: dict[str, int]) -> None:
        """Append the NASA-TLX answers after trial ``k`` (module docstring)."""
        order = self.study.order_for(self.participant)
        name = order[k - 1].name if 1 <= k <= len(order) else None
        line = json.dumps({"utc": datetime.now(UTC).isoformat(timespec="seconds"),
                           "trial": k, "name": name, "scores": scores,
                           "raw_tlx": sum(scores.values()) / len(scores)})
        with open(tlx_path(self.db, self.participant), "a") as f:
            f.write(line + "\n")

    def close(self) -> None:
        """Release the lock (the file is removed first, then unlocked)."""
        if self.fd is None:
            return
        try:
            os.unlink(self.path)
        except FileNotFoundError:
            pass
        fcntl.flock(self.fd, fcntl.LOCK_UN)
        os.close(self.fd)
        self.fd = None

    def run(self, front: FrontEnd, log=print) -> list[dict]:
        """Run (or resume) the participant's trials through ``front``; the trial rows."""
        study, participant, db = self.study, self.participant, self.db
        self.position = 0
        controls = front.source()
        if controls is not None and hasattr(controls, "on_calibration"):
            controls.on_calibration.append(self._record_calibration)
            controls.on_tlx.append(self._record_tlx)
        if study.questionnaire and hasattr(front, "questionnaire"):
            front.questionnaire = study.questionnaire
        try:
            store = ResultStore(db)
            try:
                writer = TrialWriter(store.conn, participant)
                lost = writer.discard_unfinished()
                if lost:
                    log(f"trial {', '.join(map(str, lost))} of {participant!r} did not "
                        "finish; running it again")
                done = {r["trial"] for r in writer.trials()}
                order = study.order_for(participant)
                for position, trial in enumerate(order, start=1):
                    if position in done:
                        continue
                    self.position = position
                    run_trial(study, trial, position, len(order), participant, db, writer,
                              front, log)
                return writer.trials()
            finally:
                store.close()
        finally:
            front.close()
            self.close()


def run_study(study: Study, participant: str, db: str | Path, front: FrontEnd,
              resume: bool = False, log=print) -> list[dict]:
    """Run (or resume) ``participant``'s trials of ``study`` into ``db``; the trial rows."""
    try:
        session = Session(study, participant, db, resume)
    except BaseException:
        front.close()
        raise
    return session.run(front, log)


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
        "rerun": str(rerun), "started_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        "physics": trial.physics, "robot": trial.robot})
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
