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


def atomic_output(out: str | Path, write: Callable[[Path], object]) -> Path:
    """Call ``write(tmp_path)`` and move the result onto ``out``; nothing is left on failure."""
    out = Path(out)
    parent = out.parent if str(out.parent) else Path(".")
    if not parent.is_dir():
        raise ConfigError(f"cannot write {out}: folder {parent} does not exist")
    if not os.access(parent, os.W_OK):
        raise ConfigError(f"cannot write {out}: folder {parent} is not writable")
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
    from .geometry.world import load_world

    world = load_world(args.map)
    deg = [len(n) for n in world.graph.neighbors]
    info = {
        "name": world.name,
        "width": world.spec.width,
        "height": world.spec.height,
        "obstacles": len(world.spec.obstacles),
        "hyperplanes": len(world.arrangement.normals),
        "polytopes": world.n_polytopes,
        "edges": world.graph.n_edges,
        "free_cells": world.n_cells,
        "max_degree": max(deg, default=0),
        "has_preference": world.preference is not None,
    }
    if args.json:
        print(json.dumps(info))
    else:
        for k, v in info.items():
            print(f"{k:>15}: {v}")
    return 0


def cmd_map_draw(args: argparse.Namespace) -> int:
    from .geometry.world import load_world
    from .viz.mapdraw import save_map_figure

    world = load_world(args.map)
    out = Path(args.out)
    if out.suffix.lower() not in (".png", ".pdf", ".svg"):
        raise ConfigError(f"--out {out}: use a .png, .pdf or .svg file name")
    atomic_output(out, lambda p: save_map_figure(world, p))
    print(f"wrote {out}")
    return 0


# --- bench / demo ---------------------------------------------------------------------------
def cmd_bench(args: argparse.Namespace) -> int:
    from .benchmarks import run_benchmarks

    result = run_benchmarks(maps=args.maps, quick=args.quick)
    if args.json:
        print(json.dumps(result))
    else:
        print(json.dumps(result, indent=2))
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    from .demo import run_demo

    run_demo(out=Path(args.out), seed=args.seed)
    return 0


# --- parser ---------------------------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="pathpref",
        description="Infer a person's goal and path preference from sparse nudges "
        "(Peltzer et al. 2023).",
    )
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

    b = sub.add_parser("bench", help="measure build, update and planning times")
    b.add_argument("--json", action="store_true", help="print one JSON object")
    b.add_argument("--maps", nargs="+", default=["simple", "office", "classroom"])
    b.add_argument("--quick", action="store_true", help="fewer repetitions (smoke test)")
    b.set_defaults(func=cmd_bench)

    d = sub.add_parser("demo", help="the main job: run the demo and write its outputs")
    d.add_argument("--out", default="out", help="output folder (default: out)")
    d.add_argument("--seed", type=int, default=0)
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


if __name__ == "__main__":
    sys.exit(main())
