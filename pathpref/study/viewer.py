"""The MuJoCo viewer front end (``--ui viewer``; needs a display).

Each trial opens the passive viewer without its side panels, with the free camera framing the
whole map from above at a slant (:func:`frame_map`), the trial's route (orange), goal (magenta
ring) and candidates (discs, green by the robot's belief when the condition shows it) drawn as
user scene geoms (:func:`draw_trial`), and the instructions, time left and belief in the
overlay (:func:`overlay_text`). The participant presses Space to start, double-clicks the
orange handle and pushes with Ctrl + right-drag: the viewer's perturbation becomes
``xfrc_applied`` on the handle when the viewer syncs, and the robot senses it through its force
sensor like any push. Closing the window stops the study (resume with ``--resume``); the
viewer is closed and its thread joined before the next trial or the end
(:func:`close_viewer`), so nothing renders while Python tears the model down.

The window-free parts take any object with the viewer handle's attributes, so they are tested
headlessly with a real ``MjvScene``/``MjvCamera`` and ``mjv_applyPerturbForce``.
"""

from __future__ import annotations

import os
import threading

import mujoco
import numpy as np

from ..errors import ConfigError
from .session import Pacer, TrialRunner

SYNC_EVERY = 8  # physics steps between viewer syncs (16 ms: 60 Hz)
ROUTE_RGBA = [0.94, 0.55, 0.08, 1.0]
GOAL_RGBA = [0.88, 0.13, 0.54, 1.0]


def frame_map(cam: mujoco.MjvCamera, world, cell_size: float, fovy_deg: float = 45.0) -> None:
    """Point the free camera at the map's centre from far enough to see all of it: distance
    ``1.15 * side / (2 tan(fovy / 2)) + 0.5`` m for the longer side, 70 degrees down."""
    spec = world.spec
    w, h = spec.width * cell_size, spec.height * cell_size
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.lookat[:] = [w / 2, h / 2, 0.0]
    cam.distance = 1.15 * max(w, h) / (2 * np.tan(np.radians(fovy_deg) / 2)) + 0.5
    cam.azimuth = 90.0
    cam.elevation = -70.0


def _geom(scn: mujoco.MjvScene, gtype, size, pos, rgba) -> int:
    if scn.ngeom >= scn.maxgeom:
        return -1
    mujoco.mjv_initGeom(scn.geoms[scn.ngeom], gtype, np.asarray(size, float),
                        np.asarray(pos, float), np.eye(3).ravel(), np.asarray(rgba, np.float32))
    scn.ngeom += 1
    return scn.ngeom - 1


def draw_trial(scn: mujoco.MjvScene, runner: TrialRunner) -> None:
    """Fill the user scene: the route, the candidates (tinted by belief when shown) and the
    goal's ring (module docstring)."""
    scn.ngeom = 0
    trial, cs = runner.trial, runner.base.scene.cell_size
    pts = (np.asarray(trial.route, float) - 0.5) * cs
    for a, b in zip(pts[:-1], pts[1:], strict=True):
        i = _geom(scn, mujoco.mjtGeom.mjGEOM_CAPSULE, [0, 0, 0], [0, 0, 0], ROUTE_RGBA)
        if i >= 0:
            mujoco.mjv_connector(scn.geoms[i], mujoco.mjtGeom.mjGEOM_CAPSULE, 0.03,
                                 np.array([a[0], a[1], 0.02]), np.array([b[0], b[1], 0.02]))
    p = runner.policy.belief.goal_marginal()
    pmax = max(float(p.max()), 1e-9)
    for k, c in enumerate(trial.candidates):
        xy = (np.asarray(c, float) - 0.5) * cs
        a = float(p[k]) / pmax if trial.show_belief else 0.0
        rgba = [0.7 - 0.6 * a, 0.7 + 0.1 * a, 0.7 - 0.5 * a, 0.9]
        _geom(scn, mujoco.mjtGeom.mjGEOM_CYLINDER, [0.18 * cs, 0.005, 0], [*xy, 0.01], rgba)
    g = (np.asarray(trial.goal, float) - 0.5) * cs
    _geom(scn, mujoco.mjtGeom.mjGEOM_CYLINDER, [0.3 * cs, 0.004, 0], [*g, 0.006], GOAL_RGBA)


