"""Figures of grid-world episodes: trajectories over the map and belief traces."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ..geometry.grid import MOVES  # noqa: E402
from ..geometry.world import World  # noqa: E402
from .mapdraw import draw_map  # noqa: E402
from .plots import COLORS, finish_belief_axes  # noqa: E402


def trajectories_figure(world: World, results, out: str | Path) -> None:
    """One panel per episode: path, start, candidates, true goal, human pushes and the
    human's preference (red arrows), with a legend in every panel."""
    n = len(results)
    fig, axes = plt.subplots(1, n, figsize=(4.2 * n, 4.4), squeeze=False)
    for ax, r in zip(axes[0], results, strict=True):
        draw_map(world, ax=ax, show_ids=False, show_edges=False)
        xy = np.array([[s.x, s.y] for s in r.log], float) - 0.5
        col = COLORS.get(r.spec.method, "k")
        ax.plot(*xy.T, "-o", color=col, ms=3, lw=2, zorder=6, label=f"path of {r.spec.method}")
        goals = np.array(r.instance_cells["goals"], float) - 0.5
        ax.scatter(*goals.T, marker="s", s=60, facecolor="lightskyblue", edgecolor="k", zorder=5,
                   label="goal candidates")
        ax.scatter(*goals[r.instance.true_goal], marker="o", s=160, facecolor="hotpink",
                   edgecolor="k", zorder=7, label="true goal")
        ax.scatter(*xy[0], marker="^", s=120, color="k", zorder=7, label="start")
        ax.plot([], [], color="k", marker=r"$\rightarrow$", ls="", ms=12,
                label="human push (direction)")
        ax.plot([], [], color="crimson", marker=r"$\rightarrow$", ls="", ms=12,
                label="human's preferred route")
        for s, nxt in zip(r.log[:-1], r.log[1:], strict=True):
            if nxt.heading >= 0:
                d = MOVES[nxt.heading] * 0.6
                ax.annotate("", xy=(s.x - 0.5 + d[0], s.y - 0.5 + d[1]),
                            xytext=(s.x - 0.5, s.y - 0.5), zorder=8,
                            arrowprops=dict(arrowstyle="-|>", color="k", lw=1.2))
        verdict = "success" if r.success else ("goal, wrong path" if r.goal_reached else "failed")
        ax.set_title(f"{r.spec.method}: {verdict} ({r.steps} steps)", fontsize=9)
        ax.legend(loc="upper right", fontsize=6, framealpha=0.85)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def belief_figure(results, out: str | Path) -> None:
    """P(true goal) and goal entropy over each episode's steps."""
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    for r in results:
        t = [s.t for s in r.log]
        col = COLORS.get(r.spec.method)
        axes[0].plot(t, [s.p_true_goal for s in r.log], color=col, label=r.spec.method)
        axes[1].plot(t, [s.goal_entropy for s in r.log], color=col, label=r.spec.method)
    finish_belief_axes(fig, axes, out, dpi=120)
