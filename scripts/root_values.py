"""The robust search's root values at one decision of a recorded episode, at several query
counts: are the moves told apart, or is the choice noise?

    .venv/bin/python scripts/root_values.py --map classroom --instance 1 --run 0 \\
        --delta-t 5 --step 23 --queries 5000 50000 300000

Runs the episode (robust preset, consistent human unless ``--human map``, the spec of
``pathpref evaluate --seed 0``) up to decision ``--step``, then searches again from that
decision's state (the same belief, history and expected pushes) with each query count, and
prints per root move its visits, its mean return and the polytope it leads to. The
episode's own decision is printed first.
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("MUJOCO_GL", "disable")

import numpy as np  # noqa: E402

from pathpref.episode import EpisodeSpec, cached_world  # noqa: E402
from pathpref.episode.runner import run_episode  # noqa: E402
from pathpref.planning import policies  # noqa: E402

MOVES = ("N", "NE", "E", "SE", "S", "SW", "W", "NW")


class _Stop(Exception):
    """Raised once the decision of interest has been searched."""


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--map", default="classroom")
    ap.add_argument("--instance", type=int, default=1)
    ap.add_argument("--run", type=int, default=0)
    ap.add_argument("--delta-t", type=int, default=5)
    ap.add_argument("--step", type=int, default=23)
    ap.add_argument("--method", default="path_preference")
    ap.add_argument("--human", default="consistent", choices=["map", "consistent"])
    ap.add_argument("--queries", type=int, nargs="+", default=[5000, 50000, 300000])
    args = ap.parse_args(argv)
    world = cached_world(args.map)
    act = policies.PlannerPolicy.act

    def traced(self, t, cell, heading):
        a = act(self, t, cell, heading)
        if t != args.step:
            return a
        v = int(world.cell_polytope[cell])
        print(f"t = {t}, cell {world.cells[cell].tolist()}, polytope {v}; the episode chose "
              f"{MOVES[a]}; P(true goal) = {self.belief.goal_marginal()[self.ctx.true_goal]:.2f}")
        depth = self.ctx.t_max - t + 1
        for q in args.queries:
            self.planner.queries = q
            res = self.planner.search(cell, self.belief, depth, 123, self.history,
                                      self.expected_pushes(t))
            print(f"  {q} queries: chooses {MOVES[res.action]} (ties within one standard "
                  "error broken by the rollout heuristic)")
            for b in range(8):
                to = int(world.motion.next_cell[cell, b])
                print(f"    {MOVES[b]:>2} -> polytope {int(world.cell_polytope[to]):3d}: "
                      f"visits {res.visits[b]:7d}, value {res.values[b]:.3f}")
        raise _Stop

    policies.PlannerPolicy.act = traced
    spec = EpisodeSpec.single(args.map, args.method, args.delta_t, seed=0,
                              instance=args.instance, run=args.run, preset="robust",
                              human=args.human, t_max=world.spec.t_max)
    try:
        run_episode(spec)
    except _Stop:
        return 0
    finally:
        policies.PlannerPolicy.act = act
    print(f"the episode ended before step {args.step}")
    return 1


if __name__ == "__main__":
    np.set_printoptions(precision=3)
    raise SystemExit(main())
