"""The subcommands of ``pathpref`` (one ``cmd_*`` function each; the parser that dispatches to
them is :mod:`.cli`). Every output is checked before any work (:mod:`.checks`) and written whole
or not at all."""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from pathlib import Path

from ..errors import ConfigError, did_you_mean
from .checks import (
    FIGURE_SUFFIXES,
    STUDY_MAKER,
    SWEEP_MAKER,
    atomic_output,
    check_database,
    check_episode_count,
    check_goal_count,
    check_methods,
    check_model_size,
    check_model_size_early,
    check_output_folder,
    check_writable,
    is_disk_full,
    load_world_checked,
    staged_outputs,
    write_error,
)
from .physics_args import physics_json


def _new_database_guard(db: str | Path):
    """A function that removes ``db`` and its SQLite side files when this command created it
    (after a failure such as a full disk); an existing database is never removed."""
    existed = Path(db).exists()

    def cleanup() -> None:
        if existed:
            return
        for suffix in ("", "-journal", "-wal", "-shm"):
            try:
                os.unlink(f"{db}{suffix}")
            except FileNotFoundError:
                pass

    return cleanup


# --- map ------------------------------------------------------------------------------------
def cmd_map_info(args: argparse.Namespace) -> int:
    """``pathpref map info``: sizes of the map's arrangement, graph and free space."""
    import numpy as np

    world = load_world_checked(args.map, args.force)
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
    """``pathpref map draw``: the map, its polytopes and preference as a figure."""
    from ..viz.mapdraw import save_map_figure

    out = check_writable(args.out, "--out", FIGURE_SUFFIXES)
    world = load_world_checked(args.map, args.force)
    atomic_output(out, lambda p: save_map_figure(world, p))
    print(f"wrote {out}")
    return 0


def cmd_map_generate(args: argparse.Namespace) -> int:
    """``pathpref map generate``: a random floor plan with a preferred route, checked (it
    loads, and an instance's start and goal candidates can be drawn on it), as JSON."""
    from ..episode.instances import sample_instance
    from ..geometry.generate import check_plan_request, floor_plan
    from ..geometry.world import load_world

    lo, hi = args.sizes  # each in range at parse time, the pair here (one line, no work)
    check_plan_request(args.width, args.height, args.rotated, (lo, hi))
    out = check_writable(args.out, "--out", (".json",)) if args.out else None
    plan = floor_plan(args.seed, args.route, args.width, args.height, args.rotated, args.boxes,
                      (lo, hi), name=args.name,
                      description=f"pathpref map generate --seed {args.seed} --route "
                      f"{args.route}")
    world = load_world(plan)
    try:
        sample_instance(world, args.seed, 10, consistent=True, t_max=world.spec.t_max)
    except ConfigError as e:
        raise ConfigError(f"the plan of seed {args.seed} is too fragmented to place a route "
                          f"with instances ({e}); try another --seed or fewer or smaller "
                          "obstacles") from None
    text = json.dumps(plan, indent=1) + "\n"
    if out is None:
        print(text, end="")
    else:
        atomic_output(out, lambda p: p.write_text(text))
        print(f"wrote {out} ({world.n_polytopes} polytopes, {world.n_cells} free cells, "
              f"{args.route} route)")
    return 0


# --- db -------------------------------------------------------------------------------------
def cmd_db_upgrade(args: argparse.Namespace) -> int:
    """``pathpref db upgrade``: migrate a results database to the current schema."""
    from ..experiments.migrate import recompute_homotopy, recompute_slack, upgrade_database

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
    h = recompute_homotopy(args.db, remap)
    if h["recomputed"] or h["left"]:
        print(f"homotopy_success filled in for {h['recomputed']} older episodes from their "
              f"stored steps; {h['left']} left NULL (not measured: their map does not load "
              "as stored; point it with --map OLD=NEW)")
    sl = recompute_slack(args.db, remap)
    if sl["recomputed"] or sl["left"]:
        print(f"slack filled in for {sl['recomputed']} older episodes from their instances; "
              f"{sl['left']} left NULL (not measured: their map does not load as stored; "
              "point it with --map OLD=NEW)")
    return 0


def cmd_db_check(args: argparse.Namespace) -> int:
    """``pathpref db check``: report the damage of a database (exit 0 intact, 2 not)."""
    from ..experiments.migrate import check_database, check_text

    r = check_database(args.db)
    print(check_text(r))
    return 0 if r["intact"] else 2


