"""The `robust` search: PO-UCT for the probability of success, guided by the human model's cost
tables (compiled with numba).

Same tree and observation model as the paper's search (:mod:`.pomcp`); what it optimises, where
its root states come from and how it searches differ.

0. **Root states.** Under the route prior (:mod:`pathpref.inference.routes`, the ``robust``
   preset's) each simulation starts from one of ``m`` particles ``(g, theta)`` drawn exactly
   from the posterior before the search (:func:`tree_pool`: Wilson's algorithm, compiled); a
   full tree per particle judges every crossing of a simulation by one preference that leads
   to ``g`` (1). (Drawing a fresh tree in every simulation is exact too, but a random walk to
   the goal's polytope costs ~400 steps on ``classroom``: 4x the search.) The rule
   (:meth:`~.pomcp.POMCP._pool`): ``m = min(TREE_POOL, ceil(queries / SIMS_PER_TREE))``
   (at least ``SIMS_PER_TREE`` simulations per particle on average), and the pool is drawn
   only when the belief has changed since the last one (goal marginal or walk rows not
   equal): between pushes the decisions reuse it.
   Under the independent prior, ``g ~ P(g | o)`` and each ``p_v ~ P(p_v | g, o)`` are drawn
   lazily per simulation, as in the paper's search.
1. **Success reward.** A simulation earns ``R_g gamma^(L-1) (a + (1 - a) rho^n)`` when it
   reaches the sampled goal at its ``L``-th step (``a``: :attr:`~.pomdp.Rewards.arrival`, the
   share of the goal's value that arriving earns whatever the route; 0 in the ``robust``,
   ``robust-wait`` and ``robust-check`` presets, whose reward is then ``R_g gamma^(L-1)
   rho^n``), ``n`` the number of transitions, in the simulation or earlier in
   the episode (the search is given the episode's transitions), that left a *known* polytope
   ``v`` by a face other than the sampled ``p_v`` (``rho``:
   :attr:`~.pomdp.Rewards.goal_after_violation`). No other reward. Each violation costs its own
   factor: with one factor for any number, a robot that has violated once (in every particle) is
   free to cross anything, and wanders back and forth between polytopes on its way. A polytope is
   known once the belief holds an observation made in it. Under the independent prior the
   transitions out of the others count as allowed, because the robot will be told about them
   (pushed) when it gets there. Under the route prior this is modelled: the search is told when
   the human is next expected to push and how often (``push_next``, ``push_every``, estimated by
   the policy from the inputs so far); a polytope in which a simulated push falls counts as told
   (its exits allowed), and leaving any other unknown polytope is judged by the particle's
   ``p_v``. So the robot crosses polytopes between two pushes only where the preferred route is
   likely, and may wait for a push where it is not; with a push every step, it is told
   everywhere. With ``rho = 0``, ``gamma = 1`` and every polytope known, the expected reward is
   the probability of the paper's success (goal reached, every transition preferred); under the
   independent uniform prior, a random preference vector almost never leads to the goal, so
   valuing unknown polytopes by their prior would make every route look hopeless and the robot
   would take the shortest one. ``rho > 0`` keeps the goal worth reaching when no preferred
   route seems possible. Nothing can be farmed: the reward is paid once, at the goal (the
   paper's ``R_p`` is paid at every preferred crossing, so under an independent prior crossing a
   confidently preferred face back and forth beats reaching the goal), and no number of
   uncertain crossings ahead outweighs the goal (the paper's ``R_n`` summed over a large map's
   crossings does, and the robot stays put). Crossing straight back through the face just
   crossed is a violation in every sample in which the first crossing was not one (``p_v = w``
   and then ``w -> v``: the success rule would need ``v -> w`` again, a cycle).
2. **Guided rollouts toward a target.** Past the tree the simulated robot heads for a
   *target*: among the goal candidates with ``P(c) > 0`` it has not yet passed in this
   simulation, the one with the largest ``P(c) gamma^d(s, c)`` (the next one once it passes a
   candidate that is not the simulation's goal; the simulation still ends only at its own
   goal). With probability ``1 - eps`` it takes the move minimising ``c(s, a) + h(s')``:
   ``h = D_{v, p_v}(., target)``, the human model's constrained cost-to-go through the
   particle's preferred face, in the polytope ``v`` it is in until that crossing is made (known
   ``v`` only under the independent prior; every ``v`` under the route prior, whose particle
   trees never lead back through a polytope by a face it does not prefer); ``h = d(., target)``
   otherwise; else a random move that stays in ``v``. The goal-only planner rolls out along
   ``d(., target)``. Heading for the simulation's own goal instead would value standing between
   the candidates, since from there every simulation "knows" where to go. Each move is a
   look-up in a table
   built once per planner (:func:`rollout_moves`), and a rollout stops as soon as the
   simulation's goal is out of reach (``L + d(s, g) > depth``: its return is 0 whatever
   follows).
3. **Only moves.** Blocked moves (the robot stays) are not in the tree: waiting in place never
   earns anything here (waiting for a push is done by moving within a polytope); with 7, one
   is, as the move that waits for a push.
4. **Exploration scaled to the returns.** UCB1 with ``c R sqrt(log N / n)``, ``R`` the spread
   (max - min) of the returns seen so far in this search: ``c`` is unitless.
5. **Anytime.** With ``budget_s > 0`` the search stops after that much wall time (checked every
   32 queries) or at ``queries``, whichever comes first.
6. **Root choice.** The root move with the best mean return ``q_a``, unless other moves are
   within ``z`` standard errors of it (``q_a >= q_best - z sqrt(se_a^2 + se_best^2)``, the
   errors from the root returns' second moments; ``z``: :data:`~.pomcp.TIE_Z`). Among those the
   move chosen minimises ``c(s, a) + h(s')`` toward the rollouts' first target (2), ``h``
   averaged over the root particles' preferred exits of the current polytope (``d(s', target)``
   without particles). One step saved is worth a fraction ``1 - gamma`` of a return (1/60 on
   ``classroom``), below the noise of 5000 simulations, so by the means alone the robot drifts
   inside a polytope on its way; the heuristic breaks only ties the search cannot resolve, and
   it commits to one candidate (an average over the candidates' distances has its minimum
   between them, where the robot would stay).
7. **Waiting for a push** (:attr:`~.pomdp.Preset.wait_for_pushes`, the ``robust-wait``
   preset; route prior only). The tree of 0-6 branches on moves only, so no plan in it can
   depend on what a push will say, and a robot unsure which face of its polytope the human
   prefers gambles on one. Here, at every step of a simulation's tree descent where a push is
   expected (``push_next``, ``push_every``), the simulated human's heading is drawn from the
   likelihood ``P(h | s, g, p_v)`` at the simulated cell for the particle's goal and
   preferred exit, and the descent moves to that heading's child node (one per heading), so
   the moves below it are chosen knowing it; and where a move is blocked (a wall), the first
   blocked move is in the tree as *stay*, so the robot may stand still for one step and be
   told (the root's tie rule, 6, weighs only the moves that go somewhere: a stay tied with
   one of them yields to it). A simulation then adds at most two nodes (a heading's, an
   action's). What it changes in episodes is measured in ``docs/robust.md`` ("Waiting for a
   push").
"""

