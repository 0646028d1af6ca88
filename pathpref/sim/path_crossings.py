"""Polytope crossings along the base's continuous path, each labelled with who made it.

A guided base goes where the person's push takes it, so a decision step's start and end cells
do not tell which faces it crossed (a push can carry it through two polytopes in one step).
:class:`PathCrossings`, an ``on_substep`` hook, notes every change of the polytope under the
base at every physics step, as ``(v, w, person)``: ``person`` is True when a push acted at that
step or ended less than ``3 M / b`` before (three time constants of the guidance admittance:
the deformation it carries is 95 % done by then), i.e. the person led the base across. The
episode runner judges the crossings one by one (:meth:`~pathpref.episode.runner.
EpisodeRunner.arrive`): the robot's own crossings make the success rule, the person-led ones
are reported beside them.
"""

from __future__ import annotations

import numpy as np


class PathCrossings:
    """The crossings of ``base`` (a :class:`~.mobile_base.MobileBase` with guidance on) in
    ``world`` since the last :meth:`take` (module docstring)."""

    def __init__(self, base, world):
        self.base, self.world = base, world
        g = base.guidance
        self.led_s = 3.0 * g.mass / g.damping
        self.crossings: list[tuple[int, int, bool]] = []
        self.v = -1
        self._led_until = -np.inf

    def reset(self, cell: int) -> None:
        """The base stands in ``cell``: no crossings yet."""
        self.v = int(self.world.cell_polytope[cell])
        self.crossings = []
        self._led_until = -np.inf

    def __call__(self, base, push=None) -> None:
        """After a physics step: note a polytope change and who made it."""
        t = float(base.data.time)
        if any(p.active(t) for p in base.pushes):
            self._led_until = t + self.led_s
        w = int(self.world.cell_polytope[base.cell])
        if w != self.v:
            self.crossings.append((self.v, w, t <= self._led_until))
            self.v = w

    def take(self) -> list[tuple[int, int, bool]]:
        """The crossings since the last call, in order."""
        out, self.crossings = self.crossings, []
        return out
