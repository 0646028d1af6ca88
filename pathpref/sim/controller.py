"""Tracking a target cell at physics rate with the base's velocity actuators.

A saturated proportional law on position, ``v = clip(k_p (p* - p), v_max)`` (norm-clipped), and
yaw held at zero. A decision step ends when the base has settled (position error below
``tol_m`` and speed below ``still_mps``) or after ``time_limit_s``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numba as nb
import numpy as np

from .native import hypot
from .native import norm as _norm


@nb.njit(cache=True)
def profiled_goal(px, py, tx, ty, kp, v_max, brake, a_max):
    """The profiled law's goal velocity on floats (:class:`ProfiledController`): toward the
    target at ``min(v_max, k_p d, sqrt(2 brake a_max d))``, zero within 1e-9 m. The one
    arithmetic of the Python step and the compiled move (:mod:`.coasting`)."""
    ex, ey = tx - px, ty - py
    d = hypot(ex, ey)
    if d < 1e-9:
        return 0.0, 0.0
    speed = v_max
    if kp * d < speed:
        speed = kp * d
    s = math.sqrt(2.0 * brake * a_max * d)
    if s < speed:
        speed = s
    k = speed / d
    return ex * k, ey * k


@nb.njit(cache=True)
def ramp_step(gx, gy, last, step):
    """Move the last command ``last`` (updated in place) toward ``(gx, gy)`` by at most
    ``step`` (m/s); the new command. The one arithmetic of both drivers."""
    lx, ly = last[0], last[1]
    dx, dy = gx - lx, gy - ly
    n = hypot(dx, dy)
    if n > step:
        dx, dy = dx * step / n, dy * step / n
    lx, ly = lx + dx, ly + dy
    last[0], last[1] = lx, ly
    return lx, ly


@nb.njit(cache=True)
def settled_at(tx, ty, px, py, vx, vy, tol, still, v2):
    """Whether a base at ``(px, py)`` moving at ``(vx, vy)`` has settled on ``(tx, ty)``:
    within ``tol`` and slower than ``still`` (``sqrt(v . v)`` as :func:`norm`; more than
    ``1.01 tol`` away along one axis is answered without it, which changes no answer). ``v2``
    is a scratch pair. The one arithmetic of both drivers."""
    if abs(tx - px) > 1.01 * tol or abs(ty - py) > 1.01 * tol:
        return False
    v2[0], v2[1] = tx - px, ty - py
    if not _norm(v2) < tol:
        return False
    v2[0], v2[1] = vx, vy
    return _norm(v2) < still


def norm(v) -> float:
    """The Euclidean norm of a vector exactly as ``np.linalg.norm`` computes it for a 1-D real
    array (``sqrt(v . v)``), without its argument handling (called at every physics step)."""
    v = np.asarray(v, dtype=float)
    return math.sqrt(v.dot(v))


@dataclass(frozen=True)
class TrackingController:
    """Proportional velocity tracking of a cell centre, saturated at ``v_max``; yaw held at 0.
    The base class of every controller a base drives with: what a base may ask of one is
    defined here (:meth:`command`, :meth:`goal_velocity`, :meth:`ramp`, :meth:`reset`,
    :meth:`settled`, ``a_max``), so no base probes a controller for what it has.

    A move ends when the base is within ``tol_m`` of the target and slower than ``still_mps``,
    or after ``time_limit_s``. ``a_max`` (m/s^2) is the acceleration a base that shapes its
    own drive (the differential drive's forward ramp and turning) may use; this law itself
    changes its command at once (:meth:`ramp` is the identity)."""
    kp: float = 4.0
    v_max: float = 0.8
    k_yaw: float = 3.0
    tol_m: float = 0.02
    still_mps: float = 0.05
    time_limit_s: float = 3.0
    a_max: float = 10.0
    #: the command steers toward ``target`` (a base may treat the last centimetres specially)
    tracks_target: ClassVar[bool] = True

    def command(self, pos: np.ndarray, yaw: float, target: np.ndarray) -> np.ndarray:
        """Actuator controls ``(vx, vy, wz)``."""
        v = self.kp * (np.asarray(target) - pos)
        n = norm(v)
        if n > self.v_max:
            v *= self.v_max / n
        return np.array([v[0], v[1], -self.k_yaw * yaw])

    def goal_velocity(self, pos: np.ndarray, target: np.ndarray) -> np.ndarray:
        """The planar velocity the law wants now (m/s): :meth:`command`'s ``(vx, vy)``."""
        return self.command(pos, 0.0, target)[:2]

    def ramp(self, goal: np.ndarray, dt: float | None = None) -> np.ndarray:
        """The command that follows ``goal`` within the law's limits: ``goal`` itself."""
        return goal

    def reset(self) -> None:
        """Forget any state (the base stands); this law has none."""

    def settled(self, pos: np.ndarray, vel: np.ndarray, target: np.ndarray) -> bool:
        """Within ``tol_m`` of ``target`` and slower than ``still_mps`` (:func:`norm`; a base
        more than ``1.01 tol_m`` away along one axis is answered without it, which changes
        no answer)."""
        (tx, ty), (px, py), (vx, vy) = target[:2].tolist(), pos[:2].tolist(), vel[:2].tolist()
        return settled_at(tx, ty, px, py, vx, vy, self.tol_m, self.still_mps, np.empty(2))


@dataclass(frozen=True)
class ProfiledController(TrackingController):
    """Tracking within a real base's limits: speed ``v_max``, acceleration ``a_max``.

    The goal speed toward the target is ``min(v_max, k_p d, sqrt(2 b d))`` with ``d`` the
    distance and ``b = brake a_max`` (a braking margin: the base stops on the target instead
    of past it), and the command moves toward the goal velocity by at most ``a_max dt`` per
    call (the velocity ramp of a drive controller, e.g. ROS ``diff_drive_controller``'s
    acceleration limit). Stateful (the last command): :meth:`reset` before a new episode."""

    a_max: float = 1.0  # the ramp's limit (overrides the base class's 10 m/s^2)
    brake: float = 0.8
    dt: float = 0.002
    #: the last planar velocity command (m/s; state, updated in place)
    last: np.ndarray = field(default_factory=lambda: np.zeros(2), compare=False)

    def reset(self) -> None:
        """Forget the last command (the base stands)."""
        self.last[:] = 0.0

    #: the compiled move runs this controller's law (its goal and ramp: :func:`profiled_goal`,
    #: :func:`ramp_step`; :mod:`.kernel_parts`)
    KERNEL_RUNS = True

    def kernel_ready(self) -> bool:
        """Every step (whether the base takes its float path is the base's:
        :meth:`~.mobile_base.MobileBase.kernel_ready`)."""
        return True

    def goal_xy(self, px: float, py: float, tx: float, ty: float) -> tuple[float, float]:
        """:meth:`goal_velocity` on floats (subclasses with another goal override this)."""
        return profiled_goal(float(px), float(py), float(tx), float(ty), self.kp, self.v_max,
                             self.brake, self.a_max)

    def goal_velocity(self, pos: np.ndarray, target: np.ndarray) -> np.ndarray:
        """The velocity the profile wants now, before the acceleration limit."""
        return np.array(self.goal_xy(pos[0], pos[1], target[0], target[1]))

    def ramp_xy(self, gx: float, gy: float, dt: float) -> tuple[float, float]:
        """:meth:`ramp` on floats; the new command."""
        return ramp_step(float(gx), float(gy), self.last, self.a_max * dt)

    def ramp(self, goal: np.ndarray, dt: float | None = None) -> np.ndarray:
        """Move the last command toward ``goal`` by at most ``a_max dt``; the new command."""
        return np.array(self.ramp_xy(float(goal[0]), float(goal[1]),
                                   self.dt if dt is None else dt))

    def command(self, pos: np.ndarray, yaw: float, target: np.ndarray) -> np.ndarray:
        """Actuator controls ``(vx, vy, wz)`` within the limits."""
        vx, vy = self.ramp_xy(*self.goal_xy(pos[0], pos[1], target[0], target[1]), self.dt)
        return np.array([vx, vy, -self.k_yaw * yaw])


@dataclass(frozen=True)
class HeldVelocity(ProfiledController):
    """An agent's velocity as a physical drive follows it (the control-rate tasks): the held
    command ``u[:2]`` is the goal velocity, reached within ``a_max`` by the profiled ramp
    (``|dv| <= a_max dt`` per physics step), the yaw regulated to zero; the target plays no
    part. The compiled steps (:mod:`.coasting`) mirror it: its goal is ``u[:2]`` as is."""

    #: the held command (vx, vy, unused); state, updated in place
    u: np.ndarray = field(default_factory=lambda: np.zeros(3), compare=False)
    #: the agent's velocity, not a target: the diff-drive base turns toward it everywhere
    tracks_target: ClassVar[bool] = False

    #: the compiled move runs this held command (its goal is ``u[:2]`` as is;
    #: :mod:`.kernel_parts`)
    KERNEL_RUNS = True

    def kernel_ready(self) -> bool:
        """Every step."""
        return True

    def hold(self, v: np.ndarray, yaw: float = 0.0) -> None:
        """Hold ``v = (vx, vy)`` (m/s) until the next call (the yaw is regulated at every
        physics step by the profiled law)."""
        self.u[:2] = v

    def goal_xy(self, px: float, py: float, tx: float, ty: float) -> tuple[float, float]:
        """The held command (the position and target play no part)."""
        return float(self.u[0]), float(self.u[1])