def cmd_db_salvage(args: argparse.Namespace) -> int:
    """``pathpref db salvage``: copy every intact episode into a new database."""
    from ..experiments.migrate import salvage_database

    r = salvage_database(args.db, args.out)
    about = "" if r["lost_exact"] else "at most "
    print(f"saved {r['episodes']} episodes and {r['steps']} step rows of {args.db} into "
          f"{args.out}; lost {about}{r['episodes_lost']} episodes ({r['incomplete']} with "
          f"missing step rows) and {about}{r['steps_lost']} step rows")
    if r["study"]:
        print(f"saved {r['trials']} study trials ({r['trial_rows']} rows of the study "
              f"tables); lost {about}{r['trials_lost']} trials (rows missing or unreadable)")
    return 0


def cmd_db_merge(args: argparse.Namespace) -> int:
    """``pathpref db merge``: join sweep databases (shards) into one, each episode once, all
    or nothing (:mod:`pathpref.experiments.merge`)."""
    from ..experiments.merge import merge_databases

    r = merge_databases(args.out, args.inputs)
    print(f"merged {len(args.inputs)} databases into {args.out}: {r['copied']} episodes "
          f"copied ({r['steps']} step rows), {r['replaced']} failed ones replaced by finished "
          f"ones, {r['duplicates']} already there left out ({r['conflicts']} with another "
          f"outcome); {args.out} holds {r['episodes']} episodes")
    if r["no_steps"] and r["with_steps"]:
        named = "; ".join(r["no_steps_named"])
        more = r["no_steps"] - len(r["no_steps_named"])
        print(f"note: {r['no_steps']} of its {r['no_steps'] + r['with_steps']} finished "
              "episodes have no step rows (run with --no-steps; from "
              + ", ".join(f"{db}: {n}" for db, n in r["no_steps_from"].items())
              + f"): {named}" + (f" and {more} more" if more > 0 else "")
              + "; replay and step-based reports leave them out")
    return 0


# --- experiments ----------------------------------------------------------------------------
def _common_episode_args(args: argparse.Namespace, map_name: str) -> dict:
    """The episode fields every running command shares (None: the preset's value, resolved
    by :class:`~pathpref.episode.EpisodeSpec`)."""
    from ..episode import cached_map

    if args.time_budget_ms is not None and not args.time_budget_ms > 0:
        raise ConfigError(f"--time-budget-ms must be a positive number of milliseconds, got "
                          f"{args.time_budget_ms:g}")
    return {
        "preset": args.preset,
        "time_budget_ms": args.time_budget_ms or 0.0,
        "human": args.human,
        "push_rule": args.push_rule,
        "queries": args.queries,
        "t_max": args.t_max if args.t_max is not None else cached_map(map_name).t_max,
        "normalize": args.likelihood == "normalized",
        "coupling": args.coupling,
        "prior": args.prior,
        "ucb_c": args.ucb_c,
        "timeout_s": args.episode_timeout,
    }


def load_simulator(sim: str) -> None:
    """Import the simulator package behind ``--sim`` so that its bodies register with the
    episode layer (the grid body needs none; MuJoCo is imported only when asked for)."""
    if sim == "mujoco":
        from .. import sim as _  # noqa: F401


