"""The study tables of the results store (schema 4): force-interaction trials with people.

One row per trial in ``trials`` (participant, trial position, condition, outcome, time, pushes,
effort), and what happened during it, written as it happens by :class:`TrialWriter`:

* ``trial_steps``: one row per decision step (time, cell, action, belief in the trial's goal);
* ``trial_forces``: the force the front end applied to the handle and the force the robot's
  sensor measured (world x-y, N), one row per control step (the physics step, 2 ms);
* ``trial_pushes``: one row per push (a maximal interval of non-zero applied force): start,
  end, peak (N) and impulse (N s);
* ``trial_cues``: every cue the robot's detector found: time, cell, heading sector (0..7: N,
  NE, ..., NW), magnitude (peak N), impulse and duration;
* ``trial_beliefs``: the robot's goal probabilities after every update (start, cue, move);
* ``study_calibrations``: the participant's gamepad calibrations (rest, reach, the stick rule's
  dead zone and maximum force), and ``study_tlx``: their NASA-TLX answers after each trial
  (six 0..100 scales and the raw TLX, their mean); both late tables
  (:data:`LATE_STUDY_TABLES`).

Times are simulated seconds since the trial began (a person's trial runs in real time, so they
are wall seconds too). A trial row is written with ``status = 'running'`` when it starts and
set to ``'done'`` with its outcome at its end; every decision step commits its rows, so a killed
session leaves its finished trials whole and one ``running`` trial, which a resumed session
deletes (:meth:`TrialWriter.discard_unfinished`) and runs again.
"""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Iterable, Sequence
from typing import Any

#: (table, columns with types, primary key): every study table, in creation order
STUDY_TABLES: tuple[tuple[str, tuple[tuple[str, str], ...], str], ...] = (
    ("trials", (
        ("participant", "TEXT"), ("trial", "INTEGER"), ("name", "TEXT"),
        ("study_index", "INTEGER"), ("study", "TEXT"), ("study_hash", "TEXT"),
        ("condition", "TEXT"),
        ("show_belief", "INTEGER"), ("front_end", "TEXT"),
        ("map", "TEXT"), ("map_hash", "TEXT"), ("method", "TEXT"), ("preset", "TEXT"),
        ("queries", "INTEGER"), ("start", "TEXT"), ("goal", "TEXT"), ("candidates", "TEXT"),
        ("route", "TEXT"), ("time_limit_s", "REAL"), ("seed", "INTEGER"),
        ("status", "TEXT"), ("outcome", "TEXT"), ("success", "INTEGER"), ("time_s", "REAL"),
        ("steps", "INTEGER"), ("pushes", "INTEGER"), ("cues", "INTEGER"),
        ("effort_ns", "REAL"), ("violations", "INTEGER"), ("rerun", "TEXT"),
        ("started_utc", "TEXT"), ("wall_s", "REAL"), ("physics", "TEXT"), ("robot", "TEXT"),
        ("homotopy_success", "INTEGER")),
        "participant, trial"),
    ("trial_steps", (
        ("participant", "TEXT"), ("trial", "INTEGER"), ("t", "INTEGER"), ("time_s", "REAL"),
        ("x", "INTEGER"), ("y", "INTEGER"), ("action", "INTEGER"), ("p_goal", "REAL"),
        ("goal_entropy", "REAL")), "participant, trial, t"),
    ("trial_forces", (
        ("participant", "TEXT"), ("trial", "INTEGER"), ("k", "INTEGER"), ("time_s", "REAL"),
        ("fx", "REAL"), ("fy", "REAL"), ("sensed_fx", "REAL"), ("sensed_fy", "REAL")),
        "participant, trial, k"),
    ("trial_pushes", (
        ("participant", "TEXT"), ("trial", "INTEGER"), ("k", "INTEGER"),
        ("t_start", "REAL"), ("t_end", "REAL"), ("peak_n", "REAL"), ("impulse_x", "REAL"),
        ("impulse_y", "REAL")), "participant, trial, k"),
    ("trial_cues", (
        ("participant", "TEXT"), ("trial", "INTEGER"), ("k", "INTEGER"), ("time_s", "REAL"),
        ("x", "INTEGER"), ("y", "INTEGER"), ("heading", "INTEGER"), ("magnitude_n", "REAL"),
        ("impulse_x", "REAL"), ("impulse_y", "REAL"), ("duration_s", "REAL")),
        "participant, trial, k"),
    ("trial_beliefs", (
        ("participant", "TEXT"), ("trial", "INTEGER"), ("k", "INTEGER"), ("time_s", "REAL"),
        ("cause", "TEXT"), ("goals", "TEXT")), "participant, trial, k"),
    ("study_calibrations", (
        ("participant", "TEXT"), ("k", "INTEGER"), ("utc", "TEXT"), ("trial", "INTEGER"),
        ("device", "TEXT"), ("rest_x", "REAL"), ("rest_y", "REAL"), ("reach", "REAL"),
        ("deadzone", "REAL"), ("max_force_n", "REAL")), "participant, k"),
    ("study_tlx", (
        ("participant", "TEXT"), ("trial", "INTEGER"), ("name", "TEXT"), ("utc", "TEXT"),
        ("mental", "INTEGER"), ("physical", "INTEGER"), ("temporal", "INTEGER"),
        ("performance", "INTEGER"), ("effort", "INTEGER"), ("frustration", "INTEGER"),
        ("raw_tlx", "REAL")), "participant, trial"),
    ("trial_path", (
        ("participant", "TEXT"), ("trial", "INTEGER"), ("k", "INTEGER"), ("time_s", "REAL"),
        ("x", "REAL"), ("y", "REAL"), ("ee_x", "REAL"), ("ee_y", "REAL"), ("ee_z", "REAL")),
        "participant, trial, k"),
)
STUDY_TABLE_NAMES = tuple(t for t, _, _ in STUDY_TABLES)
#: the study tables added to schema 5 after its first study files were written: a file may
#: lack them (read as empty; created in place when opened for writing): the participant's
#: gamepad calibrations (``k = 0, 1, ...`` in order; ``trial``: the position of the trial
#: under way or next, 0 before the first) and NASA-TLX answers (one per finished trial)
#: and the continuous path (``trial_path``: the base's position, m in the scene's world frame,
#: and the end effector's, NULL for the plain base, every :data:`PATH_EVERY`-th physics step)
LATE_STUDY_TABLES = ("study_calibrations", "study_tlx", "trial_path")
#: physics steps between two ``trial_path`` rows: with the 2 ms step, 100 rows per second
PATH_EVERY = 5
#: the participant's own records, not a trial's: kept when a trial is discarded or lost
SESSION_TABLES = ("study_calibrations",)
TRIAL_COLUMNS = tuple(c for c, _ in STUDY_TABLES[0][1])
#: the last columns of ``trials``, added to schema 5 after its first study files were written:
#: a file may lack them (read as it is; added in place when opened for writing, NULL in the
#: old rows: the default physics ``Physics()`` and the ``navigate`` robot those trials ran;
#: ``homotopy_success`` NULL: not measured)
LATE_TRIAL_COLUMNS = ("physics", "robot", "homotopy_success")


