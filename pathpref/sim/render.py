"""Rendering rollouts headlessly (EGL by default; ``MUJOCO_GL`` is set to ``egl`` when unset).

:class:`RolloutRenderer` renders the two 3-D views of a video frame, top-down (square) and
perspective, with overlays drawn as extra geoms in the MuJoCo scene from an :class:`Overlay`:
every polytope outlined (the robot's current one thick, yellow), the human's preferred
transitions as dark grey arrows, goal candidates as discs in the colours the caller gives (the
video tints them by absolute probability) with the true goal ringed in pink, a blue ring on the
robot and its trail, the human's push as a red arrow into the pushed body (1 m per 30 N) and the
detected cue as a green arrow from the robot. The caller (``pathpref render``) composes the
views with the text and chart panel of :mod:`pathpref.viz.video`.

**Every push, whatever its timing.** :class:`PushTrace` follows the force the simulation
applies to the pushed body (``xfrc_applied``: the renderer shows the truth, the robot never
reads it), so a push is drawn whether it came with the decision step's push phase or at any
time (pushes while driving, several at once, the viewer's perturbation).

**Close-up.** In a scene with the carry arm (a body ``tool/tray``) or the TidyBot (a body
``tidybot/base_link``) the perspective view carries an inset (:data:`CLOSEUP_SHARE` of its
height, bottom right) from a camera that follows that body (:data:`CLOSEUP`: how far away, and
how far below the body it aims, and how steeply it looks down), with the overlays, so the tray's
yield under a push, or the robot a person pushes, is visible.
"""

from __future__ import annotations

import errno
import os
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from ..errors import ConfigError
from . import GL_HELP
from .scene import Scene

PUSH_M_PER_N = 1.0 / 30.0  # arrow length per newton of push
CUE_ARROW_M = 0.8  # length of the detected cue's arrow
#: the scene's lights brighten a horizontal matte surface seen from above by 1.65x
#: (measured: rgb (71, 41, 120) renders as (119, 69, 198)); overlay colours meant as given
#: are scaled by its inverse
UNLIT = 1.0 / 1.65
#: a push is drawn while the applied horizontal force exceeds this (N)
PUSH_SHOWN_N = 0.5
#: the close-up: share of the perspective view's height
CLOSEUP_SHARE = 0.6
#: the bodies a close-up follows, the first the model has: camera distance (m), how far below
#: the body it aims (m; the tray's arm under it in the picture, the TidyBot's arm above its
#: base) and its elevation (degrees; steep enough for the TidyBot's that the horizon stays out)
CLOSEUP = {"tool/tray": (1.4, 0.25, -20.0), "tidybot/base_link": (2.6, -0.45, -35.0)}


def applied_push(data: mujoco.MjData, body: int) -> np.ndarray:
    """The force the simulation applies to ``body`` at this step (N, world frame, 3-D with
    z = 0): the pushes' sum, from ``xfrc_applied``."""
    f = np.zeros(3)
    f[:2] = data.xfrc_applied[body, :2]
    return f


class PushTrace:
    """The push to draw (module docstring): a push begins when the applied horizontal force
    rises above :data:`PUSH_SHOWN_N`; it is drawn with the force acting now while it acts,
    then with its peak (faded) until ``hold_s`` after it began."""

    def __init__(self, hold_s: float):
        self.hold_s = float(hold_s)
        self.t0: float | None = None
        self.peak = np.zeros(3)
        self.now = np.zeros(3)
        self.acting = False

    def update(self, t: float, force: np.ndarray) -> None:
        """One physics step's applied force (``applied_push``) at time ``t``."""
        f = np.asarray(force, float)
        n = float(np.hypot(f[0], f[1]))
        acting = n > PUSH_SHOWN_N
        if acting and not self.acting:
            self.t0, self.peak = float(t), f.copy()
        elif acting and n > float(np.hypot(self.peak[0], self.peak[1])):
            self.peak = f.copy()
        self.acting, self.now = acting, f.copy()

    def shown(self, t: float) -> tuple[np.ndarray, float] | None:
        """The force to draw at ``t`` and its alpha (1 while acting, 0.7 after), or None."""
        if self.acting:
            return self.now, 1.0
        if self.t0 is not None and t - self.t0 <= self.hold_s:
            return self.peak, 0.7
        return None


