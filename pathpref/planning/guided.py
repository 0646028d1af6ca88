"""The `robust` search: PO-UCT for the probability of success, guided by the human model's cost
tables (compiled with numba).

Same tree, root sampling (``g ~ P(g | o)``, each ``p_v ~ P(p_v | g, o)`` drawn lazily) and
observation model as the paper's search (:mod:`.pomcp`); what it optimises and how it searches
differ.

1. **Success reward.** A simulation earns ``R_g gamma^(L-1)`` when it reaches the sampled goal
   at its ``L``-th step, and ``rho`` times that if some transition, in the simulation or earlier
   in the episode (the search is given the episode's transitions), left a *known* polytope ``v``
   by a face other than the sampled ``p_v`` (``rho``:
   :attr:`~.pomdp.Rewards.goal_after_violation`). No other reward. A polytope is known once the
   belief holds an observation made in it; the preferences of the others are not sampled and
   their transitions count as allowed, because the robot will be told about them (pushed) when
   it gets there. With ``rho = 0``, ``gamma = 1`` and every polytope known, the expected reward
   is the probability of the paper's success (goal reached, every transition preferred); under
   the independent uniform prior, a random preference vector almost never leads to the goal, so
   valuing unknown polytopes by their prior would make every route look hopeless and the robot
   would take the shortest one. ``rho > 0`` keeps the goal worth reaching when no preferred
   route seems possible. Nothing can be farmed: the reward is paid once, at the goal (the paper's
   ``R_p`` is paid at every preferred crossing, so under an independent prior crossing a
   confidently preferred face back and forth beats reaching the goal), and no number of uncertain
   crossings ahead outweighs the goal (the paper's ``R_n`` summed over a large map's crossings
   does, and the robot stays put). Crossing straight back through the face just crossed is a
   violation in every sample in which the first crossing was not one (``p_v = w`` and then
   ``w -> v``: the success rule would need ``v -> w`` again, a cycle).
2. **Guided rollouts.** Past the tree, with probability ``1 - eps`` the move minimising
   ``c(s, a) + h(s')`` with ``h = D_{v, p_v}(., g)``, the constrained cost-to-go of the human
   model in the current known polytope ``v`` (:mod:`pathpref.inference.costs`), ``h = d(., g)``
   across ``p_v``'s face, in unknown polytopes and once the simulation has made ``v``'s
   preferred crossing (mutual preferences cannot trap a rollout); otherwise a random move that
   stays in ``v``. The goal-only planner rolls out along ``d(., g)``. The tables are those of the
   belief, so guidance costs a look-up per move.
3. **Only moves.** Blocked moves (the robot stays) are not in the tree: waiting never earns
   anything here.
4. **Exploration scaled to the returns.** UCB1 with ``c R sqrt(log N / n)``, ``R`` the spread
   (max - min) of the returns seen so far in this search: ``c`` is unitless.
5. **Anytime.** With ``budget_s > 0`` the search stops after that much wall time (checked every
   32 queries) or at ``queries``, whichever comes first.
"""

from __future__ import annotations

import time

import numba as nb
import numpy as np

from .tree import best_root_action, new_tree, sample_index, sample_slot

EPS_RANDOM = 0.1


@nb.njit(cache=True)
def _clock():
    with nb.objmode(t="f8"):
        t = time.perf_counter()
    return t


@nb.njit(cache=True, inline="always")
def _theta(v, gi, q, nbr, pref_cdf, theta, stamp):
    """Slot ``k`` of the preferred neighbour of ``v`` in simulation ``q``, drawn lazily from
    ``P(p_v | g)`` (cumulative ``pref_cdf[gi, v]``)."""
    if stamp[v] != q:
        stamp[v] = q
        theta[v] = sample_slot(v, gi, nbr, pref_cdf)
    return theta[v]


@nb.njit(cache=True, inline="always")
def _step(s, a, gi, q, next_cell, cross_slot, cell_poly, nbr, goal_cells, pref_cdf, theta,
          stamp, made_q, known, use_pref, viol):
    """Generative step: (next cell, violated so far, done). Records preferred crossings made in
    simulation ``q`` in ``made_q``."""
    s2 = next_cell[s, a]
    k = cross_slot[s, a]
    v = cell_poly[s]
    if use_pref and k >= 0 and known[v]:
        if _theta(v, gi, q, nbr, pref_cdf, theta, stamp) == k:
            made_q[v] = q
        else:
            viol = True
    return s2, viol, s2 == goal_cells[gi]


