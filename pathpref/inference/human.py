"""The Boltzmann human observation model (paper Eq. 1 and 5, SPEC 4) and a simulated human.

A human intervention is a heading, binned to one of the 8 compass moves ``h`` (the observation
``o`` is the cell one move away, or ``s`` itself when the move is blocked). For goal ``g`` and
preferred neighbour ``p = N(v(s))[k]`` the cost excess of heading ``h`` is::

    Delta(s, h, g, k) = C_{g,k}(s, o) - C*_{g,k}(s)

    o inside v(s):                 C = c(s, o) + D_{v,k}(o, g)
    o across the preferred face:   C = c(s, o) + d(o, g)
    o across another face:         Delta = 2 c(s, o)              (step there and back)
    g inside v(s):                 C = c(s, o) + d(o, g) for every o (nothing constrained)
    blocked heading:               Delta = 4                       (stay put plus the penalty)

with ``C* = D_{v,k}(s, g)`` (:mod:`pathpref.inference.costs`). The likelihood is
``P(h | s, g, k) = exp(-gamma_h Delta) / Z`` with ``Z`` the sum over the 8 headings
(``normalize=True``, the default) or ``Z = 1`` (the authors' code, ``normalize=False``).
Blocked headings all lead to ``o = s``; their likelihood is the same for every ``(g, k)`` up to
the count of blocked headings, so conditioning on ``h`` or on ``o`` gives the same posterior.

The goal-only model (Best and Fitch) uses the unconstrained excess
``c(s, o) + d(o, g) - d(s, g)`` (blocked: 4).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..errors import ConfigError
from ..geometry.following import goal_polytope_distance
from ..geometry.world import World
from .costs import CostTables, build_cost_tables

GAMMA_H = 1.5
BLOCK_PENALTY = 4.0
#: likelihood tables larger than this are refused before allocation (bytes; the excess, the
#: likelihood and the goal-only tables are held together)
MAX_TABLE_BYTES = 6 * 2**30
#: cells per block of the excess (:func:`cost_excess`, :attr:`ObservationModel.likelihood`)
EXCESS_CHUNK = 2048


def cost_excess(world: World, tables: CostTables, chunk: int | None = None
                ) -> tuple[np.ndarray, np.ndarray]:
    """``Delta`` with preference ``(n, 8, G, K)`` and goal-only ``(n, 8, G)`` (see module doc).

    Padded neighbour slots (``k >= deg``) hold ``Delta = 0``; they are never read, except slot 0
    of a polytope without neighbours, which holds the goal-only excess.
    Unreachable goals get ``Delta = 0`` (uniform likelihood). Computed ``chunk`` cells at a
    time (every entry depends on its own cell and the cells one move away), so the temporaries
    stay small on large maps.
    """
    n, G = world.n_cells, len(tables.goals)
    K = world.graph.neighbor_table().shape[1]
    delta = np.empty((n, 8, G, K))
    delta_u = np.empty((n, 8, G))
    for sl, d, du in _cost_excess_chunks(world, tables, chunk):
        delta[sl], delta_u[sl] = d, du
    return delta, delta_u


def _cost_excess_chunks(world: World, tables: CostTables, chunk: int | None = None):
    """:func:`cost_excess` ``chunk`` (:data:`EXCESS_CHUNK` when None) cells at a time: yields
    ``(cells slice, Delta rows, goal-only Delta rows)``."""
    n = world.n_cells
    chunk = EXCESS_CHUNK if chunk is None else chunk
    nbr_all = world.graph.neighbor_table()
    for lo in range(0, n, chunk):
        sl = slice(lo, min(lo + chunk, n))
        yield (sl, *_cost_excess_rows(world, tables, nbr_all, sl))


def _cost_excess_rows(world: World, tables: CostTables, nbr_all: np.ndarray, sl: slice
                      ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`cost_excess` for the cells ``sl``."""
    m = world.motion
    nxt, step, blocked = m.next_cell[sl], m.cost[sl], m.blocked[sl]
    v_src = world.cell_polytope[sl]
    v_tgt = world.cell_polytope[nxt]
    dist = tables.dist  # (G, n)
    D = tables.constrained  # (n, K, G)
    d_here = dist[:, sl].T  # (c, G)
    d_next = dist[:, nxt].transpose(1, 2, 0)  # (c, 8, G)
    step_ = step[:, :, None]
    # goal-only
    with np.errstate(invalid="ignore"):
        delta_u = step_ + d_next - d_here[:, None, :]
    delta_u = np.where(blocked[:, :, None], BLOCK_PENALTY, delta_u)
    delta_u = np.where(np.isfinite(delta_u), delta_u, 0.0)
    # with preference
    nbr = nbr_all[v_src]  # (c, K)
    crossing = (~blocked) & (v_tgt != v_src[:, None])  # (c, 8)
    to_pref = crossing[:, :, None] & (v_tgt[:, :, None] == nbr[:, None, :])  # (c, 8, K)
    goal_inside = tables.goal_polytope[None, :] == v_src[:, None]  # (c, G)
    Dk = D[sl].transpose(0, 2, 1)  # (c, G, K)
    with np.errstate(invalid="ignore"):
        stay_in = step[:, :, None, None] + D[nxt].transpose(0, 1, 3, 2) - Dk[:, None]
        exit_pref = (step_ + d_next)[..., None] - Dk[:, None]
    delta = np.where(
        crossing[:, :, None, None],
        np.where(to_pref[:, :, None, :], exit_pref, 2.0 * step[:, :, None, None]),
        stay_in,
    )
    # goal inside v(s), or constraint infeasible: the unconstrained excess
    use_u = goal_inside[:, None, :, None] | ~tables.feasible[sl].transpose(0, 2, 1)[:, None]
    delta = np.where(use_u, delta_u[..., None], delta)
    delta = np.where(blocked[:, :, None, None], BLOCK_PENALTY, delta)
    delta = np.where(np.isfinite(delta), delta, 0.0)
    deg = np.array([len(nb) for nb in world.graph.neighbors])[v_src]
    pad = np.arange(delta.shape[3])[None, :] >= deg[:, None]  # (c, K)
    delta = np.where(pad[:, None, None, :], 0.0, delta)
    # a polytope without neighbours has one "no preference" slot: the unconstrained model
    lone = deg == 0
    delta[lone, :, :, 0] = delta_u[lone]
    return delta, delta_u