def cmd_evaluate(args: argparse.Namespace) -> int:
    """``pathpref evaluate``: run (or resume) a sweep into ``--db`` and print its tables."""
    from ..experiments.report import load_records, markdown_tables
    from ..experiments.sweep import parse_shard, run_sweep, shard_specs, sweep_specs
    if args.shard is not None:
        parse_shard(args.shard)  # a malformed --shard before any work
    check_database(args.db)
    check_episode_count([args.instances, args.runs, len(args.delta_t),
                         len(check_methods(args.methods))], "the sweep")
    load_simulator(args.sim)
    check_goal_count(args.map, args.goals)
    check_model_size_early(args.map, args.goals)
    check_model_size(load_world_checked(args.map, args.force), args.goals)
    specs = sweep_specs(args.map, args.methods, args.delta_t, args.instances, args.runs,
                        seed=args.seed, n_goals=args.goals, sim=args.sim, robot=args.task,
                        physics=physics_json(args, args.sim), record_path_hz=args.record_path,
                        **_common_episode_args(args, args.map))
    if args.shard is not None:
        specs = shard_specs(specs, *parse_shard(args.shard))
    cleanup = _new_database_guard(args.db)
    try:
        counts = run_sweep(specs, args.db, workers=args.workers, progress=not args.no_progress,
                           retry_failed=args.retry_failed, backend=args.backend,
                           address=args.address, steps=not args.no_steps)
    except Exception as e:
        if not is_disk_full(e):
            raise
        cleanup()
        raise write_error(args.db, e) from None
    elsewhere = counts.get("elsewhere", 0)
    print(f"{counts['ran']} episodes run ({counts['failed']} failed), {counts['skipped']} already "
          f"in {args.db}" + (f" ({elsewhere} of them run by another sweep)" if elsewhere else "")
          + f", {counts['seconds']} s ({counts['episodes_per_s']:g} episodes/s)"
          + (f"; shard {args.shard} of the sweep" if args.shard is not None else ""))
    from ..episode import cached_map

    recs = [r for r in load_records(args.db) if r["map_hash"] == cached_map(args.map).content_hash]
    print(markdown_tables(recs))
    return 0


def cmd_report(args: argparse.Namespace) -> int:
    """``pathpref report``: tables, side-by-side with the paper, CSV and optional figure."""
    from ..experiments.report import (
        load_records,
        load_trials,
        markdown_tables,
        physical_tables,
        side_by_side,
        study_tables,
        write_csv,
    )

    check_database(args.db, "database", must_exist=True)
    csv_path = Path(args.csv) if args.csv else Path(args.db).with_suffix(".csv")
    check_writable(csv_path, "--csv", (".csv",))
    if args.figure:
        check_writable(args.figure, "--figure", FIGURE_SUFFIXES)
    recs = load_records(args.db, exclude_failed=args.exclude_failed)
    trials = load_trials(args.db)
    if trials:
        from ..study.answers import load_answers, tlx_records, tlx_table
        from ..study.rationality import participant_fits, rationality_table

        fits = participant_fits(args.db)
        tlx = tlx_table(tlx_records(load_answers(args.db)[1], trials))
        print(study_tables(trials) + "\n\n" + rationality_table(fits)
              + (f"\n\n{tlx}" if tlx else "") + ("\n" if recs else ""))
    elif not recs:
        raise ConfigError(f"{args.db} holds no episodes or study trials yet; "
                          f"{SWEEP_MAKER.format(db=args.db)} (a sweep), or "
                          f"{STUDY_MAKER.format(db=args.db)}")
    if recs:
        print(markdown_tables(recs))
        both = side_by_side(recs)
        if both:
            print("\n" + both)
        reading = physical_tables(recs)
        if reading:
            print("\n" + reading)
        atomic_output(csv_path, lambda p: write_csv(recs, p))
        print(f"\nwrote {csv_path}")
        if args.figure:
            from ..viz.plots import success_figure

            atomic_output(args.figure, lambda p: success_figure(recs, p))
            print(f"wrote {args.figure}")
    if trials:  # a database of episodes and trials: the study's files get a -study suffix
        from ..experiments.report import study_records
        from ..viz.plots import study_figure

        srecs = study_records(trials)
        for r in srecs:  # the participant's gamma_h fit (NaN on the condition rows)
            f = fits.get(r["group"]) if r["by"] == "participant" else None
            r["gamma_h"], r["gamma_h_low"], r["gamma_h_high"] = (
                (math.nan,) * 3 if f is None else (f.gamma, f.low, f.high))

        def beside(path: str | Path) -> Path:
            path = Path(path)
            return path if not recs else path.with_name(f"{path.stem}-study{path.suffix}")

        study_csv = beside(csv_path)
        atomic_output(study_csv, lambda p: write_csv(srecs, p))
        print(("" if recs else "\n") + f"wrote {study_csv}")
        if args.figure:
            fig = beside(args.figure)
            atomic_output(fig, lambda p: study_figure(srecs, p))
            print(f"wrote {fig}")
    return 0


