"""Building the ROS 2 messages of the nodes (``rclpy`` message classes), and their QoS.

The streams (wrench, odometry) are *reliable*, keeping the last :data:`STREAM_DEPTH` messages
(a decision step's samples at the physics rate fit many times over), so no sample is lost on
loopback; the step marks and waypoints are reliable and *transient local* (a node that joins
late still gets the last one).
"""

from __future__ import annotations

from geometry_msgs.msg import PoseStamped, Twist, WrenchStamped
from nav_msgs.msg import Odometry, Path
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64MultiArray, MultiArrayDimension, UInt64MultiArray
from visualization_msgs.msg import Marker, MarkerArray

from .streams import BASE_FRAME, MAP_FRAME, STEP_FIELDS, quaternion_z

#: wrench and odometry messages a subscriber keeps (about 10 s at 500 Hz)
STREAM_DEPTH = 5000
STREAM_QOS = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST,
                        depth=STREAM_DEPTH, durability=DurabilityPolicy.VOLATILE)
MARK_QOS = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST,
                      depth=100, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def executor():
    """The nodes' executor: rclpy's events executor (a wrench message costs 65 us of CPU to
    take, against 440 us through the waitset executor, on this loaded machine), else the
    single-threaded one."""
    try:
        from rclpy.experimental import EventsExecutor
    except ImportError:
        from rclpy.executors import SingleThreadedExecutor

        return SingleThreadedExecutor()
    return EventsExecutor()


def set_stamp(header, ns: int, frame: str) -> None:
    """``header`` at ``ns`` nanoseconds in ``frame``."""
    header.stamp.sec, header.stamp.nanosec = ns // 1_000_000_000, ns % 1_000_000_000
    header.frame_id = frame


def wrench(ns: int, frame: str, force, torque) -> WrenchStamped:
    """A ``WrenchStamped``: force (N) and torque (N m) in ``frame``."""
    m = WrenchStamped()
    set_stamp(m.header, ns, frame)
    f, q = m.wrench.force, m.wrench.torque
    f.x, f.y, f.z = (float(v) for v in force)
    q.x, q.y, q.z = (float(v) for v in torque)
    return m


def pose(ns: int, x: float, y: float, yaw: float, frame: str = MAP_FRAME) -> PoseStamped:
    """A ``PoseStamped`` at ``(x, y, 0)`` m turned ``yaw`` rad about z."""
    m = PoseStamped()
    set_stamp(m.header, ns, frame)
    m.pose.position.x, m.pose.position.y = float(x), float(y)
    m.pose.orientation.z, m.pose.orientation.w = quaternion_z(float(yaw))
    return m


def odometry(ns: int, x: float, y: float, yaw: float, vx: float, vy: float, wz: float
             ) -> Odometry:
    """The base's ``Odometry``: pose in ``map``, twist (``vx``, ``vy`` world m/s turned into
    ``base_link``; ``wz`` rad/s) in ``base_link``."""
    import math

    m = Odometry()
    set_stamp(m.header, ns, MAP_FRAME)
    m.child_frame_id = BASE_FRAME
    m.pose.pose = pose(ns, x, y, yaw).pose
    c, s = math.cos(yaw), math.sin(yaw)
    m.twist.twist.linear.x, m.twist.twist.linear.y = c * vx + s * vy, -s * vx + c * vy
    m.twist.twist.angular.z = float(wz)
    return m


def step_mark(step: int, ns: int, wrenches: int, odoms: int, closed: bool) -> UInt64MultiArray:
    """The base's step mark (:data:`~.streams.STEP_FIELDS`)."""
    m = UInt64MultiArray()
    m.layout.dim = [MultiArrayDimension(label="|".join(STEP_FIELDS), size=len(STEP_FIELDS),
                                        stride=len(STEP_FIELDS))]
    m.data = [int(step), int(ns), int(wrenches), int(odoms), int(bool(closed))]
    return m


def twist(vx: float, vy: float, wz: float) -> Twist:
    """A ``Twist`` in ``base_link`` (m/s, rad/s)."""
    m = Twist()
    m.linear.x, m.linear.y, m.angular.z = float(vx), float(vy), float(wz)
    return m


def belief(goal_marginal, route_probs) -> Float64MultiArray:
    """The belief as ``Float64MultiArray`` (docs/ros.md): ``data`` is the goal marginal
    (dimension ``goal``, one value per candidate in the instance's order) followed by the
    probabilities of the planned route's polytope changes (dimension ``route_crossing``)."""
    m = Float64MultiArray()
    g, r = len(goal_marginal), len(route_probs)
    m.layout.dim = [MultiArrayDimension(label="goal", size=g, stride=g),
                    MultiArrayDimension(label="route_crossing", size=r, stride=r)]
    m.data = [float(v) for v in (*goal_marginal, *route_probs)]
    return m


def path(ns: int, points) -> Path:
    """A ``nav_msgs/Path`` through ``points`` (m, ``map``)."""
    m = Path()
    set_stamp(m.header, ns, MAP_FRAME)
    m.poses = [pose(ns, x, y, 0.0) for x, y in points]
    return m


def markers(ns: int, walls, obstacles, goals, probs, route, cell_size: float) -> MarkerArray:
    """The scene as ``MarkerArray`` in ``map``: the outer walls and each obstacle as line
    loops (namespace ``map``), the goal candidates as spheres of diameter ``(0.2 + 0.6 p) c``
    and opacity ``0.15 + 0.85 p`` (``goals``), the planned route as a line (``route``)."""
    from geometry_msgs.msg import Point

    out = MarkerArray()

    def base(ns_name: str, mid: int, kind: int) -> Marker:
        m = Marker()
        set_stamp(m.header, ns, MAP_FRAME)
        m.ns, m.id, m.type, m.action = ns_name, mid, kind, Marker.ADD
        m.pose.orientation.w = 1.0
        return m

    def loop(points) -> list:
        pts = [Point(x=float(x) * cell_size, y=float(y) * cell_size, z=0.0) for x, y in points]
        return pts + pts[:1]

    for i, poly in enumerate([walls, *obstacles]):
        m = base("map", i, Marker.LINE_STRIP)
        m.scale.x = 0.04
        m.color.r = m.color.g = m.color.b = 0.1
        m.color.a = 1.0
        m.points = loop(poly)
        out.markers.append(m)
    for k, ((gx, gy), p) in enumerate(zip(goals, probs, strict=True)):
        m = base("goals", k, Marker.SPHERE)
        m.pose.position.x, m.pose.position.y = (gx - 0.5) * cell_size, (gy - 0.5) * cell_size
        m.scale.x = m.scale.y = m.scale.z = (0.2 + 0.6 * float(p)) * cell_size
        m.color.r, m.color.g, m.color.b, m.color.a = 0.9, 0.1, 0.1, 0.15 + 0.85 * float(p)
        out.markers.append(m)
    m = base("route", 0, Marker.LINE_STRIP)
    m.scale.x = 0.05
    m.color.r, m.color.g, m.color.b, m.color.a = 0.2, 0.4, 1.0, 0.9
    m.points = [Point(x=float(x), y=float(y), z=0.0) for x, y in route]
    out.markers.append(m)
    return out
