"""Draw docs/motion_rule.png: the motion rule on a map with one rotated obstacle.

Left: the paper's rule (a move that crosses two lines at once is blocked) makes a straight move
between two free cells impossible. Right: pathpref's rule: the straight move crosses both lines
at once and records a *move edge* between the polytope it left and the one it entered. Drawn
for a point robot (``POINT_ROBOT``: the corner rule alone); the default robot's footprint
removes this move, which passes within its reach of the table (docs/motion_rule.md, "The
robot's footprint"). Run: ``python scripts/motion_rule_figure.py docs/motion_rule.png``.
"""

from __future__ import annotations

import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Polygon  # noqa: E402

from pathpref.geometry.footprint import POINT_ROBOT  # noqa: E402
from pathpref.geometry.generate import rotated_rectangle  # noqa: E402
from pathpref.geometry.polygon import h_polygon  # noqa: E402
from pathpref.geometry.world import load_world  # noqa: E402
from pathpref.viz.mapdraw import draw_map  # noqa: E402


def main(out: str) -> None:
    box = rotated_rectangle(np.array([3.75, 2.08]), np.array([2.2, 1.0]), 1.107)
    world = load_world({"name": "one rotated table", "width": 7, "height": 6,
                        "obstacles": [{"vertices": box.tolist()}]}, footprint=POINT_ROBOT)
    arr, m = world.arrangement, world.motion
    e = int(np.flatnonzero(world.graph.edge_hyperplane < 0)[0])  # the one move edge
    i, a = (int(x[0]) for x in np.nonzero(m.crossed_edge == e))
    p0, p1 = world.cells[i] - 0.5, world.cells[m.next_cell[i, a]] - 0.5
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.8))
    for ax, title in zip(axes, ("paper: blocked (two lines at once)",
                                "pathpref: one move, one move edge"), strict=True):
        draw_map(world, ax=ax, show_preference=False)
        for n, c in zip(arr.normals, arr.offsets, strict=True):  # the arrangement's lines
            t = np.linspace(-20, 20, 2)
            base = n * c
            ax.plot(base[0] - n[1] * t, base[1] + n[0] * t, color="0.5", lw=0.6, zorder=2)
        # thin polytopes crossed by the move: sign vectors between the two ends, no cell
        s0 = arr.signs[world.cell_polytope[i]]
        s1 = arr.signs[world.cell_polytope[m.next_cell[i, a]]]
        known = {sig.tobytes() for sig in arr.signs}
        for frac in np.linspace(0.05, 0.95, 19):
            x = p0 + frac * (p1 - p0)
            side = x @ arr.normals.T - arr.offsets > 1e-9
            if side.tobytes() not in known and (side != s0).any() and (side != s1).any():
                flip = np.where(side, -1.0, 1.0)
                poly = h_polygon(arr.normals * flip[:, None], arr.offsets * flip, 7, 6)
                ax.add_patch(Polygon(poly, facecolor="gold", edgecolor="darkorange", zorder=2.5))
        for o in world.spec.obstacles:
            ax.add_patch(Polygon(o.vertices, facecolor="0.15", edgecolor="k", zorder=2.6))
        ax.plot(*(world.cells - 0.5).T, ".", color="0.2", ms=3, zorder=4)
        blocked = ax is axes[0]
        ax.annotate("", xy=p1, xytext=p0, zorder=6, arrowprops=dict(
            arrowstyle="-|>", lw=2.2, color="crimson" if blocked else "tab:green"))
        if blocked:
            ax.plot(*(0.5 * (p0 + p1)), "x", color="crimson", ms=14, mew=3, zorder=7)
        ax.set_title(title, fontsize=10)
    fig.suptitle("A straight move may cross several lines at once (gold: a crossed polytope that "
                 "holds no cell, when there is one); blue dashed: move edges", fontsize=10)
    fig.tight_layout()
    fig.savefig(out, dpi=120)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "docs/motion_rule.png")