from __future__ import annotations

import numba as nb
import numpy as np
from llvmlite import ir
from numba.core import cgutils
from numba.extending import intrinsic

from ..inference.chains import draw_observed_exits
from .tree import best_root_action, init_node, new_tree, sample_index, sample_slot

EPS_RANDOM = 0.1


def _first_from() -> np.ndarray:
    """``[m, off]``: the first move ``a = (off + j) % 8``, ``j = 0..7``, in the bit set ``m``
    (``off`` when ``m`` is empty): a rollout's pick among its tied moves as one look-up."""
    out = np.zeros((256, 8), np.int64)
    for m in range(256):
        for off in range(8):
            out[m, off] = next(((off + j) % 8 for j in range(8) if (m >> ((off + j) % 8)) & 1),
                               off)
    return out


FIRST_FROM = _first_from()
#: the stamp of a preference slot set before the simulation (:func:`_theta`)
FIXED = -2


#: ``CLOCK_MONOTONIC`` of Linux's ``<time.h>``: the clock of Python's ``time.perf_counter``
CLOCK_MONOTONIC = 1


@intrinsic
def _monotonic(typingctx):
    """Seconds of ``clock_gettime(CLOCK_MONOTONIC)`` (``tv_sec + 1e-9 tv_nsec``, what
    ``time.perf_counter`` reads), the ``timespec`` on the stack: the C library's function
    bound by name, so numba's cache keeps the callers (an object-mode ``perf_counter`` was
    compiled again in every process, 0.3-0.8 s CPU at its first decision)."""
    i32, i64 = ir.IntType(32), ir.IntType(64)

    def codegen(context, builder, sig, args):
        ts = cgutils.alloca_once(builder, ir.ArrayType(i64, 2))
        fn = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(i32, [i32, ts.type]), "clock_gettime")
        builder.call(fn, [ir.Constant(i32, CLOCK_MONOTONIC), ts])
        sec, nsec = (builder.sitofp(builder.load(builder.gep(ts, [ir.Constant(i32, 0),
                                                                  ir.Constant(i32, k)])),
                                    ir.DoubleType()) for k in (0, 1))
        return builder.fadd(sec, builder.fmul(nsec, ir.Constant(ir.DoubleType(), 1e-9)))

    return nb.types.float64(), codegen


