"""What a participant gives besides pushes: gamepad calibrations and NASA-TLX answers, stored
in the study tables ``study_calibrations`` and ``study_tlx`` (:mod:`pathpref.experiments.trials`),
and summarised for the report.

**Raw TLX.** The six NASA-TLX scales (mental, physical and temporal demand, performance,
effort, frustration) are each 0..100; the raw (unweighted) TLX of one answer is their mean,
``(s_1 + ... + s_6) / 6``, also 0..100. The report gives, per participant and per condition,
the mean raw TLX over that group's answers with the 95% Student-t interval clipped to
``[0, 100]`` (:func:`~pathpref.experiments.report.range_interval`; fewer than 3 answers: no
interval).

**Older files.** Sessions before these tables appended the same records as JSON lines beside the
database (``DB.PARTICIPANT.calibration.jsonl``, ``DB.PARTICIPANT.tlx.jsonl``). They are read
too: a participant's calibrations from the file when the table has none of theirs, a TLX answer
when the table has none for that trial; a session (``study run``) imports its participant's
lines into the tables before its first trial by the same rule, so nothing is counted twice.
**A bad line is skipped and named**, never fatal: a line that is not UTF-8, not a JSON object
(a truncated line), holds a non-finite number (``Infinity``, ``1e300`` where a whole number
belongs) or is not a record of its kind is left out with one warning line on stderr
(``pathpref: warning: FILE:N skipped: ...``; the first :data:`MAX_WARNINGS` of a file, then
their count); the file's other lines still count. Reading stops after
:data:`MAX_LEGACY_LINES` lines (with a warning) and a line longer than
:data:`MAX_LINE_BYTES` is skipped unread. An export reads only its participant's files, so
one participant's bad file never touches another's export.
"""

from __future__ import annotations

import glob
import json
import math
import sys
from collections import defaultdict
from pathlib import Path
from typing import Any

from ..experiments.store import ResultStore
from ..experiments.trials import TrialWriter, has_study_tables, missing_study_tables, read_rows
from .controls import MAX_FORCE_N, STICK_DEADZONE, TLX_SCALES

#: a legacy JSON-lines file is read up to this many lines (one line per answer)
MAX_LEGACY_LINES = 100_000
#: a legacy line longer than this (bytes) is skipped unread
MAX_LINE_BYTES = 64 * 1024
#: bad lines of one file named one warning each; the rest are counted in one more line
MAX_WARNINGS = 5
#: a trial position in a legacy record is at most this
MAX_TRIAL = 100_000


def calibration_path(db: str | Path, participant: str) -> Path:
    """Where sessions before the ``study_calibrations`` table put the participant's gamepad
    calibrations: JSON lines beside the database (module docstring)."""
    db = Path(db)
    return db.with_name(f"{db.name}.{participant}.calibration.jsonl")


def tlx_path(db: str | Path, participant: str) -> Path:
    """Where sessions before the ``study_tlx`` table put the participant's NASA-TLX answers."""
    db = Path(db)
    return db.with_name(f"{db.name}.{participant}.tlx.jsonl")


def calibration_row(cal, trial: int, utc: str) -> dict[str, Any]:
    """The ``study_calibrations`` row of a :class:`~.controls.StickCalibration` made before
    (or during) trial ``trial`` (0: before the first), with the stick rule's constants."""
    return {"utc": utc, "trial": int(trial), "device": cal.device,
            "rest_x": float(cal.rest[0]), "rest_y": float(cal.rest[1]),
            "reach": float(cal.reach), "deadzone": STICK_DEADZONE, "max_force_n": MAX_FORCE_N}


def tlx_row(scores: dict[str, int], name: str | None, utc: str) -> dict[str, Any]:
    """The ``study_tlx`` row of one answer (the six scales) after the trial ``name``; its
    ``raw_tlx`` is their mean."""
    return {"name": name, "utc": utc, **{k: int(scores[k]) for k in TLX_SCALES},
            "raw_tlx": sum(int(scores[k]) for k in TLX_SCALES) / len(TLX_SCALES)}


class _Skipped:
    """The bad lines of one legacy file: each named in a warning (the first
    :data:`MAX_WARNINGS`), the rest counted at :meth:`done`."""

    def __init__(self, path: Path):
        self.path, self.n = path, 0

    def __call__(self, line: int, why: str) -> None:
        self.n += 1
        if self.n <= MAX_WARNINGS:
            print(f"pathpref: warning: {self.path}:{line} skipped: {why}; fix or delete the "
                  "line", file=sys.stderr)

    def done(self) -> None:
        if self.n > MAX_WARNINGS:
            print(f"pathpref: warning: {self.path}: {self.n - MAX_WARNINGS} more bad lines "
                  "skipped", file=sys.stderr)


def _no_constant(name: str):
    raise ValueError(f"{name} is not a number pathpref writes")


