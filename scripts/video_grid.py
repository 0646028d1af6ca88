"""The README's frame grid (docs/video_grid.png): render the tour's episode at 960 x 540 with
``pathpref render`` and lay six frames out 3 x 2 (two early frames, four moments spread over the
rest, the last one the outcome card).

The episode is the tour's (:func:`pathpref.apps.demo.tour_seed`), filmed on the Stanford
TidyBot (``--robot-model tidybot``; ``--robot-model disk`` films the cylinder): path
preference on ``simple`` with the demo's corrective human, at the first ``--seed`` whose
preferred route the demo's film rule accepts (at least 8 steps, 2 polytope crossings and 10
spare steps; the route only, never an outcome). The script prints the seed, the command and
the episode's outcome.

    MUJOCO_GL=egl python scripts/video_grid.py --out docs/video_grid.png
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

import imageio.v2 as iio  # noqa: E402
import numpy as np  # noqa: E402

from pathpref.apps.demo import (  # noqa: E402
    DEMO_DELTA_T,
    DEMO_MAP,
    DEMO_PUSH_RULE,
    FILM_METHOD,
    tour_seed,  # noqa: E402
)
from pathpref.viz.video import frame_grid  # noqa: E402


def main() -> None:
    """Render, pick six frames, write the grid."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="docs/video_grid.png", help="grid image (.png)")
    ap.add_argument("--robot-model", default="tidybot", choices=("tidybot", "disk"),
                    help="the body filmed (default: the Stanford TidyBot)")
    args = ap.parse_args()
    seed = tour_seed()
    with tempfile.TemporaryDirectory() as tmp:
        video = Path(tmp) / "v.mp4"
        cmd = ["render", "--map", DEMO_MAP, "--method", FILM_METHOD, "--delta-t",
               str(DEMO_DELTA_T), "--push-rule", DEMO_PUSH_RULE, "--seed", str(seed),
               "--robot-model", args.robot_model]
        print("pathpref " + " ".join(f"'{a}'" if " " in a else a for a in cmd))
        subprocess.run([sys.executable, "-m", "pathpref", *cmd, "--out", str(video),
                        "--no-progress"], check=True)
        reader = iio.get_reader(str(video))
        n = reader.count_frames()
        picks = [4, 20, *(int(i) for i in np.linspace(40, n - 1, 4))]
        frames = [reader.get_data(int(i)) for i in picks]
        reader.close()
    iio.imwrite(args.out, frame_grid(frames, cols=3, scale=0.5))
    print(f"wrote {args.out} from {n} frames: {picks} (seed {seed})")


if __name__ == "__main__":
    main()