def cmd_timing(args: argparse.Namespace) -> int:
    """``pathpref timing``: the paper's Table II (first-decision update and solve times)."""
    from tqdm import tqdm

    from ..experiments.timing import time_map, timing_markdown

    for m in args.maps:  # validate every map before any work
        load_world_checked(m, args.force).require_preference()
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
    """``pathpref belief-curves``: Fig. 4 (P(true goal) and entropy over time) on its instance."""
    from ..episode import FIG4
    from ..experiments.curves import curves_from_store
    from ..experiments.sweep import fixed_specs, run_sweep
    from ..viz.plots import belief_curves_figure

    out = check_writable(args.out, "--out", FIGURE_SUFFIXES)
    db = args.db or str(out.with_suffix(".sqlite"))
    check_database(db)
    check_episode_count([args.runs, 2], "belief-curves")
    load_world_checked(args.map, args.force)
    common = _common_episode_args(args, args.map)
    specs = fixed_specs(args.map, ["path_preference", "goal_only"], args.delta_t, args.runs,
                        FIG4, seed=args.seed, **common)
    cleanup = _new_database_guard(db)
    try:
        counts = run_sweep(specs, db, workers=args.workers, progress=not args.no_progress)
    except Exception as e:
        if not is_disk_full(e):
            raise
        cleanup()
        raise write_error(db, e) from None
    if counts.get("busy"):
        raise ConfigError(f"{counts['busy']} of {len(specs)} episodes are being run by "
                          f"another sweep on {db}; run again when it has finished")
    if counts["failed"]:
        raise ConfigError(f"{counts['failed']} of {len(specs)} episodes failed (see 'pathpref "
                          f"report {db}'); the curves need complete episodes: raise "
                          "--episode-timeout or fix the cause, and run again with a new --db")
    keys = {m: [s.key() for s in specs if s.method == m] for m in ("path_preference", "goal_only")}
    curves = curves_from_store(db, keys, common["t_max"])
    atomic_output(out, lambda p: belief_curves_figure(curves, p))
    t_end = common["t_max"]
    ts = sorted({t for t in (0, 5, 10, t_end) if t <= t_end})
    for m, c in curves.items():
        print(f"{m:>16}: P(true goal) at t={'/'.join(map(str, ts))}: "
              + "/".join(f"{c['p_mean'][t]:.2f}" for t in ts)
              + "; entropy: " + "/".join(f"{c['h_mean'][t]:.2f}" for t in ts))
    print(f"wrote {out} (episodes in {db})")
    return 0


def cmd_render(args: argparse.Namespace) -> int:
    """``pathpref render``: one MuJoCo episode as a video and/or a rerun recording."""
    out = check_writable(args.out, "--out", (".mp4",)) if args.out else None
    rerun = check_writable(args.rerun, "--rerun", (".rrd",)) if args.rerun else None
    if out is None and rerun is None:
        raise ConfigError("give --out video.mp4 and/or --rerun recording.rrd")
    if out is not None and rerun is not None and out.resolve() == rerun.resolve():
        raise ConfigError("--out and --rerun name the same file")
    from ..episode import EpisodeSpec
    from ..episode.body import check_runnable
    from ..planning.policies import METHODS
    from .rollout import (
        DEFAULT_SIZE,
        parse_size,
        print_progress,
        record_rollout,  # imports MuJoCo: checks MUJOCO_GL
    )

    if args.method not in METHODS:
        raise ConfigError(f"--method must be one method (render shows one episode): "
                          f"{', '.join(METHODS)}; got {args.method!r}"
                          f"{did_you_mean(args.method, METHODS)}")
    width, height = parse_size(args.size) if args.size else DEFAULT_SIZE
    width, height = args.width or width, args.height or height
    if width < height:
        raise ConfigError(f"the video must be at least as wide as high (the top view is "
                          f"H x H), got {width}x{height}")
    load_world_checked(args.map, args.force)
    common = _common_episode_args(args, args.map)
    if getattr(args, "policy", None) is not None:
        return _film_policy(args, out, rerun, width, height, common)
    if args.task not in ("navigate", "carry"):
        raise ConfigError(f"--robot must be navigate or carry for the method's own rollout "
                          f"(any task of pathpref_tasks with --policy), got {args.task!r}")
    spec = EpisodeSpec.single(args.map, args.method, args.delta_t, seed=args.seed,
                              sim="mujoco", robot=args.task,
                              physics=physics_json(args, "mujoco"), **common)
    check_runnable(spec)
    # temporary files made exclusively (mkstemp) beside the outputs, moved on success
    with staged_outputs([out, rerun]) as (tmp_video, tmp_rerun):
        rec = record_rollout(spec, video=tmp_video, rerun=tmp_rerun, width=width,
                             height=height,
                             progress=None if args.no_progress else print_progress)
    r = rec.result
    print(f"{args.method} on {args.map}: goal reached {r.goal_reached}, preference followed "
          f"{r.pref_followed}, {r.steps} steps, {r.inputs} pushes; {rec.frames} frames")
    for path in (out, args.rerun):
        if path:
            print(f"wrote {path}")
    return 0


