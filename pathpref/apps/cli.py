"""The ``pathpref`` command line: the parser and :func:`main`.

Every subcommand (:mod:`.commands`) turns a :class:`~pathpref.errors.PathprefError` into one
line on stderr and exit status 2; numbers are range-checked at parse time and every output is
checked before any work (:mod:`.checks`); an output file is written whole or not at all.
"""

from __future__ import annotations

import argparse
import os
import sqlite3
import sys
from collections.abc import Sequence

from ..errors import PathprefError, did_you_mean
from ..inference.priors import PRIORS
from ..planning.pomdp import DEFAULT_PRESET, PRESETS
from ..switches import check_switches
from . import commands as c
from .checks import RangeAction, atomic_output, check_writable, is_disk_full, write_error
from .physics_args import physics_options

__all__ = ["atomic_output", "build_parser", "check_writable", "main"]


# --- parser ---------------------------------------------------------------------------------
def force_option(sp: argparse.ArgumentParser) -> None:
    """``--force``: build a map whose arrangement may exceed the size limit."""
    sp.add_argument("--force", action="store_true",
                    help="build the map even when its arrangement may exceed the size limit "
                    "(arrangement.MAX_POLYTOPES, see docs/limits.md)")


class DefaultsFormatter(argparse.HelpFormatter):
    """Help with every option's default: ``(default: X)`` is appended unless the text already
    says it (``%(default)s`` or the word "default"), the default is None (the text says what
    None means) or the option is a switch."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if (action.default is None or action.default is argparse.SUPPRESS
                or isinstance(action, argparse._StoreTrueAction | argparse._VersionAction
                              | argparse._HelpAction)
                or "default" in text or not action.option_strings):
            return text
        shown = " ".join(map(str, action.default)) if isinstance(action.default, list) \
            else action.default
        return f"{text} (default: {shown})"


class OneLineParser(argparse.ArgumentParser):
    """Usage errors as one line (``pathpref: error: ...``) and exit status 2; help lists
    every option's default (:class:`DefaultsFormatter`); no abbreviated options (``--run``
    is not ``--runs``: an option is spelled out or refused); an unknown choice names the
    closest one ("did you mean")."""

    def __init__(self, *args, **kwargs):
        kwargs.setdefault("formatter_class", DefaultsFormatter)
        kwargs.setdefault("allow_abbrev", False)
        super().__init__(*args, **kwargs)

    def _check_value(self, action: argparse.Action, value) -> None:  # type: ignore[override]
        """Refuse a value outside ``action.choices``, naming the closest choice."""
        if action.choices is not None and value not in action.choices:
            choices = ", ".join(map(repr, action.choices))
            raise argparse.ArgumentError(action, f"invalid choice: {value!r}"
                                         f"{did_you_mean(value, action.choices)} (choose "
                                         f"from {choices})")

    def error(self, message: str):  # type: ignore[override]
        """Print the usage error as one line and exit with status 2."""
        self.exit(2, f"pathpref: error: {message} (see '{self.prog} --help')\n")


class RefusedOption(argparse.Action):
    """An option a subcommand refuses with a reason (``why(value)``: one line naming the fix)
    instead of argparse's bare "unrecognized arguments"; hidden from the help."""

    def __init__(self, option_strings, dest, why, **kwargs):
        kwargs.setdefault("help", argparse.SUPPRESS)
        super().__init__(option_strings, dest, **kwargs)
        self.why = why

    def __call__(self, parser, namespace, values, option_string=None):
        """Refuse the option: a usage error (one line, exit status 2)."""
        parser.error(self.why(values))