def boltzmann(delta: np.ndarray, gamma: float, normalize: bool) -> np.ndarray:
    """``exp(-gamma Delta)``, normalised over the heading axis (axis 1) when asked."""
    lik = np.multiply(delta, -gamma)  # in place from here: one table-sized array
    np.exp(lik, out=lik)
    if normalize:
        lik /= lik.sum(axis=1, keepdims=True)
    return lik


@dataclass(frozen=True, eq=False)
class CellTable:
    """A per-cell table ``T[s][h, g, k]`` whose width is the cell's own slot count
    ``k_s = max(deg(v(s)), 1)`` (the neighbours of its polytope, or the one "no preference"
    slot of a polytope without any), not the map's maximum degree.

    Cell ``s``'s block is ``flat[offsets[s]: offsets[s + 1]]`` read as ``(8, G, k_s)``
    (C order), so ``offsets[s + 1] - offsets[s] = 8 G k_s`` and the table holds
    ``8 G sum_s k_s`` numbers against ``8 G n K`` padded.
    """

    flat: np.ndarray
    offsets: np.ndarray
    slots: np.ndarray
    n_goals: int

    def __getitem__(self, cell: int) -> np.ndarray:
        """``(8, G, k_s)`` block of free cell ``cell`` (a view)."""
        c = int(cell)
        return self.flat[self.offsets[c]: self.offsets[c + 1]].reshape(
            8, self.n_goals, int(self.slots[c]))

    def padded(self, width: int, fill: float) -> np.ndarray:
        """The ``(n, 8, G, width)`` table with slots ``k >= k_s`` set to ``fill``."""
        n, G = len(self.slots), self.n_goals
        out = np.full((n, 8, G, width), fill)
        for k in np.unique(self.slots).tolist():
            group = np.flatnonzero(self.slots == k)
            for lo in range(0, len(group), EXCESS_CHUNK):  # bounded index temporaries
                cells = group[lo: lo + EXCESS_CHUNK]
                idx = self.offsets[cells][:, None] + np.arange(8 * G * k)[None, :]
                out[cells, :, :, :k] = self.flat[idx].reshape(len(cells), 8, G, k)
        return out


def cell_slots(world: World) -> np.ndarray:
    """``(n,)`` slot count ``k_s = max(deg(v(s)), 1)`` of each free cell (:class:`CellTable`)."""
    deg = np.array([len(nb) for nb in world.graph.neighbors], dtype=np.int64)
    return np.maximum(deg, 1)[world.cell_polytope]