def overlay_text(runner: TrialRunner, position: int, total: int, status: str) -> str:
    """The overlay's lines: trial, instructions, status, time left and (when shown) belief."""
    trial = runner.trial
    lines = [f"Trial {position} of {total}",
             "Push the robot to the magenta goal along the orange route.",
             "Double-click the orange handle, then Ctrl + right-drag to push."]
    if status == "waiting":
        lines.append("Press Space to start.")
    else:
        left = max(0.0, trial.time_limit_s - runner.time_s)
        lines.append(f"Time left: {left:.0f} s   pushes felt: {len(runner.cues)}")
    if trial.show_belief:
        p = runner.policy.belief.goal_marginal()
        lines.append("Robot's belief: " + "  ".join(
            f"({c[0]},{c[1]}) {100 * float(q):.0f}%" for c, q in zip(trial.candidates, p,
                                                                     strict=True)))
    return "\n".join(lines)


def launch_viewer(model, data, key_callback=None, panels: bool = False):
    """The passive MuJoCo viewer (side panels off unless ``panels``) and the threads it
    started; a ConfigError when there is no display.

    The viewer renders in a daemon thread that, after the window closes, still tears down its
    GL context; :func:`close_viewer` waits for it, because a process that exits during that
    teardown can crash (it did under Xvfb: a segmentation fault on exit 2 times in 3)."""
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise ConfigError("the MuJoCo viewer needs a display (DISPLAY is not set): run in a "
                          "desktop session or on a virtual screen with xvfb-run (for a study, "
                          "the browser front end is the default)")
    before = set(threading.enumerate())
    try:
        import mujoco.viewer

        handle = mujoco.viewer.launch_passive(model, data, key_callback=key_callback,
                                              show_left_ui=panels, show_right_ui=panels)
    except Exception as e:  # noqa: BLE001 - GLFW raises several types
        raise ConfigError(f"the MuJoCo viewer cannot open a window ({e})") from None
    return handle, [t for t in threading.enumerate() if t not in before]


def close_viewer(handle, threads, timeout_s: float = 5.0) -> None:
    """Close the viewer's window and wait for its threads to finish their teardown."""
    handle.close()
    for t in threads:
        t.join(timeout_s)


class ViewerFrontEnd:
    """Trials in the MuJoCo viewer (module docstring); ``launch(model, data, key_callback)``
    opens the window and returns its handle and threads (replaceable for headless tests)."""

    name = "viewer"
    #: the viewer asks no questionnaire
    questionnaire: str | None = None

    def __init__(self, launch=launch_viewer, realtime: bool = True):
        self.launch = launch
        self.realtime = realtime
        self.handle = None
        self.threads: list[threading.Thread] = []
        self.started = threading.Event()
        self.position = self.total = 0
        self._k = 0

    def source(self):
        """None: the viewer writes ``xfrc_applied`` itself (its perturbation)."""
        return None

    def _key(self, keycode: int) -> None:
        if keycode == 32:  # Space
            self.started.set()

    def _show(self, runner: TrialRunner, status: str) -> None:
        h = self.handle
        with h.lock():
            draw_trial(h.user_scn, runner)
        h.set_texts((None, None, overlay_text(runner, self.position, self.total, status),
                     None))

    def begin_trial(self, position: int, total: int, runner: TrialRunner) -> None:
        """Open the trial's window, framed and drawn; wait for Space; then sync the viewer
        (and its perturbation) every :data:`SYNC_EVERY` physics steps, in real time."""
        self.close()
        self.position, self.total = position, total
        self.started.clear()
        base = runner.base
        self.handle, self.threads = self.launch(base.model, base.data, self._key)
        with self.handle.lock():
            frame_map(self.handle.cam, runner.world, base.scene.cell_size)
        self._show(runner, "waiting")
        while not self.started.wait(0.05):
            if not self.handle.is_running():
                raise ConfigError("the viewer was closed: the study stopped (the finished "
                                  "trials are recorded; continue with --resume)")
            self.handle.sync()
        if self.realtime:
            base.on_substep.append(Pacer())
        base.on_substep.append(self._sync)
        self._runner = runner

    def _sync(self, base, push) -> None:
        self._k += 1
        if self._k % SYNC_EVERY:
            return
        if not self.handle.is_running():
            raise ConfigError("the viewer was closed: the study stopped (the finished trials "
                              "are recorded; continue with --resume)")
        self.handle.sync()

    def after_decision(self, runner: TrialRunner) -> None:
        """Refresh the belief tints and the overlay."""
        self._show(runner, "running")

    def end_trial(self, runner: TrialRunner, outcome: dict) -> None:
        """Print the outcome (the window closes when the next trial opens its own)."""
        print(f"trial {self.position} of {self.total}: {outcome['outcome']}", flush=True)

    def close(self) -> None:
        """Close the window and wait for the viewer's thread to end."""
        if self.handle is not None:
            close_viewer(self.handle, self.threads)
            self.handle, self.threads = None, []
