"""Conducting a study: a participant's trials in order, each run, recorded and resumable.

:func:`run_study` opens the results database (the same store as sweeps, schema 4), refuses a
participant id that already has trials unless ``resume`` (then the trial a killed session left
unfinished is deleted and run again, and finished trials are skipped), and runs the
participant's trials (:meth:`~.plan.Study.order_for`) through a :class:`FrontEnd`: the browser
(:mod:`.server`), the MuJoCo viewer (:mod:`.viewer`) or a scripted participant
(:mod:`.script`). Every trial gets a rerun file beside the database:
``DB_STEM.rerun/PARTICIPANT-K-NAME.rrd`` (a symbolic link at that name is refused before the
session starts, never written through; a trial that fails leaves none).

**A full disk** (the database or the rerun file) ends the session with one line; the trial
under way stays unfinished and ``--resume`` runs it again.

**One live session per participant.** :class:`Session` takes an exclusive ``flock`` on
``DB.PARTICIPANT.lock`` beside the database (opened with ``O_NOFOLLOW``: a symbolic link there
is refused, never followed) before it reads or deletes anything, and holds it
until the session ends (the operating system drops it when the process dies, so a killed
session never blocks its ``--resume``). A second session of the same participant, ``--resume``
or not, is refused with one line naming the process that holds the lock, and nothing is
deleted. All checks (participant, lock, existing trials, study file) run before a front end
is made, so a refused command serves no page and prints no URL.

**Gamepad calibration** (:class:`~.controls.StickCalibration`): the calibration the
participant's front end accepted last becomes a row of ``study_calibrations`` (time, the trial
under way or next, device, rest, reach, dead zone, maximum force) at the next write: one per
decision step at most, however many the page sends.

**Questionnaire** (the study's ``questionnaire``: ``nasa-tlx``): the front end asks it after
every trial; the answer about the trial just ended, once (:meth:`~.controls.Controls.ask_tlx`),
becomes a row of ``study_tlx`` (trial position and name, time, the six
scales, and the raw TLX: their mean).

Both arrive on the front end's thread (the browser's server); they are queued and written by
the session's thread, each in its own transaction as the trials' rows are: before every trial,
after every decision step, after every trial (the questionnaire's answer is in by then) and at
the session's end. A session first imports its participant's records that older sessions wrote
as JSON lines beside the database (:mod:`.answers`).
"""

from __future__ import annotations

import errno
import fcntl
import os
import re
import sqlite3
import stat
import threading
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, Protocol

from ..episode import cached_map
from ..errors import ConfigError
from ..experiments.store import ResultStore
from ..experiments.trials import TrialWriter, dumps
from .answers import calibration_row, import_legacy, tlx_row
from .controls import Controls
from .plan import Study, Trial
from .record import TrialRecorder
from .session import TrialRunner

PARTICIPANT_RE = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}")


class FrontEnd(Protocol):
    """What shows a trial to the participant and carries their pushes to the physics."""

    name: str
    #: the questionnaire to ask after the trials (the study's; None: none). Set by the study
    #: before the first trial; a front end that cannot ask one ignores it
    questionnaire: str | None

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


def _utc() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


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


def check_rerun_path(path: Path) -> Path:
    """A trial's rerun file is written only as a file of its own: a symbolic link (or
    anything but a regular file) at its name is refused with one line, before any work."""
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return path
    except OSError as e:
        raise ConfigError(f"cannot write the rerun file {path}: {e.strerror}") from None
    if stat.S_ISLNK(st.st_mode) or not stat.S_ISREG(st.st_mode):
        raise ConfigError(f"the rerun file {path} is a symbolic link or not a regular file; "
                          "delete it (pathpref writes its own)")
    return path


def disk_full(e: BaseException) -> bool:
    """An error of a full disk or quota: OSError ENOSPC/EDQUOT, SQLite's 'database or disk
    is full', the rerun SDK's RuntimeError '... No space left on device (os error 28)'."""
    if isinstance(e, OSError):
        return e.errno in (errno.ENOSPC, getattr(errno, "EDQUOT", errno.ENOSPC))
    if isinstance(e, sqlite3.Error):
        return "database or disk is full" in str(e)
    return isinstance(e, RuntimeError) and (
        f"(os error {errno.ENOSPC})" in str(e)
        or f"(os error {getattr(errno, 'EDQUOT', errno.ENOSPC)})" in str(e))


def lock_path(db: str | Path, participant: str) -> Path:
    """The lock file of ``participant``'s sessions in ``db`` (module docstring)."""
    db = Path(db)
    return db.with_name(f"{db.name}.{participant}.lock")


