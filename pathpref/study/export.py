"""``pathpref study export``: a participant's recorded trials as files other tools read.

Into ``OUT/PARTICIPANT/``:

* a tidy table folder, CSV (the default), Parquet (``--format parquet``: one ``.parquet`` file
  per table with the same name, columns and rows, typed: the SQL ``INTEGER``/``REAL``/``TEXT``
  of the study tables as Arrow ``int64``/``float64``/``string``, NULL kept; written with
  pyarrow, ``pip install 'pathpref[parquet]'``) or both (``--format both``); one observation
  per row, one table per file, a header row, ``participant`` and ``trial`` in every row:
  ``trials.csv`` (the trial rows as stored), ``steps.csv``, ``forces.csv`` (every control
  step, 2 ms), ``path.csv`` (the base's and end effector's positions, 100 Hz),
  ``pushes.csv``, ``cues.csv`` and ``beliefs.csv`` (long form: one row per
  belief update *and goal candidate*: ``k, time_s, cause, goal, goal_x, goal_y, p``);
  ``calibration.csv`` and ``tlx.csv``: the participant's gamepad calibrations and NASA-TLX
  answers (:mod:`.answers`; also those older sessions wrote as JSON lines beside the
  database);
* per trial, ``trial-KK.mcap`` (MCAP, JSON messages with JSON Schemas, zstd chunks), readable
  by the ``mcap`` Python reader and Foxglove:

  - ``/force/applied`` and ``/force/sensed``: a wrench (``geometry_msgs/WrenchStamped``'s
    layout: ``force`` and ``torque`` vectors, N and N m, frame ``world``) per recorded control
    step, at the recorded rate (every row of ``trial_forces``); the torque is that of the
    force at the grip about the sensor's origin, ``r x F`` with the trial's body's grip
    offset (:mod:`pathpref.sim.grip`: the grip 0.05 m below the sensor on the disk, 0.3 m on
    the TidyBot), for the sensed wrench too: what a six-axis sensor reads when the grip's
    force is the handle's only load;
  - ``/pushes``, ``/cues``: one message per push and per cue (their rows' fields);
  - ``/belief``: the goal probabilities after every update, with the candidates' cells;
  - ``/pose``: ``foxglove.PoseInFrame`` of the base at the recorded path's rate (every
    ``trial_path`` row, 100 Hz), and ``/tf`` (``foxglove.FrameTransform`` ``world -> base``) at
    the same times, so the 3-D view moves as the base did; a trial with no recorded path (a
    file written before ``trial_path``) has them at every decision step instead, at the centre
    of the cell the base stood on, ``(cell - 0.5) * cell_size`` m with the scene's default
    cell size (:data:`pathpref.sim.scene.CELL_SIZE_M`);
  - the same forces and poses as ROS 2 messages (CDR encoding, ``ros2msg`` schemas, through
    ``mcap-ros2-support``; :mod:`.ros2_msgs`), which Foxglove and rerun's MCAP import decode as
    typed data: ``/ros/force/applied`` and ``/ros/force/sensed`` (``geometry_msgs/msg/
    WrenchStamped``, one per ``trial_forces`` row) and ``/ros/pose`` (``geometry_msgs/msg/
    PoseStamped``, one per ``/pose``); ``/ros/path`` (``PoseStamped``, the base's
    recorded position, every ``trial_path`` row, 100 Hz) and ``/ros/end_effector`` (the same
    for the end effector, when the robot has one).

  Log times are the trial's start (``started_utc``, whole seconds) plus the row's ``time_s``,
  in nanoseconds since the Unix epoch.

Rows are read from the database a chunk at a time and written as they come (no table is held
in memory), so a 3600 s trial (1.8 million force rows) exports in bounded memory.

**Whole or nothing.** Every file is written into a new temporary folder inside ``OUT``
(``tempfile.mkdtemp``: ``.PARTICIPANT.`` and a random suffix), which is renamed to
``OUT/PARTICIPANT`` when all are written (into an existing ``OUT/PARTICIPANT`` each file is
moved with :func:`os.replace`; files there that the export does not write are kept). Every row
is checked as it passes (:mod:`pathpref.experiments.trial_rows`): a row changed outside
pathpref (a candidates column that is not JSON, a belief over a goal the trial lacks, a start
time that is not one, a force that is text, a time of 1e308) is one error line naming the
table, the row and the column. On that, on a full disk or any other failure, the temporary
folder is removed (and ``OUT`` when the export made it): nothing is left behind. """

