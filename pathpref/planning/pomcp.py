"""POMCP (Silver and Veness 2010) for the path-preference POMDP, compiled with numba (SPEC 7).

PO-UCT with ``queries`` simulations per decision, UCB constant ``c``, search depth ``depth``
(``T_max - t + 1``), uniform-random rollouts, a tree rebuilt at every decision.

Root states come from the exact belief, not from particles: each simulation draws the goal
``g ~ P(g | o_1:t)`` and, lazily the first time it leaves a polytope ``v``,
``p_v ~ P(p_v | g, o_1:t)``, which is exact because the posterior factorises given ``g`` (SPEC 5).

Inside the search the robot expects no human input, so the only observation is whether it
stands on a wrong goal candidate, a function of its cell. A history is therefore fixed by its
action sequence: each (node, action) pair has one child, and the tree is stored in flat arrays
(``child[node, a]``, visit counts and mean returns per action).

Speed (``pathpref bench``): about 10 ms for 5000 queries at depth 30 on ``simple``, against
~500 ms for the authors' Julia code.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

from ..errors import ConfigError
from ..geometry.world import World
from ..inference.belief import Belief
from ..inference.costs import CostTables
from ..inference.human import CellTable
from ..inference.routes import components
from .guided import (
    complete_tree,
    observed_first_trees,
    reach_table,
    rollout_moves,
    search_robust,
    tree_pool,
)
from .pomdp import Rewards
from .search_inputs import (
    NO_HEADINGS,
    BeliefRows,
    HeadingTable,
    PaperSettings,
    PaperTables,
    RobustSettings,
    RobustTables,
)
from .tree import best_root_action, init_node, new_tree, sample_index, sample_slot

#: root particles of a route-prior belief per decision (exact draws, :func:`.guided.tree_pool`).
#: 128, not 512: on ``classroom`` the draws took a third of a decision (a random walk from each
#: polytope to the goal's on a map of long loops), and success did not change within the
#: intervals (docs/robust.md)
TREE_POOL = 128
#: the pool holds at most one particle per ``SIMS_PER_TREE`` simulations of the decision
#: (:meth:`POMCP._pool`): 128 at the paper's 5000 queries, 32 at the bench floor plan's 1000
SIMS_PER_TREE = 32
#: and at most ``max(POOL_MIN, POOL_POLYTOPE_TREES / P)`` particles on a plan of ``P``
#: polytopes (a tree's Wilson draw costs about ``9 P`` walk steps): 128 up to ``P = 261`` (the
#: paper's maps and the held-out plans keep their pools and moves), 72 at 469 polytopes
#: (32 x 32, 16 rotated), 32 from 1045 (40 x 40, 32 rotated), where the first decision fell
#: from 49-52 to 25-30 ms CPU (paired sweep: docs/results/pool_by_plan_size.md)
POOL_POLYTOPE_TREES = 33_440
#: the fewest particles the plan-size bound leaves (the 200 x 200 bench plan at 1000 queries
#: keeps its 32)
POOL_MIN = 32
#: a tree's Wilson walks may take ``WALK_STEPS_PER_POLYTOPE * P + WALK_STEPS_MIN`` steps before
#: it is drawn observed exits first instead (:func:`.guided.tree_pool`; the walk with no
#: evidence takes 5-13 ``P`` steps in expectation on the paper's maps and examples/maps, median
#: 9 ``P`` on ``classroom``)
WALK_STEPS_PER_POLYTOPE = 64
WALK_STEPS_MIN = 4096
#: walk stages over the unobserved polytopes (uniform rows) tried per tree before giving up,
#: each with twice the budget of the one before (:func:`.guided.observed_first_trees`): at
#: most ``255`` budgets per tree (1.8 million steps on a 49-polytope plan)
WALK_TRIES = 8
#: robust search: root moves within this many standard errors of the best mean return count
#: as tied, and the rollout heuristic picks among them (:func:`.guided._root_choice`)
TIE_Z = 1.0


@nb.njit(cache=True, inline="always")
def _step(s, a, gi, q, world, pref_cdf, theta, stamp, settings):
    """Generative step on the map's tables ``world`` (:class:`.search_inputs.PaperTables`) with
    the rewards of ``settings`` (:class:`.search_inputs.PaperSettings`); returns (next cell,
    reward, done). Samples p_v lazily into theta."""
    cell_poly, nbr = world.cell_poly, world.nbr
    Rp, Rn = settings.preferred, settings.non_preferred
    s2 = world.next_cell[s, a]
    r = -world.cost[s, a]
    if settings.use_pref and world.crossed[s, a] >= 0:
        v = cell_poly[s]
        if world.goal_poly[gi] == v:
            r += Rn
        else:
            if stamp[v] != q:
                stamp[v] = q
                theta[v] = nbr[v, sample_slot(v, gi, nbr, pref_cdf)]
            if cell_poly[s2] == theta[v]:
                r += Rp
            else:
                r += Rn
    done = s2 == world.goal_cells[gi]
    if done:
        r += settings.goal
    return s2, r, done


@nb.njit(cache=True)
def _search(world, goal_cdf, pref_cdf, settings, s0, seed):
    """The paper's PO-UCT (module docstring) from cell ``s0`` on the map's tables ``world``
    (:class:`.search_inputs.PaperTables`), the belief's cumulative goal marginal and
    preference rows, and ``settings`` (:class:`.search_inputs.PaperSettings`): its tree and
    buffers, the simulations (:func:`_simulate`), the best root action; returns ``(action,
    root visits, root values, nodes)``."""
    np.random.seed(seed)
    depth = settings.depth
    n_node, n_sa, q_sa, child = new_tree(settings.queries)
    P = world.nbr.shape[0]
    theta = -np.ones(P, np.int64)
    stamp = -np.ones(P, np.int64)
    path_node = np.zeros(depth + 1, np.int64)
    path_a = np.zeros(depth + 1, np.int64)
    path_r = np.zeros(depth + 1)
    n_nodes = _simulate(world, (goal_cdf, pref_cdf), (n_node, n_sa, q_sa, child),
                        (theta, stamp, path_node, path_a, path_r), settings, s0)
    return best_root_action(n_sa, q_sa), n_sa[0].copy(), q_sa[0].copy(), n_nodes


@nb.njit(cache=True, _nrt=False)
def _simulate(world, belief, nodes, scratch, settings, s0):
    """The simulations of :func:`_search` on its records and arrays (grouped in tuples);
    returns the
    number of nodes. Compiled without reference counting (it allocates nothing; the caller
    owns every array for the whole call): the counts numba updates around an inlined
    helper's array arguments cost as much as the search itself."""
    depth, queries, c, discount = settings.depth, settings.queries, settings.c, \
        settings.discount
    goal_cdf, pref_cdf = belief
    n_node, n_sa, q_sa, child = nodes
    theta, stamp, path_node, path_a, path_r = scratch
    n_nodes = 1
    for q in range(queries):
        gi = sample_index(goal_cdf)
        s = s0
        node = 0
        L = 0
        leaf = 0.0
        while L < depth:
            # UCB1 with untried actions first (random order among them)
            a = -1
            off = np.random.randint(8)
            for j in range(8):
                b = (off + j) % 8
                if n_sa[node, b] == 0:
                    a = b
                    break
            if a < 0:
                best = -1e300
                logn = np.log(n_node[node])
                for b in range(8):
                    val = q_sa[node, b] + c * np.sqrt(logn / n_sa[node, b])
                    if val > best:
                        best = val
                        a = b
            s2, r, done = _step(s, a, gi, q, world, pref_cdf, theta, stamp, settings)
            path_node[L] = node
            path_a[L] = a
            path_r[L] = r
            L += 1
            s = s2
            if done:
                break
            ch = child[node, a]
            if ch < 0:
                child[node, a] = n_nodes
                init_node(n_node, n_sa, q_sa, child, n_nodes)
                n_nodes += 1
                # uniform-random rollout for the remaining depth
                disc = 1.0
                for _ in range(depth - L):
                    b = np.random.randint(8)
                    s, r2, d2 = _step(s, b, gi, q, world, pref_cdf, theta, stamp, settings)
                    leaf += disc * r2
                    disc *= discount
                    if d2:
                        break
                break
            node = ch
        ret = leaf
        for i in range(L - 1, -1, -1):
            ret = path_r[i] + discount * ret
            nd = path_node[i]
            b = path_a[i]
            n_node[nd] += 1
            n_sa[nd, b] += 1
            q_sa[nd, b] += (ret - q_sa[nd, b]) / n_sa[nd, b]
    return n_nodes