def study_sql(table: str, columns: Sequence[str] | None = None) -> str:
    """The ``CREATE TABLE`` statement of one study table with ``columns`` (all of them by
    default), as SQLite stores it, also after ``ALTER TABLE ADD COLUMN`` (new columns go
    before the primary key)."""
    cols, pk = next((c, pk) for t, c, pk in STUDY_TABLES if t == table)
    types = dict(cols)
    names = [c for c, _ in cols] if columns is None else list(columns)
    return (f"CREATE TABLE {table} ({', '.join(f'{c} {types[c]}' for c in names)}, "
            f"PRIMARY KEY ({pk}))")


def trial_columns_ok(columns: Sequence[str]) -> bool:
    """``columns`` (of a stored ``trials`` table) are pathpref's, the late ones
    (:data:`LATE_TRIAL_COLUMNS`) possibly missing from the end."""
    n = len(TRIAL_COLUMNS) - len(LATE_TRIAL_COLUMNS)
    return len(columns) >= n and tuple(columns) == TRIAL_COLUMNS[:len(columns)]


def missing_trial_columns(conn: sqlite3.Connection) -> list[str]:
    """The late ``trials`` columns (:data:`LATE_TRIAL_COLUMNS`) the file lacks."""
    have = {r[1] for r in conn.execute("PRAGMA table_xinfo(trials)")}
    return [c for c in LATE_TRIAL_COLUMNS if c not in have]


def complete_trial_columns(conn: sqlite3.Connection) -> None:
    """Add the late ``trials`` columns the file lacks (inside the caller's transaction)."""
    types = dict(STUDY_TABLES[0][1])
    for c in missing_trial_columns(conn):
        conn.execute(f"ALTER TABLE trials ADD COLUMN {c} {types[c]}")


def create_study_tables(conn: sqlite3.Connection) -> None:
    """Create every study table (inside the caller's transaction)."""
    for t in STUDY_TABLE_NAMES:
        conn.execute(study_sql(t))