from __future__ import annotations

import csv
import errno
import json
import os
import shutil
import stat
import tempfile
from datetime import datetime
from pathlib import Path

from ..episode.cache import cached_map
from ..errors import ConfigError, PathprefError
from ..experiments.store import ResultStore
from ..experiments.trial_rows import MAX_TIME_S, check_goals, check_row, checked
from ..experiments.trials import (
    LATE_STUDY_TABLES,
    STUDY_TABLES,
    has_study_tables,
    participants_hint,
)
from ..sim.grip import torque
from ..sim.scene import CELL_SIZE_M
from . import mcap_scene, ros2_msgs
from .answers import load_answers

CHUNK_ROWS = 4096
IDENTITY = {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}
VEC3 = {"type": "object", "properties": {k: {"type": "number"} for k in "xyz"}}
TIME = {"type": "object", "properties": {"sec": {"type": "integer"},
                                         "nsec": {"type": "integer"}}}
WRENCH_SCHEMA = {"title": "pathpref.WrenchStamped", "type": "object", "properties": {
    "timestamp": TIME, "frame_id": {"type": "string"}, "force": VEC3, "torque": VEC3}}
POSE_SCHEMA = {"title": "foxglove.PoseInFrame", "type": "object", "properties": {
    "timestamp": TIME, "frame_id": {"type": "string"}, "pose": {"type": "object", "properties": {
        "position": VEC3, "orientation": {"type": "object", "properties": {
            k: {"type": "number"} for k in "xyzw"}}}}}}


def _row_schema(title: str, table: str) -> dict:
    cols = next(c for t, c, _ in STUDY_TABLES if t == table)
    kinds = {"REAL": "number", "INTEGER": "integer", "TEXT": "string"}
    return {"title": title, "type": "object",
            "properties": {c: {"type": kinds[ty]} for c, ty in cols}}


def _rows(conn, table: str, participant: str, trial: int | None, order: str):
    """The rows of ``table`` for the participant (and trial), a chunk at a time; none from a
    late table (:data:`~pathpref.experiments.trials.LATE_STUDY_TABLES`) a file written before
    it lacks."""
    if table in LATE_STUDY_TABLES and not conn.execute(
            "SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = ?", (table,)
    ).fetchone():
        return
    where = "WHERE participant = ?" + (" AND trial = ?" if trial is not None else "")
    cur = conn.execute(f"SELECT * FROM {table} {where} ORDER BY {order}",
                       (participant,) if trial is None else (participant, trial))
    names = [d[0] for d in cur.description]
    while True:
        chunk = cur.fetchmany(CHUNK_ROWS)
        if not chunk:
            return
        for r in chunk:
            yield dict(zip(names, r, strict=True))