def study_physics_refusals(sr: argparse.ArgumentParser) -> None:
    """``study run`` takes no physics flag: a trial's physics is set in the study file
    (``robot_model`` is refused there too, with the same reason, :func:`~pathpref.study.plan.
    disk_only`)."""
    from ..episode.physics import FIELDS, flag
    from ..study.plan import NOT_THE_PARTICIPANT, STUDY_TIMINGS, disk_only

    sr.add_argument("--robot-model", action=RefusedOption, dest="_refused",
                    why=lambda v: f"study run has no --robot-model: the trial's physics "
                    f"robot_model {disk_only(v)}")
    for name, (group, _) in FIELDS.items():
        if name == "robot_model":
            continue
        if group == "human" and name != "timing":
            why = f"{flag(name)} {NOT_THE_PARTICIPANT}"
        else:
            value = f"one of {', '.join(STUDY_TIMINGS)}" if name == "timing" else "..."
            why = (f"set it per trial in the study file: \"physics\": {{\"{name}\": "
                   f"{value}}} (docs/study.md)")
        sr.add_argument(flag(name), action=RefusedOption, dest="_refused",
                        nargs=0 if name == "use_strength" else None,
                        why=lambda v, name=name, why=why: f"study run has no {flag(name)}: "
                        f"{why}")


