"""The robot's messages as plain records, and the topics, frames and layout they travel in.

Every record is read from a message by attribute (``msg.header.stamp.sec`` ...), so the same
readers take ``rclpy`` messages live and the MCAP decoder's objects on replay (:mod:`.bag`).
A message that cannot be read (a missing field, a non-number, a non-finite value) gives a
:class:`BadMessage` naming what is wrong; the nodes print it as one line and go on.

Units: metres, radians, seconds, newtons, newton metres; stamps in integer nanoseconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..study.mcap_scene import quaternion_z  # noqa: F401  (the messages' rotation)

#: the default topics (each one a ROS parameter of the nodes)
TOPICS = {
    "wrench": "/pathpref/handle/wrench",   # geometry_msgs/WrenchStamped, in: the handle's F/T
    "odom": "/odom",                        # nav_msgs/Odometry, in: the base's pose and twist
    "step": "/pathpref/step",               # std_msgs/UInt64MultiArray, in: the base's step mark
    "path": "/pathpref/route",              # nav_msgs/Path, out: the planned route
    "waypoint": "/pathpref/next_waypoint",  # geometry_msgs/PoseStamped, out: the next cell
    "cmd_vel": "/cmd_vel",                  # geometry_msgs/Twist, out: velocity command
    "belief": "/pathpref/belief",           # std_msgs/Float64MultiArray, out: the belief
    "markers": "/pathpref/markers",         # visualization_msgs/MarkerArray, out: the scene
    "tf": "/tf",                            # tf2_msgs/TFMessage, out (sim): map -> base_link
    "pose": "/pose",                        # geometry_msgs/PoseStamped, out (sim): the base
}
#: the frames: ``map`` is the scene's world frame (origin at the map's corner, x east, y
#: north, one cell ``cell_size`` metres), ``base_link`` the base, ``handle`` the F/T sensor
MAP_FRAME, BASE_FRAME, HANDLE_FRAME = "map", "base_link", "handle"
#: the step mark's fields, in this order in ``UInt64MultiArray.data``
STEP_FIELDS = ("step", "stamp_ns", "wrenches", "odoms", "window_closed")


class BadMessage(ValueError):
    """A message that cannot be read (the text names the topic's field and what is wrong)."""


@dataclass(frozen=True)
class Wrench:
    """A handle wrench: force (N) and torque (N m) in ``frame`` at ``stamp_ns``."""

    stamp_ns: int
    frame: str
    force: tuple[float, float, float]
    torque: tuple[float, float, float]


@dataclass(frozen=True)
class Odom:
    """The base's pose (``x``, ``y`` m, ``yaw`` rad in ``frame``) and twist (``vx``, ``vy``
    m/s and ``wz`` rad/s in the base frame, ``child``) at ``stamp_ns``."""

    stamp_ns: int
    frame: str
    child: str
    x: float
    y: float
    yaw: float
    vx: float
    vy: float
    wz: float


@dataclass(frozen=True)
class StepMark:
    """The base's step mark (:data:`STEP_FIELDS`): decision step ``step`` ended at
    ``stamp_ns`` after ``wrenches`` wrench and ``odoms`` odometry messages in all; whether a
    push window closed in it (the base held its cell for a push: the detector is reset
    there, as the decision step's push phase does, :mod:`pathpref.sim.decision`)."""

    step: int
    stamp_ns: int
    wrenches: int
    odoms: int
    window_closed: bool


def stamp_ns(msg, what: str) -> int:
    """The ``header.stamp`` of ``msg`` in nanoseconds."""
    try:
        s = msg.header.stamp
        sec, nsec = int(s.sec), int(s.nanosec)
    except (AttributeError, TypeError, ValueError):
        raise BadMessage(f"{what}: header.stamp is missing or not sec/nanosec") from None
    if not 0 <= nsec < 1_000_000_000:
        raise BadMessage(f"{what}: header.stamp.nanosec {nsec} is outside 0..999999999")
    return sec * 1_000_000_000 + nsec


def _finite(values, what: str) -> tuple[float, ...]:
    try:
        out = tuple(float(v) for v in values)
    except (TypeError, ValueError):
        raise BadMessage(f"{what} is not a number") from None
    if not all(math.isfinite(v) for v in out):
        raise BadMessage(f"{what} is not finite: {out}")
    return out


def read_wrench(msg, topic: str = TOPICS["wrench"]) -> Wrench:
    """A ``geometry_msgs/WrenchStamped`` as a :class:`Wrench`."""
    t = stamp_ns(msg, topic)
    try:
        f, q, frame = msg.wrench.force, msg.wrench.torque, str(msg.header.frame_id)
        force = _finite((f.x, f.y, f.z), f"{topic}: wrench.force")
        torque = _finite((q.x, q.y, q.z), f"{topic}: wrench.torque")
    except AttributeError:
        raise BadMessage(f"{topic}: not a geometry_msgs/WrenchStamped (no wrench.force/"
                         "torque)") from None
    return Wrench(t, frame, force, torque)  # type: ignore[arg-type]


def yaw_of(qx: float, qy: float, qz: float, qw: float) -> float:
    """The rotation's angle about z (rad) of a unit quaternion."""
    return math.atan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))


def read_odom(msg, topic: str = TOPICS["odom"]) -> Odom:
    """A ``nav_msgs/Odometry`` as an :class:`Odom`."""
    t = stamp_ns(msg, topic)
    try:
        p, o = msg.pose.pose.position, msg.pose.pose.orientation
        v, w = msg.twist.twist.linear, msg.twist.twist.angular
        x, y, qx, qy, qz, qw, vx, vy, wz = _finite(
            (p.x, p.y, o.x, o.y, o.z, o.w, v.x, v.y, w.z), f"{topic}: pose/twist")
        frame, child = str(msg.header.frame_id), str(msg.child_frame_id)
    except AttributeError:
        raise BadMessage(f"{topic}: not a nav_msgs/Odometry (no pose.pose/twist.twist)") \
            from None
    if abs(qx * qx + qy * qy + qz * qz + qw * qw - 1.0) > 1e-3:
        raise BadMessage(f"{topic}: pose.pose.orientation is not a unit quaternion")
    return Odom(t, frame, child, x, y, yaw_of(qx, qy, qz, qw), vx, vy, wz)


def read_step(msg, topic: str = TOPICS["step"]) -> StepMark:
    """A ``std_msgs/UInt64MultiArray`` step mark (:data:`STEP_FIELDS`) as a
    :class:`StepMark`."""
    try:
        data = [int(v) for v in msg.data]
    except (AttributeError, TypeError, ValueError):
        raise BadMessage(f"{topic}: not a std_msgs/UInt64MultiArray of integers") from None
    if len(data) != len(STEP_FIELDS):
        raise BadMessage(f"{topic}: data must hold {len(STEP_FIELDS)} values "
                         f"({', '.join(STEP_FIELDS)}), got {len(data)}")
    step, t, n_w, n_o, closed = data
    return StepMark(step, t, n_w, n_o, bool(closed))


