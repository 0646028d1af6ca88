"""Rendering rollouts headlessly (EGL by default; ``MUJOCO_GL`` is set to ``egl`` when unset).

Each video frame shows two views side by side, top-down and perspective, with overlays drawn as
extra geoms in the MuJoCo scene: goal candidates as discs tinted by the robot's belief (grey =
unlikely, green = likely; the true goal ringed in pink), the human's push as an arrow from the
handle (1 m per 30 N), and the outline of the polytope the robot is in.
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

from ..errors import ConfigError
from . import GL_HELP
from .scene import Scene


def make_renderer(model: mujoco.MjModel, height: int, width: int) -> mujoco.Renderer:
    """A renderer, or a ConfigError that names the missing system packages."""
    import os

    if not (16 <= height <= 2160 and 16 <= width <= 3840):
        raise ConfigError(f"frame size {width}x{height} is out of range (16..3840 x 16..2160)")
    try:
        return mujoco.Renderer(model, height=height, width=width)
    except Exception as e:  # noqa: BLE001 - GL errors come as several types
        raise ConfigError(GL_HELP.format(gl=os.environ.get("MUJOCO_GL", "")) + f" ({e})") from None


def _add_geom(scn: mujoco.MjvScene, gtype, size, pos, rgba, mat=None) -> int:
    if scn.ngeom >= scn.maxgeom:
        return -1
    g = scn.geoms[scn.ngeom]
    mujoco.mjv_initGeom(g, gtype, np.asarray(size, float), np.asarray(pos, float),
                        np.eye(3).ravel() if mat is None else np.asarray(mat, float).ravel(),
                        np.asarray(rgba, np.float32))
    scn.ngeom += 1
    return scn.ngeom - 1


def _add_line(scn, a, b, width, rgba, gtype=mujoco.mjtGeom.mjGEOM_CAPSULE) -> None:
    i = _add_geom(scn, gtype, [0, 0, 0], [0, 0, 0], rgba)
    if i >= 0:
        mujoco.mjv_connector(scn.geoms[i], gtype, width, np.asarray(a, float), np.asarray(b, float))


class RolloutRenderer:
    """Renders frames of a :class:`Scene` with the overlays of the module docstring."""

    def __init__(self, scene: Scene, width: int = 480, height: int = 360):
        self.scene = scene
        self.renderer = make_renderer(scene.model, height, width)
        self.opt = mujoco.MjvOption()

    def overlays(self, goal_cells: np.ndarray, belief: np.ndarray, true_goal: int,
                 polygon: np.ndarray | None, push_origin: np.ndarray | None,
                 push_force: np.ndarray | None, route: np.ndarray | None = None) -> None:
        """Draw the goals (tinted by belief), the current polytope, the push arrow and, when
        given, a route to convey (cells ``(x, y)``, an orange line through their centres)."""
        scn = self.renderer.scene
        cs = self.scene.cell_size
        if route is not None:
            pts = (np.asarray(route, float) - 0.5) * cs
            for a, b in zip(pts[:-1], pts[1:], strict=True):
                _add_line(scn, [a[0], a[1], 0.015], [b[0], b[1], 0.015], 0.03,
                          [0.94, 0.55, 0.08, 0.9])
        pmax = max(float(belief.max()), 1e-9)
        for k, c in enumerate(goal_cells):
            xy = (np.asarray(c) - 0.5) * cs
            a = float(belief[k]) / pmax
            rgba = [0.6 * (1 - a) + 0.1 * a, 0.6 * (1 - a) + 0.8 * a, 0.6 * (1 - a) + 0.2 * a, 0.9]
            _add_geom(scn, mujoco.mjtGeom.mjGEOM_CYLINDER, [0.18 * cs, 0.005, 0],
                      [xy[0], xy[1], 0.01], rgba)
            if k == true_goal:
                _add_geom(scn, mujoco.mjtGeom.mjGEOM_CYLINDER, [0.24 * cs, 0.003, 0],
                          [xy[0], xy[1], 0.005], [1.0, 0.3, 0.7, 0.9])
        if polygon is not None and len(polygon) >= 3:
            pts = np.asarray(polygon) * cs
            for a, b in zip(pts, np.roll(pts, -1, axis=0), strict=True):
                _add_line(scn, [a[0], a[1], 0.02], [b[0], b[1], 0.02], 0.015,
                          [1.0, 0.85, 0.1, 0.9])
        if push_origin is not None and push_force is not None:
            f = np.asarray(push_force, float)
            n = np.linalg.norm(f[:2])
            if n > 0.5:
                tip = np.asarray(push_origin, float) + np.array([*f[:2] / 30.0 * 1.0, 0.0])
                _add_line(scn, push_origin, tip, 0.05, [0.9, 0.1, 0.1, 1.0],
                          gtype=mujoco.mjtGeom.mjGEOM_ARROW)

    def frame(self, data: mujoco.MjData, **overlay) -> np.ndarray:
        """One RGB frame (H x 2W x 3): top-down view | perspective view."""
        views = []
        for cam in ("top", "perspective"):
            self.renderer.update_scene(data, camera=cam, scene_option=self.opt)
            self.overlays(**overlay)
            views.append(self.renderer.render())
        return np.concatenate(views, axis=1)

    def close(self) -> None:
        """Release the renderer's GL context."""
        self.renderer.close()


def write_video(frames: list[np.ndarray], out: str | Path, fps: int = 25) -> Path:
    """Encode frames as H.264 MP4 (imageio-ffmpeg); refuses a blank video."""
    import imageio.v2 as imageio

    if not frames:
        raise ConfigError("no frames were rendered")
    if all(float(np.asarray(f).std()) < 1.0 for f in frames[:: max(1, len(frames) // 10)]):
        raise ConfigError("rendered frames are blank: the GL backend produced no image; "
                          + GL_HELP.format(gl="egl"))
    with imageio.get_writer(str(out), fps=fps, codec="libx264", quality=7,
                            macro_block_size=8, format="FFMPEG") as w:
        for f in frames:
            w.append_data(np.ascontiguousarray(f))
    return Path(out)
