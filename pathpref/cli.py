"""The ``pathpref`` command line.

Every subcommand turns a :class:`~pathpref.errors.PathprefError` into one line on stderr and
exit status 2; an output file is written whole or not at all.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path

from .errors import ConfigError, PathprefError
from .planning.pomdp import DEFAULT_PRESET, PRESETS


def check_writable(out: str | Path) -> Path:
    """Fail before any work when ``out`` cannot be written."""
    out = Path(out)
    parent = out.parent if str(out.parent) else Path(".")
    if not parent.is_dir():
        raise ConfigError(f"cannot write {out}: folder {parent} does not exist")
    if not os.access(parent, os.W_OK):
        raise ConfigError(f"cannot write {out}: folder {parent} is not writable")
    return out


def atomic_output(out: str | Path, write: Callable[[Path], object]) -> Path:
    """Call ``write(tmp_path)`` and move the result onto ``out``; nothing is left on failure."""
    out = check_writable(out)
    parent = out.parent if str(out.parent) else Path(".")
    fd, tmp = tempfile.mkstemp(dir=parent, prefix=f".{out.stem}.", suffix=out.suffix)
    os.close(fd)
    try:
        write(Path(tmp))
        os.replace(tmp, out)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return out


# --- map ------------------------------------------------------------------------------------
def cmd_map_info(args: argparse.Namespace) -> int:
    import numpy as np

    from .geometry.world import load_world

    world = load_world(args.map)
    deg = [len(n) for n in world.graph.neighbors]
    comp = np.bincount(world.motion.components())
    info = {
        "name": world.name,
        "width": world.spec.width,
        "height": world.spec.height,
        "obstacles": len(world.spec.obstacles),
        "hyperplanes": len(world.arrangement.normals),
        "polytopes": world.n_polytopes,
        "edges": world.graph.n_edges,
        "free_cells": world.n_cells,
        "decomposition": world.spec.decomposition,
        "move_edges": world.graph.n_move_edges,
        "components": len(comp),
        "largest_component_cells": int(comp.max()),
        "max_degree": max(deg, default=0),
        "has_preference": world.preference is not None,
        "t_max": world.spec.t_max,
        "map_hash": world.spec.content_hash,
    }
    if args.json:
        print(json.dumps(info))
    else:
        for k, v in info.items():
            print(f"{k:>23}: {v}")
        if len(comp) > 1:
            print(f"note: free space splits into {len(comp)} parts that the robot cannot move "
                  "between; instances draw goals only from the start's part")
    return 0


def cmd_map_draw(args: argparse.Namespace) -> int:
    from .geometry.world import load_world
    from .viz.mapdraw import save_map_figure

    world = load_world(args.map)
    out = check_writable(args.out)
    if out.suffix.lower() not in (".png", ".pdf", ".svg"):
        raise ConfigError(f"--out {out}: use a .png, .pdf or .svg file name")
    atomic_output(out, lambda p: save_map_figure(world, p))
    print(f"wrote {out}")
    return 0


# --- db -------------------------------------------------------------------------------------
def cmd_db_upgrade(args: argparse.Namespace) -> int:
    from .experiments.migrate import upgrade_database

    remap = {}
    for item in args.map or []:
        old, sep, new = item.partition("=")
        if not sep or not old or not new:
            raise ConfigError(f"--map {item!r}: write it as OLD=NEW (a stored map name = a file)")
        remap[old] = new
    r = upgrade_database(args.db, remap)
    if r["backup"] is None:
        print(f"{args.db} is already at schema {r['to']} ({r['episodes']} episodes); nothing to do")
    else:
        print(f"upgraded {args.db} from schema {r['from']} to {r['to']}: {r['episodes']} episodes, "
              f"{r['steps']} steps ({r['merged']} duplicate rows of one map under two paths "
              f"merged); the old file is {r['backup']}")
    return 0


def cmd_db_check(args: argparse.Namespace) -> int:
    """Report the damage of a database: exit 0 when intact, 2 when not."""
    from .experiments.migrate import check_database, check_text

    r = check_database(args.db)
    print(check_text(r))
    return 0 if r["intact"] else 2


def cmd_db_salvage(args: argparse.Namespace) -> int:
    from .experiments.migrate import salvage_database

    r = salvage_database(args.db, args.out)
    about = "" if r["lost_exact"] else "at most "
    print(f"saved {r['episodes']} episodes and {r['steps']} step rows of {args.db} into "
          f"{args.out}; lost {about}{r['episodes_lost']} episodes ({r['incomplete']} with "
          f"missing step rows) and {about}{r['steps_lost']} step rows")
    return 0


# --- experiments ----------------------------------------------------------------------------
def _common_episode_args(args: argparse.Namespace, map_name: str) -> dict:
    from .experiments.episode import cached_map
    from .planning.pomdp import get_preset

    preset = get_preset(args.preset)
    if args.time_budget_ms is not None and not args.time_budget_ms > 0:
        raise ConfigError(f"--time-budget-ms must be a positive number of milliseconds, got "
                          f"{args.time_budget_ms:g}")
    if args.time_budget_ms is not None and preset.search != "robust":
        raise ConfigError("--time-budget-ms needs the robust search: add --preset robust")
    return {
        "preset": args.preset,
        "time_budget_ms": args.time_budget_ms or 0.0,
        "human": args.human,
        "queries": args.queries if args.queries is not None else preset.queries,
        "t_max": args.t_max if args.t_max is not None else cached_map(map_name).t_max,
        "normalize": args.likelihood == "normalized",
        "coupling": preset.coupling if args.coupling is None else args.coupling,
        "ucb_c": args.ucb_c,
        "timeout_s": args.episode_timeout,
    }


def cmd_evaluate(args: argparse.Namespace) -> int:
    from .experiments.report import load_records, markdown_tables
    from .experiments.sweep import run_sweep, sweep_specs

    specs = sweep_specs(args.map, args.methods, args.delta_t, args.instances, args.runs,
                        seed=args.seed, n_goals=args.goals, sim=args.sim, task=args.task,
                        **_common_episode_args(args, args.map))
    counts = run_sweep(specs, args.db, workers=args.workers, progress=not args.no_progress,
                       retry_failed=args.retry_failed, backend=args.backend,
                       address=args.address)
    print(f"{counts['ran']} episodes run ({counts['failed']} failed), {counts['skipped']} already "
          f"in {args.db}, {counts['seconds']} s")
    from .experiments.episode import cached_map

    recs = [r for r in load_records(args.db) if r["map_hash"] == cached_map(args.map).content_hash]
    print(markdown_tables(recs))
    return 0


def cmd_report(args: argparse.Namespace) -> int:
    from .experiments.report import load_records, markdown_tables, side_by_side, write_csv

    if not Path(args.db).exists():
        raise ConfigError(f"no results database at {args.db}; run 'pathpref evaluate' first")
    recs = load_records(args.db)
    if not recs:
        raise ConfigError(f"{args.db} holds no episodes yet")
    print(markdown_tables(recs))
    both = side_by_side(recs)
    if both:
        print("\n" + both)
    csv_path = Path(args.csv) if args.csv else Path(args.db).with_suffix(".csv")
    atomic_output(csv_path, lambda p: write_csv(recs, p))
    print(f"\nwrote {csv_path}")
    if args.figure:
        from .viz.plots import success_figure

        atomic_output(args.figure, lambda p: success_figure(recs, p))
        print(f"wrote {args.figure}")
    return 0


def cmd_timing(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from .experiments.episode import cached_world
    from .experiments.timing import time_map, timing_markdown

    for m in args.maps:  # validate every map before any work
        cached_world(m).require_preference()
    results = []
    with tqdm(total=args.instances * len(args.maps), unit="inst", file=sys.stderr,
              disable=args.no_progress) as bar:
        for m in args.maps:
            results.append(time_map(m, instances=args.instances, queries=args.queries,
                                    preset=args.preset, seed=args.seed, progress=bar))
    if args.json:
        print(json.dumps(results))
    else:
        print(timing_markdown(results))
    return 0


def cmd_belief_curves(args: argparse.Namespace) -> int:
    from .experiments.curves import curves_from_store
    from .experiments.instances import FIG4
    from .experiments.sweep import fixed_specs, run_sweep
    from .viz.plots import belief_curves_figure

    out = check_writable(args.out)
    db = args.db or str(out.with_suffix(".sqlite"))
    fixed = {"start": list(FIG4["start"]), "goals": [list(g) for g in FIG4["goals"]],
             "true_goal": FIG4["true_goal"], "free_goal_polytope": True}
    common = _common_episode_args(args, args.map)
    specs = fixed_specs(args.map, ["path_preference", "goal_only"], args.delta_t, args.runs,
                        fixed, seed=args.seed, **common)
    run_sweep(specs, db, workers=args.workers, progress=not args.no_progress)
    keys = {m: [s.key() for s in specs if s.method == m] for m in ("path_preference", "goal_only")}
    curves = curves_from_store(db, keys, common["t_max"])
    atomic_output(out, lambda p: belief_curves_figure(curves, p))
    for m, c in curves.items():
        t_end = common["t_max"]
        print(f"{m:>16}: P(true goal) at t=0/5/10/{t_end}: "
              + "/".join(f"{c['p_mean'][t]:.2f}" for t in (0, 5, 10, t_end))
              + "; entropy: " + "/".join(f"{c['h_mean'][t]:.2f}" for t in (0, 5, 10, t_end)))
    print(f"wrote {out} (episodes in {db})")
    return 0


def cmd_render(args: argparse.Namespace) -> int:
    from .experiments.episode import EpisodeSpec
    from .experiments.instances import seed_for
    from .sim.rollout import record_rollout

    out = check_writable(args.out) if args.out else None
    if out is not None and out.suffix.lower() != ".mp4":
        raise ConfigError(f"--out {out}: videos are written as .mp4")
    if args.rerun:
        check_writable(args.rerun)
    if out is None and not args.rerun:
        raise ConfigError("give --out video.mp4 and/or --rerun recording.rrd")
    common = _common_episode_args(args, args.map)
    spec = EpisodeSpec(map=args.map, method=args.method, delta_t=args.delta_t, instance=0,
                       run=0, instance_seed=seed_for(args.seed, 0),
                       run_seed=seed_for(args.seed, 0, 0), sim="mujoco", task=args.task,
                       **common)
    tmp = out.with_name(f".{out.stem}.partial.mp4") if out else None
    try:
        rec = record_rollout(spec, video=tmp, rerun=args.rerun, width=args.width,
                             height=args.height)
        if tmp is not None:
            os.replace(tmp, out)
    finally:
        if tmp is not None and tmp.exists():
            tmp.unlink()
    r = rec.result
    print(f"{args.method} on {args.map}: goal reached {r.goal_reached}, preference followed "
          f"{r.pref_followed}, {r.steps} steps, {r.inputs} pushes; {rec.frames} frames")
    for path in (out, args.rerun):
        if path:
            print(f"wrote {path}")
    return 0


def cmd_interact(args: argparse.Namespace) -> int:
    os.environ.setdefault("MUJOCO_GL", "glfw")  # the viewer needs a windowing backend
    from .sim.interact import InteractiveSession, run_viewer

    session = InteractiveSession(map=args.map, method=args.method, seed=args.seed,
                                 queries=args.queries)
    print("Double-click the orange handle, then Ctrl + right-drag to push the robot.")
    run_viewer(session)
    return 0


# --- bench / demo ---------------------------------------------------------------------------
def cmd_bench(args: argparse.Namespace) -> int:
    from .benchmarks import run_benchmarks

    result = run_benchmarks(maps=args.maps, quick=args.quick, physics=not args.no_physics)
    if args.json:
        print(json.dumps(result))
    else:
        print(json.dumps(result, indent=2))
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    from .demo import run_demo

    out = Path(args.out)
    check_writable(out / "summary.csv" if out.is_dir() else out)
    if args.runs < 1:
        raise ConfigError(f"--runs must be at least 1, got {args.runs}")
    run_demo(out=out, seed=args.seed, sim=args.sim, runs=args.runs, preset=args.preset)
    return 0


# --- parser ---------------------------------------------------------------------------------
class OneLineParser(argparse.ArgumentParser):
    """Usage errors as one line (``pathpref: error: ...``) and exit status 2."""

    def error(self, message: str):  # type: ignore[override]
        self.exit(2, f"pathpref: error: {message} (see '{self.prog} --help')\n")


def build_parser() -> argparse.ArgumentParser:
    p = OneLineParser(
        prog="pathpref",
        description="Infer a person's goal and path preference from sparse nudges "
        "(Peltzer et al. 2023).",
    )
    from . import __version__

    p.add_argument("--version", action="version", version=f"pathpref {__version__}")
    sub = p.add_subparsers(dest="command", required=True)

    mp = sub.add_parser("map", help="inspect and draw maps")
    msub = mp.add_subparsers(dest="map_command", required=True)
    mi = msub.add_parser("info", help="polytope/edge/cell counts of a map")
    mi.add_argument("map", help="built-in name (simple, office, classroom) or a JSON map file")
    mi.add_argument("--json", action="store_true", help="print one JSON object")
    mi.set_defaults(func=cmd_map_info)
    md = msub.add_parser("draw", help="draw obstacles, polytopes, edges and preference arrows")
    md.add_argument("map")
    md.add_argument("--out", required=True, help="output image (.png, .pdf, .svg)")
    md.set_defaults(func=cmd_map_draw)

    def episode_options(sp: argparse.ArgumentParser, preset: str = DEFAULT_PRESET) -> None:
        sp.add_argument("--preset", default=preset, choices=sorted(PRESETS),
                        help=f"robust (guided search, exact belief), paper (the paper's "
                        f"planner) or original (the authors' code); default {preset}")
        sp.add_argument("--time-budget-ms", type=float, default=None,
                        help="robust search: wall time per decision (anytime; default: the "
                        "query count only)")
        sp.add_argument("--human", choices=["map", "consistent"], default="map",
                        help="the human's preference: the map's (the paper's protocol, "
                        "default) or consistent with its goal (goals the preference leads to)")
        sp.add_argument("--queries", type=int, default=None, help="POMCP queries (5000)")
        sp.add_argument("--t-max", type=int, default=None,
                        help="mission time in decision steps (default: the map's t_max field, "
                        "else 3 x its longer side: 30 on simple/office, 60 on classroom)")
        sp.add_argument("--likelihood", choices=["normalized", "unnormalized"],
                        default="normalized", help="robot's likelihood (authors: unnormalized)")
        sp.add_argument("--coupling", action=argparse.BooleanOptionalAction, default=None,
                        help="back-edge belief coupling (default: the preset's; on for paper "
                        "and original as in the authors' code, off for robust)")
        sp.add_argument("--ucb-c", type=float, default=1.0, help="POMCP UCB constant (1)")
        sp.add_argument("--episode-timeout", type=float, default=0.0,
                        help="record an episode as failed after this many seconds (0: none)")
        sp.add_argument("--seed", type=int, default=0)
        sp.add_argument("--workers", type=int, default=os.cpu_count() or 1)
        sp.add_argument("--no-progress", action="store_true", help="no progress bar")

    dbp = sub.add_parser("db", help="maintain results databases")
    dbsub = dbp.add_subparsers(dest="db_command", required=True)
    du = dbsub.add_parser("upgrade", help="migrate a database of an older schema (keeps a .bak)")
    du.add_argument("db", help="results database (.sqlite)")
    du.add_argument("--map", action="append", metavar="OLD=NEW",
                    help="point a stored map name at a file (when it has moved); repeatable")
    du.set_defaults(func=cmd_db_upgrade)
    dc = dbsub.add_parser("check", help="report damage: integrity, schema, rows (exit 2 if any)")
    dc.add_argument("db", help="results database (.sqlite)")
    dc.set_defaults(func=cmd_db_check)
    ds = dbsub.add_parser("salvage", help="copy every intact episode into a new database")
    ds.add_argument("db", help="damaged results database (.sqlite)")
    ds.add_argument("out", help="new database to write (must not exist)")
    ds.set_defaults(func=cmd_db_salvage)

    ev = sub.add_parser("evaluate", help="run a sweep of episodes into a results database")
    ev.add_argument("--map", default="simple")
    ev.add_argument("--methods", nargs="+", default=["all"],
                    help="compliant goal_only path_preference blended oracle goal_known; "
                    "all (the paper's four) or reference (oracle, goal_known)")
    ev.add_argument("--delta-t", nargs="+", type=int, default=[1, 5, 10, 20, 30])
    ev.add_argument("--instances", type=int, default=6)
    ev.add_argument("--runs", type=int, default=50)
    ev.add_argument("--goals", type=int, default=10, help="goal candidates per instance")
    ev.add_argument("--db", default="results.sqlite")
    ev.add_argument("--sim", default="grid", choices=["grid", "mujoco"],
                    help="grid world (default) or the MuJoCo base with force cues")
    ev.add_argument("--task", default="navigate", choices=["navigate", "carry"],
                    help="navigate, or carry (arm on the base; needs --sim mujoco)")
    ev.add_argument("--backend", default="local", help="local (process pool) or ray")
    ev.add_argument("--address", default=None,
                    help="Ray cluster address (auto, ray://host:10001); default: start locally")
    ev.add_argument("--retry-failed", action="store_true", help="re-run failed episodes")
    episode_options(ev)
    ev.set_defaults(func=cmd_evaluate)

    rp = sub.add_parser("report", help="Table I from a results database (Markdown + CSV)")
    rp.add_argument("db")
    rp.add_argument("--csv", default=None, help="CSV path (default: DB name with .csv)")
    rp.add_argument("--figure", default=None, help="success vs ΔT figure (.png)")
    rp.set_defaults(func=cmd_report)

    tm = sub.add_parser("timing", help="Table II: solve and update time at the first decision")
    tm.add_argument("--maps", nargs="+", default=["simple", "office", "classroom"])
    tm.add_argument("--instances", type=int, default=100)
    tm.add_argument("--queries", type=int, default=5000)
    tm.add_argument("--preset", default="paper", choices=sorted(PRESETS))
    tm.add_argument("--seed", type=int, default=0)
    tm.add_argument("--json", action="store_true")
    tm.add_argument("--no-progress", action="store_true")
    tm.set_defaults(func=cmd_timing)

    bc = sub.add_parser("belief-curves", help="Fig. 4: P(true goal) and entropy over time")
    bc.add_argument("--out", default="fig4.png")
    bc.add_argument("--db", default=None, help="episode store (default: OUT with .sqlite)")
    bc.add_argument("--map", default="simple")
    bc.add_argument("--runs", type=int, default=50)
    bc.add_argument("--delta-t", type=int, default=1)
    episode_options(bc, preset="paper")
    bc.set_defaults(func=cmd_belief_curves)

    rd = sub.add_parser("render", help="render a MuJoCo rollout to MP4 and/or a rerun file")
    rd.add_argument("--map", default="simple")
    rd.add_argument("--method", default="path_preference")
    rd.add_argument("--delta-t", type=int, default=5)
    rd.add_argument("--task", default="navigate", choices=["navigate", "carry"],
                    help="navigate (base) or carry (arm on the base, mink IK)")
    rd.add_argument("--out", default=None, help="video file (.mp4)")
    rd.add_argument("--rerun", default=None, help="rerun recording (.rrd)")
    rd.add_argument("--width", type=int, default=480, help="width of each of the two views")
    rd.add_argument("--height", type=int, default=360)
    episode_options(rd)
    rd.set_defaults(func=cmd_render)

    it = sub.add_parser("interact", help="push the robot yourself in the MuJoCo viewer")
    it.add_argument("--map", default="office")
    it.add_argument("--method", default="path_preference")
    it.add_argument("--seed", type=int, default=0)
    it.add_argument("--queries", type=int, default=2000)
    it.set_defaults(func=cmd_interact)

    b = sub.add_parser("bench", help="measure build, update and planning times")
    b.add_argument("--json", action="store_true", help="print one JSON object")
    b.add_argument("--maps", nargs="+", default=["simple", "office", "classroom"])
    b.add_argument("--quick", action="store_true", help="fewer repetitions (smoke test)")
    b.add_argument("--no-physics", action="store_true", help="skip the MuJoCo figures")
    b.set_defaults(func=cmd_bench)

    d = sub.add_parser("demo", help="the main job: run the demo and write its outputs")
    d.add_argument("--out", default="out", help="output folder (default: out)")
    d.add_argument("--seed", type=int, default=0)
    d.add_argument("--sim", default="mujoco", choices=["mujoco", "grid"])
    d.add_argument("--runs", type=int, default=30, help="grid runs per method behind the rates")
    d.add_argument("--preset", default=DEFAULT_PRESET, choices=sorted(PRESETS))
    d.set_defaults(func=cmd_demo)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except PathprefError as e:
        print(f"pathpref: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("pathpref: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # e.g. `pathpref report db | head`
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0


if __name__ == "__main__":
    sys.exit(main())