@dataclass
class Overlay:
    """What a frame shows besides the physics (map units: grid cells; vectors: world)."""

    goal_cells: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    goal_rgba: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    true_goal: int = -1
    #: every polytope's outline (grid units) and the index of the robot's (-1: none)
    polygons: list = field(default_factory=list)
    current: int = -1
    #: preferred transitions as (from, to) points in grid units
    preference: list = field(default_factory=list)
    #: the base's past positions (m)
    trail: np.ndarray | None = None
    robot_xy: np.ndarray | None = None
    #: the push: origin (m, 3-D) and force (N, 3-D); the detected cue: origin and direction
    push_origin: np.ndarray | None = None
    push_force: np.ndarray | None = None
    push_alpha: float = 1.0
    cue_origin: np.ndarray | None = None
    cue_direction: np.ndarray | None = None
    cue_alpha: float = 1.0
    #: a route to convey (a study trial's): cells ``(x, y)``, an orange line through their centres
    route: np.ndarray | None = None


def make_renderer(model: mujoco.MjModel, height: int, width: int) -> mujoco.Renderer:
    """A renderer, or a ConfigError that names the missing system packages."""
    import os

    if not (16 <= height <= 2160 and 16 <= width <= 3840):
        raise ConfigError(f"frame size {width}x{height} is out of range (16..3840 x 16..2160)")
    try:
        return mujoco.Renderer(model, height=height, width=width)
    except Exception as e:  # noqa: BLE001 - GL errors come as several types
        raise ConfigError(GL_HELP.format(gl=os.environ.get("MUJOCO_GL", "")) + f" ({e})") from None


_EYE = np.eye(3).ravel()  # an overlay geom's orientation (read by MuJoCo, never written)


def _add_geom(scn: mujoco.MjvScene, gtype, size, pos, rgba, mat=None,
              emission: float = 0.0) -> int:
    """Append a geom to ``scn`` (``emission`` 1: its own colour, unshaded); -1 when full."""
    if scn.ngeom >= scn.maxgeom:
        return -1
    g = scn.geoms[scn.ngeom]
    mujoco.mjv_initGeom(g, gtype, np.asarray(size, float), np.asarray(pos, float),
                        _EYE if mat is None else np.asarray(mat, float).ravel(),
                        np.asarray(rgba, np.float32))
    g.emission = emission
    scn.ngeom += 1
    return scn.ngeom - 1


def _add_line(scn, a, b, width, rgba, gtype=mujoco.mjtGeom.mjGEOM_CAPSULE) -> None:
    """A capsule, line or arrow from ``a`` to ``b`` (an arrow's head at ``b``)."""
    i = _add_geom(scn, gtype, [0, 0, 0], [0, 0, 0], rgba)
    if i >= 0:
        a, b = np.asarray(a, float), np.asarray(b, float)
        if gtype == mujoco.mjtGeom.mjGEOM_ARROW:
            # MuJoCo draws an arrow of size[2] = |b - a| half as long (measured: a 1 m arrow
            # covers 0.53 m of the top view), so it is given twice the length
            b = a + 2.0 * (b - a)
        mujoco.mjv_connector(scn.geoms[i], gtype, width, a, b)