def _film_policy(args: argparse.Namespace, out, rerun, width: int, height: int,
                 common: dict) -> int:
    """``pathpref render --policy``: one episode of a task driven by the given policy."""
    from .film import film_policy, load_policy

    if out is None or rerun is not None:
        raise ConfigError("--policy films a video: give --out video.mp4 (no --rerun)")
    checkpoint = str(args.policy).endswith(".zip")  # a stable-baselines3 agent
    policy = None if checkpoint else load_policy(args.policy)
    from pathpref_tasks import task_names

    if args.task not in task_names():
        raise ConfigError(f"--robot must be a task of pathpref_tasks: "
                          f"{', '.join(task_names())}; got {args.task!r}")
    kwargs = {"map": args.map, "method": args.method, "delta_t": args.delta_t,
              "seed": args.seed, "preset": common["preset"], "queries": common["queries"],
              "t_max": common["t_max"], "coupling": common["coupling"], "force": args.force,
              "physics": physics_json(args, "mujoco")}
    if checkpoint:  # the trained agent on its Gymnasium task's defaults
        from pathpref_tasks.gym import GYM_MIN_GOAL_DISTANCE, GYM_REWARD
        from pathpref_tasks.policies import checkpoint_policy

        kwargs.update(reward=GYM_REWARD, min_goal_distance=GYM_MIN_GOAL_DISTANCE)
        policy = checkpoint_policy(args.policy, args.task, kwargs)
    with staged_outputs([out, None]) as (tmp_video, _):
        metrics, frames = film_policy(args.task, policy, tmp_video, width, height, kwargs)
    print(f"{args.policy} on {args.task} {args.map}: success {metrics['success']}, goal "
          f"reached {metrics['goal_reached']}, {metrics['violations']} violations, "
          f"{metrics['steps']} steps, {metrics['pushes']} pushes; {frames} frames")
    print(f"wrote {out}")
    return 0


def cmd_examples(args: argparse.Namespace) -> int:
    """``pathpref examples DEST``: copy the examples out (:mod:`.examples`)."""
    from .examples import copy_examples

    written = copy_examples(args.dest)
    print(f"copied {len(written)} example files into {args.dest}; start with "
          f"python {Path(args.dest) / 'tutorial.py'} --tiny")
    return 0


def cmd_interact(args: argparse.Namespace) -> int:
    """``pathpref interact``: push the robot yourself in the MuJoCo viewer."""
    os.environ.setdefault("MUJOCO_GL", "glfw")  # the viewer needs a windowing backend
    from .interact import InteractiveSession, run_viewer

    load_world_checked(args.map, args.force)
    session = InteractiveSession(map=args.map, method=args.method, seed=args.seed,
                                 queries=args.queries)
    print("Double-click the orange handle, then Ctrl + right-drag to push the robot.")
    run_viewer(session)
    return 0


# --- studies --------------------------------------------------------------------------------
def cmd_study_run(args: argparse.Namespace) -> int:
    """``pathpref study run``: a participant's trials through the browser, the viewer or a
    push script, recorded in ``--db`` (:mod:`pathpref.study`)."""
    from ..study.conduct import check_participant
    from ..study.plan import load_study

    study = load_study(args.study)
    check_participant(args.participant)
    check_database(args.db)
    script = None
    if args.script:
        from ..study.script import PushScript

        script = PushScript.load(args.script)
        script.check_names(study)
    # every refusal (lock, existing participant, study file) before a page is served
    lsl = None
    if getattr(args, "lsl", False):
        from ..study.lsl import LslOutlets

        lsl = LslOutlets(args.participant)
    live = None
    if args.live_port is not None:
        if args.live_port == args.port:
            raise ConfigError(f"--live-port {args.live_port} is the study server's --port; "
                              "choose another")
        from ..study.live import LiveView

        live = LiveView(args.live_port)
    try:
        return _study_session(args, study, script, lsl, live)
    finally:
        if live is not None:
            live.close()