@dataclass
class SearchResult:
    """The chosen action and the root statistics of one search."""

    action: int
    visits: np.ndarray
    values: np.ndarray
    nodes: int
    queries: int = 0


class POMCP:
    """Online planner over ``(s, g, theta)`` (or ``(s, g)`` when ``rewards.use_preference`` is
    False). The tree is rebuilt at every call of :meth:`search`.

    Args:
        world: the map.
        goals: goal candidate cells (indices), in the order of the belief's goal axis.
        rewards: the planner's rewards and discount.
        queries: simulations per decision (5000 in the paper; the cap under a time budget).
        c: UCB exploration constant (1 in the paper).
        tables: the human model's cost tables; given, the search is the `robust` one of
            :mod:`pathpref.planning.guided` (guided rollouts, scaled exploration, preferred
            crossings paid once per episode); None is the paper's search.
        budget_ms: wall-time budget per decision for the robust search (0: ``queries`` only).
        likelihood: the human model's per-cell heading likelihood
            (:attr:`~pathpref.inference.human.ObservationModel.cell_likelihood`); given, the
            robust search waits for the pushes it expects (:mod:`.guided`, 7;
            :attr:`~.pomdp.Preset.wait_for_pushes`).
    """

    def __init__(self, world: World, goals: np.ndarray, rewards: Rewards, queries: int = 5000,
                 c: float = 1.0, tables: CostTables | None = None, budget_ms: float = 0.0,
                 likelihood: CellTable | None = None):
        m = world.motion
        self.world = world
        self.rewards = rewards
        self.queries = int(queries)
        self.c = float(c)
        # the world's arrays themselves when of the kernels' types (read only: no copy)
        self.next_cell = np.asarray(m.next_cell, dtype=np.int64)
        self.cost = np.asarray(m.cost, dtype=np.float64)
        self.crossed = np.asarray(m.crossed_edge, dtype=np.int64)
        self.cell_poly = np.asarray(world.cell_polytope, dtype=np.int64)
        self.nbr = world.graph.neighbor_table().astype(np.int64)
        self.goal_cells = np.asarray(goals, dtype=np.int64)
        self.goal_poly = self.cell_poly[self.goal_cells]
        deg = (self.nbr >= 0).sum(axis=1)
        K = self.nbr.shape[1]
        uniform = np.where(np.arange(K)[None, :] < deg[:, None],
                           (np.arange(K)[None, :] + 1) / np.maximum(deg, 1)[:, None], 1.0)
        self._uniform_cdf = uniform  # (P, K)
        if (tables is not None) != (rewards.model == "success"):
            raise ConfigError("the robust search (cost tables given) plans with the success "
                              "reward, the paper's search with the additive one")
        self.tables = tables
        self.budget_s = float(budget_ms) / 1000.0
        #: the heading likelihood's flat table, offsets and slot counts (empty: no waiting)
        self.wait = likelihood is not None
        if likelihood is None:
            self._lik = NO_HEADINGS
        else:
            self._lik = HeadingTable(np.ascontiguousarray(likelihood.flat, dtype=np.float64),
                                     np.asarray(likelihood.offsets, dtype=np.int64),
                                     np.asarray(likelihood.slots, dtype=np.int64))
        self._paper_tables = PaperTables(self.next_cell, self.cost, self.crossed,
                                         self.cell_poly, self.nbr, self.goal_cells,
                                         self.goal_poly)
        #: the last root pool and the distribution it was drawn from (:meth:`_pool`)
        self._kept_pool: tuple | None = None
        self.pools_drawn = 0
        #: trees whose walks passed every budget (:meth:`_observed_first`) and were completed
        #: by :func:`~.guided.complete_tree`: their observed exits are an exact draw, their
        #: unobserved exits the fewest polytopes to the goal's (0 on every plan measured)
        self.completed_trees = 0
        if tables is not None:
            self.blocked = m.blocked.copy()
            v_next = self.cell_poly[self.next_cell]
            slot = (self.nbr[self.cell_poly][:, None, :] == v_next[:, :, None])  # (n, 8, K)
            self.cross_slot = np.where(self.crossed >= 0, slot.argmax(axis=2), -1)
            self.ctg = np.ascontiguousarray(tables.constrained, dtype=np.float64)
            self.dist = np.ascontiguousarray(tables.dist, dtype=np.float64)
            self.component = components(world.graph.neighbors)
            self.moves = rollout_moves(self.next_cell, self.cost, self.blocked, self.cross_slot,
                                       self.ctg, self.dist)
            self.reach = reach_table(self.dist, float(rewards.discount))
            self._robust_tables = RobustTables(
                self.next_cell, self.cost, self.blocked, self.cross_slot, self.cell_poly,
                self.nbr, self.goal_cells, self.ctg, self.dist, self.reach, self.moves)

    def preference_cdf(self, belief: Belief) -> np.ndarray:
        """``(G, P, K)`` cumulative per-polytope rows ``T_v(g, k)`` normalised (uniform where
        never observed): ``P(p_v = N(v)[k] | g)`` under the independent prior, the rows of
        Wilson's walk under the route prior (:mod:`pathpref.inference.routes`)."""
        G = len(self.goal_cells)
        cdf = np.broadcast_to(self._uniform_cdf, (G, *self._uniform_cdf.shape)).copy()
        for v in belief.observed_polytopes():
            cond = belief.local_given_goal(v)
            cdf[:, v, : cond.shape[1]] = np.cumsum(cond, axis=1)
        return cdf

    def search(self, cell: int, belief: Belief, depth: int, seed: int,
               history: list[tuple[int, int]] = (), pushes: tuple[int, int] = (1, 1),
               late_goals: np.ndarray | None = None) -> SearchResult:
        """Plan from ``cell`` with root states drawn from ``belief``; return the best action.

        ``history``: the episode's polytope transitions ``(v, w)`` so far (robust search: they
        count toward the success reward). ``pushes``: ``(next, every)``, the simulation step of
        the next expected push and the interval after it (robust search, route prior).
        ``late_goals``: ``(G,)`` the goals whose particles roll out by the shortest way,
        keeping the preference where it was observed (:mod:`.slack`, rule 0'; None: none)."""
        goal_cdf = np.cumsum(belief.goal_marginal())
        cdf = self.preference_cdf(belief) if self.rewards.use_preference else self._dummy_cdf()
        r = self.rewards
        depth = int(max(depth, 1))
        if self.tables is not None:
            pool_g, pool_theta = self._pool(belief, goal_cdf, cdf, seed)
            late = np.zeros(len(pool_g), np.bool_) if late_goals is None else \
                np.asarray(late_goals, np.bool_)[pool_g]
            rows = BeliefRows(goal_cdf, cdf, self._known(belief), *self._history(history),
                              pool_g, pool_theta, late)
            settings = RobustSettings(
                depth, self.queries, self.c, float(r.discount), float(r.goal),
                float(r.goal_after_violation), float(r.arrival), bool(r.use_preference),
                self.budget_s, int(pushes[0]), max(int(pushes[1]), 1), TIE_Z, self.wait)
            a, visits, values, nodes, done = search_robust(
                self._robust_tables, rows, self._lik, settings, int(cell), int(seed) % (2**32))
            return SearchResult(int(a), visits, values, int(nodes), int(done))
        settings = PaperSettings(depth, self.queries, self.c, float(r.discount), float(r.goal),
                                 float(r.preferred), float(r.non_preferred),
                                 bool(r.use_preference))
        a, visits, values, nodes = _search(self._paper_tables, goal_cdf, cdf, settings,
                                           int(cell), int(seed) % (2**32))
        return SearchResult(int(a), visits, values, int(nodes), self.queries)

    def particles(self, belief: Belief, seed: int) -> tuple[np.ndarray, np.ndarray] | None:
        """``(goal indices, preference slots)``: :meth:`pool_size` exact draws of the
        route-prior posterior of ``belief`` without a search (:meth:`_pool`: the same draws,
        and the same reuse while the belief is unchanged, as the search's root particles);
        None for a belief without route-prior draws (the independent prior)."""
        if self.tables is None:
            return None
        goals, slots = self._pool(belief, np.cumsum(belief.goal_marginal()),
                                  self.preference_cdf(belief), seed)
        return (goals, slots) if len(goals) else None

    def root_particles(self) -> tuple[np.ndarray, np.ndarray] | None:
        """``(goal indices, preference slots)`` of the root particles the last robust search
        started from (:meth:`_pool`), or None when it drew none (the independent prior)."""
        kept = self._kept_pool
        return None if kept is None or len(kept[3]) == 0 else (kept[3], kept[4])

    def pool_size(self) -> int:
        """Root particles per decision: ``m = min(TREE_POOL, ceil(queries / SIMS_PER_TREE),
        max(POOL_MIN, ceil(POOL_POLYTOPE_TREES / P)))`` on a plan of ``P`` polytopes.
        Each simulation starts from one particle drawn uniformly, so a particle is the start of
        ``queries / m >= SIMS_PER_TREE`` simulations on average; a tree costs a Wilson draw of
        ``~9 P`` walk steps, a simulation at most ``depth`` steps, and more particles than that
        buy draws the search barely uses; on large plans the draws' cost, ``~9 P m`` steps, is
        held near ``9 POOL_POLYTOPE_TREES``."""
        by_plan = max(POOL_MIN, -(-POOL_POLYTOPE_TREES // max(len(self.nbr), 1)))
        return min(TREE_POOL, -(-self.queries // SIMS_PER_TREE), by_plan)

    def _pool(self, belief: Belief, goal_cdf: np.ndarray, cdf: np.ndarray, seed: int):
        """Root particles ``(goal index, preference slots)`` of a route-prior belief
        (:func:`~.guided.tree_pool`, :meth:`pool_size` exact draws); empty otherwise (the search
        then draws ``g`` and each ``p_v`` lazily, independently).

        **Reuse.** The pool is kept and handed to the next decision while the distribution it
        is drawn from is unchanged: the same goal marginal ``goal_cdf`` and the same normalised
        walk rows ``cdf`` (compared exactly; the route posterior ``P(theta | g, o)`` is a
        function of these alone, module :mod:`pathpref.inference.routes`). Between two pushes
        (no observation, no candidate ruled out) every decision then searches from the same
        exact draws: each decision's particles are still exact draws of its posterior, only
        correlated with the previous decision's (``ΔT - 1`` of ``ΔT`` decisions draw nothing)."""
        if not (self.rewards.use_preference and belief.route_prior):
            return np.zeros(0, np.int64), np.zeros((0, len(self.nbr)), np.int64)
        kept = self._kept_pool
        observed = np.asarray(belief.observed_polytopes(), dtype=np.int64)
        if kept is not None and np.array_equal(kept[0], goal_cdf) and \
                self._same_rows(kept[1], kept[2], observed, cdf):
            return kept[3], kept[4]
        self._kept_pool = kept = None  # freed before the new pool is drawn
        m = self.pool_size()
        mixture = belief.particles(m, np.random.default_rng(int(seed) + 3))
        if mixture is None:
            goals, slots = self._trees(belief, goal_cdf, cdf, m, seed)
        else:  # the homotopy prior: way particles, and trees for the route prior's share
            m_tree, tree_cdf, goals, slots = mixture
            if m_tree:
                tg, ts = self._trees(belief, tree_cdf, cdf, m_tree, seed)
                goals, slots = np.concatenate([tg, goals]), np.concatenate([ts, slots])
        self._kept_pool = (goal_cdf.copy(), observed, cdf[:, observed].copy(), goals, slots)
        self.pools_drawn += 1
        return goals, slots

    def _same_rows(self, kept_v: np.ndarray, kept_rows: np.ndarray, observed: np.ndarray,
                   cdf: np.ndarray) -> bool:
        """True when ``cdf`` equals, exactly, the walk rows a pool was drawn from, kept as the
        rows ``kept_rows`` of the polytopes ``kept_v`` observed then. Every other row of
        either is the uniform one (:meth:`preference_cdf`), so the two ``(G, P, K)`` arrays
        are equal iff they agree on the polytopes observed then or now; the kept rows cost
        ``G K`` numbers per observed polytope, not ``G P K``."""
        both = np.union1d(kept_v, observed)
        then = np.broadcast_to(self._uniform_cdf[both], (cdf.shape[0], len(both), cdf.shape[2]))
        then = then.copy()
        then[:, np.searchsorted(both, kept_v)] = kept_rows
        return bool(np.array_equal(then, cdf[:, both]))

    def _trees(self, belief: Belief, goal_cdf: np.ndarray, cdf: np.ndarray, m: int,
               seed: int) -> tuple[np.ndarray, np.ndarray]:
        """``m`` exact draws of ``(g, theta)`` of the route prior's posterior, ``g`` from
        ``goal_cdf`` (:func:`~.guided.tree_pool`; the draws whose walks passed their budget
        by :meth:`_observed_first`)."""
        budget = WALK_STEPS_PER_POLYTOPE * len(self.nbr) + WALK_STEPS_MIN
        goals, slots, over = tree_pool(self.nbr, cdf, goal_cdf, self.goal_poly, self.component,
                                       m, (int(seed) + 1) % (2**32), budget)
        if over.any():
            slots[over] = self._observed_first(belief, goals[over], cdf, seed, budget)
        return goals, slots

    def _observed_first(self, belief, goals: np.ndarray, cdf: np.ndarray, seed: int,
                        budget: int) -> np.ndarray:
        """Trees for ``goals`` drawn observed exits first (:func:`~.guided.observed_first_trees`),
        for the draws whose walks passed their budget in :func:`~.guided.tree_pool`."""
        chains = {int(g): belief.observed_chain(int(g)) for g in np.unique(goals)}
        G = len(self.goal_cells)
        kmax = max(1, max(len(c.states) for c in chains.values()))
        K = self.nbr.shape[1]
        states = np.zeros((G, kmax), np.int64)
        n_states = np.zeros(G, np.int64)
        slot_w = np.zeros((G, kmax, K))
        heads = np.zeros((G, kmax, K, kmax + 1))
        n_slots = np.zeros((G, kmax), np.int64)
        for g, c in chains.items():
            k = len(c.states)
            n_states[g] = k
            states[g, :k] = c.states
            slot_w[g, :k, : c.slot_w.shape[1]] = c.slot_w
            heads[g, :k, : c.heads.shape[1], : k + 1] = c.heads
            n_slots[g, :k] = c.n_slots
        slots, ok = observed_first_trees(self.nbr, cdf, goals, self.goal_poly, self.component,
                                         states, n_states, slot_w, heads, n_slots,
                                         (int(seed) + 2) % (2**32), budget, WALK_TRIES)
        for j in np.flatnonzero(~ok):
            slots[j] = complete_tree(self.nbr, slots[j], int(self.goal_poly[goals[j]]))
        self.completed_trees += int((~ok).sum())
        return slots

    def _known(self, belief: Belief) -> np.ndarray:
        """``(P,)`` True for the polytopes with at least one observation in ``belief``."""
        known = np.zeros(len(self.nbr), dtype=bool)
        known[belief.observed_polytopes()] = True
        return known

    def _history(self, history) -> tuple[np.ndarray, np.ndarray]:
        """``(hist_v, hist_k)``: each transition ``v -> w`` as ``v`` and the slot of ``w`` in
        ``N(v)``."""
        h = np.array(history, dtype=np.int64).reshape(-1, 2)
        hit = self.nbr[h[:, 0]] == h[:, 1, None]
        if not hit.any(axis=1).all():
            raise IndexError("a transition of the history is not between neighbours")
        return h[:, 0].copy(), hit.argmax(axis=1)

    def _dummy_cdf(self) -> np.ndarray:
        return np.ones((len(self.goal_cells), *self._uniform_cdf.shape))