class RolloutRenderer:
    """Renders the views of a video frame of ``width`` x ``height`` pixels: the top view is
    ``height`` square on the left, the perspective view fills the right column's top
    ``persp_share`` (the rest of the column is the caller's panel); a frame narrower than
    ``height * 1.2`` gets the top view only."""

    def __init__(self, scene: Scene, width: int = 960, height: int = 540,
                 persp_share: float = 0.5):
        self.scene = scene
        self.width, self.height = int(width), int(height)
        self.side = min(self.height, self.width)
        self.column = self.width - self.side
        self.persp_h = max(16, int(round(self.height * persp_share)))
        vis = scene.model.vis  # visual settings only; the physics is untouched
        vis.global_.offwidth = max(vis.global_.offwidth, self.width)
        vis.global_.offheight = max(vis.global_.offheight, self.height)
        # for software GL (llvmpipe, what EGL gives on a machine without a GPU): coarser
        # tessellation of rounded geoms (2x the frame rate of MuJoCo's 28 x 16, no visible
        # difference at video sizes) and no multisampling (1.4x; the lines are drawn thick)
        vis.quality.numslices, vis.quality.numstacks = 12, 6
        vis.quality.offsamples = 0
        self.top = make_renderer(scene.model, self.side, self.side)
        self.persp = (make_renderer(scene.model, self.persp_h, self.column)
                      if self.column >= 16 else None)
        self.opt = mujoco.MjvOption()
        m = scene.model
        names = {m.body(i).name for i in range(m.nbody)}
        #: the body the close-up follows (-1: none) and how far below it it aims
        self.followed, self.closeup_drop = -1, 0.0
        self.closeup = None
        for name, (distance, drop, elevation) in CLOSEUP.items():
            if name in names and self.persp is not None:
                self.followed, self.closeup_drop = int(m.body(name).id), drop
                ch = max(16, int(round(self.persp_h * CLOSEUP_SHARE)))
                cw = max(16, min(self.column, int(round(ch * 4 / 3))))
                self.closeup = make_renderer(m, ch, cw)
                self.closeup_cam = mujoco.MjvCamera()
                self.closeup_cam.type = mujoco.mjtCamera.mjCAMERA_FREE
                self.closeup_cam.distance = distance
                self.closeup_cam.azimuth, self.closeup_cam.elevation = -60.0, elevation
                break

    def overlays(self, scn: mujoco.MjvScene, o: Overlay) -> None:
        """Add the overlay geoms of ``o`` to ``scn`` (module docstring)."""
        cs = self.scene.cell_size
        line = mujoco.mjtGeom.mjGEOM_LINE  # width in pixels; no lighting, cheap to draw
        px = max(1.0, self.side / 360)
        for k, poly in enumerate(o.polygons):
            if len(poly) < 3 or k == o.current:
                continue
            pts = np.asarray(poly) * cs
            for a, b in zip(pts, np.roll(pts, -1, axis=0), strict=True):
                _add_line(scn, [a[0], a[1], 0.012], [b[0], b[1], 0.012], px,
                          [0.3, 0.4, 0.65, 1.0], gtype=line)
        if 0 <= o.current < len(o.polygons) and len(o.polygons[o.current]) >= 3:
            pts = np.asarray(o.polygons[o.current]) * cs
            for a, b in zip(pts, np.roll(pts, -1, axis=0), strict=True):
                _add_line(scn, [a[0], a[1], 0.02], [b[0], b[1], 0.02], 3 * px,
                          [1.0, 0.8, 0.05, 1.0], gtype=line)
        if o.route is not None and len(o.route) >= 2:
            pts = (np.asarray(o.route, float) - 0.5) * cs
            for a, b in zip(pts[:-1], pts[1:], strict=True):
                _add_line(scn, [a[0], a[1], 0.015], [b[0], b[1], 0.015], 4 * px,
                          [0.94, 0.55, 0.08, 1.0], gtype=line)
        for a, b in o.preference:
            a3 = [a[0] * cs, a[1] * cs, 0.03]
            b3 = [b[0] * cs, b[1] * cs, 0.03]
            _add_line(scn, a3, b3, 0.035, [0.2, 0.2, 0.22, 1.0], gtype=mujoco.mjtGeom.mjGEOM_ARROW)
        for k, c in enumerate(o.goal_cells):
            xy = (np.asarray(c) - 0.5) * cs
            rgba = np.array(o.goal_rgba[k], float)
            rgba[:3] *= UNLIT  # shown in the colour given (the chart's), not brightened
            i = _add_geom(scn, mujoco.mjtGeom.mjGEOM_CYLINDER, [0.3 * cs, 0.006, 0],
                          [xy[0], xy[1], 0.012], rgba)
            if i >= 0:
                scn.geoms[i].specular = 0.0
            if k == o.true_goal:
                _add_geom(scn, mujoco.mjtGeom.mjGEOM_CYLINDER, [0.4 * cs, 0.004, 0],
                          [xy[0], xy[1], 0.006], [1.0, 0.3, 0.7, 1.0])
        if o.trail is not None and len(o.trail) >= 2:
            for a, b in zip(o.trail[:-1], o.trail[1:], strict=True):
                if np.hypot(*(b - a)) > 1e-3:
                    _add_line(scn, [a[0], a[1], 0.04], [b[0], b[1], 0.04], 2.5 * px,
                              [0.1, 0.4, 1.0, 1.0], gtype=line)
        if o.robot_xy is not None:
            _add_geom(scn, mujoco.mjtGeom.mjGEOM_CYLINDER, [0.55 * cs, 0.008, 0],
                      [o.robot_xy[0], o.robot_xy[1], 0.045], [0.1, 0.4, 1.0, 0.55])
        if o.push_origin is not None and o.push_force is not None:
            f = np.asarray(o.push_force, float)
            if np.linalg.norm(f[:2]) > 0.5:  # the arrow's tip at the pushed body, like a hand
                tip = np.asarray(o.push_origin, float)
                tail = tip - np.array([*f[:2] * PUSH_M_PER_N, 0.0])
                _add_line(scn, tail, tip, 0.06, [0.95, 0.1, 0.1, o.push_alpha],
                          gtype=mujoco.mjtGeom.mjGEOM_ARROW)
        if o.cue_origin is not None and o.cue_direction is not None:
            d = np.asarray(o.cue_direction, float)
            d = d / max(np.linalg.norm(d), 1e-9) * CUE_ARROW_M
            a = np.array([o.cue_origin[0], o.cue_origin[1], 0.5])
            _add_line(scn, a, a + np.array([d[0], d[1], 0.0]), 0.06,
                      [0.1, 0.85, 0.3, o.cue_alpha], gtype=mujoco.mjtGeom.mjGEOM_ARROW)

    def views(self, data: mujoco.MjData, overlay: Overlay) -> tuple[np.ndarray,
                                                                     np.ndarray | None]:
        """The top view (``height`` square) and the perspective view (None when the frame
        has no room for it), both with the overlays."""
        out = []
        for r, cam in ((self.top, "top"), (self.persp, "perspective")):
            if r is None:
                out.append(None)
                continue
            r.update_scene(data, camera=cam, scene_option=self.opt)
            r.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False  # a floor, not a mirror
            self.overlays(r.scene, overlay)
            out.append(r.render())
        if self.closeup is not None and out[1] is not None:
            out[1] = self._inset(out[1], self.closeup_view(data, overlay))
        return out[0], out[1]

    def closeup_view(self, data: mujoco.MjData, overlay: Overlay) -> np.ndarray:
        """The close-up (module docstring): a free camera looking at the followed body."""
        cam = self.closeup_cam
        cam.lookat[:] = data.xpos[self.followed] - np.array([0.0, 0.0, self.closeup_drop])
        r = self.closeup
        r.update_scene(data, camera=cam, scene_option=self.opt)
        r.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
        self.overlays(r.scene, overlay)
        return r.render()

    @staticmethod
    def _inset(view: np.ndarray, inset: np.ndarray, border: int = 2) -> np.ndarray:
        """``inset`` in ``view``'s bottom right corner with a white border (a copy)."""
        out = view.copy()
        h, w = min(inset.shape[0], out.shape[0]), min(inset.shape[1], out.shape[1])
        out[-h:, -w:] = 255
        out[-h + border:, -w + border:] = inset[border:h, border:w]
        return out

    def close(self) -> None:
        """Release the renderers' GL contexts."""
        for r in (self.top, self.persp, self.closeup):
            if r is not None:
                r.close()


