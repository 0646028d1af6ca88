"""Belief curves (the paper's Fig. 4): P(true goal) and goal entropy over time.

Runs ``runs`` episodes per method on one pinned instance (default: ``simple``, start (1,1),
candidates (1..10, 8), true goal (1, 8), human input every step, no preference in the goal's
polytope as in the authors' setup) and returns, per method, the mean and standard deviation
over runs of each quantity at every step ``t = 0..T_max``. An episode that ends early (goal
reached) keeps its last value for the remaining steps.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .store import ResultStore


def curves_from_store(db: str, keys_by_method: dict[str, list[str]], t_max: int
                      ) -> dict[str, dict[str, Any]]:
    """Mean and std of P(true goal) and goal entropy per method, steps 0..t_max."""
    out: dict[str, dict[str, Any]] = {}
    with ResultStore(db, create=False) as store:
        for method, keys in keys_by_method.items():
            p = np.zeros((len(keys), t_max + 1))
            h = np.zeros((len(keys), t_max + 1))
            for i, k in enumerate(keys):
                steps = store.steps(k)
                pv = np.array([s["p_true_goal"] for s in steps])
                hv = np.array([s["goal_entropy"] for s in steps])
                p[i, : len(pv)], p[i, len(pv):] = pv, pv[-1]
                h[i, : len(hv)], h[i, len(hv):] = hv, hv[-1]
            out[method] = {"t": np.arange(t_max + 1), "p_mean": p.mean(0), "p_std": p.std(0),
                           "h_mean": h.mean(0), "h_std": h.std(0), "runs": len(keys)}
    return out