#: what each preset is (docs/robust.md); the default is named from the planner's own
PRESET_HELP = ("the planner's settings: paper (the paper's POMCP), original (the authors' "
               "code), robust (route prior, guided search), robust-wait (robust whose search "
               "can wait for the next push), robust-check (robust-wait that checks each "
               "crossing against waiting for the next pushes), robust-slack (robust-check "
               "that budgets its waits over the route and arrives first when time runs "
               "out) or robust-value (robust-slack that judges arriving per goal inside "
               "one search and waits for a second push before an unsure crossing)")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of every subcommand."""
    p = OneLineParser(
        prog="pathpref",
        description="Infer a person's goal and path preference from sparse nudges "
        "(Peltzer et al. 2023).",
    )
    from .. import __version__

    p.add_argument("--version", action="version", version=f"pathpref {__version__}")
    sub = p.add_subparsers(dest="command", required=True)

    mp = sub.add_parser("map", help="inspect and draw maps")
    msub = mp.add_subparsers(dest="map_command", required=True)
    mi = msub.add_parser("info", help="polytope/edge/cell counts of a map")
    mi.add_argument("map", help="built-in name (simple, office, classroom) or a JSON map file")
    mi.add_argument("--json", action="store_true", help="print one JSON object")
    force_option(mi)
    mi.set_defaults(func=c.cmd_map_info)
    md = msub.add_parser("draw", help="draw obstacles, polytopes, edges and preference arrows")
    md.add_argument("map", help="built-in name (simple, office, classroom) or a JSON map file")
    md.add_argument("--out", required=True, help="output image (.png, .pdf, .svg)")
    force_option(md)
    md.set_defaults(func=c.cmd_map_draw)
    from ..geometry.generate import PLAN_DEFAULTS, ROUTE_KINDS

    mg = msub.add_parser("generate", help="write a random floor plan with a preferred route "
                         "(JSON) from a seed")
    mg.add_argument("--seed", action=RangeAction, limits="seed", default=0,
                    help="the plan's seed (default 0)")
    mg.add_argument("--width", action=RangeAction, limits="plan_side",
                    default=PLAN_DEFAULTS["width"],
                    help=f"cells across (default {PLAN_DEFAULTS['width']})")
    mg.add_argument("--height", action=RangeAction, limits="plan_side",
                    default=PLAN_DEFAULTS["height"],
                    help=f"cells up (default {PLAN_DEFAULTS['height']})")
    mg.add_argument("--rotated", action=RangeAction, limits="plan_obstacles",
                    default=PLAN_DEFAULTS["rotated"],
                    help=f"rectangles at random angles (default {PLAN_DEFAULTS['rotated']})")
    mg.add_argument("--boxes", action=RangeAction, limits="plan_obstacles",
                    default=PLAN_DEFAULTS["boxes"],
                    help=f"cell-aligned boxes (default {PLAN_DEFAULTS['boxes']})")
    mg.add_argument("--sizes", action=RangeAction, limits="plan_obstacle_size", nargs=2,
                    metavar=("LO", "HI"), default=list(PLAN_DEFAULTS["size_range"]),
                    help="obstacle sides are drawn in LO..HI cells, HI below min(width, "
                    "height) / sqrt 2 with rotated rectangles (default "
                    f"{PLAN_DEFAULTS['size_range'][0]:g} {PLAN_DEFAULTS['size_range'][1]:g})")
    mg.add_argument("--route", choices=ROUTE_KINDS, default="open",
                    help="open: through four waypoints of the largest free area; loop: a "
                    "closed route round the map (default open)")
    mg.add_argument("--name", help="the plan's name (default: random_WxH_Rr Bb_SEED)")
    mg.add_argument("--out", help="the JSON file to write (default: print it)")
    mg.set_defaults(func=c.cmd_map_generate)

    def episode_options(sp: argparse.ArgumentParser, preset: str = DEFAULT_PRESET,
                        sweep: bool = True) -> None:
        """The planner and episode options; ``sweep=False`` (one episode, ``render``)
        accepts but does not list ``--workers`` and ``--episode-timeout``, which do nothing
        there."""
        hidden = None if sweep else argparse.SUPPRESS
        sp.add_argument("--preset", default=preset, choices=sorted(PRESETS),
                        help=PRESET_HELP + " (default: %(default)s)")
        sp.add_argument("--time-budget-ms", action=RangeAction, limits="time_budget_ms",
                        default=None,
                        help="robust search: wall time per decision (anytime; default: the "
                        "query count only)")
        sp.add_argument("--human", choices=["map", "consistent"], default="map",
                        help="the human's preference: the map's (the paper's protocol, "
                        "default) or consistent with its goal (goals the preference leads "
                        "to; every polytope's preference then leads to the goal)")
        sp.add_argument("--push-rule", default="", metavar="RULE",
                        help="when the human pushes: every --delta-t steps (default, '') or "
                        "only when needed, 'corrective delay=D miss=M' (reaction delay D "
                        "steps, misses a need with probability M; needs --delta-t 1)")
        sp.add_argument("--queries", action=RangeAction, limits="queries", default=None,
                        help="POMCP queries per decision (default: the preset's, 5000)")
        sp.add_argument("--t-max", action=RangeAction, limits="t_max", default=None,
                        help="mission time in decision steps (default: the map's t_max field, "
                        "else 3 x its longer side: 30 on simple/office, 60 on classroom)")
        sp.add_argument("--likelihood", choices=["normalized", "unnormalized"],
                        default="normalized",
                        help="the robot's observation likelihood (the authors' code: "
                        "unnormalized)")
        sp.add_argument("--coupling", action=argparse.BooleanOptionalAction, default=None,
                        help="back-edge belief coupling (default: the preset's; on for paper "
                        "and original as in the authors' code, off for robust)")
        sp.add_argument("--prior", default=None, metavar="{" + ",".join(PRIORS) + "}",
                        help="the path-preference belief's prior, or one another package "
                        "registers (default: the preset's; "
                        "independent for paper and original, routes for robust: preferences "
                        "that lead to the goal; learned-gamma: independent, with the human's "
                        "rationality inferred over 0.5, 1.5, 5)")
        sp.add_argument("--ucb-c", action=RangeAction, limits="ucb_c", default=None,
                        help="POMCP UCB constant (default: the preset's, 1)")
        sp.add_argument("--episode-timeout", action=RangeAction, limits="episode_timeout",
                        default=0.0,
                        help=hidden or "record an episode as failed after this many seconds "
                        "(0: none)")
        sp.add_argument("--seed", action=RangeAction, limits="seed", default=0,
                        help="seed of the instances and runs (the same seed, the same episodes)")
        sp.add_argument("--workers", action=RangeAction, limits="workers",
                        default=os.cpu_count() or 1,
                        help=hidden or "worker processes (default: the number of CPUs)")
        sp.add_argument("--no-progress", action="store_true", help="no progress output")
        force_option(sp)

    dbp = sub.add_parser("db", help="maintain results databases")
    dbsub = dbp.add_subparsers(dest="db_command", required=True)
    du = dbsub.add_parser("upgrade", help="migrate a database of an older schema (keeps a .bak)")
    du.add_argument("db", help="results database (.sqlite)")
    du.add_argument("--map", action="append", metavar="OLD=NEW",
                    help="point a stored map name at a file (when it has moved); repeatable "
                    "(default: none)")
    du.set_defaults(func=c.cmd_db_upgrade)
    dc = dbsub.add_parser("check", help="report damage (exit 0 when intact, 2 when not)")
    dc.add_argument("db", help="results database (.sqlite)")
    dc.set_defaults(func=c.cmd_db_check)
    ds = dbsub.add_parser("salvage", help="copy every intact episode into a new database")
    ds.add_argument("db", help="damaged results database (.sqlite)")
    ds.add_argument("out", help="new database to write (must not exist)")
    ds.set_defaults(func=c.cmd_db_salvage)
    dm = dbsub.add_parser("merge", help="join sweep databases (shards) into one, each episode "
                          "once (exit 2 when two runs of an episode disagree)")
    dm.add_argument("out", help="database to write into (created when missing)")
    dm.add_argument("inputs", nargs="+", help="databases to copy from (read only)")
    dm.set_defaults(func=c.cmd_db_merge)

    ev = sub.add_parser("evaluate", help="run a sweep of episodes into a results database")
    ev.add_argument("--map", default="simple",
                    help="built-in name (simple, office, classroom) or a JSON map file")
    ev.add_argument("--methods", nargs="+", default=["all"],
                    help="compliant goal_only path_preference blended hindsight oracle "
                    "goal_known; all (the paper's four), reference (oracle, goal_known) or "
                    "baselines (hindsight: hindsight optimisation, Javdani et al. 2018)")
    ev.add_argument("--delta-t", nargs="+", action=RangeAction, limits="delta_t",
                    default=[1, 5, 10, 20, 30],
                    help="decision steps between the human's inputs (one or more)")
    ev.add_argument("--instances", action=RangeAction, limits="instances", default=6,
                    help="instances (start, goal candidates, true goal) per method and ΔT")
    ev.add_argument("--runs", action=RangeAction, limits="runs", default=50,
                    help="runs per instance; a sweep is methods x ΔT x instances x runs "
                    "episodes, 4 x 5 x 6 x 50 = 6000 if nothing is changed")
    ev.add_argument("--goals", action=RangeAction, limits="goals", default=10,
                    help="goal candidates per instance")
    ev.add_argument("--db", default="results.sqlite",
                    help="results database (SQLite); episodes already in it are skipped")
    ev.add_argument("--sim", default="grid",
                    help="the body: grid (grid world), mujoco (the MuJoCo base with force "
                    "cues) or a body another package registers (pathpref.bodies)")
    ev.add_argument("--robot", "--task", dest="task", default="navigate",
                    help="which robot: navigate (the base), carry (arm on the base; needs "
                    "--sim mujoco) or another task the body offers; --task is its older name")
    ev.add_argument("--backend", default="local", help="local (process pool) or ray")
    ev.add_argument("--address", default=None,
                    help="Ray cluster address (auto, ray://host:10001); default: start locally")
    ev.add_argument("--retry-failed", action="store_true", help="re-run failed episodes")
    ev.add_argument("--shard", default=None, metavar="I/N",
                    help="run only shard I of N of the sweep (episodes split by key; one "
                    "database per shard, joined by 'pathpref db merge'; default: all)")
    ev.add_argument("--no-steps", action="store_true",
                    help="store no per-step rows (most of a database's size; replay and "
                    "step-based reports need them)")
    ev.add_argument("--record-path", action=RangeAction, limits="record_path", default=0.0,
                    metavar="HZ",
                    help="--sim mujoco: store each episode's continuous path (base pose, end "
                    "effector, applied force) at HZ samples per simulated second, at least 50 "
                    "(100: every 5th 2 ms physics step), in the table episode_path; 0: none. "
                    "It does not change any result or key (docs/study_export.md)")
    episode_options(ev)
    physics_options(ev)
    ev.set_defaults(func=c.cmd_evaluate)

    rp = sub.add_parser("report", help="Table I from a results database (Markdown + CSV)")
    rp.add_argument("db", help="results database (.sqlite)")
    rp.add_argument("--csv", default=None, help="CSV path (default: DB name with .csv)")
    rp.add_argument("--figure", default=None,
                    help="success vs ΔT figure (.png, .pdf, .svg; default: none)")
    rp.add_argument("--exclude-failed", action="store_true",
                    help="leave failed episodes (an error, a timeout) out of the rates; by "
                    "default each counts as a failure. Every table says how many failed")
    rp.set_defaults(func=c.cmd_report)

    tm = sub.add_parser("timing", help="Table II: solve and update time at the first decision")
    tm.add_argument("--maps", nargs="+", default=["simple", "office", "classroom"],
                    help="maps (built-in names or JSON files)")
    tm.add_argument("--instances", action=RangeAction, limits="instances", default=100,
                    help="instances per map")
    tm.add_argument("--queries", action=RangeAction, limits="queries", default=5000,
                    help="POMCP queries per decision")
    tm.add_argument("--preset", default="paper", choices=sorted(PRESETS),
                    help=PRESET_HELP + "; Table II is the paper's (default: paper)")
    tm.add_argument("--seed", action=RangeAction, limits="seed", default=0,
                    help="seed of the instances")
    tm.add_argument("--json", action="store_true", help="print one JSON object")
    tm.add_argument("--no-progress", action="store_true", help="no progress output")
    force_option(tm)
    tm.set_defaults(func=c.cmd_timing)

    bc = sub.add_parser("belief-curves", help="Fig. 4: P(true goal) and entropy over time")
    bc.add_argument("--out", default="fig4.png", help="figure (.png, .pdf, .svg)")
    bc.add_argument("--db", default=None, help="episode store (default: OUT with .sqlite)")
    bc.add_argument("--map", default="simple",
                    help="built-in name (simple, office, classroom) or a JSON map file")
    bc.add_argument("--runs", action=RangeAction, limits="runs", default=50,
                    help="runs averaged per curve")
    bc.add_argument("--delta-t", action=RangeAction, limits="delta_t", default=1,
                    help="decision steps between the human's inputs")
    episode_options(bc, preset="paper")
    bc.set_defaults(func=c.cmd_belief_curves)

    rd = sub.add_parser("render", help="render a MuJoCo rollout to MP4 and/or a rerun file")
    rd.add_argument("--map", default="simple",
                    help="built-in name (simple, office, classroom) or a JSON map file")
    rd.add_argument("--method", default="path_preference",
                    help="the one method to render (compliant, goal_only, path_preference, "
                    "blended, goal_known, oracle)")
    rd.add_argument("--delta-t", action=RangeAction, limits="delta_t", default=5,
                    help="decision steps between the human's pushes")
    rd.add_argument("--robot", "--task", dest="task", default="navigate",
                    help="which robot: navigate (base) or carry (arm on the base, mink IK); "
                    "with --policy any task of pathpref_tasks (navigate_control, "
                    "carry_control, ...); --task is its older name")
    rd.add_argument("--policy", default=None, metavar="MODULE:FUNCTION|AGENT.zip",
                    help="film this policy instead of the method's own moves: a callable of "
                    "a dm_env TimeStep returning the task's action, or a stable-baselines3 "
                    "agent saved as .zip (examples/train_ppo.py; the method still keeps "
                    "the robot's belief drawn in the video; default: the method's own moves)")
    rd.add_argument("--out", default=None,
                    help="video file (.mp4; default: none, give --out and/or --rerun)")
    rd.add_argument("--rerun", default=None,
                    help="rerun recording (.rrd; default: none, give --out and/or --rerun)")
    rd.add_argument("--size", default=None, metavar="WxH",
                    help="video size: 960x540 (default), 1280x720 or any WxH")
    rd.add_argument("--width", action=RangeAction, limits="frame_size", default=None,
                    help="video width (default: from --size)")
    rd.add_argument("--height", action=RangeAction, limits="frame_size", default=None,
                    help="video height (default: from --size)")
    episode_options(rd, sweep=False)
    physics_options(rd)
    rd.set_defaults(func=c.cmd_render)

    it = sub.add_parser("interact", help="push the robot yourself in the MuJoCo viewer")
    it.add_argument("--map", default="office",
                    help="built-in name (simple, office, classroom) or a JSON map file")
    it.add_argument("--method", default="path_preference", help="the robot's method")
    it.add_argument("--seed", action=RangeAction, limits="seed", default=0,
                    help="seed of the instance")
    it.add_argument("--queries", action=RangeAction, limits="queries", default=2000,
                    help="POMCP queries per decision")
    force_option(it)
    it.set_defaults(func=c.cmd_interact)

    st = sub.add_parser("study", help="force-interaction studies with people (browser, "
                        "viewer or scripted participants), recorded in a results database")
    stsub = st.add_subparsers(dest="study_command", required=True)
    sr = stsub.add_parser("run", help="run a participant's trials of a study file")
    sr.add_argument("study", help="study file (.json or .toml; see docs/study.md)")
    sr.add_argument("--participant", required=True, help="participant id (letters, digits, "
                    "_ . -)")
    sr.add_argument("--db", required=True, help="results database (.sqlite; sweeps' store)")
    sr.add_argument("--ui", choices=["browser", "viewer"], default="browser",
                    help="browser (default: serves a page, prints its URL) or the MuJoCo "
                    "viewer (needs a display)")
    sr.add_argument("--port", action=RangeAction, limits="port", default=8765,
                    help="browser: TCP port (0: any free port; default 8765)")
    sr.add_argument("--host", default="127.0.0.1",
                    help="browser: address to bind (default 127.0.0.1; any other serves "
                    "other machines and needs the random token printed in the URL)")
    sr.add_argument("--script", default=None, help="scripted participant: a JSON file of "
                    "timed pushes (no screen; runs faster than real time; default: none, a "
                    "person pushes)")
    sr.add_argument("--resume", action="store_true",
                    help="continue a participant's trials (the unfinished one runs again)")
    sr.add_argument("--live-port", type=int, default=None, metavar="PORT",
                    help="serve a Foxglove live view of the trials on ws://127.0.0.1:PORT "
                    "(scene, goal belief, /tf and /pose at 100 Hz; needs foxglove-sdk: pip "
                    "install 'pathpref[export]'; default: none; docs/study_export.md)")
    sr.add_argument("--lsl", action="store_true",
                    help="stream force, pose and events as Lab Streaming Layer outlets "
                    "(needs pylsl: pip install 'pathpref[lsl]'; docs/study_export.md)")
    study_physics_refusals(sr)
    sr.set_defaults(func=c.cmd_study_run)
    se = stsub.add_parser("export", help="a participant's trials as a tidy CSV/Parquet folder "
                          "and one MCAP file per trial (docs/study_export.md)")
    se.add_argument("db", help="results database holding study trials")
    se.add_argument("--participant", required=True, help="the participant's id")
    se.add_argument("--out", required=True, help="folder; the files go to OUT/PARTICIPANT/")
    se.add_argument("--no-mcap", action="store_true", help="CSV only (no mcap package needed)")
    se.add_argument("--format", choices=["csv", "parquet", "both"], default="csv",
                    help="the tables as CSV (default), Parquet (needs pyarrow: pip install "
                    "'pathpref[parquet]') or both")
    se.set_defaults(func=c.cmd_study_export)

    ds_ = sub.add_parser("dataset", help="study trials or physical episodes as a LeRobot v3 "
                         "dataset (docs/study_export.md)")
    ds_.add_argument("db", help="results database (study trials or a --sim mujoco sweep)")
    ds_.add_argument("--out", required=True, help="a new folder: the dataset's root")
    ds_.add_argument("--source", choices=["study", "episodes", "paths"], default="study",
                     help="study: every finished trial at 100 frames/s (default); episodes: "
                     "the --sim mujoco episodes, a frame per decision step; paths: their "
                     "paths recorded with evaluate --record-path, a frame per sample")
    ds_.set_defaults(func=c.cmd_dataset)

    rpl = sub.add_parser("replay", help="render a recorded study trial to a video")
    rpl.add_argument("db", help="results database holding study trials")
    rpl.add_argument("--participant", required=True, help="the participant's id")
    rpl.add_argument("--trial", action=RangeAction, limits="trial", required=True,
                     help="the trial's position (1, 2, ...)")
    rpl.add_argument("--out", required=True, help="video file (.mp4)")
    rpl.add_argument("--width", action=RangeAction, limits="frame_size", default=960,
                     help="video width in pixels (default: %(default)s)")
    rpl.add_argument("--height", action=RangeAction, limits="frame_size", default=540,
                     help="video height in pixels (default: %(default)s)")
    rpl.set_defaults(func=c.cmd_replay)

    b = sub.add_parser("bench", help="measure build, update and planning times")
    b.add_argument("--json", action="store_true", help="print one JSON object")
    b.add_argument("--maps", nargs="+", default=["simple", "office", "classroom"],
                    help="maps to time")
    b.add_argument("--quick", action="store_true", help="fewer repetitions (smoke test)")
    b.add_argument("--no-physics", action="store_true", help="skip the MuJoCo figures")
    force_option(b)
    b.set_defaults(func=c.cmd_bench)

    ex = sub.add_parser("examples", help="copy the examples (tutorial, PPO training, "
                        "example maps) into a folder")
    ex.add_argument("dest", help="folder to copy them into (made when missing; no file in it "
                    "is overwritten)")
    ex.set_defaults(func=c.cmd_examples)

    d = sub.add_parser("demo", help="where inferring the path preference matters: the "
                       "stored sweep's verdicts, grid rates, MuJoCo videos (docs/demo.md)")
    d.add_argument("--out", default="out", help="output folder")
    d.add_argument("--seed", action=RangeAction, limits="seed", default=0,
                   help="seed of the instances and runs")
    d.add_argument("--sim", default="mujoco", choices=["mujoco", "grid"],
                   help="body of the filmed episodes (grid: no videos)")
    d.add_argument("--runs", action=RangeAction, limits="runs", default=30,
                   help="grid runs per method behind the rates (30: the stored sweep's cell)")
    d.add_argument("--preset", default=DEFAULT_PRESET, choices=sorted(PRESETS),
                   help=PRESET_HELP + " (default: %(default)s); the stored sweep says "
                   "which one made it")
    d.set_defaults(func=c.cmd_demo)
    ros = sub.add_parser("ros", help="pathpref as ROS 2 nodes: the planner on a robot's "
                         "topics and the MuJoCo base as a robot (docs/ros.md; the 'ros' extra)")
    rsub = ros.add_subparsers(dest="ros_command", required=True)
    for name, text, func in (
            ("planner", "the planner node: handle wrench and odometry in; route, waypoint, "
             "velocity command, belief and markers out", c.cmd_ros_planner),
            ("sim", "the MuJoCo base as a ROS 2 robot: odometry, pose and the simulated "
             "person's handle wrench out; the planner's waypoints in", c.cmd_ros_sim)):
        rn = rsub.add_parser(name, help=text)
        rn.add_argument("--map", default="simple",
                        help="built-in name (simple, office, classroom) or a JSON map file")
        rn.add_argument("--method", default="path_preference",
                        help="the planner's method (as in evaluate --methods)")
        rn.add_argument("--delta-t", action=RangeAction, limits="delta_t", default=5,
                        help="decision steps between the person's pushes")
        rn.add_argument("--instance", action=RangeAction, limits="seed", default=0,
                        help="instance index under --seed (evaluate's first is 0)")
        rn.add_argument("--run", action=RangeAction, limits="seed", default=0,
                        help="run index of the instance (evaluate's first is 0)")
        rn.add_argument("--goals", action=RangeAction, limits="goals", default=10,
                        help="goal candidates of the instance")
        rn.add_argument("--robot", "--task", dest="task", default="navigate",
                        help="navigate (the base) or carry (arm on the base)")
        rn.add_argument("--timeout", type=float, default=300.0,
                        help="wall-clock seconds after which the node stops")
        rn.add_argument("--json", action="store_true",
                        help="print the node's outcome as one JSON object when it stops")
        rn.add_argument("--live-port", type=int, default=None, metavar="PORT",
                        help="serve a Foxglove live view on 127.0.0.1:PORT (default: none; "
                        "the study server's port is 8765, use another, e.g. 8766)")
        if name == "planner":
            rn.add_argument("--record", default=None, metavar="OUT.mcap",
                            help="write every message in and out as MCAP (ROS 2 profile, CDR; "
                            "default: none)")
        else:
            rn.add_argument("--path-hz", type=float, default=100.0,
                            help="odometry and /pose rate (Hz, at least 50)")
            rn.add_argument("--drive", choices=["waypoint", "cmd_vel"], default="waypoint",
                            help="what the base follows: the next waypoint with its own "
                            "tracking controller (as evaluate's body) or the planner's "
                            "velocity commands (needs --realtime)")
            rn.add_argument("--realtime", type=float, default=0.0,
                            help="pace the physics to the wall clock times this factor (0: "
                            "as fast as the planner answers)")
        rn.add_argument("--ros-args", dest="ros_args", nargs=argparse.REMAINDER, default=None,
                        help="everything after it goes to ROS (-p wrench_topic:=/ft ...; "
                        "default: none)")
        episode_options(rn, sweep=False)
        physics_options(rn)
        rn.set_defaults(func=func)
    rr = rsub.add_parser("replay", help="replay a recording of 'ros planner --record' through "
                         "the planner offline; exit 0 when every decision equals the recorded "
                         "one bit for bit")
    rr.add_argument("recording", help="the .mcap file")
    rr.add_argument("--json", action="store_true", help="print the replay as one JSON object")
    rr.set_defaults(func=c.cmd_ros_replay)
    dr = sub.add_parser("doctor", help="check that this installation can run the compiled "
                        "physics: versions, native symbols, the internals relied on (one line "
                        "per failure, exit 1)")
    dr.set_defaults(func=c.cmd_doctor)

    wu = sub.add_parser("warmup", help="compile (or load from numba's cache) every kernel, "
                        "rare paths included, so that no decision compiles (make install "
                        "runs it)")
    wu.add_argument("--quiet", action="store_true", help="no line per warm-up step")
    wu.set_defaults(func=c.cmd_warmup)
    _mark_leaves(p)
    return p


def _mark_leaves(parser: argparse.ArgumentParser) -> None:
    """Every subcommand's parser knows itself (``_parser``), so that an unrecognised option
    is reported by the subcommand it was given to, with its closest option."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                sub.set_defaults(_parser=sub)
                _mark_leaves(sub)


