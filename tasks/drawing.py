"""The task drawn into every standard render as MuJoCo scene geometry (``mjvScene`` user geoms
added after the scene is built), so that ``env.physics.render``, Gymnasium's ``rgb_array``
(and ``RecordVideo``) and the dm_control viewer (:mod:`.viewer`) show it:

* the goal candidates as discs coloured by the belief (``belief_rgba``: the video's colours),
  the true goal ringed in pink;
* every polytope outlined, the robot's current one thick and yellow;
* the human's preferred route (``p_v`` of each polytope, the preference the human pushes for)
  as dark grey arrows between polytope centres;
* the robot ringed in blue;
* the human's push while it acts, a red arrow into the pushed body (1 m per 30 N), and the
  last cue the detector read, a green arrow from the robot, for :data:`CUE_SHOWN_S` after it
  was read.

The geoms are those of ``pathpref render`` (:meth:`pathpref.sim.render.RolloutRenderer.overlays`
draws them from an :class:`~pathpref.sim.render.Overlay`); nothing of the physics changes.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from pathpref.sim.render import Overlay, RolloutRenderer
from pathpref.sim.scene import Scene

#: simulated seconds a read cue stays drawn
CUE_SHOWN_S = 2.0
#: the image side (pixels) line widths are scaled for (``RolloutRenderer``: ``side / 360``)
LINE_SIDE_PX = 480


@dataclass
class _Lines:
    """What :meth:`RolloutRenderer.overlays` reads of its renderer: the scene (cell size) and
    the image side (line widths in pixels)."""

    scene: Scene
    side: int


class _SceneSlots:
    """An ``MjvScene`` whose ``geoms`` reach every slot up to ``maxgeom``, as
    :meth:`RolloutRenderer.overlays` fills them (``scn.geoms[scn.ngeom]``, then ``ngeom += 1``):
    the scene dm_control builds lists only its first ``ngeom`` geoms, so a slot past them is
    fetched with ``ngeom`` raised for the look-up (the geom is a view of the scene's buffer)."""

    def __init__(self, scn: mujoco.MjvScene):
        self._scn = scn

    @property
    def ngeom(self) -> int:
        """The scene's geoms in use."""
        return self._scn.ngeom

    @ngeom.setter
    def ngeom(self, n: int) -> None:
        self._scn.ngeom = n

    @property
    def maxgeom(self) -> int:
        """The scene's geom slots."""
        return self._scn.maxgeom

    @property
    def geoms(self) -> _SceneSlots:
        """Indexable by any slot below ``maxgeom``."""
        return self

    def __getitem__(self, i: int):
        s = self._scn
        if i < s.ngeom:
            return s.geoms[i]
        n = s.ngeom
        s.ngeom = i + 1
        try:
            return s.geoms[i]
        finally:
            s.ngeom = n


class TaskDrawing:
    """Draws a task's current state into an ``MjvScene`` (module docstring); called with the
    scene after MuJoCo built it (:meth:`__call__`)."""

    def __init__(self, task):
        from pathpref.viz.mapdraw import preference_arrows  # matplotlib: imported when drawn

        self.task = task
        w = task.world
        self.polygons = w.arrangement.polygons
        r = task.runner
        self.preference = preference_arrows(w, r.pref)
        self.goal_cells = w.cells[list(r.instance.goals)]
        self._lines = _Lines(task.scene, LINE_SIDE_PX)

    def overlay(self) -> Overlay:
        """The :class:`~pathpref.sim.render.Overlay` of the task's state now."""
        from pathpref.viz.video import belief_rgba

        t, r, b = self.task, self.task.runner, self.task.base
        now = float(b.data.time)
        o = Overlay(goal_cells=self.goal_cells,
                    goal_rgba=belief_rgba(r.policy.belief.goal_marginal()),
                    true_goal=r.instance.true_goal, polygons=self.polygons,
                    current=int(t.world.cell_polytope[b.cell]), preference=self.preference,
                    robot_xy=b.position.copy())
        acting = {id(p): p for p in (t.body.last_push, *b.pushes)
                  if p is not None and p.active(now)}  # each push once
        pushes = list(acting.values())
        if pushes:
            o.push_origin = b.data.xpos[b.pushed_body].copy()
            o.push_force = np.sum([p.force(now) for p in pushes], axis=0)
        if b.felt and now - b.felt[-1].t_cue <= CUE_SHOWN_S and b.felt[-1].impulse:
            o.cue_origin, o.cue_direction = b.position.copy(), np.array(b.felt[-1].impulse)
        return o

    def __call__(self, scn: mujoco.MjvScene) -> None:
        """Add the task's geoms to ``scn`` (as many as it has room for)."""
        RolloutRenderer.overlays(self._lines, _SceneSlots(scn), self.overlay())