def _legacy_lines(path: Path, skip: _Skipped) -> list[tuple[int, dict]]:
    """The JSON objects of a legacy file with their line numbers (none when it is absent);
    a bad line goes to ``skip`` (module docstring)."""
    if not path.is_file():
        return []
    out = []
    with open(path, "rb") as f:
        n = 0
        while True:
            raw = f.readline(MAX_LINE_BYTES + 1)
            if not raw:
                break
            n += 1
            if n > MAX_LEGACY_LINES:
                skip(n, f"the file has over {MAX_LEGACY_LINES} lines; the rest is not read")
                break
            if len(raw) > MAX_LINE_BYTES:
                while raw and not raw.endswith(b"\n"):  # the rest of the long line
                    raw = f.readline(MAX_LINE_BYTES)
                skip(n, f"longer than {MAX_LINE_BYTES} bytes")
                continue
            try:
                text = raw.decode("utf-8")
            except UnicodeDecodeError:
                skip(n, "not UTF-8 text")
                continue
            if not text.strip():
                continue
            try:
                obj = json.loads(text, parse_constant=_no_constant)
            except (ValueError, RecursionError):
                obj = None
            if not isinstance(obj, dict):
                skip(n, "not a JSON object (a truncated line?)")
                continue
            out.append((n, obj))
    return out


def _whole(v, lo: int, hi: int) -> int:
    if not isinstance(v, int) or isinstance(v, bool) or not lo <= v <= hi:
        raise ValueError
    return v


def _finite(v, bound: float = 1e6) -> float:
    if not isinstance(v, int | float) or isinstance(v, bool) or not abs(v) <= bound:
        raise ValueError  # NaN fails the comparison too
    return float(v)


def legacy_calibrations(db: str | Path, participant: str) -> list[dict[str, Any]]:
    """The participant's calibrations in the legacy file, as ``study_calibrations`` rows
    (``k`` in file order); bad lines skipped and named (module docstring)."""
    path = calibration_path(db, participant)
    skip = _Skipped(path)
    rows = []
    for n, o in _legacy_lines(path, skip):
        try:
            rest = [_finite(v, 1.5) for v in o["rest"]]
            if len(rest) != 2 or not isinstance(o["utc"], str) or \
                    not isinstance(o["device"], str):
                raise ValueError
            row = {"utc": o["utc"], "trial": _whole(o["trial"], 0, MAX_TRIAL),
                   "device": o["device"], "rest_x": rest[0], "rest_y": rest[1],
                   "reach": _finite(o["reach"]), "deadzone": _finite(o["deadzone"]),
                   "max_force_n": _finite(o["max_force_n"])}
        except (KeyError, TypeError, ValueError, IndexError):
            skip(n, "not a calibration record (utc, trial, device, rest, reach, deadzone, "
                 "max_force_n)")
            continue
        rows.append({"participant": participant, "k": len(rows), **row})
    skip.done()
    return rows


def legacy_tlx(db: str | Path, participant: str) -> list[dict[str, Any]]:
    """The participant's NASA-TLX answers in the legacy file, as ``study_tlx`` rows (the first
    answer of a trial counts, as in the session); bad lines skipped and named."""
    path = tlx_path(db, participant)
    skip = _Skipped(path)
    rows: dict[int, dict[str, Any]] = {}
    for n, o in _legacy_lines(path, skip):
        try:
            scores = {k: _whole(o["scores"][k], 0, 100) for k in TLX_SCALES}
            trial = _whole(o["trial"], 1, MAX_TRIAL)
            name = o.get("name")
            if not (name is None or isinstance(name, str)) or not isinstance(o["utc"], str):
                raise ValueError
            row = tlx_row(scores, name, o["utc"])
        except (KeyError, TypeError, ValueError):
            skip(n, f"not a NASA-TLX record (utc, trial, name, scores {', '.join(TLX_SCALES)} "
                 "whole numbers in 0..100)")
            continue
        rows.setdefault(trial, {"participant": participant, "trial": trial, **row})
    skip.done()
    return [rows[k] for k in sorted(rows)]


def _legacy_participants(db: str | Path, kind: str) -> list[str]:
    """Participants with a legacy ``kind`` file (``calibration`` or ``tlx``) beside ``db``."""
    db = Path(db)
    head, tail = f"{db.name}.", f".{kind}.jsonl"
    pattern = f"{glob.escape(db.name)}.*{tail}"  # the file name may hold [, *, ?
    return sorted(p.name[len(head):-len(tail)] for p in db.parent.glob(pattern)
                  if len(p.name) > len(head) + len(tail))


def merged(db_rows: list[dict], legacy: dict[str, list[dict]], kind: str) -> list[dict]:
    """``db_rows`` and the legacy rows the database lacks (module docstring): for
    ``calibration`` a participant's file when the table has none of theirs, for ``tlx`` each
    answer whose ``(participant, trial)`` the table lacks."""
    out = list(db_rows)
    if kind == "calibration":
        have = {r["participant"] for r in db_rows}
        for p, rows in legacy.items():
            if p not in have:
                out += rows
        return sorted(out, key=lambda r: (r["participant"], r["k"]))
    have_t = {(r["participant"], r["trial"]) for r in db_rows}
    out += [r for rows in legacy.values() for r in rows
            if (r["participant"], r["trial"]) not in have_t]
    return sorted(out, key=lambda r: (r["participant"], r["trial"]))