def unrecognized(parser: argparse.ArgumentParser, extra: list[str]) -> str:
    """The usage error of arguments ``parser`` does not know, naming the closest option of
    the first unknown one."""
    options = [o for a in parser._actions for o in a.option_strings]
    first = next((x.split("=", 1)[0] for x in extra if x.startswith("-")), "")
    return f"unrecognized arguments: {' '.join(extra)}{did_you_mean(first, options)}"


def console_main() -> int:
    """The ``pathpref`` command: :func:`main`; a process left holding a failed rerun recording
    (:func:`pathpref.viz.rerun_log.holds_failed`: a full disk) then ends at once, its output
    flushed, since rerun's destructor of that stream would wait on the file without end."""
    rc = main()
    recordings = sys.modules.get("pathpref.viz.rerun_log")
    if recordings is not None and recordings.holds_failed():
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(rc)
    return rc


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; a :class:`PathprefError` becomes one line and exit status 2."""
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra:
        leaf = getattr(args, "_parser", parser)
        leaf.error(unrecognized(leaf, extra))
    try:
        check_switches()  # a PATHPREF_* switch of another value: one line, before any work
        return int(args.func(args) or 0)
    except PathprefError as e:  # one line, whatever text a library put in the message
        text = " ".join(" ".join(part.split()) for part in str(e).splitlines() if part.strip())
        print(f"pathpref: error: {text}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("pathpref: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # e.g. `pathpref report db | head`
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except (OSError, sqlite3.Error) as e:  # a full disk while writing: one line
        if not is_disk_full(e):
            raise
        print(f"pathpref: error: {write_error(getattr(e, 'filename', None) or 'output', e)}",
              file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
