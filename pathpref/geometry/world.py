"""A built map: its arrangement, polytope graph, grid motion and human preference, together.

``World`` is what every layer above geometry works on. Build one with :func:`load_world`
(a built-in name, a JSON path or a dict) or :meth:`World.from_spec`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import MapError
from .arrangement import Arrangement, build_arrangement, check_arrangement_size
from .coarse import coarsen
from .graph import PolytopeGraph, build_graph
from .grid import GridMotion, build_motion
from .maps import MapSpec, load_map
from .preference import parse_preference


@dataclass(frozen=True, eq=False)
class World:
    """Map + arrangement + graph + motion (+ preference, ``-1`` entries = none)."""

    spec: MapSpec
    arrangement: Arrangement
    graph: PolytopeGraph
    motion: GridMotion
    preference: np.ndarray | None

    @classmethod
    def from_spec(cls, spec: MapSpec) -> World:
        """Build the arrangement, polytope graph, grid motion and preference of ``spec``."""
        arr = build_arrangement(spec)
        graph = build_graph(arr)
        motion = build_motion(arr, graph)
        if spec.decomposition == "coarse":
            arr, graph, motion = coarsen(spec, arr, graph, motion)
        pref = parse_preference(arr, graph, motion, spec.preference)
        return cls(spec=spec, arrangement=arr, graph=graph, motion=motion, preference=pref)

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

    def require_preference(self) -> np.ndarray:
        """The map's preference, or a MapError telling how to add one."""
        if self.preference is None:
            raise MapError(
                f"map '{self.name}' has no 'preference'; add a table or a route to the map file"
            )
        return self.preference


def load_world(source: str | Path | dict[str, Any] | MapSpec, force: bool = False) -> World:
    """Load and build a map (built-in name, JSON path, dict or MapSpec); a MapError before
    building when its arrangement may exceed the size limit, unless ``force``
    (:func:`~pathpref.geometry.arrangement.check_arrangement_size`)."""
    spec = source if isinstance(source, MapSpec) else load_map(source)
    check_arrangement_size(spec, force)
    return World.from_spec(spec)
