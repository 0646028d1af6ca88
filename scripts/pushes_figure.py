"""Success against pushes per episode: the periodic human and the corrective one.

    .venv/bin/python scripts/pushes_figure.py --out docs/pushes.png --db-dir /tmp/pushes

For every map (``simple``, ``office``, ``classroom`` and the four plans of ``examples/maps/``)
one sweep (robust preset, consistent human; compliant, goal only, path preference, blend) per
human setting: the periodic human at every ``--delta-t`` and the corrective human at every
``--corrective`` rule (``Delta_T = 1``, :mod:`pathpref.episode.corrective`), written to
``DB_DIR/<map>.sqlite`` (resumable: finished episodes are skipped on a rerun). Then one panel
per map (the example plans pooled in one panel): a point per method and setting at (mean pushes
per episode, strict success) with its Wilson 95 % interval, and a hollow marker at the same
pushes for the homotopy-level success; colour is the method, the marker the setting. A JSON of
every point is written beside the figure (``--json``); ``--from-json FILE`` redraws the figure
from such a file without running anything.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "disable")

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from pathpref.experiments.report import METHOD_LABEL, wilson  # noqa: E402
from pathpref.experiments.store import ResultStore  # noqa: E402
from pathpref.experiments.sweep import run_sweep, sweep_specs  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ("atrium", "hall", "lab", "warehouse")
METHODS = ["compliant", "goal_only", "path_preference", "blended"]
COLOURS = {"compliant": "tab:gray", "goal_only": "tab:blue", "path_preference": "tab:red",
           "blended": "tab:orange"}
MARKERS = ["o", "s", "D", "^", "v", "P"]


def settings(delta_ts: list[int], rules: list[str]) -> list[tuple[str, int, str]]:
    """``(label, delta_t, push_rule)`` of every human setting of the figure."""
    out = [(f"ΔT={d}", d, "") for d in delta_ts]
    out += [(r.replace("corrective ", "corrective, "), 1, r) for r in rules]
    return out


def run_map(map_name: str, db: Path, args, human: list[tuple[str, int, str]]) -> None:
    """The sweep of ``map_name`` under every setting into ``db`` (skips what is done)."""
    specs = []
    for _, dt, rule in human:
        specs += sweep_specs(map_name, METHODS, [dt], args.instances, args.runs,
                             seed=args.seed, human="consistent", queries=args.queries or None,
                             push_rule=rule, preset=args.preset)
    counts = run_sweep(specs, str(db), workers=args.workers, progress=False)
    print(f"{map_name}: {counts['ran']} run, {counts['skipped']} already there, "
          f"{counts['seconds']} s", flush=True)


def points(rows: list[dict], human: list[tuple[str, int, str]]) -> list[dict]:
    """One point per (method, setting) over ``rows``: episodes, mean pushes per episode (and
    per successful episode, and all pushes over the successes: what one success cost), strict
    and homotopy-level success with Wilson 95 % intervals (a failed row counts as a
    failure)."""
    out = []
    for label, dt, rule in human:
        for m in METHODS:
            rs = [r for r in rows if r["method"] == m and r["delta_t"] == dt
                  and (r["push_rule"] or "") == rule]
            if not rs:
                continue
            n = len(rs)
            k, kh = sum(r["success"] for r in rs), sum(r["homotopy_success"] or 0 for r in rs)
            won = [r["inputs"] for r in rs if r["success"]]
            out.append({"method": m, "setting": label, "n": n,
                        "pushes": sum(r["inputs"] for r in rs) / n,
                        "pushes_per_success": sum(won) / len(won) if won else None,
                        # every push the method needed, over its successes: the interventions
                        # one success cost (None: no success)
                        "pushes_for_one_success": sum(r["inputs"] for r in rs) / k if k else None,
                        "success": k / n, "ci": wilson(k, n),
                        "homotopy": kh / n, "homotopy_ci": wilson(kh, n)})
    return out


def figure(panels: dict[str, list[dict]], human: list[tuple[str, int, str]], out: Path,
           title: str) -> None:
    """The figure of the module docstring, one panel per entry of ``panels``."""
    cols = 2
    rows = -(-len(panels) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(11, 4.2 * rows + 0.9), sharey=True,
                             squeeze=False)
    marker = {label: MARKERS[i % len(MARKERS)] for i, (label, _, _) in enumerate(human)}
    for ax in axes.flat[len(panels):]:
        ax.set_visible(False)
    for ax, (name, pts) in zip(axes.flat, panels.items(), strict=False):
        for p in pts:
            c, mk = COLOURS[p["method"]], marker[p["setting"]]
            lo, hi = p["ci"]
            ax.errorbar(p["pushes"], p["success"], yerr=[[p["success"] - lo], [hi - p["success"]]],
                        fmt=mk, color=c, ms=7, capsize=3, lw=1)
            ax.plot(p["pushes"], p["homotopy"], mk, mfc="none", mec=c, ms=9, mew=1.2)
            ax.plot([p["pushes"]] * 2, [p["success"], p["homotopy"]], ":", color=c, lw=0.8)
        n = sorted({p["n"] for p in pts})
        ax.set_title(f"{name} (n = {'/'.join(map(str, n))} per point)", fontsize=10)
        ax.set_xlabel("pushes per episode (mean)")
        ax.set_xlim(left=0)
        ax.set_ylim(-0.03, 1.03)
        ax.grid(alpha=0.3)
        ax.set_ylabel("success rate")
    # colour: a bar per method; shape: a grey marker per human setting; fill: which success
    # (a hexagon, a shape no setting uses, so that no legend entry shares a marker)
    handles = [plt.Line2D([], [], color=COLOURS[m], lw=6, label=METHOD_LABEL.get(
        m, m.replace("_", " "))) for m in METHODS]
    handles += [plt.Line2D([], [], color="0.35", marker=marker[label], ls="", mfc="0.35",
                           label=label) for label, _, _ in human]
    handles += [plt.Line2D([], [], color="0.35", marker="h", ls="", ms=8,
                           label="filled: strict success, bar 95% CI"),
                plt.Line2D([], [], color="0.35", marker="h", mfc="none", ls="", ms=9,
                           label="hollow: homotopy-level success")]
    fig.legend(handles=handles, loc="lower center", ncol=5, fontsize=9, frameon=False)
    fig.suptitle(title, fontsize=11)
    fig.tight_layout(rect=(0, 0.07, 1, 0.96))
    fig.savefig(out, dpi=110)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "docs" / "pushes.png"))
    ap.add_argument("--json", default=None, help="points (default: --out with .json)")
    ap.add_argument("--db-dir", default="pushes_dbs")
    ap.add_argument("--instances", type=int, default=4)
    ap.add_argument("--runs", type=int, default=1)
    ap.add_argument("--queries", type=int, default=200,
                    help="POMCP queries per decision (0: the robust preset's own)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--preset", default="robust", help="the preset of every sweep "
                    "(robust, or robust-wait: the search that waits for pushes)")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--delta-t", type=int, nargs="+", default=[1, 5])
    ap.add_argument("--corrective", nargs="+", default=["corrective delay=1 miss=0.2"],
                    help="corrective push rules ('corrective delay=D miss=M')")
    ap.add_argument("--from-json", default=None,
                    help="redraw the figure from a stored points JSON (no sweep)")
    args = ap.parse_args()
    if args.from_json:
        data = json.loads(Path(args.from_json).read_text())
        labels = dict.fromkeys(p["setting"] for pts in data["panels"].values() for p in pts)
        figure(data["panels"], [(label, 0, "") for label in labels], Path(args.out),
               data["title"])
        print(f"wrote {args.out} from {args.from_json}")
        return
    human = settings(args.delta_t, args.corrective)
    db_dir = Path(args.db_dir)
    db_dir.mkdir(parents=True, exist_ok=True)
    maps = {"simple": "simple", "office": "office", "classroom": "classroom"}
    maps |= {e: str(ROOT / "examples" / "maps" / f"{e}.json") for e in EXAMPLES}
    rows: dict[str, list[dict]] = {}
    for name, source in maps.items():
        db = db_dir / f"{name}.sqlite"
        run_map(source, db, args, human)
        with ResultStore(db, create=False) as st:
            rows[name] = [r for r in st.episodes() if r["status"] != "running"]
    panels = {name: points(rows[name], human) for name in ("simple", "office", "classroom")}
    panels["examples/maps (4 plans pooled)"] = points(
        [r for e in EXAMPLES for r in rows[e]], human)
    queries = args.queries or "its own"
    title = (f"Success against pushes per episode: {args.preset} preset, {queries} queries, "
             f"consistent human, {args.instances} instances x {args.runs} runs per map")
    figure(panels, human, Path(args.out), title)
    out_json = Path(args.json) if args.json else Path(args.out).with_suffix(".json")
    out_json.write_text(json.dumps({"title": title, "panels": panels}, indent=1) + "\n")
    print(f"wrote {args.out} and {out_json}")


if __name__ == "__main__":
    main()