def _study_session(args: argparse.Namespace, study, script, lsl, live) -> int:
    """The locked session of ``study run`` through its front end (:func:`cmd_study_run`)."""
    from ..study.conduct import Session

    session = Session(study, args.participant, args.db, resume=args.resume, lsl=lsl,
                      live=live)
    if live is not None:
        print(f"live view: connect Foxglove to ws://127.0.0.1:{live.port}", flush=True)
    try:
        if script is not None:
            from ..study.script import ScriptedFrontEnd

            front = ScriptedFrontEnd(script)
            print(f"scripted participant {args.participant}: pushes from {args.script} "
                  "(no screen; faster than real time)", flush=True)
        elif args.ui == "viewer":
            os.environ.setdefault("MUJOCO_GL", "glfw")
            from ..study.viewer import ViewerFrontEnd

            front = ViewerFrontEnd()
        else:
            from ..study.server import BrowserFrontEnd

            front = BrowserFrontEnd(host=args.host, port=args.port)
            print(f"open {front.url} in a browser (Ctrl-C to stop)", flush=True)
    except BaseException:
        session.close()
        raise
    rows = session.run(front, log=lambda m: print(m, flush=True))
    ok = sum(r["success"] or 0 for r in rows)
    print(f"{args.participant}: {len(rows)} trial(s) recorded in {args.db}, {ok} successful")
    return 0


def cmd_study_export(args: argparse.Namespace) -> int:
    """``pathpref study export``: a participant's trials as CSV/Parquet and MCAP files."""
    from ..study.conduct import check_participant
    from ..study.export import export_participant

    check_participant(args.participant)
    check_database(args.db, "database", must_exist=True, made_by=STUDY_MAKER)
    counts = export_participant(args.db, args.participant, args.out, mcap=not args.no_mcap,
                                fmt=args.format)
    folder = Path(args.out) / args.participant
    print(f"wrote {folder}: " + ", ".join(f"{k} {v}" for k, v in counts.items()))
    return 0


def cmd_dataset(args: argparse.Namespace) -> int:
    """``pathpref dataset``: study trials or physical episodes as a LeRobot v3 dataset."""
    check_database(args.db, "database", must_exist=True)
    from ..study.lerobot import export_dataset

    info = export_dataset(args.db, args.out, args.source)
    print(f"wrote {args.out}: LeRobot {info['codebase_version']} dataset, "
          f"{info['total_episodes']} episodes, {info['total_frames']} frames at "
          f"{info['fps']} fps")
    return 0


def cmd_replay(args: argparse.Namespace) -> int:
    """``pathpref replay``: a recorded study trial as a video."""
    out = check_writable(args.out, "--out", (".mp4",))
    check_database(args.db, "database", must_exist=True, made_by=STUDY_MAKER)
    from ..study.replay import replay_trial

    with staged_outputs([out]) as (tmp,):
        frames = replay_trial(args.db, args.participant, args.trial, tmp, args.width,
                              args.height)
    print(f"wrote {out} ({frames} frames)")
    return 0


# --- bench / demo ---------------------------------------------------------------------------
def cmd_bench(args: argparse.Namespace) -> int:
    """``pathpref bench``: the benchmarks as JSON (:mod:`pathpref.apps.benchmarks`)."""
    from .benchmarks import run_benchmarks

    for m in args.maps:
        load_world_checked(m, args.force)
    result = run_benchmarks(maps=args.maps, quick=args.quick, physics=not args.no_physics)
    if args.json:
        print(json.dumps(result))
    else:
        print(json.dumps(result, indent=2))
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    """``pathpref demo``: the stored sweep's verdicts, the grid re-run, the filmed setting's
    rate, figures and videos (:mod:`.demo`)."""
    from .demo import run_demo

    out = check_output_folder(args.out, "--out")
    run_demo(out=out, seed=args.seed, sim=args.sim, runs=args.runs, preset=args.preset)
    return 0