@nb.njit(cache=True)
def _clock():
    """Seconds of a monotonic clock (``time.perf_counter``'s), for the search's budget."""
    return _monotonic()


@nb.njit(cache=True, inline="always")
def _theta(v, gi, q, nbr, pref_cdf, theta, stamp):
    """Slot ``k`` of the preferred neighbour of ``v`` in simulation ``q``, drawn lazily from
    ``P(p_v | g)`` (cumulative ``pref_cdf[gi, v]``) under the independent prior; under the route
    prior every slot was set at the start of the simulation (:func:`tree_pool`): ``theta`` is
    then the particle's row of the pool and ``stamp`` all :data:`FIXED` (nothing drawn or
    copied per simulation)."""
    if stamp[v] != q and stamp[v] != FIXED:
        stamp[v] = q
        theta[v] = sample_slot(v, gi, nbr, pref_cdf)
    return theta[v]


@nb.njit(cache=True, _nrt=False)
def _wilson(nbr, pref_cdf, gi, r, comp, fixed, row, in_tree, walk, budget):
    """One tree for goal ``gi`` (polytope ``r``) into ``row`` by Wilson's algorithm (see
    :func:`tree_pool`): the polytopes with ``fixed[v] >= 0`` move by that slot, the others by
    their rows of ``pref_cdf``. False when the walks took more than ``budget`` steps (``row``
    is then incomplete)."""
    P = nbr.shape[0]
    in_tree[:] = False
    in_tree[r] = True
    row[r] = -1
    steps = 0
    for v0 in range(P):
        if in_tree[v0]:
            continue
        if comp[v0] != comp[r] or nbr[v0, 0] < 0:
            row[v0] = sample_slot(v0, gi, nbr, pref_cdf)
            in_tree[v0] = True
            continue
        u = v0
        while not in_tree[u]:
            k = fixed[u] if fixed[u] >= 0 else sample_slot(u, gi, nbr, pref_cdf)
            walk[u] = k
            u = nbr[u, k]
            steps += 1
            if steps > budget:
                return False
        u = v0
        while not in_tree[u]:
            in_tree[u] = True
            row[u] = walk[u]
            u = nbr[u, walk[u]]
    return True


@nb.njit(cache=True)
def tree_pool(nbr, pref_cdf, goal_cdf, root, comp, m, seed, budget):
    """``m`` exact draws of ``(g, theta)`` from the route-prior posterior
    (:mod:`pathpref.inference.routes`): ``g`` from ``goal_cdf``, then ``theta`` by Wilson's
    algorithm, ``pref_cdf[g]`` holding the walk's rows: from each polytope not yet in the tree,
    a random walk until it meets the tree, loop-erased, joins it (the goal's polytope
    ``root[g]`` first, with no exit, slot -1). Polytopes outside the goal's component (and
    without neighbours) are drawn independently from their rows.

    **Bounded.** A walk's expected length is the trace of the walk's Green function, which
    evidence can make astronomical (two polytopes pointing at each other: ``~1/eps`` round
    trips). A tree whose walks pass ``budget`` steps is abandoned and flagged in ``over``,
    and so is every later tree of the same goal without a walk; the caller draws them by
    :func:`observed_first_trees`. This keeps every draw exact and the draws independent:
    the number of steps Wilson's algorithm takes is the total length of the cycles it pops
    plus one step per polytope, and the popped cycles are independent of the tree it returns
    (Propp and Wilson 1998, cycle popping), so a tree is independent of the event
    ``steps > budget``; and which sampler draws a tree depends only on earlier, independent
    draws. At most one budget per goal is spent in vain.

    Returns ``(goal index (m,), slot of p_v (m, P), over (m,))``."""
    np.random.seed(seed)
    P = nbr.shape[0]
    goals = np.zeros(m, np.int64)
    slots = np.zeros((m, P), np.int64)
    over = np.zeros(m, np.bool_)
    in_tree = np.zeros(P, np.bool_)
    walk = np.zeros(P, np.int64)
    free = -np.ones(P, np.int64)
    trapped = np.zeros(goal_cdf.shape[0], np.bool_)
    for j in range(m):
        gi = sample_index(goal_cdf)
        goals[j] = gi
        if trapped[gi]:  # a walk for this goal has already passed its budget
            over[j] = True
            continue
        over[j] = not _wilson(nbr, pref_cdf, gi, root[gi], comp, free, slots[j], in_tree, walk,
                              budget)
        trapped[gi] = over[j]
    return goals, slots, over