class Session:
    """``participant``'s session of ``study`` in ``db``, checked and locked (module docstring);
    :meth:`run` runs it, :meth:`close` releases the lock (``run`` does, at its end)."""

    def __init__(self, study: Study, participant: str, db: str | Path, resume: bool = False,
                 lsl=None, live=None):
        check_participant(participant)
        self.lsl = lsl  # LslOutlets (:mod:`.lsl`) streaming the trials, or None
        self.live = live  # a Foxglove LiveView (:mod:`.live`) of the trials, or None
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
            try:  # never through a link: a planted symlink would have its target truncated
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, 0o644)
            except OSError as e:
                if e.errno == errno.ELOOP:
                    raise ConfigError(f"the session lock {self.path} is a symbolic link; "
                                      "delete it (pathpref makes its own)") from None
                raise ConfigError(f"cannot create the session lock {self.path}: {e.strerror}; "
                                  "give a --db in a writable folder") from None
            if not stat.S_ISREG(os.fstat(fd).st_mode):
                os.close(fd)
                raise ConfigError(f"the session lock {self.path} is not a regular file; "
                                  "delete it (pathpref makes its own)")
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
        for position, trial in enumerate(self.study.order_for(self.participant), start=1):
            check_rerun_path(rerun_path(self.db, self.participant, position, trial))
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
        """Queue a gamepad calibration (any thread; :meth:`_flush` writes it). Once per
        step: a calibration still queued is replaced by the newer one, so a flush (one per
        decision step, and one before and after each trial) writes one at most."""
        row = calibration_row(cal, self.position, _utc())
        with self._queue_lock:
            self._queue = [q for q in self._queue if q[0] != "calibration"]
            self._queue.append(("calibration", row))

    def _record_tlx(self, k: int, scores: dict[str, int]) -> None:
        """Queue the NASA-TLX answers after trial ``k`` (any thread): only the trial just
        ended (the session's current position) is answered, the rest is dropped."""
        if k != self.position:
            return
        order = self.study.order_for(self.participant)
        name = order[k - 1].name if 1 <= k <= len(order) else None
        with self._queue_lock:
            self._queue.append(("tlx", (k, tlx_row(scores, name, _utc()))))

    def _flush(self, writer: TrialWriter) -> None:
        """Write the queued calibrations and answers (the session's thread; each its own
        transaction, module docstring). The queue holds what arrived since the last flush:
        a few records."""
        with self._queue_lock:
            queued, self._queue = self._queue, []
        for kind, item in queued:
            if kind == "calibration":
                writer.write_calibration(item)
            else:
                writer.write_tlx(*item)

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
        self._queue: list[tuple[str, Any]] = []
        self._queue_lock = threading.Lock()
        controls = front.source()
        if isinstance(controls, Controls):  # calibrations and answers come through them
            controls.on_calibration.append(self._record_calibration)
            controls.on_tlx.append(self._record_tlx)
        front.questionnaire = study.questionnaire
        try:
            store = ResultStore(db)
            writer = TrialWriter(store.conn, participant)
            try:
                import_legacy(writer, db)
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
                    self._flush(writer)
                    run_trial(study, trial, position, len(order), participant, db, writer,
                              front, log, between=lambda: self._flush(writer),
                              lsl=self.lsl, live=self.live)
                    self._flush(writer)
                return writer.trials()
            except Exception as e:
                if not disk_full(e):
                    raise
                what = db
                if isinstance(e, RuntimeError) and self.position:  # the rerun SDK's
                    what = rerun_path(db, participant, self.position,
                                      study.order_for(participant)[self.position - 1])
                raise ConfigError(
                    f"cannot write {what}: no space left on device"
                    + (f" in trial {self.position}, left unfinished" if self.position else "")
                    + "; free some space and run the same command with --resume") from None
            finally:
                try:
                    self._flush(writer)
                except Exception as e:  # the first error is the one to tell
                    if not disk_full(e):
                        raise
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
              db: str | Path, writer: TrialWriter, front: FrontEnd, log=print,
              between=None, lsl=None, live=None) -> dict:
    """Run one trial through ``front`` and record it (row written first as ``running``);
    ``between()`` (when given) runs after every decision step."""
    runner = TrialRunner(trial, study.seed, front.source())
    front.begin_trial(position, total, runner)
    rerun = rerun_path(db, participant, position, trial)
    rerun.parent.mkdir(parents=True, exist_ok=True)
    check_rerun_path(rerun)
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
    recorder: TrialRecorder | None = None
    wall = time.perf_counter()
    try:
        recorder = TrialRecorder(writer, position, runner, rerun, lsl, live)
        while not runner.done:
            runner.decide()
            recorder.after_decision()
            front.after_decision(runner)
            if between is not None:
                between()
        outcome = recorder.finish() | {"wall_s": time.perf_counter() - wall}
        writer.finish(position, outcome)
    except BaseException:  # the trial stays unfinished (--resume runs it again): no rerun file
        if recorder is not None and recorder.rerun is not None:
            recorder.rerun.abandon()
        rerun.unlink(missing_ok=True)
        raise
    front.end_trial(runner, outcome)
    log(f"{participant} trial {position}/{total} ({trial.name}): {outcome['outcome']} in "
        f"{outcome['time_s']:.1f} s, {outcome['pushes']} pushes, {outcome['cues']} cues, "
        f"effort {outcome['effort_ns']:.1f} N s")
    return outcome
