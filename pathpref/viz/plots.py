"""Result figures: success rate vs Delta_T (Table I), vs planning time, and belief curves
(Fig. 4). Matplotlib, Agg."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

COLORS = {"compliant": "tab:orange", "goal_only": "tab:green", "path_preference": "tab:blue",
          "blended": "tab:purple", "hindsight": "tab:brown"}


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
        ax.set_ylim(*RATE_LIMITS)
        ax.set_title(f"{g[0]} ({g[1]})\n{g[2]}", fontsize=8)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=130)
    plt.close(fig)


#: the share of a panel's data range left free above and below its points (a point at the
#: panel's limit would sit on the frame, half hidden)
MARGIN = 0.06
#: the limits of a panel of rates in [0, 1], with :data:`MARGIN`
RATE_LIMITS = (-MARGIN, 1.0 + MARGIN)


def headroom(values: list[float], margin: float = MARGIN) -> tuple[float, float]:
    """Limits from 0 to the largest finite value (point or interval end) plus ``margin`` of
    it, so the top point stays off the frame: ``(0, v_max (1 + margin))``; ``(0, 1)`` when
    no value is above 0."""
    import math

    top = max((v for v in values if math.isfinite(v)), default=0.0)
    return (0.0, top * (1.0 + margin)) if top > 0 else (0.0, 1.0)


def study_figure(records: list[dict[str, Any]], out: str | Path) -> None:
    """Per condition (the ``condition`` records of
    :func:`pathpref.experiments.report.study_records`): success rate and the share on route
    with 95% Wilson intervals, and mean effort with its range-clipped 95% t interval (a bare
    point where ``n < 3`` gives none); every point and interval inside its panel's frame."""
    fig = study_axes(records)
    fig.savefig(out, dpi=130)
    plt.close(fig)


def study_axes(records: list[dict[str, Any]]):
    """The figure of :func:`study_figure`, not yet written (its three panels)."""
    import math

    recs = [r for r in records if r["by"] == "condition"]
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8), squeeze=False)
    x = list(range(len(recs)))
    for ax, (col, label) in zip(axes[0], (("success_rate", "success rate"),
                                          ("on_route", "share of trials on route"),
                                          ("effort_ns", "effort (N s)")), strict=True):
        lo_key, hi_key = (("ci_low", "ci_high") if col == "success_rate"
                          else (f"{col}_low", f"{col}_high"))
        for i, r in enumerate(recs):
            m, lo, hi = r[col], r[lo_key], r[hi_key]
            err = None if math.isnan(lo) else [[max(0.0, m - lo)], [max(0.0, hi - m)]]
            ax.errorbar([i], [m], yerr=err, marker="o", capsize=4, color="#1e6edc")
        ax.set_xticks(x, [f"{r['group']}\n(n = {r['n']})" for r in recs], fontsize=7)
        ax.set_ylabel(label)
        if col != "effort_ns":
            ax.set_ylim(*RATE_LIMITS)
        else:
            ax.set_ylim(*headroom([v for r in recs for v in (r[col], r[hi_key])]))
        ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def budget_figure(points: list[dict[str, Any]], out: str | Path) -> None:
    """Success rate with 95% CI against the planning-time budget per decision (log scale), one
    line per method, a panel per map; each point a dict with ``map``, ``budget_ms``,
    ``method``, ``success``, ``ci`` (low, high) and ``n``."""
    maps = list(dict.fromkeys(p["map"] for p in points))  # in the order given
    fig, axes = plt.subplots(1, len(maps), figsize=(4.6 * len(maps), 3.6), squeeze=False)
    for ax, m in zip(axes[0], maps, strict=True):
        pts = [p for p in points if p["map"] == m]
        for i, method in enumerate(sorted({p["method"] for p in pts})):
            ps = sorted((p for p in pts if p["method"] == method), key=lambda p: p["budget_ms"])
            x = [p["budget_ms"] * 1.06 ** i for p in ps]  # dodged, so equal rates stay visible
            y = [p["success"] for p in ps]
            err = [[max(0.0, p["success"] - p["ci"][0]) for p in ps],
                   [max(0.0, p["ci"][1] - p["success"]) for p in ps]]
            ax.errorbar(x, y, yerr=err, marker="o", capsize=3, color=COLORS.get(method),
                        label=f"{method} (n = {ps[0]['n']})")
        ax.set_xscale("log")
        ax.set_xlabel("planning time per decision (ms)")
        ax.set_ylabel("success rate")
        ax.set_ylim(0, 1)
        ax.set_title(f"{m} (robust preset)", fontsize=9)
        ax.grid(alpha=0.3, which="both")
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


#: marker per human setting in :func:`success_pushes_figure` (distinct shapes, all filled)
SETTING_MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")


def success_pushes_figure(cells: list[dict[str, Any]], out: str | Path) -> None:
    """Strict success against mean pushes per episode: one point per method and human setting
    with its 95% Wilson interval as a vertical bar, one panel per map. Colour is the method
    (one legend), marker shape the human setting (a second legend). ``cells``: dicts with
    ``map, method, setting`` (the human's), ``n, success`` (count), ``success_ci`` and
    ``pushes_per_episode`` (``scripts/results.py``); ``human_setting`` names the human's setting."""
    maps = list(dict.fromkeys(c["map"] for c in cells))
    settings = list(dict.fromkeys(c["human_setting"] for c in cells))
    methods = list(dict.fromkeys(c["method"] for c in cells))
    palette = {**COLORS, "goal_known": "tab:gray", "oracle": "black"}
    fig, axes = plt.subplots(1, len(maps), figsize=(5.2 * len(maps), 4.2), squeeze=False,
                             sharey=True)
    for ax, m in zip(axes[0], maps, strict=True):
        for c in (c for c in cells if c["map"] == m):
            p = c["success"] / c["n"]
            lo, hi = c["success_ci"]
            ax.errorbar(c["pushes_per_episode"], p, yerr=[[max(0.0, p - lo)], [max(0.0, hi - p)]],
                        color=palette.get(c["method"], "tab:brown"), capsize=3, ls="",
                        marker=SETTING_MARKERS[settings.index(c["human_setting"])
                                               % len(SETTING_MARKERS)], ms=7)
        ax.set_title(f"map {m}")
        ax.set_xlabel("pushes per episode (mean)")
        ax.set_ylim(-0.03, 1.03)
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("success: goal by the preferred route (95% CI)")
    from matplotlib.lines import Line2D

    by_method = [Line2D([], [], color=palette.get(k, "tab:brown"), lw=6, label=k)
                 for k in methods]
    by_setting = [Line2D([], [], color="0.3", ls="", label=s,
                         marker=SETTING_MARKERS[i % len(SETTING_MARKERS)], ms=7)
                  for i, s in enumerate(settings)]
    first = axes[0][-1].legend(handles=by_method, title="method (colour)", fontsize=7,
                               title_fontsize=8, loc="lower right")
    axes[0][-1].add_artist(first)
    axes[0][0].legend(handles=by_setting, title="human (marker)", fontsize=7, title_fontsize=8,
                      loc="lower left")
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    plt.close(fig)