def _compact_tables(world: World, tables: CostTables, gamma: float, normalize: tuple[bool, ...],
                    chunk: int | None = None) -> tuple[list[CellTable], np.ndarray]:
    """``boltzmann(Delta, gamma, z)`` for each ``z`` in ``normalize`` as :class:`CellTable`
    (each cell's first ``k_s`` slots of the padded rows of :func:`cost_excess`, so every
    stored value is the padded table's), and the goal-only excess ``(n, 8, G)``; built
    ``chunk`` cells at a time (the padded excess is never held whole)."""
    n, G = world.n_cells, len(tables.goals)
    slots = cell_slots(world)
    offsets = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(8 * G * slots, out=offsets[1:])
    flats = [np.empty(int(offsets[-1])) for _ in normalize]
    delta_u = np.empty((n, 8, G))
    for sl, d, du in _cost_excess_chunks(world, tables, chunk):
        delta_u[sl] = du
        ks = slots[sl]
        groups = [(k, np.flatnonzero(ks == k)) for k in np.unique(ks).tolist()]
        for flat, z in zip(flats, normalize, strict=True):
            lik = boltzmann(d, gamma, z)
            for k, rows in groups:
                idx = offsets[sl.start + rows][:, None] + np.arange(8 * G * k)[None, :]
                flat[idx] = lik[rows, :, :, :k].reshape(len(rows), -1)
    return [CellTable(f, offsets, slots, G) for f in flats], delta_u


@dataclass(frozen=True, eq=False)
class ObservationModel:
    """Likelihood tables of the human's headings for one world and goal set.

    ``cell_likelihood[s][h, g, k] = P(h | s, g, p_{v(s)} = N(v(s))[k])`` (a :class:`CellTable`,
    ``k < k_s``) and ``goal_likelihood[s, h, g] = P(h | s, g)`` (goal-only model); an update
    is a table look-up. ``likelihood`` is the same table padded to the maximum degree (built
    only when asked for).
    """

    world: World
    tables: CostTables
    gamma: float = GAMMA_H
    normalize: bool = True

    @classmethod
    def build(
        cls, world: World, goals: np.ndarray, gamma: float = GAMMA_H, normalize: bool = True
    ) -> ObservationModel:
        """Cost tables and likelihoods for ``goals``; a ConfigError (before allocating) when
        the tables would exceed :data:`MAX_TABLE_BYTES`."""
        n, G, K = world.n_cells, len(goals), max(world.graph.max_degree, 1)
        need = 3 * n * 8 * G * (K + 1) * 8
        if need > MAX_TABLE_BYTES:
            raise ConfigError(
                f"map '{world.name}': likelihood tables for {n} cells x {G} goals x {K} "
                f"neighbour slots need {need / 2**30:.1f} GiB, above the limit "
                f"{MAX_TABLE_BYTES / 2**30:.0f} GiB; use fewer goal candidates or a smaller map")
        return cls(world, build_cost_tables(world, goals), gamma, normalize)

    @property
    def goals(self) -> np.ndarray:
        """Goal candidate cell indices, in the order of the goal axis."""
        return self.tables.goals

    @cached_property
    def _delta(self) -> tuple[np.ndarray, np.ndarray]:
        return cost_excess(self.world, self.tables)

    @cached_property
    def _compact(self) -> tuple[CellTable, CellTable]:
        """(likelihood, normalised heading probabilities) as :class:`CellTable`; one table
        when normalised (they are equal). Keeps the goal-only excess for
        :attr:`goal_likelihood`."""
        z = (True,) if self.normalize else (False, True)
        cts, delta_u = _compact_tables(self.world, self.tables, self.gamma, z)
        self.__dict__["_delta_u"] = delta_u
        return cts[0], cts[-1]

    @property
    def cell_likelihood(self) -> CellTable:
        """``P(heading | s, g, p_v(s) = N(v)[k])`` per cell, ``(8, G, k_s)`` (SPEC 4)."""
        return self._compact[0]

    @property
    def cell_heading_probs(self) -> CellTable:
        """Normalised per-cell probabilities the simulated human samples from."""
        return self._compact[1]

    def _pad(self, table: CellTable, normalized: bool) -> np.ndarray:
        # a padded slot's excess is 0: exp(0) = 1, normalised over the 8 headings 1/8
        return table.padded(self.world.graph.neighbor_table().shape[1],
                            0.125 if normalized else 1.0)

    @cached_property
    def likelihood(self) -> np.ndarray:
        """``(n, 8, G, K)`` :attr:`cell_likelihood` padded to the maximum degree ``K``
        (slots ``k >= k_s`` hold ``exp(0)``, normalised when the model is)."""
        return self._pad(self.cell_likelihood, self.normalize)

    @cached_property
    def goal_likelihood(self) -> np.ndarray:
        """``(n, 8, G)`` ``P(heading | s, g)`` of the unconstrained human (goal-only baseline)."""
        delta_u = self.__dict__.get("_delta_u")
        if delta_u is None and "_delta" not in self.__dict__:
            _ = self._compact
            delta_u = self.__dict__["_delta_u"]
        lik = boltzmann(self._delta[1] if delta_u is None else delta_u, self.gamma,
                        self.normalize)
        if self.normalize:  # nothing else reads the goal-only excess
            self.__dict__.pop("_delta_u", None)
        return lik

    @cached_property
    def heading_probs(self) -> np.ndarray:
        """Normalised ``(n, 8, G, K)`` probabilities (:attr:`cell_heading_probs` padded)."""
        return self.likelihood if self.normalize else self._pad(self.cell_heading_probs, True)

    @cached_property
    def goal_heading_probs(self) -> np.ndarray:
        """Normalised ``(n, 8, G)`` probabilities for a human with no preference."""
        if self.normalize:
            return self.goal_likelihood
        _ = self._compact
        return boltzmann(self.__dict__["_delta_u"], self.gamma, True)