def import_legacy(writer: TrialWriter, db: str | Path) -> tuple[int, int]:
    """Copy ``writer``'s participant's legacy lines the tables lack into them (module
    docstring), in one transaction; the numbers of calibrations and answers copied."""
    p, conn = writer.participant, writer.conn
    cal = legacy_calibrations(db, p)
    tlx = legacy_tlx(db, p)
    if not cal and not tlx:
        return 0, 0
    have_cal = read_rows(conn, "study_calibrations", "WHERE participant = ?", (p,))
    have_tlx = {r["trial"] for r in read_rows(conn, "study_tlx", "WHERE participant = ?",
                                               (p,))}
    new_cal = [] if have_cal else cal
    new_tlx = [r for r in tlx if r["trial"] not in have_tlx]
    with conn:
        for table, rows in (("study_calibrations", new_cal), ("study_tlx", new_tlx)):
            for r in rows:
                cols = list(r)
                conn.execute(f"INSERT INTO {table} ({', '.join(cols)}) VALUES "
                             f"({', '.join('?' * len(cols))})", [r[c] for c in cols])
    return len(new_cal), len(new_tlx)


def load_answers(db: str | Path, participant: str | None = None
                 ) -> tuple[list[dict], list[dict]]:
    """Every calibration and NASA-TLX answer of ``db`` (the tables, and the legacy files
    beside it by :func:`merged`), or only ``participant``'s (their rows and their files
    alone), read without changing the file. The table rows are checked
    (:mod:`pathpref.experiments.trial_rows`)."""
    from ..experiments.trial_rows import checked

    cal_rows: list[dict] = []
    tlx_rows: list[dict] = []
    where, args = ("WHERE participant = ?", (participant,)) if participant else ("", ())
    with ResultStore(db, create=False) as store:
        c = store.conn
        if has_study_tables(c):
            absent = missing_study_tables(c)
            if "study_calibrations" not in absent:
                cal_rows = list(checked("study_calibrations",
                                        read_rows(c, "study_calibrations", where, args), db))
            if "study_tlx" not in absent:
                tlx_rows = list(checked("study_tlx", read_rows(c, "study_tlx", where, args),
                                        db))

    def who(kind: str) -> list[str]:
        have = _legacy_participants(db, kind)
        return have if participant is None else [p for p in have if p == participant]

    cal = merged(cal_rows, {p: legacy_calibrations(db, p) for p in who("calibration")},
                 "calibration")
    tlx = merged(tlx_rows, {p: legacy_tlx(db, p) for p in who("tlx")}, "tlx")
    return cal, tlx


def tlx_records(tlx: list[dict], trials: list[dict]) -> list[dict[str, Any]]:
    """Per participant and per condition (``by``, ``group``; the condition of the trial the
    answer followed, :func:`~pathpref.experiments.report.condition_label`): the answers ``n``
    and the mean raw TLX with its interval in ``[0, 100]`` (module docstring). Answers of a
    trial not among ``trials`` (not finished, or lost) count for the participant only."""
    from ..experiments.report import condition_label, range_interval

    rows = {(t["participant"], t["trial"]): t for t in trials}
    out = []
    for by in ("participant", "condition"):
        groups: dict[str, list[float]] = defaultdict(list)
        for r in tlx:
            if by == "participant":
                groups[r["participant"]].append(float(r["raw_tlx"]))
            elif (r["participant"], r["trial"]) in rows:
                groups[condition_label(rows[(r["participant"], r["trial"])])].append(
                    float(r["raw_tlx"]))
        for g, vals in sorted(groups.items()):
            m, lo, hi = range_interval(vals, 0.0, 100.0)
            out.append({"by": by, "group": g, "n": len(vals), "raw_tlx": m,
                        "raw_tlx_low": lo, "raw_tlx_high": hi})
    return out


def tlx_table(records: list[dict[str, Any]]) -> str:
    """Markdown of :func:`tlx_records` (empty without answers)."""
    from ..experiments.report import MIN_INTERVAL_N

    if not records:
        return ""
    lines = ["**NASA-TLX (raw, 0..100) per participant and per condition**", "",
             "| by | group | answers | raw TLX [95%, clipped to 0..100] |", "|---|---|---|---|"]
    for r in records:
        cell = (f"{r['raw_tlx']:.1f} (n < {MIN_INTERVAL_N})" if math.isnan(r["raw_tlx_low"])
                else f"{r['raw_tlx']:.1f} [{r['raw_tlx_low']:.1f}, {r['raw_tlx_high']:.1f}]")
        lines.append(f"| {r['by']} | {r['group']} | {r['n']} | {cell} |")
    return "\n".join(lines)
