"""Result figures: success rate vs Delta_T (Table I) and belief curves (Fig. 4). Matplotlib, Agg."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

COLORS = {"compliant": "tab:orange", "goal_only": "tab:green", "path_preference": "tab:blue",
          "blended": "tab:purple"}


def success_figure(records: list[dict[str, Any]], out: str | Path) -> None:
    """Success rate with 95% CI against Delta_T, one line per method, a panel per map/sim."""
    groups = sorted({(r["map"], r["sim"], r["variant"]) for r in records})
    fig, axes = plt.subplots(1, len(groups), figsize=(5 * len(groups), 3.8), squeeze=False)
    for ax, g in zip(axes[0], groups, strict=True):
        recs = [r for r in records if (r["map"], r["sim"], r["variant"]) == g]
        for m in sorted({r["method"] for r in recs}):
            rs = sorted((r for r in recs if r["method"] == m), key=lambda r: r["delta_t"])
            x = [r["delta_t"] for r in rs]
            y = [r["success_rate"] for r in rs]
            # an interval read back from a CSV may miss the rate by an ulp: never negative
            err = [[max(0.0, r["success_rate"] - r["ci_low"]) for r in rs],
                   [max(0.0, r["ci_high"] - r["success_rate"]) for r in rs]]
            ax.errorbar(x, y, yerr=err, marker="o", capsize=3, label=m, color=COLORS.get(m))
        ax.set_xlabel("ΔT (steps between human inputs)")
        ax.set_ylabel("success rate")
        ax.set_ylim(0, 1)
        ax.set_title(f"{g[0]} ({g[1]})\n{g[2]}", fontsize=8)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=130)
    plt.close(fig)


def belief_curves_figure(curves: dict[str, dict[str, Any]], out: str | Path) -> None:
    """P(true goal) and goal entropy over time, mean +- 1 std (the paper's Fig. 4b-c)."""
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8))
    for m, c in curves.items():
        col = COLORS.get(m)
        for ax, key in ((axes[0], "p"), (axes[1], "h")):
            mu, sd = c[f"{key}_mean"], c[f"{key}_std"]
            ax.plot(c["t"], mu, color=col, label=f"{m} ({c['runs']} runs)")
            ax.fill_between(c["t"], mu - sd, mu + sd, color=col, alpha=0.2)
    finish_belief_axes(fig, axes, out)


def finish_belief_axes(fig, axes, out: str | Path, dpi: int = 130) -> None:
    """Label a (P(true goal), goal entropy) pair of axes over time and write the figure."""
    axes[0].set_ylabel("P(true goal)")
    axes[1].set_ylabel("goal entropy (nats)")
    for ax in axes:
        ax.set_xlabel("time step")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=dpi)
    plt.close(fig)
