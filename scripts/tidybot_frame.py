"""Render the Stanford TidyBot carrying the tray (``pathpref.sim.tidybot``) mid-push: a 30 N
push on the tray toward +y, 1 s in, the frame written as ``docs/tidybot_frame.png``.

    MUJOCO_GL=egl python scripts/tidybot_frame.py [--out OUT.png]
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco  # noqa: E402
import numpy as np  # noqa: E402
from PIL import Image  # noqa: E402

from pathpref.sim.tidybot import WholeBody, build_tidybot  # noqa: E402


def main(out: str = "docs/tidybot_frame.png") -> None:
    model = build_tidybot()
    model.vis.global_.offwidth, model.vis.global_.offheight = 960, 720
    wb = WholeBody(model)
    wb.reset()
    wb.aim(np.array([0.3, 0.0, 0.0]))  # a far target: the base helps (whole-body IK)
    for _ in range(int(1.0 / wb.dt)):
        wb.data.xfrc_applied[wb.body, :3] = (0.0, 30.0, 0.0)
        wb.step()
    cam = mujoco.MjvCamera()
    cam.lookat[:] = (wb.base_xy[0] + 0.25, wb.base_xy[1], 0.45)
    cam.distance, cam.azimuth, cam.elevation = 2.0, 135.0, -32.0
    with mujoco.Renderer(model, 720, 960) as r:
        r.update_scene(wb.data, cam)
        Image.fromarray(r.render()).save(out)
    print(out)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="docs/tidybot_frame.png", help="the PNG to write")
    main(ap.parse_args().out)
