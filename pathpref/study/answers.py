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
"""

from __future__ import annotations

import glob
import json
import math
from collections import defaultdict
from pathlib import Path
from typing import Any

from ..errors import ConfigError
from ..experiments.store import ResultStore
from ..experiments.trials import TrialWriter, has_study_tables, missing_study_tables, read_rows
from .controls import MAX_FORCE_N, STICK_DEADZONE, TLX_SCALES

#: a legacy JSON-lines file longer than this many lines is refused (one line per answer)
MAX_LEGACY_LINES = 100_000


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


def _legacy_lines(path: Path) -> list[tuple[int, dict]]:
    """The JSON objects of a legacy file with their line numbers (none when it is absent)."""
    if not path.is_file():
        return []
    out = []
    with open(path, encoding="utf-8") as f:
        for n, line in enumerate(f, start=1):
            if n > MAX_LEGACY_LINES:
                raise ConfigError(f"{path} has over {MAX_LEGACY_LINES} lines; it is not a "
                                  "session's record: move it away")
            if not line.strip():
                continue
            try:
                obj = json.loads(line)
            except (ValueError, RecursionError):
                obj = None
            if not isinstance(obj, dict):
                raise ConfigError(f"{path}:{n} is not a JSON object; fix or delete the line")
            out.append((n, obj))
    return out


def legacy_calibrations(db: str | Path, participant: str) -> list[dict[str, Any]]:
    """The participant's calibrations in the legacy file, as ``study_calibrations`` rows
    (``k`` in file order)."""
    path = calibration_path(db, participant)
    rows = []
    for n, o in _legacy_lines(path):
        try:
            rest = [float(v) for v in o["rest"]]
            row = {"utc": str(o["utc"]), "trial": int(o["trial"]), "device": str(o["device"]),
                   "rest_x": rest[0], "rest_y": rest[1], "reach": float(o["reach"]),
                   "deadzone": float(o["deadzone"]), "max_force_n": float(o["max_force_n"])}
        except (KeyError, TypeError, ValueError, IndexError):
            raise ConfigError(f"{path}:{n} is not a calibration record (utc, trial, device, "
                              "rest, reach, deadzone, max_force_n); fix or delete the line"
                              ) from None
        rows.append({"participant": participant, "k": len(rows), **row})
    return rows


def legacy_tlx(db: str | Path, participant: str) -> list[dict[str, Any]]:
    """The participant's NASA-TLX answers in the legacy file, as ``study_tlx`` rows (the first
    answer of a trial counts, as in the session)."""
    path = tlx_path(db, participant)
    rows: dict[int, dict[str, Any]] = {}
    for n, o in _legacy_lines(path):
        try:
            scores = {k: int(o["scores"][k]) for k in TLX_SCALES}
            if not all(0 <= v <= 100 for v in scores.values()):
                raise ValueError
            trial = int(o["trial"])
            row = tlx_row(scores, None if o.get("name") is None else str(o["name"]),
                          str(o["utc"]))
        except (KeyError, TypeError, ValueError):
            raise ConfigError(f"{path}:{n} is not a NASA-TLX record (utc, trial, name, scores "
                              f"{', '.join(TLX_SCALES)} in 0..100); fix or delete the line"
                              ) from None
        rows.setdefault(trial, {"participant": participant, "trial": trial, **row})
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


def load_answers(db: str | Path) -> tuple[list[dict], list[dict]]:
    """Every calibration and NASA-TLX answer of ``db`` (the tables, and the legacy files
    beside it by :func:`merged`), read without changing the file."""
    cal_rows: list[dict] = []
    tlx_rows: list[dict] = []
    with ResultStore(db, create=False) as store:
        c = store.conn
        if has_study_tables(c):
            absent = missing_study_tables(c)
            if "study_calibrations" not in absent:
                cal_rows = read_rows(c, "study_calibrations")
            if "study_tlx" not in absent:
                tlx_rows = read_rows(c, "study_tlx")
    cal = merged(cal_rows, {p: legacy_calibrations(db, p)
                            for p in _legacy_participants(db, "calibration")}, "calibration")
    tlx = merged(tlx_rows, {p: legacy_tlx(db, p) for p in _legacy_participants(db, "tlx")},
                 "tlx")
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
