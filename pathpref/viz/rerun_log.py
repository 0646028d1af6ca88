"""Rerun recordings of episodes (offline ``.rrd`` files, ``rr.RecordingStream``, no viewer),
with a blueprint stored in the file so the viewer opens a ready layout (:func:`blueprint`).

Entities (metres; the map's y axis points up on screen, so 2-D points are logged as ``(x, -y)``):

* static: ``map/obstacles``, ``map/polytopes`` (outlines), ``map/polytope_ids``, ``map/graph``
  (edges between polytope centres), ``map/preference`` (the human's preferred transitions as
  arrows), ``map/route`` (a study trial's route to convey, :meth:`RerunLogger.log_route`);
* per decision step (timelines ``step`` and ``sim_time``): ``map/goals`` (coloured by their
  absolute probability, as in the video; the true goal labelled), ``robot/path``,
  ``robot/position``, ``human/push`` (the detected impulse's direction, 0.6 m),
  ``belief/goals`` (bar chart), ``belief/p/g0`` ... (each goal's probability over time),
  ``belief/p_true_goal`` and ``belief/entropy``;
* per rendered physics frame (timeline ``sim_time``): ``robot/trajectory``, ``force/x``,
  ``force/y``, ``force/magnitude`` (the push estimate the detector reads, N),
  ``detector/active`` (0 or 1), ``camera`` (the video frame, JPEG) and, for the arm,
  ``robot/ee_trajectory`` and ``robot/ee_height``.
"""

from __future__ import annotations

import errno
import os
import re
import shutil
import threading
from pathlib import Path

import numpy as np

#: rerun's own (Rust) logger is off: an error it meets while pathpref writes a recording (a
#: full disk) reaches pathpref as an exception, which the command reports in its own one line,
#: and rerun's lines would only repeat it. ``RUST_LOG`` is read once, when rerun's bindings
#: load: it is set to ``off`` for that import only (child processes do not inherit it), unless
#: the user set it (then rerun logs as asked)
_GIVEN_RUST_LOG = os.environ.get("RUST_LOG")
if _GIVEN_RUST_LOG is None:
    os.environ["RUST_LOG"] = "off"
try:
    import rerun as rr
    import rerun.blueprint as rrb
finally:
    if _GIVEN_RUST_LOG is None:
        os.environ.pop("RUST_LOG", None)

from ..episode.physics import CELL_SIZE_M  # noqa: E402
from ..geometry.world import World  # noqa: E402
from .mapdraw import polytope_centres  # noqa: E402
from .video import belief_rgba  # noqa: E402

FLIP = np.array([1.0, -1.0])  # map y up -> rerun 2-D y down


def _xy(points) -> np.ndarray:
    return np.asarray(points, float)[..., :2] * FLIP


def blueprint() -> rrb.Blueprint:
    """The layout an opened recording shows: the map with the robot, goals, preference and
    pushes and the camera on the left; the goal belief (bars, then over time), the force and
    the detector over time on the right."""
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(
                rrb.Spatial2DView(name="map", origin="/",
                                  contents=["map/**", "robot/**", "human/**"]),
                rrb.Spatial2DView(name="camera", origin="camera"),
                row_shares=[3, 2]),
            rrb.Vertical(
                rrb.BarChartView(name="P(goal) now", origin="belief/goals"),
                rrb.TimeSeriesView(name="P(goal) over time", origin="belief/p"),
                rrb.TimeSeriesView(name="P(true goal), entropy (nats)", origin="belief",
                                   contents=["belief/p_true_goal", "belief/entropy"]),
                rrb.TimeSeriesView(name="force on the handle (N)", origin="force"),
                rrb.TimeSeriesView(name="detector active", origin="detector")),
            column_shares=[3, 2]),
        rrb.TimePanel(state="collapsed"),
        collapse_panels=False,
    )


#: the longest (s) closing a recording waits for rerun to write out its file: rerun's flush and
#: disconnect wait without end when the disk is full
CLOSE_TIMEOUT_S = 20.0


#: recordings that failed (abandoned, or not closed), kept referenced to the process's end: rerun's
#: destructor of a stream disconnects it and waits without end on a full disk, so the command
#: line ends such a process at once (:func:`pathpref.apps.cli.console_main`)
_FAILED: list = []


def holds_failed() -> bool:
    """Whether this process holds a recording that failed (:data:`_FAILED`)."""
    return bool(_FAILED)


