"""From a new map to a table of success rates and a video, with pathpref's public API.

    MUJOCO_GL=egl python examples/tutorial.py --out tutorial_out          # 29 s of CPU
    MUJOCO_GL=egl python examples/tutorial.py --out /tmp/t --tiny         # seconds (the test)

1. Draw a map: a 10 x 10 room with a table in the middle; the person prefers to walk around
   it clockwise (a drawn route, turned into preferred transitions between polytopes).
2. Look at it: polytopes, graph and preference arrows (``map.png``).
3. Infer by hand: three nudges toward the north-west update the belief over goal candidates.
4. Run a small sweep of the paper's four methods into a results database and print the table
   of success rates with 95% intervals (``results.sqlite``, ``table.md``).
5. Render one MuJoCo episode of the path-preference method: a video and a rerun recording.

One planner preset throughout, the sweep and the video alike: ``--preset`` (default: the
planner's default, ``pathpref.planning.pomdp.DEFAULT_PRESET``), printed on the first line.
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402

import pathpref as pp  # noqa: E402
from pathpref.planning.pomdp import DEFAULT_PRESET, PRESETS  # noqa: E402

ROOM = {
    "name": "tutorial_room",
    "description": "10 x 10 room, a table in the middle; walk around it clockwise",
    "width": 10, "height": 10,
    "obstacles": [{"cells": {"lower_left": [4, 4], "size": [3, 3]}},
                  {"vertices": [[8.0, 1.5], [9.5, 1.5], [9.5, 2.5], [8.0, 2.5]]}],
    "preference": {"route": [[2, 2], [2, 8], [8, 8], [8, 4]], "closed": False},
    "goal_band": {"x": [1, 10], "y": [7, 10]},
}


def main() -> None:
    """Run the tutorial's five steps (module docstring)."""
    ap = argparse.ArgumentParser(description="pathpref tutorial: map -> table -> video")
    ap.add_argument("--out", default="tutorial_out", help="output folder")
    ap.add_argument("--tiny", action="store_true", help="tiny sizes (seconds; for the test)")
    ap.add_argument("--preset", default=DEFAULT_PRESET, choices=sorted(PRESETS),
                    help="the planner's preset, for the sweep and the video (default: "
                    "%(default)s)")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    print(f"pathpref tutorial: preset {args.preset} for every episode (sweep and video)")

    # 1. the map, as a file (a dict works too: pp.load_world(ROOM))
    map_path = out / "room.json"
    map_path.write_text(json.dumps(ROOM, indent=1))
    world = pp.load_world(map_path)
    print(f"{ROOM['name']}: {world.n_polytopes} polytopes, {len(world.graph.edges)} edges")

    # 2. draw it
    from pathpref.viz.mapdraw import save_map_figure

    save_map_figure(world, out / "map.png")

    # 3. a belief over two goal candidates, updated by three nudges toward the north-west
    goals = np.array([world.cell((2, 9)), world.cell((9, 9))])
    belief = pp.PreferenceBelief(pp.ObservationModel.build(world, goals))
    start = world.cell((5, 2))
    for _ in range(3):
        belief.update(start, 7)  # heading 7 = NW
    p = belief.goal_marginal()
    print(f"after three NW nudges at (5, 2): P(goal (2, 9)) = {p[0]:.2f}, "
          f"P(goal (9, 9)) = {p[1]:.2f}")

    # 4. a sweep of the paper's four methods and its table
    instances, runs, queries = (1, 2, 100) if args.tiny else (4, 10, 2000)
    db = out / "results.sqlite"
    specs = pp.sweep_specs(str(map_path), ["all"], [1, 5], instances, runs, seed=0,
                           queries=queries, preset=args.preset)
    counts = pp.run_sweep(specs, str(db), workers=1, progress=False)
    table = pp.markdown_tables(pp.load_records(str(db)), with_paper=False)
    (out / "table.md").write_text(table)
    print(f"{counts['ran']} episodes run (preset {args.preset})\n{table}")

    # 5. one MuJoCo episode as a video and a rerun file
    from pathpref.apps.rollout import record_rollout

    spec = pp.EpisodeSpec.single(str(map_path), "path_preference", 3, seed=0, sim="mujoco",
                                 queries=queries, t_max=4 if args.tiny else 30,
                                 preset=args.preset)
    size = (320, 180) if args.tiny else (960, 540)
    rec = record_rollout(spec, video=out / "episode.mp4", rerun=out / "episode.rrd",
                         width=size[0], height=size[1])
    print(f"episode (preset {rec.result.spec.preset}): goal reached "
          f"{rec.result.goal_reached}, {rec.result.steps} steps, "
          f"{rec.frames} frames -> {out / 'episode.mp4'}, {out / 'episode.rrd'}")


if __name__ == "__main__":
    main()