@nb.njit(cache=True)
def observed_first_trees(nbr, pref_cdf, goals, root, comp, states, n_states, slot_w, heads,
                         n_slots, seed, budget, tries):
    """One exact tree per entry of ``goals`` whatever the evidence: the observed polytopes'
    exits first, jointly, from their exact conditionals
    (:func:`pathpref.inference.chains.draw_observed_exits` on goal ``g``'s chain: ``states[g,
    :n_states[g]]``, ``slot_w[g]``, ``heads[g]``, ``n_slots[g]``), then Wilson's walk over the
    unobserved polytopes, whose rows are uniform, with the observed ones moving by their drawn
    exits. A walk stage that passes its budget is drawn again with twice the budget (exact
    given the observed exits, by the argument of :func:`tree_pool`: whether a stage is kept
    depends only on its number of steps, which is independent of the tree it returns), at
    most ``tries`` times: ``budget (2^tries - 1)`` steps per tree in all. Doubling matters
    when the drawn exits make the walk long: on ``examples/maps/hall.json`` (49 polytopes, 16
    observed) a tree needed more than 16 walks of 7,232 steps, and far fewer steps than
    10^5.

    Returns ``(slots (n, P), ok (n,))``."""
    np.random.seed(seed)
    P = nbr.shape[0]
    n = goals.shape[0]
    slots = np.zeros((n, P), np.int64)
    ok = np.zeros(n, np.bool_)
    in_tree = np.zeros(P, np.bool_)
    walk = np.zeros(P, np.int64)
    fixed = -np.ones(P, np.int64)
    for j in range(n):
        g = goals[j]
        k = n_states[g]
        fixed[:] = -1
        exits = draw_observed_exits(slot_w[g, :k], heads[g, :k, :, : k + 1], n_slots[g, :k])
        for i in range(k):
            fixed[states[g, i]] = exits[i]
        b = budget
        for _ in range(tries):
            if _wilson(nbr, pref_cdf, g, root[g], comp, fixed, slots[j], in_tree, walk, b):
                ok[j] = True
                break
            b *= 2
        if not ok[j]:  # the drawn observed exits, -2 elsewhere (:func:`complete_tree`)
            slots[j, :] = -2
            for i in range(k):
                slots[j, states[g, i]] = exits[i]
    return slots, ok


def complete_tree(nbr: np.ndarray, row: np.ndarray, root: int) -> np.ndarray:
    """A tree toward ``root`` that keeps the exits set in ``row`` (slots ``>= 0``; ``-2``:
    unset): breadth first from ``root``, a polytope joins when its set exit leads into the
    tree, an unset one by its first neighbour already in the tree (the fewest polytopes to
    the root). Not a draw: the completion of a tree whose walks passed every budget
    (:meth:`~.pomcp.POMCP._observed_first`). Polytopes it cannot join (another component)
    take slot 0 (-1 without neighbours). ``O(P K)``."""
    P = len(nbr)
    out = row.copy()
    joined = np.zeros(P, bool)
    joined[root] = True
    out[root] = -1
    queue = [int(root)]
    head = 0
    while head < len(queue):
        t = queue[head]
        head += 1
        for u in nbr[t]:
            if u < 0 or joined[u]:
                continue
            k = int(np.flatnonzero(nbr[u] == t)[0])
            if row[u] >= 0 and row[u] != k:
                continue  # u's exit is set elsewhere: it joins when that polytope does
            joined[u] = True
            out[u] = k
            queue.append(int(u))
    left = ~joined & (out < 0)
    out[left] = np.where(nbr[left, 0] >= 0, 0, -1)
    return out