def _ros_spec(args: argparse.Namespace):
    """The episode of a ``pathpref ros`` node: the sweeps' rule (``evaluate --sim mujoco``
    with ``--seed``, instance ``--instance``, run ``--run``)."""
    from ..episode.spec import EpisodeSpec

    load_simulator("mujoco")
    check_goal_count(args.map, args.goals)
    spec = EpisodeSpec.single(args.map, args.method, args.delta_t, seed=args.seed,
                              instance=args.instance, run=args.run, n_goals=args.goals,
                              sim="mujoco", robot=args.task,
                              physics=physics_json(args, "mujoco"),
                              **_common_episode_args(args, args.map))
    spec.validate()
    if not args.timeout > 0:
        raise ConfigError(f"--timeout must be a positive number of seconds, got {args.timeout}")
    return spec


def _ros_out(args: argparse.Namespace, out: dict) -> int:
    if args.json:
        print(json.dumps(out))
    else:
        print(f"{out['steps']} steps, goal {'reached' if out['goal_reached'] else 'not reached'}"
              f", {len(out['felt'])} cues")
    return 0 if out["done"] else 1


def cmd_ros_planner(args: argparse.Namespace) -> int:
    """``pathpref ros planner``: the planner node (docs/ros.md)."""
    from ..ros import require_ros

    require_ros()
    spec = _ros_spec(args)
    if args.record:
        check_writable(args.record, "--record", (".mcap",))
    from ..ros.planner_node import run_planner

    ros_args = None if args.ros_args is None else ["--ros-args", *args.ros_args]
    return _ros_out(args, run_planner(spec, timeout_s=args.timeout, record=args.record,
                                      live_port=args.live_port, ros_args=ros_args))


def cmd_ros_sim(args: argparse.Namespace) -> int:
    """``pathpref ros sim``: the MuJoCo base as a ROS 2 robot (docs/ros.md)."""
    from ..ros import require_ros

    require_ros()
    spec = _ros_spec(args)
    if not args.path_hz >= 50:
        raise ConfigError(f"--path-hz must be at least 50 (Hz), got {args.path_hz:g}")
    from ..ros.sim_node import run_sim
    from ..ros.streams import TOPICS

    ros_args = None if args.ros_args is None else ["--ros-args", *args.ros_args]
    return _ros_out(args, run_sim(spec, TOPICS, path_hz=args.path_hz, realtime=args.realtime,
                                  timeout_s=args.timeout, live_port=args.live_port,
                                  ros_args=ros_args, drive=args.drive))


def cmd_ros_replay(args: argparse.Namespace) -> int:
    """``pathpref ros replay``: a planner recording through the planner offline."""
    load_simulator("mujoco")
    from ..ros.bag import replay

    out = replay(args.recording)
    same = out["waypoints_equal"] and out["beliefs_equal"]
    if args.json:
        print(json.dumps(out))
    else:
        print(f"{out['decisions']} decisions replayed: "
              + ("the same as recorded, bit for bit" if same else "they DIFFER from the "
                 "recording"))
    return 0 if same else 1
# --- doctor / warmup ------------------------------------------------------------------------
def cmd_doctor(args: argparse.Namespace) -> int:
    """``pathpref doctor``: one line per failed check on stderr and exit status 1, else one
    line of the versions checked (:mod:`.doctor`)."""
    from .doctor import CHECKS, diagnose, versions

    failures = diagnose()
    for line in failures:
        print(f"pathpref doctor: {line}", file=sys.stderr)
    if failures:
        return 1
    print(f"pathpref doctor: all {len(CHECKS)} checks passed ({versions()})")
    return 0


def cmd_warmup(args: argparse.Namespace) -> int:
    """``pathpref warmup``: every kernel compiled or loaded from numba's cache
    (:mod:`.warmup`), then one line of what it did; a kernel it did not reach is named on
    stderr (exit status 1: the warm-up misses a path)."""
    from .warmup import warm

    def progress(what: str) -> None:
        if not args.quiet:
            print(f"  {what}", file=sys.stderr, flush=True)

    r = warm(progress=progress)
    print(f"pathpref warmup: {r['kernels']} kernels ready, {r['signatures']} signatures "
          f"({r['compiled']} compiled, the rest from numba's cache) in {r['cpu_s']:.1f} s CPU")
    for name in r["unreached"]:
        print(f"pathpref warmup: {name} was not reached", file=sys.stderr)
    return 1 if r["unreached"] else 0
