"""Rerun recordings of episodes (offline ``.rrd`` files, ``rr.RecordingStream``, no viewer).

Entities: ``map/obstacles``, ``map/polytopes`` (outlines, labelled with ids), ``map/graph``
(edges between polytope centres), ``map/goals``, ``map/route`` (a study trial's route,
:meth:`RerunLogger.log_route`); per decision step (timeline ``step``): ``robot/path``,
``robot/position``, ``human/push`` (the detected impulse as an arrow), ``belief/goals`` (bar
chart), ``belief/p_true_goal`` and ``belief/entropy`` (scalars); per physics frame (timeline
``sim_time``): ``robot/trajectory`` and, for the arm, ``robot/ee_trajectory`` and
``robot/ee_height``. Map units: metres.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import rerun as rr

from ..geometry.world import World
from .mapdraw import polytope_centres


class RerunLogger:
    """Writes an episode to an offline rerun file (entities in the module docstring)."""
    def __init__(self, world: World, goal_cells: np.ndarray, true_goal: int, out: str | Path,
                 cell_size: float = 0.5, app: str = "pathpref"):
        self.rec = rr.RecordingStream(app)
        self.rec.save(str(out))
        self.cs = cell_size
        self.path: list[np.ndarray] = []
        rec, cs = self.rec, cell_size
        rec.log("map/obstacles", rr.LineStrips2D(
            [np.vstack([o.vertices, o.vertices[:1]]) * cs for o in world.spec.obstacles],
            colors=[60, 60, 70]), static=True)
        polys = [np.vstack([p, p[:1]]) * cs for p in world.arrangement.polygons if len(p) >= 3]
        centres = polytope_centres(world) * cs
        rec.log("map/polytopes", rr.LineStrips2D(polys, colors=[120, 160, 220]), static=True)
        rec.log("map/polytope_ids", rr.Points2D(
            centres, labels=[str(v) for v in range(world.n_polytopes)], radii=0.02), static=True)
        rec.log("map/graph", rr.LineStrips2D(
            [centres[[u, w]] for u, w in world.graph.edges], colors=[150, 150, 150]),
            static=True)
        g = (np.asarray(goal_cells) - 0.5) * cs
        colors = [[255, 80, 180] if k == true_goal else [80, 170, 255] for k in range(len(g))]
        rec.log("map/goals", rr.Points2D(g, radii=0.08, colors=colors,
                                         labels=[f"g{k}" for k in range(len(g))]), static=True)

    def log_route(self, cells: np.ndarray) -> None:
        """A route to convey (cells ``(x, y)``, 1-based) as a line through their centres."""
        pts = (np.asarray(cells, float) - 0.5) * self.cs
        self.rec.log("map/route", rr.LineStrips2D([pts], colors=[240, 140, 20]), static=True)

    def log_frame(self, sim_time: float, xy: np.ndarray, ee: np.ndarray | None = None) -> None:
        """The base (and, for the arm, the end-effector) position at a physics frame."""
        self.rec.set_time("sim_time", duration=float(sim_time))
        self.rec.log("robot/trajectory", rr.Points2D([xy], radii=0.03, colors=[30, 110, 220]))
        if ee is not None:
            self.rec.log("robot/ee_trajectory", rr.Points2D([np.asarray(ee)[:2]], radii=0.02,
                                                            colors=[240, 170, 30]))
            self.rec.log("robot/ee_height", rr.Scalars(float(np.asarray(ee)[2])))

    def log_step(self, t: int, xy: np.ndarray, belief: np.ndarray, p_true: float,
                 entropy: float, push: np.ndarray | None) -> None:
        """A decision step: path, position, detected push, goal belief, P(true goal), entropy."""
        rec = self.rec
        rec.set_time("step", sequence=int(t))
        self.path.append(np.asarray(xy, float))
        rec.log("robot/path", rr.LineStrips2D([np.array(self.path)], colors=[30, 110, 220]))
        rec.log("robot/position", rr.Points2D([xy], radii=0.1, colors=[30, 110, 220]))
        if push is not None:
            rec.log("human/push", rr.Arrows2D(origins=[xy], vectors=[push], colors=[220, 30, 30]))
        else:
            rec.log("human/push", rr.Clear(recursive=False))
        rec.log("belief/goals", rr.BarChart(np.asarray(belief, float)))
        rec.log("belief/p_true_goal", rr.Scalars(float(p_true)))
        rec.log("belief/entropy", rr.Scalars(float(entropy)))

    def close(self) -> None:
        """Flush and close the recording."""
        self.rec.flush()
        self.rec.disconnect()