@nb.njit(cache=True, inline="always")
def _step(s, a, gi, q, world, known, pref_cdf, theta, stamp, made_q, use_pref, viol, judged):
    """Generative step on the map's tables ``world`` (:class:`.search_inputs.RobustTables`):
    (next cell, violations so far, done). Records preferred crossings made in simulation
    ``q`` in ``made_q``."""
    s2 = world.next_cell[s, a]
    k = world.cross_slot[s, a]
    v = world.cell_poly[s]
    if use_pref and k >= 0 and (known[v] or judged):
        if _theta(v, gi, q, world.nbr, pref_cdf, theta, stamp) == k:
            made_q[v] = q
        else:
            viol += 1
    return s2, viol, s2 == world.goal_cells[gi]


@nb.njit(cache=True, inline="always")
def _heuristic(s2, k, kv, gi, ctg, dist):
    """``h(s')`` of the rollout move (module docstring, 2) for a move that crosses slot ``k``
    (-1: none) into ``s2``, ``kv`` the particle's preferred slot of the polytope left (-1: none
    or already made): ``d(s', g)`` across the preferred face or without a preference,
    ``D_{v, p_v}(s', g)`` inside ``v``, ``d(s', g) + 1e6`` across another face."""
    if kv < 0 or k == kv:
        return dist[gi, s2]
    if k < 0:
        return ctg[s2, kv, gi]
    return dist[gi, s2] + 1e6


@nb.njit(cache=True)
def reach_table(dist, discount):
    """``(G, n)`` ``gamma^d(s, c)`` of :func:`_pick_target`, computed once per planner (0 where
    ``c`` is out of reach); the same scalar ``pow`` as computing it in the search, so the
    search's choices are unchanged bit for bit."""
    out = np.zeros(dist.shape)
    for c in range(dist.shape[0]):
        for s in range(dist.shape[1]):
            if np.isfinite(dist[c, s]):
                out[c, s] = discount ** dist[c, s]
    return out


@nb.njit(cache=True, inline="always")
def _pick_target(s, q, visited_q, p_goal, dist, reach):
    """The candidate a rollout heads for (module docstring, 2): among those with ``P(c) > 0``
    not yet passed in simulation ``q``, the one with the largest ``P(c) gamma^d(s, c)``
    (``reach``: :func:`reach_table`; -1: none left)."""
    best = -1.0
    t = -1
    for c in range(p_goal.shape[0]):
        if visited_q[c] == q or p_goal[c] <= 0.0 or not np.isfinite(dist[c, s]):
            continue
        val = p_goal[c] * reach[c, s]
        if val > best:
            best = val
            t = c
    return t


@nb.njit(cache=True)
def rollout_moves(next_cell, cost, blocked, cross_slot, ctg, dist):
    """``(n, K + 1, G)`` the rollout moves (module docstring, 2) from each cell toward each
    candidate, ``[s, kv + 1, c]`` for the preferred slot ``kv`` of the cell's polytope (0: none
    known or already crossed): the set of moves ``a`` (bit ``a``) that minimise
    ``c(s, a) + h(s')``. Built once per planner, so a rollout step is a look-up and a random
    pick among the tied moves."""
    n = next_cell.shape[0]
    K = ctg.shape[1]
    G = dist.shape[0]
    out = np.zeros((n, K + 1, G), np.uint8)
    val = np.empty(8)
    for s in range(n):
        for kk in range(K + 1):
            for c in range(G):
                best = 1e300
                for a in range(8):
                    val[a] = 1e300
                    if not blocked[s, a]:
                        val[a] = cost[s, a] + _heuristic(next_cell[s, a], cross_slot[s, a],
                                                         kk - 1, c, ctg, dist)
                        best = min(best, val[a])
                m = 0
                for a in range(8):
                    if val[a] == best and best < 1e300:
                        m |= 1 << a
                out[s, kk, c] = m
    return out