class SimulatedHuman:
    """Samples headings from the Boltzmann model for a true goal and preference (SPEC 4).

    ``preference[v]`` is the preferred neighbour of ``v`` or -1 (no preference in ``v``: the
    human heads for the goal by the unconstrained shortest path there).

    ``hold`` (the consistent human): in the goal's polytope ``r`` without a preference, at a
    cell from which the goal can be reached without leaving ``r`` (a held cell,
    :func:`~pathpref.geometry.following.goal_polytope_hold`), the human pushes along the
    shortest path inside ``r`` instead, every exit of ``r`` being a non-preferred face::

        Delta(s, h) = c(s, o) + D_r(o) - D_r(s)    o in r (inf D_r: as an exit)
        Delta(s, h) = 2 c(s, o)                    o outside r (step there and back)
        Delta(s, h) = 4                            blocked heading

    with ``D_r`` the in-``r`` distance to the goal
    (:func:`~pathpref.geometry.following.goal_polytope_distance`), normalised over the 8
    headings as the goal-heading distribution is. So the human never pushes the robot out of
    the goal's polytope its own route holds (section 4's cost of a forbidden face). Elsewhere,
    and without ``hold`` (the map's human of the paper's protocol), it is unchanged.
    """

    def __init__(self, model: ObservationModel, goal_index: int, preference: np.ndarray,
                 hold: bool = False):
        self.model = model
        self.goal_index = int(goal_index)
        world = model.world
        self.pref_slot = np.array(
            [
                world.graph.neighbor_index(v, int(p)) if p >= 0 else -1
                for v, p in enumerate(preference)
            ]
        )
        #: the in-``r`` distance to the goal at the held cells (inf elsewhere); None: no hold
        self.held_distance: np.ndarray | None = None
        if hold:
            goal = int(model.goals[self.goal_index])
            if np.asarray(preference)[world.cell_polytope[goal]] < 0:
                self.held_distance = goal_polytope_distance(world, goal)

    def probs(self, cell: int) -> np.ndarray:
        """``(8,)`` heading distribution at free cell ``cell``."""
        k = self.pref_slot[self.model.world.cell_polytope[cell]]
        if k < 0:
            if self.held_distance is not None and np.isfinite(self.held_distance[cell]):
                return self._held_probs(cell)
            return self.model.goal_heading_probs[cell, :, self.goal_index]
        return self.model.cell_heading_probs[cell][:, self.goal_index, k]

    def _held_probs(self, cell: int) -> np.ndarray:
        """The heading distribution at a held cell (class docstring)."""
        world = self.model.world
        m = world.motion
        d = self.held_distance
        nxt, cost = m.next_cell[cell], m.cost[cell]
        inside = np.isfinite(d[nxt])
        delta = np.where(inside, cost + np.where(inside, d[nxt], 0.0) - d[cell], 2 * cost)
        delta = np.where(m.blocked[cell], BLOCK_PENALTY, delta)
        return boltzmann(delta[None, :], self.model.gamma, True)[0]

    def sample(self, cell: int, rng: np.random.Generator) -> int:
        """One heading index (0..7, N, NE, ..., NW)."""
        p = self.probs(cell)
        return int(rng.choice(8, p=p / p.sum()))
