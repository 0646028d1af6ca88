"""A built map: its arrangement, polytope graph, grid motion and human preference, together.

``World`` is what every layer above geometry works on. Build one with :func:`load_world`
(a built-in name, a JSON path or a dict) or :meth:`World.from_spec`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import MapError
from .arrangement import Arrangement, build_arrangement, check_arrangement_size
from .coarse import coarsen
from .footprint import DEFAULT_FOOTPRINT, Footprint
from .graph import PolytopeGraph, build_graph
from .grid import (
    GridMotion,
    apply_footprint,
    blocked_passage,
    build_motion,
    restrict_graph,
    swept_clear,
)
from .maps import MapSpec, load_map
from .preference import parse_preference


@dataclass(frozen=True, eq=False)
class World:
    """Map + arrangement + graph + motion (+ preference, ``-1`` entries = none), for a robot
    of the given :class:`~.footprint.Footprint`: the motion holds the moves that footprint
    sweeps clear, the graph the transitions those moves make (:mod:`.grid`)."""

    spec: MapSpec
    arrangement: Arrangement
    graph: PolytopeGraph
    motion: GridMotion
    preference: np.ndarray | None
    footprint: Footprint = DEFAULT_FOOTPRINT

    @classmethod
    def from_spec(cls, spec: MapSpec, footprint: Footprint = DEFAULT_FOOTPRINT) -> World:
        """Build the arrangement, polytope graph, grid motion (the moves ``footprint``
        sweeps clear) and preference of ``spec``; a MapError naming the blocked passage when
        the preference needs a move the footprint cannot make."""
        arr = build_arrangement(spec)
        graph = build_graph(arr)
        motion = build_motion(arr, graph)
        swept = swept_clear(spec, arr, footprint)
        explain = partial(blocked_passage, spec, arr, footprint)
        if spec.decomposition == "coarse":  # regions are geometry: drawn before the footprint
            arr, graph, motion = coarsen(spec, arr, graph, motion)
        graph, motion = restrict_graph(graph, apply_footprint(motion, swept))
        pref = parse_preference(arr, graph, motion, spec.preference, explain)
        return cls(spec=spec, arrangement=arr, graph=graph, motion=motion, preference=pref,
                   footprint=footprint)

    @property
    def name(self) -> str:
        """The map's name."""
        return self.spec.name

    @property
    def n_cells(self) -> int:
        """Number of free cells."""
        return self.arrangement.n_cells

    @property
    def n_polytopes(self) -> int:
        """Number of free polytopes."""
        return self.arrangement.n_polytopes

    @property
    def cells(self) -> np.ndarray:
        """``(n, 2)`` 1-based ``(x, y)`` of each free cell."""
        return self.arrangement.cells

    @property
    def cell_polytope(self) -> np.ndarray:
        """``(n,)`` polytope id of each free cell."""
        return self.arrangement.cell_polytope

    def cell(self, xy: Any, what: str = "cell") -> int:
        """Index of the free cell ``(x, y)`` (1-based); MapError if off the map or blocked
        (:meth:`Arrangement.free_cell`)."""
        return self.arrangement.free_cell(xy, what)

    def blocked_passage(self, a: int, b: int) -> str:
        """Why the robot cannot go from cell ``a`` to cell ``b`` (one sentence,
        :func:`~.grid.blocked_passage`)."""
        return blocked_passage(self.spec, build_arrangement(self.spec), self.footprint, a, b)

    def require_preference(self) -> np.ndarray:
        """The map's preference, or a MapError telling how to add one."""
        if self.preference is None:
            raise MapError(
                f"map '{self.name}' has no 'preference'; add a table or a route to the map file"
            )
        return self.preference


def load_world(source: str | Path | dict[str, Any] | MapSpec, force: bool = False,
               footprint: Footprint = DEFAULT_FOOTPRINT) -> World:
    """Load and build a map (built-in name, JSON path, dict or MapSpec) for a robot of
    ``footprint``; a MapError before building when its arrangement may exceed the size limit,
    unless ``force`` (:func:`~pathpref.geometry.arrangement.check_arrangement_size`)."""
    spec = source if isinstance(source, MapSpec) else load_map(source)
    check_arrangement_size(spec, force)
    return World.from_spec(spec, footprint)