@nb.njit(cache=True, inline="always")
def _rollout_action(s, tgt, gi, q, world, pref_cdf, theta, stamp, made_q, informed, use_pref):
    """The rollout move (module docstring, 2) toward candidate ``tgt``; ``informed``: the
    rollout follows the particle's ``p_v`` in the polytope it is in; the moves are
    ``world.moves`` (:func:`rollout_moves`)."""
    blocked, cross_slot, nbr = world.blocked, world.cross_slot, world.nbr
    v = world.cell_poly[s]
    if np.random.random() < EPS_RANDOM:  # a random move that stays in v, if there is one
        off = np.random.randint(8)
        for j in range(8):
            a = (off + j) % 8
            if not blocked[s, a] and cross_slot[s, a] < 0:
                return a
    kv = -1
    if use_pref and informed and nbr[v, 0] >= 0 and made_q[v] != q:
        kv = _theta(v, gi, q, nbr, pref_cdf, theta, stamp)
    # the first move of the set ``moves[s, kv + 1, tgt]`` from a random offset on (the offset
    # itself when the set is empty: no free move, the robot stays whatever it does)
    return FIRST_FROM[world.moves[s, kv + 1, tgt], np.random.randint(8)]


@nb.njit(cache=True, inline="always")
def _heading(s, gi, kv, G, lik_flat, lik_off, lik_slots):
    """A heading of the simulated human at cell ``s`` for goal ``gi`` and preferred slot
    ``kv`` of ``s``'s polytope, drawn from the likelihood ``P(h | s, g, p_v)`` (module
    docstring, 7; one uniform draw)."""
    ks = lik_slots[s]
    if kv < 0 or kv >= ks:
        kv = 0  # a polytope without neighbours: its one "no preference" slot
    base = lik_off[s] + gi * ks + kv
    step = G * ks
    tot = 0.0
    for h in range(8):
        tot += lik_flat[base + h * step]
    u = np.random.random() * tot
    h = 0
    acc = lik_flat[base]
    while h < 7 and u > acc:
        h += 1
        acc += lik_flat[base + h * step]
    return h


@nb.njit(cache=True, inline="always")
def _stay_move(s, blocked):
    """The move that stands still at ``s``: its first blocked move (-1: none)."""
    for b in range(8):
        if blocked[s, b]:
            return b
    return -1


@nb.njit(cache=True, inline="always")
def _hear(heard, i):
    """Node ``i`` has no heading child yet (its row of ``heard`` -1): set when the node is
    created, so the search allocates ``heard`` without filling it."""
    for h in range(8):
        heard[i, h] = -1


@nb.njit(cache=True)
def search_robust(world, belief, lik, settings, s0, seed):
    """PO-UCT of the module docstring from cell ``s0``; returns
    ``(best action, root visits, root values, nodes, queries run)``. The inputs are records
    (:mod:`.search_inputs`): ``world`` the map's tables (:class:`RobustTables`), ``belief``
    the belief's rows and root particles (:class:`BeliefRows`), ``lik`` the heading
    likelihood (:class:`HeadingTable`) and ``settings`` the search's numbers and switches
    (:class:`RobustSettings`: ``(goal, rho, arrival)`` the goal's value, the factor per
    violation and the share of the goal's value that arriving earns whatever the route,
    module docstring 1; ``wait``: branch on the expected pushes' headings and offer the stay
    move, module docstring 7)."""
    np.random.seed(seed)
    t0 = _clock()
    tree = belief.pool_g.shape[0] > 0
    wait = settings.wait and tree
    queries, depth = settings.queries, settings.depth
    nbr, goal_cells, goal_cdf = world.nbr, world.goal_cells, belief.goal_cdf
    # a simulation adds at most one action node, and with waiting one heading node before it
    n_node, n_sa, q_sa, child = new_tree(2 * queries if wait else queries)
    # node -> heading child (-1: none yet), a row set when its node is created (:func:`_hear`)
    heard = np.empty((n_node.shape[0] if wait else 1, 8), np.int64)
    _hear(heard, 0)
    P = nbr.shape[0]
    theta = -np.ones(P, np.int64)
    stamp = -np.ones(P, np.int64)
    fixed = np.full(P, FIXED, np.int64)
    made_q = -np.ones(P, np.int64)
    told_q = -np.ones(P, np.int64)
    G = goal_cells.shape[0]
    cand = -np.ones(world.next_cell.shape[0], np.int64)  # cell -> candidate index (-1: none)
    p_goal = np.zeros(G)
    visited_q = -np.ones(G, np.int64)
    prev = 0.0
    for k in range(G):  # (not ``c``: that is the exploration constant)
        cand[goal_cells[k]] = k
        p_goal[k] = goal_cdf[k] - prev
        prev = goal_cdf[k]
    path_node = np.zeros(depth + 1, np.int64)
    path_a = np.zeros(depth + 1, np.int64)
    root_sq = np.zeros(8)
    n_nodes, done_q = _simulate(
        world, belief, lik, (n_node, n_sa, q_sa, child, heard),
        (theta, stamp, fixed, made_q, told_q, cand, p_goal, visited_q, path_node, path_a,
         root_sq),
        settings, s0, t0)
    a = _root_choice(s0, n_sa[0], q_sa[0], root_sq, world, p_goal, belief.pool_theta,
                     settings.tie_z)
    return a, n_sa[0].copy(), q_sa[0].copy(), n_nodes, done_q


