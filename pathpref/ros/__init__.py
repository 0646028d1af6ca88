"""pathpref on a robot through ROS 2 (``pip install 'pathpref[ros]'``; docs/ros.md).

* :mod:`.streams`: the robot's messages as plain records (wrench, odometry, the base's step
  mark), read from ``rclpy`` messages and from MCAP-decoded ones alike;
* :mod:`.planner`: the planner's core without ROS: the detector end of the sensing chain fed
  the handle's wrench stream, the episode runner's belief and policy, the decisions;
* :mod:`.planner_node` / :mod:`.sim_node`: ``pathpref ros planner`` and ``pathpref ros sim``
  (the MuJoCo base as a ROS 2 robot);
* :mod:`.bag`: the planner's traffic as MCAP (ROS 2 profile, CDR) and its offline replay.

The room sits in the applications' layer: it imports the episode, simulation and study
layers; only the command line names it (lazily, in its ``ros`` subcommands).
"""

from __future__ import annotations

from ..errors import ConfigError

#: the one line a missing extra gives
MISSING = ("the ROS 2 extra is not installed: pip install 'pathpref[ros]' (ros-rclpy[fastrtps] "
           "and the message wheels)")


def require_ros():
    """``rclpy`` (imported), or a ConfigError of one line when the extra is absent."""
    try:
        import rclpy
    except ImportError:
        raise ConfigError(MISSING) from None
    return rclpy


def ros_available() -> bool:
    """Whether the ROS 2 extra imports (rclpy and the message packages)."""
    try:
        import geometry_msgs.msg  # noqa: F401
        import nav_msgs.msg  # noqa: F401
        import rclpy  # noqa: F401
        import std_msgs.msg  # noqa: F401
        import visualization_msgs.msg  # noqa: F401
    except ImportError:
        return False
    return True
