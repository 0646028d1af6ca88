"""The named inputs of the two compiled searches (:mod:`.pomcp`, :mod:`.guided`).

Each search takes a few records instead of a long list of positional arrays: the map's
tables (built once per planner), the belief's rows (per decision), the heading likelihood
(robust search, waiting for pushes) and the settings of the search (its preset's numbers and
switches). They are ``typing.NamedTuple`` classes, which numba compiles as tuples: a field is
read by name inside a kernel at no cost (the same loads as a plain tuple's), and the kernels'
arithmetic is unchanged bit for bit.

**Variation points.** The switches that change what the robust search does are fields of
:class:`RobustSettings`: ``use_pref`` (judge crossings by a preference, or plan for the goal
only), ``wait`` (branch on the expected pushes' headings and offer the stay move), ``tie_z``
(the root's tie rule; 0: the best mean), ``budget_s`` (anytime stop), ``push_next`` and
``push_every`` (when the simulated human pushes). Under the route prior the belief's root
particles (``BeliefRows.pool_g``, non-empty) replace the lazy draws of ``p_v``. A new
behaviour is a field here and its branch in the kernel, not a positional argument threaded
through every caller.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class PaperTables(NamedTuple):
    """The map's arrays of the paper's search (:func:`.pomcp._search`): ``next_cell[s, a]``,
    ``cost[s, a]``, ``crossed[s, a]`` (the crossed face, -1: none), ``cell_poly[s]``,
    ``nbr[v, k]`` (-1 padded), the goal candidates' cells and polytopes."""

    next_cell: np.ndarray
    cost: np.ndarray
    crossed: np.ndarray
    cell_poly: np.ndarray
    nbr: np.ndarray
    goal_cells: np.ndarray
    goal_poly: np.ndarray


class PaperSettings(NamedTuple):
    """The paper's search settings: depth, simulations, UCB constant, discount and the additive
    rewards ``R_g``, ``R_p``, ``R_n`` (:class:`~.pomdp.Rewards`); ``use_pref`` False plans
    for the goal only."""

    depth: int
    queries: int
    c: float
    discount: float
    goal: float
    preferred: float
    non_preferred: float
    use_pref: bool


class RobustTables(NamedTuple):
    """The map's arrays of the robust search (:func:`.guided.search_robust`), built once per
    planner: moves and their costs, blocked moves, the slot ``cross_slot[s, a]`` of the
    neighbour a move crosses into (-1: none), polytopes and their neighbours, the goal
    candidates' cells, the constrained cost-to-go ``ctg[s, k, g]`` and distances
    ``dist[g, s]`` of the human model, ``reach[g, s] = gamma^dist`` and the rollout moves
    (:func:`.guided.rollout_moves`)."""

    next_cell: np.ndarray
    cost: np.ndarray
    blocked: np.ndarray
    cross_slot: np.ndarray
    cell_poly: np.ndarray
    nbr: np.ndarray
    goal_cells: np.ndarray
    ctg: np.ndarray
    dist: np.ndarray
    reach: np.ndarray
    moves: np.ndarray


class BeliefRows(NamedTuple):
    """What the robust search reads of the belief at one decision: the goal marginal's
    cumulative ``goal_cdf``, the per-polytope cumulative rows ``pref_cdf[g, v, k]``, the
    polytopes ``known`` (observed), the episode's transitions ``hist_v -> slot hist_k``, and
    the root particles ``pool_g``, ``pool_theta`` (empty: the independent prior's lazy
    draws), and ``pool_late``: the particles whose rollouts arrive by the shortest way,
    keeping the preference only where it was observed (their goal's routes do not fit:
    :mod:`.slack`, rule 0'; all False but under ``robust-value``)."""

    goal_cdf: np.ndarray
    pref_cdf: np.ndarray
    known: np.ndarray
    hist_v: np.ndarray
    hist_k: np.ndarray
    pool_g: np.ndarray
    pool_theta: np.ndarray
    pool_late: np.ndarray


class HeadingTable(NamedTuple):
    """The human model's per-cell heading likelihood as flat arrays
    (:class:`~pathpref.inference.human.CellTable`: ``flat``, ``offsets``, ``slots``); one-entry
    placeholders when the search does not wait for pushes."""

    flat: np.ndarray
    offsets: np.ndarray
    slots: np.ndarray


class RobustSettings(NamedTuple):
    """The robust search's settings (module docstring: its variation points): depth,
    simulations, UCB constant ``c``, discount, the success reward ``(R_g, rho, a)``
    (:class:`~.pomdp.Rewards`: goal, goal_after_violation, arrival), ``use_pref``, the
    wall-time budget (s, 0: none), the expected pushes ``push_next``, ``push_every``, the
    root's tie width ``tie_z`` and ``wait``."""

    depth: int
    queries: int
    c: float
    discount: float
    goal: float
    rho: float
    arrival: float
    use_pref: bool
    budget_s: float
    push_next: int
    push_every: int
    tie_z: float
    wait: bool


#: the placeholder heading table of a search that does not wait for pushes
NO_HEADINGS = HeadingTable(np.zeros(1), np.zeros(1, np.int64), np.zeros(1, np.int64))