def _give_up(rec) -> None:
    """A recording that failed: rerun's exit hook (which would wait on its file again) is
    dropped, and the stream is kept referenced to the process's end (:data:`_FAILED`)."""
    rr.unregister_shutdown()
    _FAILED.append(rec)


def _within(fn, timeout_s: float) -> bool:
    """Call ``fn()`` on a daemon thread; True when it returned within ``timeout_s`` (its error,
    if any, raised here), False when it is still running (it is left to the process's end)."""
    error: list[BaseException] = []

    def call() -> None:
        try:
            fn()
        except BaseException as e:  # noqa: BLE001 - handed to the caller's thread
            error.append(e)

    t = threading.Thread(target=call, daemon=True, name="rerun-close")
    t.start()
    t.join(timeout_s)
    if t.is_alive():
        return False
    if error:
        raise error[0]
    return True


class RerunLogger:
    """Writes an episode to an offline rerun file (entities in the module docstring)."""

    def __init__(self, world: World, goal_cells: np.ndarray, true_goal: int, out: str | Path,
                 cell_size: float = CELL_SIZE_M, app: str = "pathpref",
                 preference: np.ndarray | None = None):
        self.rec = rr.RecordingStream(app)
        self.out = Path(out)
        self.rec.save(str(out), default_blueprint=blueprint())
        self.cs = cell_size
        self.path: list[np.ndarray] = []
        self.goals = _xy((np.asarray(goal_cells, float) - 0.5) * cell_size)
        self.true_goal = true_goal
        rec, cs = self.rec, cell_size
        rec.log("map/obstacles", rr.LineStrips2D(
            [_xy(np.vstack([o.vertices, o.vertices[:1]]) * cs) for o in world.spec.obstacles],
            colors=[60, 60, 70]), static=True)
        polys = [_xy(np.vstack([p, p[:1]]) * cs) for p in world.arrangement.polygons
                 if len(p) >= 3]
        centres = polytope_centres(world) * cs
        rec.log("map/polytopes", rr.LineStrips2D(polys, colors=[120, 160, 220]), static=True)
        rec.log("map/polytope_ids", rr.Points2D(
            _xy(centres), labels=[str(v) for v in range(world.n_polytopes)], radii=0.02),
            static=True)
        rec.log("map/graph", rr.LineStrips2D(
            [_xy(centres[[u, w]]) for u, w in world.graph.edges], colors=[150, 150, 150]),
            static=True)
        if preference is not None:
            pairs = [(v, int(w)) for v, w in enumerate(np.asarray(preference)) if w >= 0]
            if pairs:
                a = np.array([centres[v] for v, _ in pairs])
                b = np.array([centres[w] for _, w in pairs])
                rec.log("map/preference", rr.Arrows2D(
                    origins=_xy(a + 0.2 * (b - a)), vectors=_xy(0.6 * (b - a)),
                    colors=[50, 50, 56], radii=0.025), static=True)
        for k in range(len(self.goals)):
            rec.log(f"belief/p/g{k}", rr.SeriesLines(names=f"g{k}" + (
                " (true)" if k == true_goal else "")), static=True)

    def log_route(self, cells: np.ndarray) -> None:
        """A route to convey (cells ``(x, y)``, 1-based) as a line through their centres."""
        pts = (np.asarray(cells, float) - 0.5) * self.cs
        self.rec.log("map/route", rr.LineStrips2D([_xy(pts)], colors=[240, 140, 20]),
                     static=True)

    def _time(self, sim_time: float, step: int | None = None) -> None:
        if step is not None:
            self.rec.set_time("step", sequence=int(step))
        self.rec.set_time("sim_time", duration=float(sim_time))

    def log_frame(self, sim_time: float, xy: np.ndarray, ee: np.ndarray | None = None,
                  force: np.ndarray | None = None, detector_active: bool | None = None,
                  image: np.ndarray | None = None) -> None:
        """A physics frame: the base (and the arm's end-effector), the force estimate, the
        detector's state and the camera image (each when given)."""
        rec = self.rec
        self._time(sim_time)
        rec.log("robot/trajectory", rr.Points2D(_xy([xy]), radii=0.03, colors=[30, 110, 220]))
        if ee is not None:
            rec.log("robot/ee_trajectory", rr.Points2D(_xy([np.asarray(ee)]), radii=0.02,
                                                       colors=[240, 170, 30]))
            rec.log("robot/ee_height", rr.Scalars(float(np.asarray(ee)[2])))
        if force is not None:
            f = np.asarray(force, float)
            rec.log("force/x", rr.Scalars(float(f[0])))
            rec.log("force/y", rr.Scalars(float(f[1])))
            rec.log("force/magnitude", rr.Scalars(float(np.hypot(f[0], f[1]))))
        if detector_active is not None:
            rec.log("detector/active", rr.Scalars(float(bool(detector_active))))
        if image is not None:
            rec.log("camera", rr.Image(np.asarray(image, np.uint8)).compress(jpeg_quality=80))

    def log_step(self, t: int, xy: np.ndarray, belief: np.ndarray, p_true: float,
                 entropy: float, push: np.ndarray | None, sim_time: float | None = None
                 ) -> None:
        """A decision step: goals in their belief colours, path, position, detected push, the
        goal belief (bars and per-goal series), P(true goal), entropy."""
        rec = self.rec
        rec.set_time("step", sequence=int(t))
        if sim_time is not None:
            rec.set_time("sim_time", duration=float(sim_time))
        belief = np.asarray(belief, float)
        colors = (belief_rgba(belief)[:, :3] * 255).astype(np.uint8)
        rec.log("map/goals", rr.Points2D(
            self.goals, radii=0.1, colors=colors,
            labels=[f"g{k}" + (" (true)" if k == self.true_goal else "")
                    for k in range(len(self.goals))]))
        self.path.append(np.asarray(xy, float))
        rec.log("robot/path", rr.LineStrips2D([_xy(np.array(self.path))],
                                              colors=[30, 110, 220]))
        rec.log("robot/position", rr.Points2D(_xy([xy]), radii=0.1, colors=[30, 110, 220]))
        if push is not None:  # the impulse's direction, 0.6 m long
            v = np.asarray(push, float)[:2]
            v = v / max(float(np.hypot(*v)), 1e-9) * 0.6
            rec.log("human/push", rr.Arrows2D(origins=_xy([xy]), vectors=_xy([v]),
                                              colors=[220, 30, 30], radii=0.03))
        else:
            rec.log("human/push", rr.Clear(recursive=False))
        rec.log("belief/goals", rr.BarChart(belief))
        for k, p in enumerate(belief):
            rec.log(f"belief/p/g{k}", rr.Scalars(float(p)))
        rec.log("belief/p_true_goal", rr.Scalars(float(p_true)))
        rec.log("belief/entropy", rr.Scalars(float(entropy)))

    def close(self, timeout_s: float = CLOSE_TIMEOUT_S) -> None:
        """Flush and close the recording, waiting at most ``timeout_s`` for each; a file that
        cannot be written out in that time is an OSError (ENOSPC when its file system has no
        room left), never a wait without end."""
        try:
            self.rec.flush(timeout_sec=timeout_s)
            done = _within(self.rec.disconnect, timeout_s)
        except RuntimeError as e:  # rerun's error: a failed write, or the flush's timeout
            _give_up(self.rec)
            raise self.unwritten(str(e)) from None
        if not done:
            _give_up(self.rec)
            raise self.unwritten(f"not closed within {timeout_s:g} s")

    def unwritten(self, why: str) -> OSError:
        """The OSError of a recording rerun could not write (``why``: rerun's message): its
        ``(os error N)`` when it names one, else ENOSPC when the file's folder has no room
        left (under 1 MiB), else EIO."""
        named = re.search(r"\(os error (\d+)\)", why)
        folder = self.out.parent
        full = shutil.disk_usage(folder).free < 1 << 20 if folder.is_dir() else False
        code = int(named.group(1)) if named else errno.ENOSPC if full else errno.EIO
        return OSError(code, f"{os.strerror(code)}: rerun could not write {self.out} ({why})")

    def abandon(self, timeout_s: float = 1.0) -> None:
        """Close the recording after a failure (its file is to be removed): the flush and the
        disconnect wait at most ``timeout_s`` each (rerun's wait without end on a full disk
        never holds the caller), errors are dropped, and rerun's own flush at the process's
        exit is dropped (the process is failing; every recording of ours is closed by hand)."""
        try:
            self.rec.flush(timeout_sec=timeout_s)
        except Exception:  # noqa: BLE001, S110 - the failure that led here is the one to tell
            pass
        try:
            _within(self.rec.disconnect, timeout_s)
        except Exception:  # noqa: BLE001, S110
            pass
        _give_up(self.rec)
