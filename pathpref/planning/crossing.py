"""Look before crossing: an exact check of the robust search's move where it leaves a polytope
(:attr:`~.pomdp.Preset.check_crossings`, the ``robust-check`` preset).

The robust search (:mod:`.guided`) values waiting for a push only through the simulations
that happen to branch on it, so near a face whose preference it is unsure of, its root values
are close and noisy and the robot often gambles on one face. The crossing itself is a
one-shot decision whose value of information can be computed exactly from the belief, so it
is checked here, after the search, whenever the search's move ``a`` takes the robot at cell
``s`` from its polytope ``v`` into a neighbour ``u``:

* ``P = P(p_v = u | o)``, the probability that the crossing is the preferred one;
* ``E_k = sum over heading sequences h_1..h_k of max_e P(p_v = e, h_1..h_k | o)``, the
  expected probability of the best exit once ``k`` more pushes are felt at ``s``
  (:func:`best_exit_after_pushes`): exact under ``P(g, p_v | o)`` (the belief's
  :meth:`~pathpref.inference.belief.Belief.joint`) and the human model's heading likelihood
  ``P(h | s, g, p_v)`` normalised over the 8 headings, the headings of different pushes
  independent given ``(g, p_v)``; ``E_0 = max_e P(p_v = e | o) >= P``, and ``E_k`` is
  non-decreasing in ``k`` (a posterior's expected maximum never falls);
* ``w_k = next + (k - 1) every``, the steps until the ``k``-th push the policy expects
  (:meth:`~.policies.PlannerPolicy.expected_pushes`: the last interval between two pushes; the
  check runs only once two were felt, since before that the interval is a guess, and a guess
  of one step makes a robot pushed every 5 wait 5 steps for nothing);
* ``F(w)``, the share of the search's root particles ``(g_j, theta_j)`` whose preferred route
  from ``s`` (:func:`route_steps`: the rollouts' walk toward ``g_j`` through ``theta_j``'s
  exits) still reaches ``g_j`` in the ``depth - w`` steps left after waiting ``w``.

A success reached after a crossing that was not preferred is worth ``rho`` of one that was
(:attr:`~.pomdp.Rewards.goal_after_violation`; with an arrival share ``a > 0``,
:attr:`~.pomdp.Rewards.arrival`, ``rho`` here is :func:`effective_rho`, ``a + (1 - a) rho``),
so crossing now is worth, up to a factor both options share, ``F(0) (rho + (1 - rho) P)``, and
waiting for ``k`` pushes, then crossing by the best exit, ``F(w_k) gamma^w_k (rho + (1 - rho)
E_k)``. The robot waits when the best ``k`` in ``1..`` :data:`LOOKAHEAD_PUSHES` beats crossing
now; it then takes the root move of highest mean return among those the search tried that stay
in ``v`` (its stay move under :attr:`~.pomdp.Preset.wait_for_pushes`), or stands still
(:data:`~pathpref.geometry.grid.STAY`) if it tried none. The approximations are stated: the
route times follow the rollout policy, feasibility and the crossing's correctness are treated
as independent, and the pushes are taken at ``s`` (the robot waits within ``v``).

Bounds: ``8^k`` heading sequences for ``k <= LOOKAHEAD_PUSHES`` (4096 rows of ``G deg(v)``);
a route walk takes at most ``depth + 1`` steps per particle.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from ..geometry.grid import STAY
from .guided import FIRST_FROM

#: the most pushes the check looks ahead (``8^k`` heading sequences)
LOOKAHEAD_PUSHES = 4


def best_exit_after_pushes(joint: np.ndarray, likelihood: np.ndarray, k_max: int) -> np.ndarray:
    """``(k_max + 1,)`` ``E_0..E_k_max``: the expected probability of the most probable exit
    after ``k`` pushes (module docstring). ``joint``: ``(G, K)`` ``P(g, p_v = e | o)``;
    ``likelihood``: ``(8, G, K)`` ``P(h | s, g, p_v = e)`` (each ``(g, e)`` column is
    normalised over the headings here; an all-zero column stays zero)."""
    joint = np.asarray(joint, dtype=np.float64)
    lik = np.asarray(likelihood, dtype=np.float64)
    lik = lik / np.maximum(lik.sum(axis=0, keepdims=True), 1e-300)
    out = np.empty(k_max + 1)
    m = joint[None]  # (sequences, G, K): P(g, e, h_1..h_k | o)
    out[0] = float(m.sum(axis=1).max(axis=1).sum())
    for k in range(1, k_max + 1):
        m, best = _one_more_push(m, lik)
        out[k] = float(best.sum())
    return out


@nb.njit(cache=True)
def _one_more_push(m, lik):
    """``(m', best)``: each sequence ``m[i]`` (``(G, K)``, ``P(g, e, h_1..h_k | o)``)
    followed by each heading ``h``, ``m[i] * lik[h]``, in the order ``(i, h)``, without the
    sequences of probability zero (they add nothing), and each kept sequence's ``max_e sum_g
    m'[j, g, e]`` (the most probable exit's share; its sum over the sequences is ``E_k``,
    :func:`best_exit_after_pushes`). The sum over ``g`` is NumPy's ``m'.sum(axis=1)`` term
    for term: in order for ``K > 1``, pairwise (:func:`_pairwise`) for ``K = 1``, where
    NumPy sums the contiguous goal axis so. At most ``8 n`` rows."""
    n, G, K = m.shape
    out = np.empty((8 * n, G, K))
    best = np.empty(8 * n)
    j = 0
    for i in range(n):
        for h in range(8):
            nonzero = False
            for g in range(G):
                for e in range(K):
                    x = m[i, g, e] * lik[h, g, e]
                    out[j, g, e] = x
                    nonzero = nonzero or x != 0.0
            if not nonzero:
                continue
            top = 0.0
            for e in range(K):
                if K == 1:
                    col = _pairwise(out[j, :, 0], 0, G)
                else:
                    col = out[j, 0, e]
                    for g in range(1, G):
                        col += out[j, g, e]
                if e == 0 or col > top or col != col:
                    top = col
            best[j] = top
            j += 1
    return out[:j], best[:j]


@nb.njit(cache=True)
def _pairwise(a, lo, n):
    """``sum(a[lo:lo + n])`` added as NumPy's pairwise summation adds a contiguous run: runs
    of up to 128 terms by :func:`_pairwise_run`, longer ones as the sum of their two halves
    (the first a multiple of 8 terms), halved again as needed (an explicit stack of at most
    64 halves: numba's cache does not keep recursive functions)."""
    seg_lo = np.empty(64, np.int64)
    seg_n = np.empty(64, np.int64)
    stage = np.zeros(64, np.int64)  # 0: split, 1: left half summed, 2: right half summed
    left = np.empty(64)
    seg_lo[0], seg_n[0] = lo, n
    sp = 1
    ret = 0.0
    while sp > 0:
        t = sp - 1
        if seg_n[t] <= 128:
            ret = _pairwise_run(a, seg_lo[t], seg_n[t])
            sp -= 1
            continue
        n2 = seg_n[t] // 2
        n2 -= n2 % 8
        if stage[t] == 0:
            stage[t] = 1
            seg_lo[sp], seg_n[sp], stage[sp] = seg_lo[t], n2, 0
            sp += 1
        elif stage[t] == 1:
            left[t] = ret
            stage[t] = 2
            seg_lo[sp], seg_n[sp], stage[sp] = seg_lo[t] + n2, seg_n[t] - n2, 0
            sp += 1
        else:
            ret = left[t] + ret
            sp -= 1
    return ret


@nb.njit(cache=True)
def _pairwise_run(a, lo, n):
    """NumPy's sum of a run of at most 128 terms: in order below 8, else eight interleaved
    partial sums added as ``((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))`` and the
    terms past the last multiple of 8 after them."""
    if n < 8:
        res = 0.0
        for i in range(lo, lo + n):
            res += a[i]
        return res
    r = np.empty(8)
    for t in range(8):
        r[t] = a[lo + t]
    i = 8
    while i < n - n % 8:
        for t in range(8):
            r[t] += a[lo + i + t]
        i += 8
    res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


class ExitMemo:
    """:func:`best_exit_after_pushes` that keeps its last answer with its inputs: asked again
    for an equal ``joint`` (compared exactly), the same likelihood table and cell and at most
    as many pushes, it returns the kept ``E_0..E_k_max`` (``E_j`` does not depend on
    ``k_max``: the same operations compute it), so the crossing check and the wait budget of
    one decision, and the decisions of a robot waiting at one cell between two pushes, compute
    it once."""

    def __init__(self) -> None:
        self._last: tuple | None = None

    def __call__(self, joint: np.ndarray, likelihood, cell: int, k_max: int) -> np.ndarray:
        """``E_0..E_k_max`` of ``joint`` and the likelihood ``likelihood[cell]``."""
        last = self._last
        if last is not None and last[0] is likelihood and last[1] == cell \
                and len(last[3]) > k_max and np.array_equal(last[2], joint):
            return last[3][: k_max + 1].copy()
        out = best_exit_after_pushes(joint, likelihood[cell], k_max)
        self._last = (likelihood, int(cell), np.array(joint, dtype=np.float64), out.copy())
        return out


@nb.njit(cache=True)
def route_walks(cell, depth, pool_g, pool_theta, goal_cells, cell_poly, next_cell, moves,
                weight):
    """The preferred route of each root particle ``j`` from ``cell`` to its goal
    ``goal_cells[pool_g[j]]``, walking the rollout moves (:func:`.guided.rollout_moves`, the
    first of tied moves) through its exits ``pool_theta[j]``. Returns ``(steps, crossings,
    first)``, each ``(m,)``: the steps the walk takes (``depth + 1`` where it does not arrive
    within ``depth`` steps, or is stuck), the sum of ``weight[v]`` over the polytopes ``v``
    the walk leaves (with ``weight`` all 1: its polytope changes), and its first move (-1 at
    the goal). At most ``depth + 1`` steps
    per particle."""
    m = pool_g.shape[0]
    out = np.empty(m, np.int64)
    crossings = np.zeros(m)
    first = -np.ones(m, np.int64)
    for j in range(m):
        g = pool_g[j]
        s = cell
        steps = 0
        while s != goal_cells[g] and steps <= depth:
            kv = pool_theta[j, cell_poly[s]]
            a = FIRST_FROM[moves[s, kv + 1, g], 0]
            s2 = next_cell[s, a]
            if s2 == s:
                steps = depth + 1
                break
            if steps == 0:
                first[j] = a
            if cell_poly[s2] != cell_poly[s]:
                crossings[j] += weight[cell_poly[s]]
            s = s2
            steps += 1
        out[j] = steps if s == goal_cells[g] else depth + 1
    return out, crossings, first


def route_steps(cell, depth, pool_g, pool_theta, goal_cells, cell_poly, next_cell, moves):
    """``(m,)`` the steps of each particle's preferred route from ``cell``
    (:func:`route_walks`' first output)."""
    weight = np.ones(len(pool_theta[0]) if len(pool_theta) else 1)
    return route_walks(cell, depth, pool_g, pool_theta, goal_cells, cell_poly, next_cell,
                       moves, weight)[0]


def effective_rho(rewards) -> float:
    """What a success after one wrong crossing is worth against a strict one:
    ``a + (1 - a) rho`` (:attr:`~.pomdp.Rewards.arrival` ``a``, ``rho``:
    :attr:`~.pomdp.Rewards.goal_after_violation`); ``rho`` itself when ``a = 0``."""
    a = float(rewards.arrival)
    return float(rewards.goal_after_violation) if a == 0.0 else \
        a + (1.0 - a) * float(rewards.goal_after_violation)


def wait_value(p_cross: float, best_exit: np.ndarray, feasible: np.ndarray,
               waits: np.ndarray, rho: float, discount: float) -> tuple[float, int]:
    """``(gain, k)``: the best ``F(w_k) gamma^w_k (rho + (1 - rho) E_k)`` over ``k >= 1``
    divided by crossing now's ``F(0) (rho + (1 - rho) P)`` (module docstring), and its ``k``.
    ``best_exit``: ``E_0..E_K``; ``feasible``: ``F(0), F(w_1)..F(w_K)``; ``waits``:
    ``0, w_1..w_K``. A ratio above 1 says wait; 0 when crossing now is worth nothing."""
    now = feasible[0] * (rho + (1.0 - rho) * p_cross)
    if now <= 0.0:
        return 0.0, 0
    later = feasible[1:] * discount ** waits[1:] * (rho + (1.0 - rho) * best_exit[1:])
    k = int(np.argmax(later))
    return float(later[k] / now), k + 1


def check_crossing(planner, belief, likelihood, result, cell: int, depth: int,
                   pushes: tuple[int, int], exits: ExitMemo | None = None) -> int:
    """The move to make instead of ``result.action`` if waiting for pushes is worth more than
    crossing now (module docstring); ``result.action`` itself otherwise, and whenever the move
    stays in its polytope or the search had no root particles (the independent prior).
    ``planner``: the robust :class:`~.pomcp.POMCP` that produced ``result`` from ``cell``
    with ``depth`` steps left; ``likelihood``: the human model's
    :attr:`~pathpref.inference.human.ObservationModel.cell_likelihood`; ``pushes``:
    ``(next, every)`` as the search was given them; ``exits``: an :class:`ExitMemo` shared
    with the wait budget (None: computed here)."""
    a = int(result.action)
    if a == STAY:
        return a
    v = int(planner.cell_poly[cell])
    u = int(planner.cell_poly[planner.next_cell[cell, a]])
    slots = [int(x) for x in planner.nbr[v] if x >= 0]
    particles = planner.root_particles()
    if u == v or u not in slots or particles is None:
        return a
    joint = belief.joint(v)
    p_cross = float(joint[:, slots.index(u)].sum())
    best_exit = (exits or ExitMemo())(joint, likelihood, cell, LOOKAHEAD_PUSHES)
    if best_exit[-1] <= p_cross:  # nothing a push could say would change the exit
        return a
    nxt, every = max(int(pushes[0]), 1), max(int(pushes[1]), 1)
    waits = np.array([0] + [nxt + (k - 1) * every for k in range(1, LOOKAHEAD_PUSHES + 1)])
    times = route_steps(int(cell), int(depth), *particles, planner.goal_cells,
                        planner.cell_poly, planner.next_cell, planner.moves)
    feasible = np.array([(times + w <= depth).mean() for w in waits])
    r = planner.rewards
    gain, _ = wait_value(p_cross, best_exit, feasible, waits, effective_rho(r), r.discount)
    if gain <= 1.0:
        return a
    best, best_q = STAY, -np.inf
    for b in range(8):
        if result.visits[b] > 0 and planner.cell_poly[planner.next_cell[cell, b]] == v \
                and result.values[b] > best_q:
            best, best_q = b, float(result.values[b])
    return best