@nb.njit(cache=True, _nrt=False)
def _simulate(world, belief, lik, nodes, scratch, settings, s0, t0):
    """The simulations of :func:`search_robust`, on its records and its tree and scratch
    arrays (grouped in tuples); returns
    ``(nodes, queries run)``. Compiled without reference counting: it allocates nothing,
    and every array it touches is owned by the caller for the whole call, so the counts
    numba would otherwise update around each inlined helper's array arguments (about half
    the search's time, measured) are not needed."""
    blocked, cell_poly, nbr, goal_cells = world.blocked, world.cell_poly, world.nbr, \
        world.goal_cells
    dist, reach = world.dist, world.reach
    goal_cdf, pref_cdf, known = belief.goal_cdf, belief.pref_cdf, belief.known
    pool_g, pool_theta, hist_v, hist_k = belief.pool_g, belief.pool_theta, belief.hist_v, \
        belief.hist_k
    pool_late = belief.pool_late
    n_node, n_sa, q_sa, child, heard = nodes
    theta, stamp, fixed, made_q, told_q, cand, p_goal, visited_q, path_node, path_a, root_sq = \
        scratch
    depth, queries, c, discount = settings.depth, settings.queries, settings.c, \
        settings.discount
    Rg, rho, arrive = settings.goal, settings.rho, settings.arrival
    use_pref, budget_s = settings.use_pref, settings.budget_s
    push_next, push_every = settings.push_next, settings.push_every
    g_any = Rg * arrive  # what arriving earns whatever the route (0: the strict reward)
    g_rest = Rg * (1.0 - arrive)
    tree = pool_g.shape[0] > 0
    wait = settings.wait and tree
    G = goal_cells.shape[0]
    n_nodes = 1
    ret_lo, ret_hi = 1e300, -1e300
    done_q = 0
    for q in range(queries):
        if budget_s > 0 and q % 32 == 0 and q > 0 and _clock() - t0 > budget_s:
            break
        done_q += 1
        follows = tree  # rollouts through the particle's exits everywhere (else: known only)
        if tree:  # a particle of the route-prior posterior (tree_pool)
            j = np.random.randint(pool_g.shape[0])
            gi = pool_g[j]
            theta = pool_theta[j]  # read only: _theta draws nothing under a FIXED stamp
            stamp = fixed
            follows = not pool_late[j]
        else:
            gi = sample_index(goal_cdf)
        s = s0
        node = 0
        L = 0
        viol = 0
        if use_pref:  # the episode's own transitions count too (module docstring, 1)
            for i in range(hist_v.shape[0]):
                v = hist_v[i]
                if not known[v]:
                    continue
                k = _theta(v, gi, q, nbr, pref_cdf, theta, stamp)
                if k == hist_k[i]:
                    made_q[v] = q
                else:
                    viol += 1
        ret = 0.0
        scale = ret_hi - ret_lo if ret_hi > ret_lo else 1.0
        in_tree = True
        n_tree = 0
        tgt = -1
        while L < depth:
            # a push expected now tells the robot the preference of the polytope it is in
            push_now = tree and L >= push_next and (L - push_next) % push_every == 0
            if push_now:
                told_q[cell_poly[s]] = q
            if in_tree and push_now and wait:  # the push's heading: a node of its own (7)
                h = _heading(s, gi, theta[cell_poly[s]], G, lik.flat, lik.offsets, lik.slots)
                och = heard[node, h]
                if och < 0:
                    och = n_nodes
                    heard[node, h] = och
                    init_node(n_node, n_sa, q_sa, child, n_nodes)
                    _hear(heard, n_nodes)
                    n_nodes += 1
                node = och
            if in_tree:
                stay = _stay_move(s, blocked) if wait else -1
                a = -1
                off = np.random.randint(8)
                for j in range(8):
                    b = (off + j) % 8
                    if n_sa[node, b] == 0 and (not blocked[s, b] or b == stay):
                        a = b
                        break
                if a < 0:
                    best = -1e300
                    logn = np.log(n_node[node])
                    for b in range(8):
                        if blocked[s, b] and b != stay:
                            continue
                        val = q_sa[node, b] + c * scale * np.sqrt(logn / n_sa[node, b])
                        if val > best:
                            best = val
                            a = b
                    if a < 0:
                        a = 0  # a cell with no free neighbour: every move stays
                path_node[n_tree] = node
                path_a[n_tree] = a
                n_tree += 1
                ch = child[node, a]
                if ch < 0:  # expand one node per simulation, then roll out
                    child[node, a] = n_nodes
                    init_node(n_node, n_sa, q_sa, child, n_nodes)
                    if wait:
                        _hear(heard, n_nodes)
                    n_nodes += 1
                    in_tree = False
                else:
                    node = ch
            else:
                if tgt < 0 or s == goal_cells[tgt]:
                    tgt = _pick_target(s, q, visited_q, p_goal, dist, reach)
                    if tgt < 0:  # every candidate passed: cannot happen for a drawn goal
                        tgt = gi
                a = _rollout_action(s, tgt, gi, q, world, pref_cdf, theta, stamp, made_q,
                                    follows or known[cell_poly[s]], use_pref)
            s, viol, done = _step(s, a, gi, q, world, known, pref_cdf, theta, stamp, made_q,
                                  use_pref, viol, tree and told_q[cell_poly[s]] != q)
            L += 1
            if cand[s] >= 0:
                visited_q[cand[s]] = q
            if done:
                # the goal pays at step L - 1 (counted from 0 at the root)
                ret = g_rest * discount ** (L - 1) * rho ** viol + g_any * discount ** (L - 1)
                break
            if not in_tree and L + dist[gi, s] > depth:
                break  # the goal is out of reach: the return is 0 whatever the rollout does
        ret_lo = min(ret_lo, ret)
        ret_hi = max(ret_hi, ret)
        back = ret  # the return seen from tree depth i is ret / gamma^i
        if n_tree > 0:
            root_sq[path_a[0]] += ret * ret
        for i in range(n_tree):
            nd = path_node[i]
            b = path_a[i]
            n_node[nd] += 1
            n_sa[nd, b] += 1
            q_sa[nd, b] += (back - q_sa[nd, b]) / n_sa[nd, b]
            back /= discount
    return n_nodes, done_q