def _stamp(t0_ns: int, time_s: float) -> tuple[int, dict]:
    if not 0.0 <= time_s <= MAX_TIME_S:  # checked with its row first; never an overflow
        raise ConfigError(f"a time of {time_s!r} s is out of 0..{MAX_TIME_S:g}")
    ns = t0_ns + int(round(time_s * 1e9))
    return ns, {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def scene_topics(fx_channel, put, t0: int, trial: dict, cands: list) -> None:
    """``/scene``: one ``foxglove.SceneUpdate`` at the trial's start (:mod:`.mcap_scene`):
    walls and obstacles of the trial's map (left out when the map no longer loads: a map file
    moved since the study), the preferred route, start and goal."""
    try:
        spec = cached_map(trial["map"])
        size, obstacles = (spec.width, spec.height), [o.vertices.tolist()
                                                      for o in spec.obstacles]
    except (PathprefError, OSError):
        size, obstacles = None, []
    cid = fx_channel("/scene", mcap_scene.fx_type("SceneUpdate"))
    put(cid, "/scene", 0.0, mcap_scene.scene_update(
        t0, size, obstacles, json.loads(trial["route"]), json.loads(trial["start"]),
        json.loads(trial["goal"])))


#: arrow shaft per newton of a push's peak or a cue's magnitude (m/N), and its cap (m)
ARROW_M_PER_N, ARROW_MAX_M = 0.02, 1.5


def _base_at(conn, participant: str, trial: int, time_s: float) -> tuple[float, float] | None:
    """The base's recorded position (``trial_path``) at or before ``time_s``, or None."""
    if not conn.execute("SELECT 1 FROM sqlite_master WHERE type = 'table' AND "
                        "name = 'trial_path'").fetchone():
        return None
    r = conn.execute("SELECT x, y FROM trial_path WHERE participant = ? AND trial = ? AND "
                     "time_s <= ? ORDER BY k DESC LIMIT 1", (participant, trial, time_s)
                     ).fetchone()
    return None if r is None or None in r else (float(r[0]), float(r[1]))


def event_topics(channel, fx_channel, put, conn, participant: str, k: int, t0: int,
                 db) -> None:
    """Every push and cue of trial ``k``, three ways: ``/pushes``, ``/cues`` (the row as JSON,
    as before); ``/events/pushes``, ``/events/cues`` (``foxglove.Event``: from ``t_start`` to
    ``t_end`` for a push, from ``time_s - duration_s`` to ``time_s`` for a cue, the row's fields
    as metadata, :func:`.mcap_scene.event`); ``/scene/pushes``, ``/scene/cues``
    (``foxglove.SceneUpdate``: an arrow along the impulse, :data:`ARROW_M_PER_N` per newton of
    peak or magnitude up to :data:`ARROW_MAX_M`, from the base's recorded position at the
    push's start (no arrow when the trial has no path) or from the cue's cell centre, shown for
    the push's duration or 1 s). A push's messages are logged at its start, a cue's when it
    was detected (``time_s``)."""
    for table, kind, colour in (("trial_pushes", "push", (1.0, 0.5, 0.0)),
                                ("trial_cues", "cue", (0.6, 0.1, 0.8))):
        topic = f"/{kind}es" if kind == "push" else f"/{kind}s"
        cid = channel(topic, _row_schema(f"pathpref.{table}", table))
        ev = fx_channel(f"/events{topic}", mcap_scene.fx_type("Event"))
        arrows = fx_channel(f"/scene{topic}", mcap_scene.fx_type("SceneUpdate"))
        for r in checked(table, _rows(conn, table, participant, k, "k"), db):
            if kind == "push":
                start, end, force = r["t_start"], r["t_end"], r["peak_n"]
                at = _base_at(conn, participant, k, start)
            else:
                start, end, force = max(0.0, r["time_s"] - r["duration_s"]), r["time_s"], \
                    r["magnitude_n"]
                at = ((r["x"] - 0.5) * CELL_SIZE_M, (r["y"] - 0.5) * CELL_SIZE_M)
            when = start if kind == "push" else end  # a cue is known when detected
            put(cid, topic, when, r)
            put(ev, f"/events{topic}", when, mcap_scene.event(
                _stamp(t0, start)[0], _stamp(t0, end)[0], kind, r))
            if at is not None:
                put(arrows, f"/scene{topic}", when, mcap_scene.arrow_update(
                    _stamp(t0, when)[0], f"{kind}-{r['k']}", at[0], at[1], r["impulse_x"],
                    r["impulse_y"], min(ARROW_MAX_M, ARROW_M_PER_N * force),
                    end - start if kind == "push" else 1.0, colour))


def grip_arm(trial: dict) -> tuple[float, ...]:
    """``r = p_grip - p_sensor`` (m) of the body a trial ran (its ``robot`` task and its
    physics' ``robot_model``; NULL in an old row: ``navigate`` and ``Physics()``), at rest
    (:func:`pathpref.sim.grip.rest_offset`): the wrench topics' torque is ``r x F``."""
    from ..episode.physics import Physics
    from ..sim.grip import rest_offset

    physics = Physics.from_json(trial.get("physics")) if trial.get("physics") else None
    model = (physics or Physics()).drive.robot_model
    return rest_offset(trial.get("robot") or "navigate", model)


def write_mcap(conn, participant: str, trial: dict, out: Path,
               db: str | Path = "database") -> dict[str, int]:
    """One trial (its ``trials`` row ``trial``, checked) as an MCAP file (module docstring);
    the number of messages per topic. Every row is checked as it is read (``db`` names the
    file in the error)."""
    try:
        import foxglove.messages  # noqa: F401  (the scene, :mod:`.mcap_scene`)
        from mcap.writer import Writer
    except ImportError:
        raise ConfigError("MCAP export needs the mcap and foxglove-sdk packages: pip install "
                          "'pathpref[export]' (or pass --no-mcap)") from None
    k = trial["trial"]
    t0 = int(datetime.fromisoformat(trial["started_utc"]).timestamp()) * 1_000_000_000
    counts: dict[str, int] = {}
    with open(out, "wb") as f:
        w = Writer(f)
        w.start(profile="", library="pathpref")

        def channel(topic: str, schema: dict) -> int:
            sid = w.register_schema(schema["title"], "jsonschema",
                                    json.dumps(schema).encode())
            counts[topic] = 0
            return w.register_channel(topic, "json", sid)

        def ros_channel(topic: str, definition: tuple[str, str]):
            sid = w.register_schema(definition[0], "ros2msg", definition[1].encode())
            counts[topic] = 0
            return w.register_channel(topic, "cdr", sid), ros2_msgs.encoder(definition)

        def fx_channel(topic: str, message_type) -> int:
            name, encoding, data = mcap_scene.schema(message_type)
            sid = w.register_schema(name, encoding, data)
            counts[topic] = 0
            return w.register_channel(topic, "protobuf", sid)

        def put(cid: int, topic: str, time_s: float, msg, encode=None) -> None:
            ns, _ = _stamp(t0, time_s)
            data = (msg.encode() if hasattr(msg, "encode") else
                    json.dumps(msg).encode() if encode is None else encode(msg))
            w.add_message(cid, log_time=ns, publish_time=ns, data=data,
                          sequence=counts[topic])
            counts[topic] += 1

        applied = channel("/force/applied", WRENCH_SCHEMA)
        sensed = channel("/force/sensed", WRENCH_SCHEMA)
        ros_applied = ros_channel("/ros/force/applied", ros2_msgs.WRENCH_STAMPED)
        ros_sensed = ros_channel("/ros/force/sensed", ros2_msgs.WRENCH_STAMPED)
        arm = grip_arm(trial)
        for r in checked("trial_forces", _rows(conn, "trial_forces", participant, k, "k"),
                         db):
            ns, ts = _stamp(t0, r["time_s"])
            for cid, ros, topic, fx, fy in (
                    (applied, ros_applied, "/force/applied", r["fx"], r["fy"]),
                    (sensed, ros_sensed, "/force/sensed", r["sensed_fx"], r["sensed_fy"])):
                force = {"x": fx, "y": fy, "z": 0.0}
                tx, ty, tz = (float(v) for v in torque(arm, (fx, fy)))
                moment = {"x": tx, "y": ty, "z": tz}
                put(cid, topic, r["time_s"], {"timestamp": ts, "frame_id": "world",
                                              "force": force, "torque": moment})
                put(ros[0], "/ros" + topic, r["time_s"], {
                    "header": ros2_msgs.header(ns), "wrench": {"force": force,
                                                               "torque": moment}}, ros[1])
        event_topics(channel, fx_channel, put, conn, participant, k, t0, db)
        path = ros_channel("/ros/path", ros2_msgs.POSE_STAMPED)
        pose_ch = channel("/pose", POSE_SCHEMA)
        ros_pose = ros_channel("/ros/pose", ros2_msgs.POSE_STAMPED)
        tf = fx_channel("/tf", mcap_scene.fx_type("FrameTransform"))

        def base_pose(time_s: float, x: float, y: float) -> None:
            """/pose, /ros/pose and /tf of the base at ``(x, y)`` m at ``time_s``."""
            ns, ts = _stamp(t0, time_s)
            pose = {"position": {"x": x, "y": y, "z": 0.0}, "orientation": IDENTITY}
            put(pose_ch, "/pose", time_s, {"timestamp": ts, "frame_id": "world", "pose": pose})
            put(ros_pose[0], "/ros/pose", time_s, {"header": ros2_msgs.header(ns),
                                                    "pose": pose}, ros_pose[1])
            put(tf, "/tf", time_s, mcap_scene.base_transform(ns, x, y))

        hand = None
        for r in checked("trial_path", _rows(conn, "trial_path", participant, k, "k"), db):
            ns, _ = _stamp(t0, r["time_s"])
            put(path[0], "/ros/path", r["time_s"], {"header": ros2_msgs.header(ns), "pose": {
                "position": {"x": r["x"], "y": r["y"], "z": 0.0}, "orientation": IDENTITY}},
                path[1])
            base_pose(r["time_s"], r["x"], r["y"])
            if r["ee_x"] is not None:
                hand = hand or ros_channel("/ros/end_effector", ros2_msgs.POSE_STAMPED)
                put(hand[0], "/ros/end_effector", r["time_s"], {
                    "header": ros2_msgs.header(ns), "pose": {"position": {
                        "x": r["ee_x"], "y": r["ee_y"], "z": r["ee_z"]},
                        "orientation": IDENTITY}}, hand[1])
        cands = json.loads(trial["candidates"])
        scene_topics(fx_channel, put, t0, trial, cands)
        belief_goals = fx_channel("/scene/belief", mcap_scene.fx_type("SceneUpdate"))
        cid = channel("/belief", {"title": "pathpref.Belief", "type": "object", "properties": {
            "cause": {"type": "string"}, "p": {"type": "array", "items": {"type": "number"}},
            "candidates": {"type": "array"}}})
        for r in _rows(conn, "trial_beliefs", participant, k, "k"):
            p = check_goals(r, len(cands), db)
            put(cid, "/belief", r["time_s"], {"cause": r["cause"], "p": p,
                                              "candidates": cands})
            put(belief_goals, "/scene/belief", r["time_s"],
                mcap_scene.belief_update(_stamp(t0, r["time_s"])[0], cands, p))
        if counts["/pose"] == 0:  # no recorded path (older files): the decision steps' cells
            for r in checked("trial_steps", _rows(conn, "trial_steps", participant, k, "t"),
                             db):
                base_pose(r["time_s"], (r["x"] - 0.5) * CELL_SIZE_M,
                          (r["y"] - 0.5) * CELL_SIZE_M)
        w.finish()
    return counts


#: the export's table formats (``--format``)
FORMATS = ("csv", "parquet", "both")
#: rows per Parquet row group (the rows buffered before one is written)
PARQUET_GROUP_ROWS = 65_536
#: Arrow types of the study tables' SQL types (every column nullable)
ARROW_TYPES = {"INTEGER": "int64", "REAL": "float64", "TEXT": "string"}


class TableWriter:
    """One table of the export: ``STEM.csv`` and/or ``STEM.parquet`` (``formats``) with the
    columns ``columns`` (name, SQL type), written from one pass over the rows. CSV rows go out
    as they come; Parquet rows are buffered :data:`PARQUET_GROUP_ROWS` at a time, one row group
    each (bounded memory)."""

    def __init__(self, folder: Path, stem: str, columns: list[tuple[str, str]],
                 formats: tuple[str, ...]):
        self.names = [c for c, _ in columns]
        self.files: list[str] = []
        self.n = 0
        self._csv = self._pq = None
        if "csv" in formats:
            self.files.append(f"{stem}.csv")
            self._csv_file = open(folder / f"{stem}.csv", "w", newline="")
            self._csv = csv.writer(self._csv_file)
            self._csv.writerow(self.names)
        if "parquet" in formats:
            import pyarrow as pa
            import pyarrow.parquet as pq

            self._pa = pa
            self.schema = pa.schema([(c, getattr(pa, ARROW_TYPES[t])()) for c, t in columns])
            self.files.append(f"{stem}.parquet")
            self._pq = pq.ParquetWriter(folder / f"{stem}.parquet", self.schema)
            self._buffer: list[list] = []

    def write(self, row: list) -> None:
        """One row (values in column order)."""
        self.n += 1
        if self._csv is not None:
            self._csv.writerow(row)
        if self._pq is not None:
            self._buffer.append(row)
            if len(self._buffer) >= PARQUET_GROUP_ROWS:
                self._flush()

    def _flush(self) -> None:
        cols = list(zip(*self._buffer, strict=True)) if self._buffer else [()] * len(self.names)
        self._pq.write_table(self._pa.Table.from_arrays(
            [self._pa.array(list(v), type=f.type) for v, f in zip(cols, self.schema,
                                                                   strict=True)],
            schema=self.schema))
        self._buffer = []

    def close(self) -> dict[str, int]:
        """Finish the files; the rows written per file."""
        if self._csv is not None:
            self._csv_file.close()
        if self._pq is not None:
            if self._buffer or self.n == 0:
                self._flush()  # an empty table is a file with its schema and no rows
            self._pq.close()
        return dict.fromkeys(self.files, self.n)


def _write_table(folder: Path, stem: str, columns: list[tuple[str, str]], rows,
                 formats: tuple[str, ...]) -> dict[str, int]:
    w = TableWriter(folder, stem, columns, formats)
    try:
        for r in rows:
            w.write(r)
    except BaseException:
        try:
            w.close()  # the temporary folder goes; the first error is the one to tell
        except Exception:  # noqa: BLE001, S110
            pass
        raise
    return w.close()


def _formats(fmt: str) -> tuple[str, ...]:
    """The file formats of ``--format`` (:data:`FORMATS`); Parquet needs pyarrow."""
    if fmt not in FORMATS:
        raise ConfigError(f"--format must be one of {', '.join(FORMATS)}, got {str(fmt)[:20]!r}")
    out = ("csv", "parquet") if fmt == "both" else (fmt,)
    if "parquet" in out:
        try:
            import pyarrow.parquet  # noqa: F401
        except ImportError:
            raise ConfigError("--format parquet needs the pyarrow package: pip install "
                              "'pathpref[parquet]' (or --format csv)") from None
    return out


def _output_folder(out: Path, participant: str) -> Path:
    """``OUT/PARTICIPANT``, refused (one line, nothing made) when ``OUT`` or it is not a
    folder, or ``OUT``'s parent folder is missing."""
    folder = out / participant
    for path, what in ((out, "--out"), (folder, "--out's participant folder")):
        try:
            st = os.stat(path)
        except FileNotFoundError:
            continue
        except OSError as e:
            raise ConfigError(f"cannot write {what} {path}: {e.strerror or e}") from None
        if not stat.S_ISDIR(st.st_mode):
            raise ConfigError(f"{what} {path} exists and is not a folder; give a folder "
                              "(existing or new)")
    parent = out.parent if str(out.parent) else Path(".")
    if not out.exists() and not parent.is_dir():
        raise ConfigError(f"cannot write --out {out}: folder {parent} does not exist")
    return folder


def _write_failed(folder: Path, e: OSError) -> ConfigError:
    if e.errno in (errno.ENOSPC, getattr(errno, "EDQUOT", errno.ENOSPC)):
        reason = "no space left on device; free some space and run again"
    else:
        reason = e.strerror or str(e)
    return ConfigError(f"cannot write {folder}: {reason} (nothing was written)")


def export_participant(db: str | Path, participant: str, out: str | Path,
                       mcap: bool = True, fmt: str = "csv") -> dict[str, int]:
    """Write ``participant``'s trials of ``db`` into ``out/participant/`` (module docstring) as
    CSV (``fmt="csv"``, the default), Parquet (``"parquet"``) or both; the number of rows per
    table file and of MCAP files. Whole or nothing (module docstring)."""
    formats = _formats(fmt)
    out = Path(out)
    folder = _output_folder(out, participant)
    with ResultStore(db, create=False) as store:
        c = store.conn
        if not has_study_tables(c):
            raise ConfigError(f"{db} holds no study trials")
        trials = list(checked("trials", _rows(c, "trials", participant, None, "trial"), db))
        if not trials:
            raise ConfigError(f"{db} has no trials of participant {participant!r} "
                              f"({participants_hint(c, db)})")
        cal, tlx = load_answers(db, participant)
        made_out = not out.exists()
        tmp = None
        try:
            out.mkdir(exist_ok=True)
            tmp = Path(tempfile.mkdtemp(dir=out, prefix=f".{participant}."))
            counts = _export_into(c, db, participant, trials, cal, tlx, tmp, mcap, formats)
            if not folder.exists():
                os.rename(tmp, folder)
            else:
                for f in sorted(tmp.iterdir()):
                    os.replace(f, folder / f.name)
                tmp.rmdir()
        except OSError as e:
            raise _write_failed(folder, e) from None
        except PathprefError:
            raise
        except (ValueError, TypeError, OverflowError, KeyError) as e:  # a row no check foresaw
            raise ConfigError(f"cannot export participant {participant!r} of {db}: "
                              f"{type(e).__name__}: {str(e)[:120]}; a row was changed outside "
                              "pathpref (nothing was written)") from None
        finally:
            if tmp is not None and tmp.exists():
                shutil.rmtree(tmp, ignore_errors=True)
            if made_out and out.is_dir() and not any(out.iterdir()):
                out.rmdir()
    return counts


def _export_into(c, db, participant: str, trials: list[dict], cal: list[dict],
                 tlx: list[dict], folder: Path, mcap: bool,
                 formats: tuple[str, ...]) -> dict[str, int]:
    """Every file of the export into ``folder`` (the temporary one); the counts."""
    counts: dict[str, int] = {}

    def columns(table: str) -> list[tuple[str, str]]:
        return list(next(c for t, c, _ in STUDY_TABLES if t == table))

    for table, order in (("trials", "trial"), ("trial_steps", "trial, t"),
                         ("trial_forces", "trial, k"), ("trial_pushes", "trial, k"),
                         ("trial_cues", "trial, k"), ("trial_path", "trial, k")):
        cols = columns(table)
        stem = "trials" if table == "trials" else table[6:]
        counts |= _write_table(folder, stem, cols, (
            [r.get(col) for col, _ in cols]
            for r in checked(table, _rows(c, table, participant, None, order), db)), formats)
    cands = {t["trial"]: json.loads(t["candidates"]) for t in trials}

    def beliefs():
        for r in _rows(c, "trial_beliefs", participant, None, "trial, k"):
            if r["trial"] not in cands:
                check_row("trial_beliefs", r, db)
                raise ConfigError(f"{db}: trial_beliefs row (participant {participant!r}, "
                                  f"trial {r['trial']!r}, k {r['k']!r}) belongs to no trial; "
                                  "the row was changed outside pathpref")
            for g, p in enumerate(check_goals(r, len(cands[r["trial"]]), db)):
                x, y = cands[r["trial"]][g]
                yield [participant, r["trial"], r["k"], r["time_s"], r["cause"], g, x, y, p]

    counts |= _write_table(folder, "beliefs", [
        ("participant", "TEXT"), ("trial", "INTEGER"), ("k", "INTEGER"),
        ("time_s", "REAL"), ("cause", "TEXT"), ("goal", "INTEGER"), ("goal_x", "INTEGER"),
        ("goal_y", "INTEGER"), ("p", "REAL")], beliefs(), formats)
    for table, stem, rows in (("study_calibrations", "calibration", cal),
                              ("study_tlx", "tlx", tlx)):
        cols = columns(table)
        counts |= _write_table(folder, stem, cols, (
            [r[col] for col, _ in cols]
            for r in checked(table, (r for r in rows if r["participant"] == participant), db)),
            formats)
    if mcap:
        for t in trials:
            write_mcap(c, participant, t, folder / f"trial-{t['trial']:02d}.mcap", db)
        counts["mcap"] = len(trials)
    return counts
