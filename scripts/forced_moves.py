"""What one decision was worth: the episode's outcome with each first move forced, over the
human's future noise.

    .venv/bin/python scripts/forced_moves.py --map classroom --delta-t 1 --instance 0 --run 1 \\
        --step 1 --moves N E S --futures 20

Runs the episode (robust preset, consistent human, the spec of ``pathpref evaluate --seed 0``)
up to decision ``--step``, then, from copies of that state, plays the episode to its end with
the decision's move forced to each of ``--moves`` (and once with the policy's own choice),
each time with ``--futures`` different draws of the human's later pushes (the human's
generator reseeded; everything else as in the episode). Prints strict and homotopy-level
successes per move. A move that crosses a face the human does not prefer scores 0 strict
whatever follows; the point is how the policy's move compares with the moves it passed over.
"""

from __future__ import annotations

import argparse
import copy
import os

os.environ.setdefault("MUJOCO_GL", "disable")

import numpy as np  # noqa: E402

from pathpref.episode import EpisodeSpec  # noqa: E402
from pathpref.episode.runner import EpisodeRunner  # noqa: E402

MOVES = ("N", "NE", "E", "SE", "S", "SW", "W", "NW")


def play(state: EpisodeRunner, move: int | None, future: int) -> tuple[bool, bool]:
    """Strict and homotopy-level success from a copy of ``state`` with the next decision's
    move forced to ``move`` (None: the policy's) and the human's generator reseeded."""
    run = copy.deepcopy(state)
    run.human_rng = np.random.default_rng(10_000 + future)
    if move is not None:
        act, first = run.policy.act, [True]

        def forced(t: int, cell: int, heading: int | None) -> int:
            chosen = act(t, cell, heading)  # the policy's own bookkeeping runs as usual
            if first[0]:
                first[0] = False
                return move
            return chosen

        run.policy.act = forced
    while not run.done:  # bounded: T_max steps
        run.step()
    return bool(run.result.success), bool(run.result.homotopy_success)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--map", default="classroom")
    ap.add_argument("--delta-t", type=int, default=1)
    ap.add_argument("--instance", type=int, default=0)
    ap.add_argument("--run", type=int, default=1)
    ap.add_argument("--step", type=int, default=1, help="the decision (steps taken before it)")
    ap.add_argument("--moves", nargs="+", default=["N", "E", "S"], choices=MOVES)
    ap.add_argument("--futures", type=int, default=20)
    args = ap.parse_args(argv)
    spec = EpisodeSpec.single(args.map, "path_preference", args.delta_t, seed=0,
                              instance=args.instance, run=args.run, human="consistent",
                              preset="robust")
    run = EpisodeRunner(spec)
    while run.t < args.step and not run.done:
        run.step()
    print(f"decision {run.t} at cell {run.world.cells[run.cell].tolist()}")
    for name in [*args.moves, None]:
        move = None if name is None else MOVES.index(name)
        outcomes = [play(run, move, k) for k in range(args.futures)]
        strict = sum(s for s, _ in outcomes)
        homotopy = sum(h for _, h in outcomes)
        label = "policy" if name is None else name
        print(f"{label:>6}: strict {strict} / {args.futures}, homotopy-level {homotopy} / "
              f"{args.futures}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