@nb.njit(cache=True)
def _root_choice(s, n, q, sq, world, p_goal, pool_theta, z):
    """The root move (module docstring, 6) from the root's visits ``n``, mean returns ``q`` and
    sums of squared returns ``sq``: the best mean, unless other moves are within ``z``
    standard errors of it; among those, the one with the least ``c(s, a) + h(s')`` toward the
    rollouts' first target (:func:`_pick_target` on the goal marginal ``p_goal``), ``h``
    averaged over the root particles' preferred exits ``pool_theta`` (``d(s', target)``
    without particles)."""
    next_cell, cost, blocked, cross_slot = world.next_cell, world.cost, world.blocked, \
        world.cross_slot
    ctg, dist, reach = world.ctg, world.dist, world.reach
    best = best_root_action(n.reshape(1, 8), q.reshape(1, 8))
    if z <= 0 or n[best] < 2:
        return best
    tgt = _pick_target(s, 0, -np.ones(p_goal.shape[0], np.int64), p_goal, dist, reach)
    if tgt < 0:
        return best
    se_b = np.sqrt(max(sq[best] / n[best] - q[best] ** 2, 0.0) / n[best])
    v = world.cell_poly[s]
    m = pool_theta.shape[0]
    pick = best
    h_pick = 1e300
    for a in range(8):
        if n[a] < 2 or blocked[s, a]:
            continue
        se_a = np.sqrt(max(sq[a] / n[a] - q[a] ** 2, 0.0) / n[a])
        if a != best and q[a] < q[best] - z * np.sqrt(se_a ** 2 + se_b ** 2):
            continue
        s2 = next_cell[s, a]
        k = cross_slot[s, a]
        if m > 0:
            h = 0.0
            for j in range(m):
                h += _heuristic(s2, k, pool_theta[j, v], tgt, ctg, dist)
            h /= m
        else:
            h = dist[tgt, s2]
        h += cost[s, a]
        if h < h_pick:
            h_pick = h
            pick = a
    return pick
