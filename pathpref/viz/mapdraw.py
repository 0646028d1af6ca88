"""Draw a map like the paper's Fig. 2: obstacles, polytopes with ids, graph edges, preference.

Plain matplotlib (Agg backend, no display needed). Fed by a :class:`~pathpref.geometry.World`.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Polygon  # noqa: E402

from ..geometry.world import World  # noqa: E402


def plain_text(text: str, limit: int = 200) -> str:
    """``text`` cut to ``limit`` characters, control characters replaced; draw it with
    ``parse_math=False`` so that ``$`` and ``\\`` show literally (no mathtext, which fails on
    a name like ``$\\frac{``)."""
    return "".join(c if c.isprintable() else "?" for c in str(text)[:limit])


def polytope_centres(world: World) -> np.ndarray:
    """Mean of each polytope's free-cell centres (where its id and arrows are drawn)."""
    arr = world.arrangement
    return np.array([(arr.cells[arr.polytope_cells(v)] - 0.5).mean(axis=0)
                     for v in range(arr.n_polytopes)])


def preference_arrows(world: World, pref: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """The human's preferred transitions ``v -> p_v`` as arrows (grid units) from 20 % to 80 %
    of the way between the polytopes' centres."""
    c = polytope_centres(world) + 0.5  # centres of cells -> grid coordinates
    out = []
    for v, w in enumerate(np.asarray(pref)):
        if w >= 0:
            a, b = c[v], c[int(w)]
            out.append((a + 0.2 * (b - a), a + 0.8 * (b - a)))
    return out


#: the figure's longer side is at most this many inches (1560 px at the 130 dpi it is saved
#: with), its shorter side at least :data:`MIN_FIGURE_IN`, whatever the map's shape
MAX_FIGURE_IN = 12.0
MIN_FIGURE_IN = 3.0
#: at most about this many labelled ticks per axis (a cell each on small maps)
MAX_TICKS = 40


def figure_size(width: int, height: int) -> tuple[float, float]:
    """Inches of a map's figure: 6 (maps up to 12 cells) or 9 across its width, the height
    in proportion, then scaled so that the longer side is at most :data:`MAX_FIGURE_IN` and
    each side at least :data:`MIN_FIGURE_IN` (a 1 x 500 map is 3 x 12 inches, not 9 x 4500)."""
    size = 6.0 if max(width, height) <= 12 else 9.0
    w, h = size, size * height / width
    scale = min(1.0, MAX_FIGURE_IN / max(w, h))
    return max(w * scale, MIN_FIGURE_IN), max(h * scale, MIN_FIGURE_IN)


def _tick_step(n: int) -> int:
    return max(1, -(-n // MAX_TICKS))


def draw_map(world: World, ax=None, show_ids: bool = True, show_edges: bool = True,
             show_preference: bool = True, cell_values: np.ndarray | None = None):
    """Draw ``world`` on ``ax`` (a new figure when None) and return the axes.

    ``cell_values`` (one per free cell) shades the cells, e.g. a belief or a distance field.
    """
    spec, arr = world.spec, world.arrangement
    if ax is None:
        _, ax = plt.subplots(figsize=figure_size(spec.width, spec.height))
    cmap = plt.get_cmap("tab20")
    for v, poly in enumerate(arr.polygons):
        if len(poly) >= 3:
            ax.add_patch(Polygon(poly, closed=True, facecolor=cmap(v % 20), alpha=0.35,
                                 edgecolor="0.4", lw=0.8))
    if cell_values is not None:
        img = np.full((spec.height, spec.width), np.nan)
        img[arr.cells[:, 1] - 1, arr.cells[:, 0] - 1] = cell_values
        ax.imshow(img, origin="lower", extent=(0, spec.width, 0, spec.height), cmap="viridis",
                  alpha=0.6)
    for o in spec.obstacles:
        ax.add_patch(Polygon(o.vertices, closed=True, facecolor="0.15", edgecolor="k"))
    centres = polytope_centres(world)
    if show_edges:  # facet edges dotted grey, move edges (multi-line moves) dashed blue
        for (u, w), h in zip(world.graph.edges, world.graph.edge_hyperplane, strict=True):
            style = dict(color="0.3", ls=":") if h >= 0 else dict(color="tab:blue", ls="--")
            ax.plot(*centres[[u, w]].T, lw=0.8, zorder=3, **style)
    if show_preference and world.preference is not None:
        for v, p in enumerate(world.preference):
            if p < 0:
                continue
            a, b = centres[v], centres[p]
            d = b - a
            ax.annotate("", xy=a + 0.7 * d, xytext=a + 0.15 * d, zorder=4,
                        arrowprops=dict(arrowstyle="-|>", color="crimson", lw=1.6))
    if show_ids:
        fs = 9 if arr.n_polytopes <= 30 else 6
        for v, c in enumerate(centres):
            ax.text(*c, str(v), ha="center", va="center", fontsize=fs, zorder=5,
                    bbox=dict(boxstyle="round,pad=0.15", fc="white", ec="none", alpha=0.8))
    ax.set_xlim(0, spec.width)
    ax.set_ylim(0, spec.height)
    ax.set_xticks(np.arange(0, spec.width + 1, _tick_step(spec.width)))
    ax.set_yticks(np.arange(0, spec.height + 1, _tick_step(spec.height)))
    ax.tick_params(labelsize=6)
    ax.grid(True, color="0.85", lw=0.5, zorder=0)
    ax.set_aspect("equal")
    ax.set_title(f"{plain_text(spec.name)}: {arr.n_polytopes} polytopes, "
                 f"{world.graph.n_edges} edges", parse_math=False)
    return ax


def save_map_figure(world: World, out: str | Path) -> Path:
    """Draw ``world`` and write the figure (format from the suffix, e.g. .png or .pdf), with a
    legend below the map."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    out = Path(out)
    ax = draw_map(world)
    fig = ax.figure
    handles = [Patch(facecolor="tab:blue", alpha=0.35, edgecolor="0.4",
                     label="polytope (its id at the centre)"),
               Patch(facecolor="0.15", edgecolor="k", label="obstacle"),
               Line2D([], [], color="0.3", ls=":", label="graph edge (shared face)")]
    if world.preference is not None:
        handles.append(Line2D([], [], color="crimson", marker=r"$\rightarrow$", ls="", ms=12,
                              label="human's preferred exit"))
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.06), ncol=2,
              fontsize=7, frameon=False)
    fig.tight_layout()
    fig.savefig(out, dpi=130)
    plt.close(fig)
    return out