#: a video whose folder has less free space than this when its encoder failed was stopped by a
#: full disk (ffmpeg's own error is not visible through imageio)
FULL_DISK_BYTES = 8 * 2**20


def free_bytes(folder: str | Path) -> int:
    """Bytes an unprivileged writer may still use in ``folder`` (``statvfs``)."""
    st = os.statvfs(folder)
    return st.f_bavail * st.f_frsize


def mp4_complete(path: str | Path) -> bool:
    """True when ``path`` is a whole MP4 file: its top-level boxes start with ``ftyp``, tile the
    file exactly and include ``moov`` (the index ffmpeg writes last; a file cut short by a full
    disk lacks it or ends inside a box)."""
    try:
        size = os.path.getsize(path)
        seen, pos = [], 0
        with open(path, "rb") as f:
            while pos < size:
                f.seek(pos)
                head = f.read(16)
                if len(head) < 8:
                    return False
                n, kind = int.from_bytes(head[:4], "big"), head[4:8]
                if n == 1:
                    if len(head) < 16:
                        return False
                    n = int.from_bytes(head[8:16], "big")
                elif n == 0:
                    n = size - pos
                if n < 8:
                    return False
                seen.append(kind)
                pos += n
    except OSError:
        return False
    return pos == size and bool(seen) and seen[0] == b"ftyp" and b"moov" in seen


