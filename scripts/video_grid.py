"""The README's frame grid (docs/video_grid.png): render one episode at 960 x 540 with
``pathpref render`` and lay six frames out 3 x 2 (the first push, the detected cue, four
moments spread over the rest).

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

from pathpref.viz.video import frame_grid  # noqa: E402


def main() -> None:
    """Render, pick six frames, write the grid."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="docs/video_grid.png", help="grid image (.png)")
    ap.add_argument("--seed", type=int, default=1, help="episode seed")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        video = Path(tmp) / "v.mp4"
        subprocess.run([sys.executable, "-m", "pathpref", "render", "--map", "simple",
                        "--method", "path_preference", "--delta-t", "2", "--seed",
                        str(args.seed), "--out", str(video), "--no-progress"], check=True)
        reader = iio.get_reader(str(video))
        n = reader.count_frames()
        picks = [4, 20, *np.linspace(40, n - 1, 4).astype(int)]
        frames = [reader.get_data(int(i)) for i in picks]
        reader.close()
    iio.imwrite(args.out, frame_grid(frames, cols=3, scale=0.5))
    print(f"wrote {args.out} from {n} frames: {picks}")


if __name__ == "__main__":
    main()
