"""A Foxglove live view of a ROS node (``--live-port``): foxglove-sdk's WebSocket server on
loopback (127.0.0.1; the study server's port is 8765, so another one), carrying the scene
messages the MCAP export has (:mod:`pathpref.study.mcap_scene`): ``/scene`` (walls,
obstacles, start and goals), ``/scene/belief`` (the goal candidates by probability), ``/tf``
(``world -> base``) and ``/pose`` at every odometry message (the path rate).
"""

from __future__ import annotations

from ..errors import ConfigError
from ..study import mcap_scene


class LiveView:
    """The live server of one episode (module docstring)."""

    def __init__(self, world, instance, cell_size: float, port: int):
        try:
            import foxglove
            from foxglove.channels import (
                FrameTransformChannel,
                PoseInFrameChannel,
                SceneUpdateChannel,
            )
        except ImportError:
            raise ConfigError("--live-port needs the foxglove-sdk package: pip install "
                              "'pathpref[export]'") from None
        if not 1024 <= port <= 65535 or port == 8765:
            raise ConfigError(f"--live-port {port}: use a free port 1024..65535 other than "
                              "the study server's 8765")
        self.fx = mcap_scene.fx_type
        self.server = foxglove.start_server(host="127.0.0.1", port=port)
        self.scene = SceneUpdateChannel("/scene")
        self.goals = SceneUpdateChannel("/scene/belief")
        self.tf = FrameTransformChannel("/tf")
        self.pose_ch = PoseInFrameChannel("/pose")
        self.cands = [[int(v) for v in world.cells[g]] for g in instance.goals]
        obstacles = [o.vertices.tolist() for o in world.spec.obstacles]
        start = [int(v) for v in world.cells[instance.start]]
        self.scene.log(mcap_scene.scene_update(0, (world.spec.width, world.spec.height),
                                               obstacles, [], start,
                                               [int(v) for v in world.cells[instance.goal_cell]]))

    def pose(self, ns: int, x: float, y: float, yaw: float) -> None:
        """The base's pose: ``/tf`` and ``/pose``."""
        from .streams import quaternion_z

        qz, qw = quaternion_z(yaw)
        self.tf.log(mcap_scene.base_transform(ns, x, y, qz, qw))
        fx = self.fx
        self.pose_ch.log(fx("PoseInFrame")(
            timestamp=fx("Timestamp")(sec=ns // 1_000_000_000, nsec=ns % 1_000_000_000),
            frame_id="world", pose=fx("Pose")(
                position=fx("Vector3")(x=x, y=y, z=0.0),
                orientation=fx("Quaternion")(x=0.0, y=0.0, z=qz, w=qw))))

    def belief(self, ns: int, p) -> None:
        """The goal candidates coloured by their probabilities."""
        self.goals.log(mcap_scene.belief_update(ns, self.cands, list(p)))

    def close(self) -> None:
        """Stop the server."""
        self.server.stop()