@nb.njit(cache=True, inline="always")
def _guided_action(s, gi, q, next_cell, cost, blocked, cross_slot, cell_poly, nbr, pref_cdf,
                   theta, stamp, made_q, known, ctg, dist, use_pref):
    """The rollout move (module docstring, 2)."""
    v = cell_poly[s]
    if np.random.random() < EPS_RANDOM:  # a random move that stays in v, if there is one
        off = np.random.randint(8)
        for j in range(8):
            a = (off + j) % 8
            if not blocked[s, a] and cross_slot[s, a] < 0:
                return a
    kv = -1
    if use_pref and known[v] and nbr[v, 0] >= 0 and made_q[v] != q:
        kv = _theta(v, gi, q, nbr, pref_cdf, theta, stamp)
    best = 1e300
    off = np.random.randint(8)
    best_a = off
    for j in range(8):
        a = (off + j) % 8
        if blocked[s, a]:
            continue
        s2 = next_cell[s, a]
        if kv < 0 or cross_slot[s, a] == kv:
            h = dist[gi, s2]
        elif cross_slot[s, a] < 0:
            h = ctg[s2, kv, gi]
        else:
            h = dist[gi, s2] + 1e6
        val = cost[s, a] + h
        if val < best:
            best = val
            best_a = a
    return best_a


@nb.njit(cache=True)
def search_robust(next_cell, cost, blocked, cross_slot, cell_poly, nbr, goal_cells, goal_cdf,
                  pref_cdf, known, ctg, dist, hist_v, hist_k, s0, depth, queries, c, discount,
                  Rg, rho, use_pref, seed, budget_s):
    """PO-UCT of the module docstring; returns
    ``(best action, root visits, root values, nodes, queries run)``."""
    np.random.seed(seed)
    t0 = _clock()
    n_node, n_sa, q_sa, child = new_tree(queries)
    n_nodes = 1
    P = nbr.shape[0]
    theta = -np.ones(P, np.int64)
    stamp = -np.ones(P, np.int64)
    made_q = -np.ones(P, np.int64)
    path_node = np.zeros(depth + 1, np.int64)
    path_a = np.zeros(depth + 1, np.int64)
    ret_lo, ret_hi = 1e300, -1e300
    done_q = 0
    for q in range(queries):
        if budget_s > 0 and q % 32 == 0 and q > 0 and _clock() - t0 > budget_s:
            break
        done_q += 1
        gi = sample_index(goal_cdf)
        s = s0
        node = 0
        L = 0
        viol = False
        if use_pref:  # the episode's own transitions count too (module docstring, 1)
            for i in range(hist_v.shape[0]):
                v = hist_v[i]
                if not known[v]:
                    continue
                if _theta(v, gi, q, nbr, pref_cdf, theta, stamp) == hist_k[i]:
                    made_q[v] = q
                else:
                    viol = True
        ret = 0.0
        scale = ret_hi - ret_lo if ret_hi > ret_lo else 1.0
        in_tree = True
        n_tree = 0
        while L < depth:
            if in_tree:
                a = -1
                off = np.random.randint(8)
                for j in range(8):
                    b = (off + j) % 8
                    if n_sa[node, b] == 0 and not blocked[s, b]:
                        a = b
                        break
                if a < 0:
                    best = -1e300
                    logn = np.log(n_node[node])
                    for b in range(8):
                        if blocked[s, b]:
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
                    n_nodes += 1
                    in_tree = False
                else:
                    node = ch
            else:
                a = _guided_action(s, gi, q, next_cell, cost, blocked, cross_slot, cell_poly,
                                   nbr, pref_cdf, theta, stamp, made_q, known, ctg, dist,
                                   use_pref)
            s, viol, done = _step(s, a, gi, q, next_cell, cross_slot, cell_poly, nbr,
                                  goal_cells, pref_cdf, theta, stamp, made_q, known, use_pref,
                                  viol)
            L += 1
            if done:
                # the goal pays at step L - 1 (counted from 0 at the root)
                ret = Rg * discount ** (L - 1) * (rho if viol else 1.0)
                break
        ret_lo = min(ret_lo, ret)
        ret_hi = max(ret_hi, ret)
        back = ret  # the return seen from tree depth i is ret / gamma^i
        for i in range(n_tree):
            nd = path_node[i]
            b = path_a[i]
            n_node[nd] += 1
            n_sa[nd, b] += 1
            q_sa[nd, b] += (back - q_sa[nd, b]) / n_sa[nd, b]
            back /= discount
    return best_root_action(n_sa, q_sa), n_sa[0].copy(), q_sa[0].copy(), n_nodes, done_q
