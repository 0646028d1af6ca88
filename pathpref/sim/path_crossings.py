"""Polytope crossings along the base's continuous path, each labelled with who made it.

A guided base goes where the person's push takes it, so a decision step's start and end cells
do not tell which faces it crossed (a push can carry it through two polytopes in one step).
:class:`PathCrossings`, an ``on_substep`` hook, follows the polytope under the base at every
physics step and notes each crossing as ``(v, w, person)``: ``person`` is True when a push
acted, or ended less than ``3 M / b`` before (three time constants of the guidance
admittance: the deformation it carries is 95 % done by then), when the base entered ``w`` or
when the crossing counted, i.e. the person led the base across. The episode runner judges the
crossings one by one (:meth:`~pathpref.episode.runner.EpisodeRunner.arrive`): the robot's own
crossings make the success rule, the person-led ones are reported beside them.

**Hysteresis.** A base left on a face (a push that ends with the base straddling it) flips
between the cells on either side from one step to the next; counting every flip scored one
push as ``4 -> 6 -> 4 -> 6 -> 4``, four crossings. A crossing from the polytope ``v`` the base
was last judged in into ``w`` therefore counts only once the base is at least
:data:`HYSTERESIS_CELLS` of a cell (``d``) inside ``w``: its distance to the nearest cell of
``v`` is at least ``d cell_size`` (the cells are the squares ``cell_size`` wide around their
centres). Until then the crossing is pending: back in ``v`` it is forgotten (no crossing), in
a third polytope ``x`` it counts ``v -> w`` (the base went through ``w``) and ``w -> x`` is
pending. A robot's own move ends at a cell's centre, half a cell inside it, so its crossings
all count, as before; the chatter counts nothing.
"""

from __future__ import annotations

import numpy as np

#: how deep inside a new polytope the base must be for its crossing to count (cells)
HYSTERESIS_CELLS = 0.25


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
        #: the crossing under way: ``(w, person)`` (None: the base is in ``v``)
        self.pending: tuple[int, bool] | None = None
        self._centres: dict[int, np.ndarray] = {}

    def reset(self, cell: int) -> None:
        """The base stands in ``cell``: no crossings yet."""
        self.v = int(self.world.cell_polytope[cell])
        self.crossings = []
        self._led_until = -np.inf
        self.pending = None

    def depth(self, xy: np.ndarray, v: int) -> float:
        """The distance (m) from ``xy`` to the nearest cell of polytope ``v`` (infinity when
        it has none: ``v`` -1, a hook never reset)."""
        size = float(self.base.scene.cell_size)
        c = self._centres.get(v)
        if c is None:
            c = (self.world.cells[self.world.cell_polytope == v] - 0.5) * size
            self._centres[v] = c
        if len(c) == 0:
            return np.inf
        gap = np.maximum(np.abs(c - np.asarray(xy, float)[:2]) - 0.5 * size, 0.0)
        return float(np.sqrt((gap * gap).sum(axis=1)).min())

    def __call__(self, base, push=None) -> None:
        """After a physics step: follow the polytope under the base (module docstring)."""
        t = float(base.data.time)
        if any(p.active(t) for p in base.pushes):
            self._led_until = t + self.led_s
        led = t <= self._led_until
        w = int(self.world.cell_polytope[base.cell])
        if w == self.v:
            self.pending = None  # back where it was judged: the flip is forgotten
            return
        if self.pending is not None and self.pending[0] != w:  # through w into a third
            self.crossings.append((self.v, self.pending[0], self.pending[1]))
            self.v, self.pending = self.pending[0], None
            if w == self.v:
                return
        if self.pending is None:
            self.pending = (w, led)
        size = float(base.scene.cell_size)
        if self.depth(base.position, self.v) >= HYSTERESIS_CELLS * size - 1e-12:
            self.crossings.append((self.v, w, self.pending[1] or led))
            self.v, self.pending = w, None

    def take(self) -> list[tuple[int, int, bool]]:
        """The crossings since the last call, in order (a pending one is not yet one)."""
        out, self.crossings = self.crossings, []
        return out
