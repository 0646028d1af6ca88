"""When the back-crossings in a results database happen: per method and ΔT, the moves straight
back through the face just crossed, split into the robot's move on the step of a push (its
answer to the human's input, observed just before the move), its moves one or two steps after
a push, and the rest (no push in the last two steps).

    .venv/bin/python scripts/back_crossings.py results/atrium_robust.sqlite \\
        --map examples/maps/atrium.json --method path_preference

Reads the stored per-step log (cell after each step and the heading observed on it) and the
episode's start cell, so the counts equal the ``back_crossings`` column.
"""

from __future__ import annotations

import argparse
import json
import os
import sqlite3
import sys
from collections import defaultdict

os.environ.setdefault("MUJOCO_GL", "disable")

from pathpref.episode import cached_world  # noqa: E402

AFTER = 2  # steps after a push within which a move counts as "after a push"


def split(world, start, steps) -> tuple[int, int, int]:
    """``(on a push's step, 1..AFTER steps after a push, other)`` for one episode's ``steps``
    (rows ``(t, x, y, heading)``, ``heading`` the input observed before step ``t``'s move)
    from cell ``start``."""
    poly = world.cell_polytope
    prev = int(poly[start])
    last = None
    last_push = -10**9
    out = [0, 0, 0]
    for t, x, y, heading in steps:
        p = int(poly[world.cell((x, y))])
        if p != prev:
            if last == (p, prev):
                out[0 if heading >= 0 else 1 if t - last_push <= AFTER else 2] += 1
            last = (prev, p)
        prev = p
        if heading >= 0:
            last_push = t
    return out[0], out[1], out[2]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("db")
    ap.add_argument("--map", required=True, help="the map the database was run on")
    ap.add_argument("--method", default=None, help="one method (default: all)")
    args = ap.parse_args(argv)
    world = cached_world(args.map)
    con = sqlite3.connect(f"file:{args.db}?mode=ro", uri=True)
    sums: dict[tuple[str, int], list[int]] = defaultdict(lambda: [0, 0, 0, 0, 0])
    try:
        q = "SELECT key, method, delta_t, start, back_crossings FROM episodes WHERE status='ok'"
        for key, method, dt, start, stored in con.execute(q).fetchall():
            if args.method and method != args.method:
                continue
            steps = con.execute("SELECT t, x, y, heading FROM steps WHERE key = ? ORDER BY t",
                                (key,)).fetchall()
            by_push, after, other = split(world, world.cell(tuple(json.loads(start))), steps)
            if by_push + after + other != stored:
                raise SystemExit(f"{key}: counted {by_push + after + other} back-crossings, "
                                 f"the database says {stored}")
            s = sums[(method, dt)]
            s[0] += 1
            s[1] += by_push
            s[2] += after
            s[3] += other
    finally:
        con.close()
    print("| method | ΔT | episodes | back-crossings | on a push's step | 1-2 steps after one "
          "| other |")
    print("|---|---|---|---|---|---|---|")
    for (method, dt), (n, a, b, c, _) in sorted(sums.items()):
        print(f"| {method} | {dt} | {n} | {a + b + c} | {a} | {b} | {c} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