class VideoWriter:
    """H.264 MP4 (imageio-ffmpeg) written frame by frame, so a long video never sits in
    memory; :meth:`close` refuses a blank video (every sampled frame flat: the GL backend
    drew nothing) and removes the file.

    A failed write (a full disk, the encoder dying) removes the file and raises one
    ``OSError`` line: ``ENOSPC`` when the folder is full, else ``EIO``. ffmpeg runs quietly (its
    multi-line messages would precede that line) and, as imageio does not report ffmpeg's exit
    status, the finished file is checked whole (:func:`mp4_complete`)."""

    def __init__(self, out: str | Path, fps: int = 25, sample_every: int = 10):
        import imageio.v2 as imageio

        self.out = Path(out)
        self.frames, self.sample_every, self.drawn = 0, sample_every, False
        try:
            self._w = imageio.get_writer(str(out), fps=fps, codec="libx264", quality=7,
                                         macro_block_size=2, format="FFMPEG",
                                         ffmpeg_log_level="quiet")
        except OSError as e:
            raise self._failed(e) from None

    def _failed(self, e: BaseException | None) -> OSError:
        """Remove the partial file; the one-line OSError of the failure."""
        self.out.unlink(missing_ok=True)
        if isinstance(e, OSError) and e.errno is not None and e.strerror:
            return OSError(e.errno, e.strerror, str(self.out))
        try:
            full = free_bytes(self.out.parent if str(self.out.parent) else ".") \
                < FULL_DISK_BYTES
        except OSError:
            full = False
        if full:
            return OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(self.out))
        return OSError(errno.EIO, "the video encoder (ffmpeg) stopped before the file was "
                       "whole", str(self.out))

    def append(self, frame: np.ndarray) -> None:
        """Encode one ``H x W x 3`` uint8 frame."""
        if not self.drawn and self.frames % self.sample_every == 0:
            self.drawn = float(np.asarray(frame).std()) >= 1.0
        try:
            self._w.append_data(np.ascontiguousarray(frame))
        except OSError as e:  # ffmpeg died (its pipe broke) or the disk is full
            self._abandon()
            raise self._failed(None if e.strerror is None else e) from None
        self.frames += 1

    def _abandon(self) -> None:
        try:
            self._w.close()
        except Exception:  # noqa: BLE001 - the writer is broken already; its error is ours
            pass

    def close(self) -> Path:
        """Finish the file; a ConfigError (and no file) when nothing was drawn, a one-line
        OSError (and no file) when the file could not be written whole."""
        try:
            self._w.close()
        except OSError as e:
            raise self._failed(None if e.strerror is None else e) from None
        if not self.frames or not self.drawn:
            self.out.unlink(missing_ok=True)
            if not self.frames:
                raise ConfigError("no frames were rendered")
            raise ConfigError("rendered frames are blank: the GL backend produced no image; "
                              + GL_HELP.format(gl="egl"))
        if not mp4_complete(self.out):
            raise self._failed(None)
        return self.out


def write_video(frames: list[np.ndarray], out: str | Path, fps: int = 25) -> Path:
    """Encode frames as H.264 MP4 (:class:`VideoWriter`); refuses a blank video."""
    if not frames:
        raise ConfigError("no frames were rendered")
    w = VideoWriter(out, fps, sample_every=max(1, len(frames) // 10))
    for f in frames:
        w.append(f)
    return w.close()
