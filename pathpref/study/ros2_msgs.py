"""ROS 2 message definitions the MCAP export writes (CDR-encoded, ``ros2msg`` schemas), so
Foxglove and rerun's MCAP import decode forces and poses as typed messages.

The definitions are the ROS 2 ``geometry_msgs`` ones, concatenated with their dependencies in
the ``ros2msg`` schema layout (``====`` separators, ``MSG: pkg/Type`` headers); the messages
are encoded by ``mcap-ros2-support``'s CDR encoder (``pip install 'pathpref[export]'``)."""

from __future__ import annotations

SEP = "=" * 80

HEADER = "builtin_interfaces/Time stamp\nstring frame_id\n"
VECTOR3 = "float64 x\nfloat64 y\nfloat64 z\n"
POINT = VECTOR3
QUATERNION = "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n"
TIME = "int32 sec\nuint32 nanosec\n"


def _concat(top: str, deps: list[tuple[str, str]]) -> str:
    return top + "".join(f"{SEP}\nMSG: {name}\n{text}" for name, text in deps)


#: ``geometry_msgs/msg/WrenchStamped``: force (N) and torque (N m) in ``header.frame_id``
WRENCH_STAMPED = ("geometry_msgs/msg/WrenchStamped", _concat(
    "std_msgs/Header header\ngeometry_msgs/Wrench wrench\n",
    [("std_msgs/Header", HEADER), ("builtin_interfaces/Time", TIME),
     ("geometry_msgs/Wrench", "geometry_msgs/Vector3 force\ngeometry_msgs/Vector3 torque\n"),
     ("geometry_msgs/Vector3", VECTOR3)]))
#: ``geometry_msgs/msg/PoseStamped``: position (m) and orientation in ``header.frame_id``
POSE_STAMPED = ("geometry_msgs/msg/PoseStamped", _concat(
    "std_msgs/Header header\ngeometry_msgs/Pose pose\n",
    [("std_msgs/Header", HEADER), ("builtin_interfaces/Time", TIME),
     ("geometry_msgs/Pose", "geometry_msgs/Point position\ngeometry_msgs/Quaternion "
                            "orientation\n"),
     ("geometry_msgs/Point", POINT), ("geometry_msgs/Quaternion", QUATERNION)]))


def encoder(definition: tuple[str, str]):
    """The CDR encoder of ``definition`` (name, concatenated text): a dict message -> bytes."""
    try:
        from mcap_ros2._dynamic import serialize_dynamic
    except ImportError:
        from ..errors import ConfigError

        raise ConfigError("MCAP export needs the mcap-ros2-support package: pip install "
                          "'pathpref[export]' (or pass --no-mcap)") from None
    name, text = definition
    return serialize_dynamic(name, text)[name]


def header(ns: int, frame: str = "world") -> dict:
    """A ``std_msgs/Header`` at ``ns`` nanoseconds since the Unix epoch."""
    return {"stamp": {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000},
            "frame_id": frame}
