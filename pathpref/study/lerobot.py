"""Study trials and physical episodes as a LeRobot v3 dataset (``pathpref dataset``), the
layout LeRobot's ``LeRobotDataset`` loads (codebase ``v3.0``)::

    OUT/meta/info.json                              fps, features (dtype, shape, names), paths
    OUT/meta/stats.json                             per feature: min, max, mean, std, count
    OUT/meta/tasks.parquet                          task text (the index) -> task_index
    OUT/meta/episodes/chunk-000/file-000.parquet    one row per episode: length, tasks, rows
    OUT/data/chunk-000/file-000.parquet             one row per frame, many episodes per file

Every frame row has LeRobot's own columns (``timestamp = frame_index / fps`` float32,
``frame_index``, ``episode_index``, ``index`` over the dataset, ``task_index``) and:

**Study trials** (``--source study``, every finished trial of every participant; 100 frames per
second, one per ``trial_path`` row, i.e. every :data:`~pathpref.experiments.trials.PATH_EVERY`-th
2 ms physics step):

* ``observation.state`` float32 ``[x, y]``: the base's recorded position (m, world frame);
* ``observation.robot_action`` int64: the robot's decision in force (``trial_steps.action`` of
  the latest decision step at or before the frame);
* ``action`` float32 ``[vx, vy]``: the base's velocity over the frame, ``(p[k+1] - p[k]) * fps``
  m/s (zero on an episode's last frame);
* ``intervention`` float32 ``[fx, fy]``: the person's push, the force applied to the handle at
  the frame's physics step (``trial_forces``, N);
* ``is_intervention`` bool: ``|intervention| > PUSH_ON_N`` (0.5 N, the push threshold of the
  trial's own push count).

**Episodes** (``--source episodes``: the ``--sim mujoco`` episodes of a sweep with their steps;
one frame per decision step, so ``fps`` is 1 as a convention: a frame is a decision, whose
length in seconds depends on the episode's physics):

* ``observation.state`` float32 ``[x, y]``: the robot's cell after decision step ``t`` (map
  units; frame 0: the start);
* ``intervention`` int64: the person's push right after it, the heading the robot observed
  (0..7 = N, NE, ..., NW; -1: none; stored on step row ``t + 1``);
* ``is_intervention`` bool: the person pushed then (``steps.is_intervention`` of row ``t``; a
  row of an older sweep without it: the observed heading is >= 0);
* ``action`` int64: the robot's next action, taken after that push (row ``t + 1``'s; -1 on
  the last frame).

**Recorded paths** (``--source paths``: the ``--sim mujoco`` episodes of a sweep run with
``--record-path HZ``, their ``episode_path`` rows; one frame per sample at the recorded rate,
which must be a whole number of frames per second and the same for every episode, e.g. 100; the
last sample of an episode, taken at its end between two sampling instants, is left out):

* ``observation.state`` float32 ``[x, y, yaw]``: the base's pose (m, rad, world frame);
* ``observation.end_effector`` float32 ``[x, y, z]``: the end effector (m), only when every
  exported episode has one (the ``carry`` robot);
* ``action`` float32 ``[vx, vy]``: the base's velocity over the frame, as for study trials;
* ``intervention`` float32 ``[fx, fy]``: the simulated human's push, the force applied at the
  sample's physics step (N);
* ``is_intervention`` bool: ``|intervention| > PUSH_ON_N``, as for study trials.

Each episode's task is its text (:func:`task_text`: ``"reach goal (5, 9) of map simple
along the route (5, 2) (2, 2) (2, 9) (5, 9)"`` for a trial); ``meta/episodes`` also names
where it came from (``source_key``: participant/trial, or the sweep's episode key) and its
outcome (``success``). Written into a temporary folder and renamed at the end (whole or
nothing); rows are streamed (bounded memory), a data file holds at most :data:`FILE_ROWS`
frames, a chunk :data:`CHUNK_FILES` files. Needs pyarrow and pandas
(``pip install 'pathpref[dataset]'``); LeRobot itself is needed only to load the result.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path

from ..errors import ConfigError, is_disk_full
from ..experiments.store import (
    PATH_RULES,
    STEP_RULES,
    ResultStore,
    check_copied_rows,
    check_rows_of,
    missing_base_tables,
)
from ..experiments.trial_rows import checked
from ..experiments.trials import has_study_tables
from .record import PUSH_ON_N

CODEBASE_VERSION = "v3.0"
#: frames per data file (then a new file, at an episode's end) and files per chunk folder
FILE_ROWS = 1_000_000
CHUNK_FILES = 1000
CHUNK_FILE = "chunk-{chunk_index:03d}/file-{file_index:03d}"
DATA_PATH = "data/" + CHUNK_FILE + ".parquet"
GROUP_ROWS = 65_536
SOURCES = ("study", "episodes", "paths")

#: LeRobot's own columns of every frame
DEFAULT_FEATURES = {
    "timestamp": {"dtype": "float32", "shape": [1], "names": None},
    "frame_index": {"dtype": "int64", "shape": [1], "names": None},
    "episode_index": {"dtype": "int64", "shape": [1], "names": None},
    "index": {"dtype": "int64", "shape": [1], "names": None},
    "task_index": {"dtype": "int64", "shape": [1], "names": None},
}
STUDY_FEATURES = {
    "observation.state": {"dtype": "float32", "shape": [2], "names": ["x", "y"]},
    "observation.robot_action": {"dtype": "int64", "shape": [1], "names": None},
    "action": {"dtype": "float32", "shape": [2], "names": ["vx", "vy"]},
    "intervention": {"dtype": "float32", "shape": [2], "names": ["fx", "fy"]},
    "is_intervention": {"dtype": "bool", "shape": [1], "names": None},
}
PATH_FEATURES = {
    "observation.state": {"dtype": "float32", "shape": [3], "names": ["x", "y", "yaw"]},
    "action": {"dtype": "float32", "shape": [2], "names": ["vx", "vy"]},
    "intervention": {"dtype": "float32", "shape": [2], "names": ["fx", "fy"]},
    "is_intervention": {"dtype": "bool", "shape": [1], "names": None},
}
#: with an end effector on every exported episode (the carry robot)
END_EFFECTOR_FEATURE = {"observation.end_effector": {"dtype": "float32", "shape": [3],
                                                     "names": ["x", "y", "z"]}}
EPISODE_FEATURES = {
    "observation.state": {"dtype": "float32", "shape": [2], "names": ["x", "y"]},
    "action": {"dtype": "int64", "shape": [1], "names": None},
    "intervention": {"dtype": "int64", "shape": [1], "names": None},
    "is_intervention": {"dtype": "bool", "shape": [1], "names": None},
}


def _arrow_type(pa, ft: dict):
    base = {"float32": pa.float32(), "int64": pa.int64(), "bool": pa.bool_()}[ft["dtype"]]
    return base if ft["shape"] == [1] else pa.list_(base, ft["shape"][0])


class _Stats:
    """Streaming min, max, mean and std (population) per dimension of a numeric feature."""

    def __init__(self, dims: int):
        self.n, self.lo, self.hi = 0, [math.inf] * dims, [-math.inf] * dims
        self.s, self.ss = [0.0] * dims, [0.0] * dims

    def add(self, v) -> None:
        vs = v if isinstance(v, list) else [v]
        self.n += 1
        for i, x in enumerate(vs):
            x = float(x)
            self.lo[i], self.hi[i] = min(self.lo[i], x), max(self.hi[i], x)
            self.s[i] += x
            self.ss[i] += x * x

    def as_dict(self) -> dict:
        n = max(self.n, 1)
        mean = [s / n for s in self.s]
        std = [math.sqrt(max(0.0, ss / n - m * m)) for ss, m in zip(self.ss, mean, strict=True)]
        return {"min": self.lo, "max": self.hi, "mean": mean, "std": std, "count": [self.n]}


class LeRobotWriter:
    """A LeRobot v3 dataset written episode by episode into ``root`` (module docstring)."""

    def __init__(self, root: Path, fps: int, features: dict, robot_type: str):
        import pyarrow as pa
        import pyarrow.parquet as pq

        self._pa, self._pq = pa, pq
        self.root, self.fps, self.robot_type = root, fps, robot_type
        self.features = features | DEFAULT_FEATURES
        self.schema = pa.schema([(k, _arrow_type(pa, ft)) for k, ft in self.features.items()])
        self.tasks: dict[str, int] = {}
        self.episodes: list[dict] = []
        self.stats = {k: _Stats(ft["shape"][0]) for k, ft in self.features.items()
                      if ft["dtype"] != "bool"}
        self.bools = {k: [0, 0] for k, ft in self.features.items() if ft["dtype"] == "bool"}
        self.total = 0
        self.file_index = -1
        self._file_rows = FILE_ROWS
        self._writer = None
        self._buffer: list[dict] = []

    def _where(self) -> tuple[int, int]:
        return divmod(self.file_index, CHUNK_FILES)

    def _open_next(self) -> None:
        self._close_file()
        self.file_index += 1
        chunk, file = self._where()
        path = self.root / DATA_PATH.format(chunk_index=chunk, file_index=file)
        path.parent.mkdir(parents=True, exist_ok=True)
        self._writer = self._pq.ParquetWriter(path, self.schema)
        self._file_rows = 0

    def _flush(self) -> None:
        if self._buffer:
            self._writer.write_table(self._pa.Table.from_pylist(self._buffer,
                                                                schema=self.schema))
            self._buffer = []

    def _close_file(self) -> None:
        if self._writer is not None:
            self._flush()
            self._writer.close()
            self._writer = None

    def add_episode(self, task: str, frames: Iterable[dict], extra: dict) -> int:
        """Append one episode (its frames: the features' values); the frames written. An
        episode of no frame is left out (-1)."""
        if self._writer is None or self._file_rows >= FILE_ROWS:
            self._open_next()
        ep = len(self.episodes)
        t = self.tasks.setdefault(task, len(self.tasks))
        n = 0
        for f in frames:
            row = f | {"timestamp": n / self.fps, "frame_index": n, "episode_index": ep,
                       "index": self.total + n, "task_index": t}
            for k, s in self.stats.items():
                s.add(row[k])
            for k, c in self.bools.items():
                c[bool(row[k])] += 1
            self._buffer.append(row)
            n += 1
            if len(self._buffer) >= GROUP_ROWS:
                self._flush()
        if n == 0:
            return -1
        chunk, file = self._where()
        self.episodes.append({"episode_index": ep, "tasks": [task], "length": n,
                              "data/chunk_index": chunk, "data/file_index": file,
                              "dataset_from_index": self.total,
                              "dataset_to_index": self.total + n,
                              "meta/episodes/chunk_index": 0, "meta/episodes/file_index": 0}
                             | extra)
        self.total += n
        self._file_rows += n
        return n

    def finish(self) -> dict:
        """Write the metadata; ``meta/info.json`` as a dict."""
        import pandas as pd

        self._close_file()
        meta = self.root / "meta"
        (meta / "episodes" / "chunk-000").mkdir(parents=True, exist_ok=True)
        pd.DataFrame({"task_index": list(self.tasks.values())},
                     index=list(self.tasks)).to_parquet(meta / "tasks.parquet")
        self._pq.write_table(self._pa.Table.from_pylist(self.episodes),
                             meta / "episodes" / "chunk-000" / "file-000.parquet")
        stats = {k: s.as_dict() for k, s in self.stats.items()}
        for k, (no, yes) in self.bools.items():
            n = max(no + yes, 1)
            mean = yes / n
            stats[k] = {"min": [bool(no == 0 and yes > 0)], "max": [yes > 0], "mean": [mean],
                        "std": [math.sqrt(mean * (1 - mean))], "count": [no + yes]}
        (meta / "stats.json").write_text(json.dumps(stats, indent=2))
        info = {"codebase_version": CODEBASE_VERSION, "robot_type": self.robot_type,
                "total_episodes": len(self.episodes), "total_frames": self.total,
                "total_tasks": len(self.tasks), "chunks_size": CHUNK_FILES,
                "data_files_size_in_mb": 100, "video_files_size_in_mb": 200, "fps": self.fps,
                "splits": {"train": f"0:{len(self.episodes)}"}, "data_path": DATA_PATH,
                "video_path": None, "features": self.features}
        (meta / "info.json").write_text(json.dumps(info, indent=4))
        return info


def task_text(goal, map_name: str, route=None) -> str:
    """An episode's task: ``reach goal (x, y) of map NAME along the route (x, y) ... (x, y)``
    (a study trial's route, its cells) or ``... along the map's preferred route``."""
    way = ("the map's preferred route" if route is None else
           "the route " + " ".join(f"({x}, {y})" for x, y in route))
    return f"reach goal ({goal[0]}, {goal[1]}) of map {map_name} along {way}"


def _study_frames(conn, db, participant: str, trial: int, fps: int) -> Iterator[dict]:
    """The frames of one trial (module docstring): ``trial_path`` rows joined with the force
    of their physics step and the decision in force, a row of look-ahead for the velocity."""
    where = (participant, trial)
    path = checked("trial_path", _iter(conn, "SELECT * FROM trial_path WHERE participant = ? "
                                       "AND trial = ? ORDER BY k", where), db)
    forces = checked("trial_forces", _iter(conn, "SELECT * FROM trial_forces WHERE "
                                           "participant = ? AND trial = ? ORDER BY k", where), db)
    steps = checked("trial_steps", _iter(conn, "SELECT * FROM trial_steps WHERE "
                                         "participant = ? AND trial = ? ORDER BY t", where), db)
    force = next(forces, None)
    step, after = None, next(steps, None)

    def frames() -> Iterator[dict]:
        nonlocal force, step, after
        for r in path:
            t = r["time_s"]
            while force is not None and force["time_s"] < t - 1e-9:
                force = next(forces, None)
            while after is not None and after["time_s"] <= t + 1e-9:
                step, after = after, next(steps, None)
            fx, fy = (0.0, 0.0) if force is None or abs(force["time_s"] - t) > 1e-6 else (
                force["fx"], force["fy"])
            yield {"observation.state": [r["x"], r["y"]],
                   "observation.robot_action": -1 if step is None else step["action"],
                   "intervention": [fx, fy], "is_intervention": math.hypot(fx, fy) > PUSH_ON_N}

    return _with_action(frames(), fps)


def _with_action(frames: Iterator[dict], fps: int) -> Iterator[dict]:
    """Each frame with its ``action``: the velocity to the next frame's position (``fps``
    times the step, m/s), 0 at the last frame (a row of look-ahead)."""
    prev = None
    for cur in frames:
        if prev is not None:
            (x0, y0), (x1, y1) = prev["observation.state"][:2], cur["observation.state"][:2]
            yield prev | {"action": [(x1 - x0) * fps, (y1 - y0) * fps]}
        prev = cur
    if prev is not None:
        yield prev | {"action": [0.0, 0.0]}


def _iter(conn, sql: str, params) -> Iterator[dict]:
    cur = conn.execute(sql, params)
    names = [d[0] for d in cur.description]
    while chunk := cur.fetchmany(4096):
        for r in chunk:
            yield dict(zip(names, r, strict=True))


def _write_study(conn, db, root: Path) -> dict:
    if not has_study_tables(conn) or not conn.execute(
            "SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = 'trial_path'"
    ).fetchone():
        raise ConfigError(f"{db} holds no study trials with a recorded path (trial_path)")
    w = LeRobotWriter(root, 100, STUDY_FEATURES, "pathpref_mobile_base")
    trials = list(checked("trials", _iter(
        conn, "SELECT * FROM trials WHERE status = 'done' ORDER BY participant, trial", ()), db))
    if not trials:
        raise ConfigError(f"{db} holds no finished study trials (record them with 'pathpref "
                          "study run'; a sweep's episodes: --source episodes)")
    for t in trials:
        w.add_episode(task_text(json.loads(t["goal"]), t["map"], json.loads(t["route"])),
                      _study_frames(conn, db, t["participant"], t["trial"], 100),
                      {"source_key": f"{t['participant']}/{t['trial']}",
                       "success": int(t["success"])})
    return w.finish()


def _episode_frames(steps: Iterator[dict]) -> Iterator[dict]:
    """Frame ``t`` of an episode from step rows ``t`` and ``t + 1`` (module docstring): the
    state after step ``t``, the push right after it (its heading as the robot observed it,
    stored on row ``t + 1``) and the action then taken (row ``t + 1``'s)."""
    cur = next(steps, None)
    while cur is not None:
        nxt = next(steps, None)
        heading = -1 if nxt is None else nxt["heading"]
        pushed = cur["is_intervention"]
        yield {"observation.state": [cur["x"], cur["y"]],
               "action": -1 if nxt is None else nxt["action"], "intervention": heading,
               "is_intervention": bool(pushed) if pushed is not None else heading >= 0}
        cur = nxt


#: the episode columns a dataset reads (each checked: :func:`_episodes`)
EPISODE_READ = ("rowid, key, map, status, start, goals, true_goal, success, goal_reached, "
                "pref_followed, metrics")


def _episodes(conn, db, where: str) -> list[dict]:
    """The ``ok`` ``--sim mujoco`` episode rows ``where`` selects, each checked
    (:func:`~pathpref.experiments.store.check_copied_rows`: a tampered value is one line)."""
    return list(check_copied_rows(_iter(
        conn, f"SELECT {EPISODE_READ} FROM episodes WHERE sim = 'mujoco' AND status = 'ok' "
        f"{where} ORDER BY key", ()), db))


def _write_episodes(conn, db, root: Path) -> dict:
    w = LeRobotWriter(root, 1, EPISODE_FEATURES, "pathpref_mobile_base")
    eps = _episodes(conn, db, "")
    for e in eps:
        goal = json.loads(e["goals"])[e["true_goal"]]
        frames = _episode_frames(check_rows_of("steps", _iter(
            conn, "SELECT rowid, t, x, y, action, heading, is_intervention FROM steps WHERE "
            "key = ? ORDER BY t", (e["key"],)), db, STEP_RULES))
        w.add_episode(task_text(goal, e["map"]), frames,
                      {"source_key": e["key"], "success": int(e["success"] or 0)})
    if not w.episodes:
        raise ConfigError(f"{db} holds no --sim mujoco episodes with their steps (a sweep run "
                          "with --no-steps stores none)")
    return w.finish()


def _path_fps(conn, db, keys: list[str]) -> int:
    """The one recorded rate of the paths of ``keys``, in whole frames per second: ``1 / (t_1
    - t_0)`` of each path; ConfigError when they differ or are not whole."""
    rates = set()
    for key in keys:
        t = [r["time_s"] for r in check_rows_of("episode_path", _iter(
            conn, "SELECT rowid, k, time_s FROM episode_path WHERE key = ? AND k < 2 ORDER BY "
            "k", (key,)), db, PATH_RULES)]
        if len(t) == 2 and t[1] > t[0]:
            rates.add(round(1.0 / (t[1] - t[0]), 6))
    if len(rates) != 1 or not float(next(iter(rates))).is_integer():
        shown = ", ".join(f"{r:g}" for r in sorted(rates)) or "none"
        raise ConfigError(f"{db}: the recorded paths must share one rate of whole frames per "
                          f"second for a dataset (found {shown} Hz); record them with "
                          "--record-path 100, say")
    return int(next(iter(rates)))


def _path_frames(rows: Iterator[dict], fps: int, end_effector: bool) -> Iterator[dict]:
    """The frames of one recorded path (module docstring): the samples on the ``k / fps``
    grid (within 1 us), with their velocity (:func:`_with_action`)."""
    def frames() -> Iterator[dict]:
        for r in rows:
            if abs(r["time_s"] - r["k"] / fps) > 1e-6:
                continue  # the episode's last sample, between two instants
            fx, fy = r["fx"], r["fy"]
            cur = {"observation.state": [r["x"], r["y"], r["yaw"]],
                   "intervention": [fx, fy], "is_intervention": math.hypot(fx, fy) > PUSH_ON_N}
            if end_effector:
                cur["observation.end_effector"] = [r["ee_x"], r["ee_y"], r["ee_z"]]
            yield cur

    return _with_action(frames(), fps)


def _write_paths(conn, db, root: Path) -> dict:
    if missing_base_tables(conn):
        raise ConfigError(f"{db} holds no recorded paths (run the sweep with --record-path)")
    eps = _episodes(conn, db, "AND key IN (SELECT DISTINCT key FROM episode_path)")
    if not eps:
        raise ConfigError(f"{db} holds no --sim mujoco episodes with a recorded path (run the "
                          "sweep with --record-path 100)")
    fps = _path_fps(conn, db, [e["key"] for e in eps])
    ee = conn.execute("SELECT count(*) FROM episode_path WHERE ee_x IS NULL").fetchone()[0] == 0
    w = LeRobotWriter(root, fps, PATH_FEATURES | (END_EFFECTOR_FEATURE if ee else {}),
                      "pathpref_mobile_manipulator" if ee else "pathpref_mobile_base")
    for e in eps:
        goal = json.loads(e["goals"])[e["true_goal"]]
        frames = _path_frames(check_rows_of("episode_path", _iter(
            conn, "SELECT rowid, * FROM episode_path WHERE key = ? ORDER BY k", (e["key"],)),
            db, PATH_RULES), fps, ee)
        w.add_episode(task_text(goal, e["map"]), frames,
                      {"source_key": e["key"], "success": int(e["success"] or 0)})
    return w.finish()


WRITERS = {"study": _write_study, "episodes": _write_episodes, "paths": _write_paths}


def export_dataset(db: str | Path, out: str | Path, source: str) -> dict:
    """Write ``db``'s study trials (``source="study"``), physical episodes (``"episodes"``)
    or their recorded paths (``"paths"``) as a LeRobot v3 dataset at ``out`` (a new folder);
    its ``meta/info.json``."""
    if source not in SOURCES:
        raise ConfigError(f"--source must be one of {', '.join(SOURCES)}, got {source[:20]!r}")
    try:
        import pandas  # noqa: F401
        import pyarrow.parquet  # noqa: F401
    except ImportError:
        raise ConfigError("a LeRobot dataset needs pyarrow and pandas: pip install "
                          "'pathpref[dataset]'") from None
    out = Path(out)
    if os.path.lexists(out):
        raise ConfigError(f"--out {out} exists; give a new folder")
    parent = out.parent if str(out.parent) else Path(".")
    if not parent.is_dir():
        raise ConfigError(f"cannot write --out {out}: folder {parent} does not exist")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ConfigError(f"cannot write --out {out}: folder {parent} is not writable")
    with ResultStore(db, create=False) as store:
        tmp: Path | None = None
        try:
            tmp = Path(tempfile.mkdtemp(dir=parent, prefix=f".{out.name}."))
            info = WRITERS[source](store.conn, db, tmp)
            os.rename(tmp, out)
        except OSError as e:  # a read-only or full file system: one line, nothing kept
            why = ("no space left on device; free some space and run again" if is_disk_full(e)
                   else e.strerror or str(e))
            raise ConfigError(f"cannot write --out {out}: {why} (no partial dataset was kept)"
                              ) from None
        finally:
            if tmp is not None and tmp.exists():
                shutil.rmtree(tmp, ignore_errors=True)
    return info