def missing_study_tables(conn: sqlite3.Connection) -> list[str]:
    """The late study tables (:data:`LATE_STUDY_TABLES`) the file lacks."""
    have = {r[0] for r in conn.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
    return [t for t in LATE_STUDY_TABLES if t not in have]


def complete_study_tables(conn: sqlite3.Connection) -> None:
    """Create the late study tables the file lacks (inside the caller's transaction)."""
    for t in missing_study_tables(conn):
        conn.execute(study_sql(t))


class TrialWriter:
    """Writes one participant's trials into an open results database connection ``conn``
    (schema 4, see module docstring). Each ``write_*`` call is its own transaction."""

    def __init__(self, conn: sqlite3.Connection, participant: str):
        self.conn = conn
        self.participant = participant

    def trials(self) -> list[dict[str, Any]]:
        """This participant's trial rows, by position."""
        cur = self.conn.execute("SELECT * FROM trials WHERE participant = ? ORDER BY trial",
                                (self.participant,))
        names = [d[0] for d in cur.description]
        return [dict(zip(names, r, strict=True)) for r in cur]

    def discard_unfinished(self) -> list[int]:
        """Delete every row of this participant's trials that did not finish (a killed
        session's trial in progress); returns their positions."""
        lost = [r["trial"] for r in self.trials() if r["status"] != "done"]
        with self.conn:
            for k in lost:
                for t in (t for t in STUDY_TABLE_NAMES if t not in SESSION_TABLES):
                    self.conn.execute(f"DELETE FROM {t} WHERE participant = ? AND trial = ?",
                                      (self.participant, k))
        return lost

    def begin(self, trial: int, row: dict[str, Any]) -> None:
        """Write the trial's row as ``running`` (its settings; outcome columns empty)."""
        full = {c: None for c in TRIAL_COLUMNS} | row | {
            "participant": self.participant, "trial": trial, "status": "running"}
        with self.conn:
            self.conn.execute(
                f"INSERT INTO trials ({', '.join(TRIAL_COLUMNS)}) VALUES "
                f"({', '.join('?' * len(TRIAL_COLUMNS))})", [full[c] for c in TRIAL_COLUMNS])

    def write(self, trial: int, rows: dict[str, Sequence[Sequence[Any]]]) -> None:
        """Append rows (without participant and trial) to study tables, in one transaction:
        ``rows[table] = [(t, ...), ...]``."""
        with self.conn:
            for table, values in rows.items():
                if not values:
                    continue
                n = len(next(c for t, c, _ in STUDY_TABLES if t == table))
                self.conn.executemany(
                    f"INSERT INTO {table} VALUES ({', '.join('?' * n)})",
                    [(self.participant, trial, *v) for v in values])

    def write_calibration(self, row: dict[str, Any]) -> int:
        """Append a gamepad calibration (the columns of ``study_calibrations`` but
        participant and ``k``) as the participant's next ``k``, in one transaction; ``k``."""
        cols = [c for c, _ in next(c for t, c, _ in STUDY_TABLES if t == "study_calibrations")]
        with self.conn:
            k = self.conn.execute("SELECT coalesce(max(k) + 1, 0) FROM study_calibrations "
                                  "WHERE participant = ?", (self.participant,)).fetchone()[0]
            full = row | {"participant": self.participant, "k": k}
            self.conn.execute(f"INSERT INTO study_calibrations VALUES "
                              f"({', '.join('?' * len(cols))})", [full.get(c) for c in cols])
        return int(k)

    def write_tlx(self, trial: int, row: dict[str, Any]) -> bool:
        """Store the NASA-TLX answers after ``trial`` (the columns of ``study_tlx`` but
        participant and trial) in one transaction; False (nothing written) when that trial
        has its answers already (the first answer counts)."""
        cols = [c for c, _ in next(c for t, c, _ in STUDY_TABLES if t == "study_tlx")]
        full = row | {"participant": self.participant, "trial": trial}
        with self.conn:
            cur = self.conn.execute(f"INSERT OR IGNORE INTO study_tlx VALUES "
                                    f"({', '.join('?' * len(cols))})",
                                    [full.get(c) for c in cols])
        return cur.rowcount == 1

    def finish(self, trial: int, outcome: dict[str, Any]) -> None:
        """Set the trial's outcome columns and mark it ``done``."""
        sets = {**outcome, "status": "done"}
        with self.conn:
            self.conn.execute(
                f"UPDATE trials SET {', '.join(f'{k} = ?' for k in sets)} "
                "WHERE participant = ? AND trial = ?",
                [*sets.values(), self.participant, trial])


def read_rows(conn: sqlite3.Connection, table: str, where: str = "",
              params: Iterable[Any] = ()) -> list[dict[str, Any]]:
    """Rows of a study table as dicts (``where`` an SQL condition with ``params``)."""
    if table not in STUDY_TABLE_NAMES:
        raise ValueError(f"not a study table: {table}")
    cur = conn.execute(f"SELECT * FROM {table} {where}", tuple(params))
    names = [d[0] for d in cur.description]
    return [dict(zip(names, r, strict=True)) for r in cur]


def has_study_tables(conn: sqlite3.Connection) -> bool:
    """The database holds the study tables (schema 4; a schema-3 file read as it is does not)."""
    return conn.execute("SELECT count(*) FROM sqlite_master WHERE type = 'table' AND name = "
                        "'trials'").fetchone()[0] == 1


def dumps(value: Any) -> str:
    """JSON of a stored setting (cells, routes, conditions), keys sorted."""
    return json.dumps(value, sort_keys=True)


def participants_hint(conn, db: object) -> str:
    """Which participants ``db`` holds trials of, or how trials are recorded when none."""
    who = [r[0] for r in conn.execute("SELECT DISTINCT participant FROM trials ORDER BY 1")]
    if who:
        return f"it has trials of {', '.join(map(repr, who))}"
    return (f"it holds no trials: record them with 'pathpref study run STUDY --participant ID "
            f"--db {db}'")
