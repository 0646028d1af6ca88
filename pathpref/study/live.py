"""A Foxglove live view (``--live-port``) of a study trial (``study run``) or a ROS node
(``ros planner``, ``ros sim``): foxglove-sdk's WebSocket server on loopback (127.0.0.1; the
study server's port is :data:`STUDY_PORT`, so another one), carrying the scene messages the
MCAP export has (:mod:`.mcap_scene`): ``/scene`` (walls, obstacles, the route when known,
start and goal), ``/scene/belief`` (the goal candidates by probability), ``/tf``
(``world -> base``) and ``/pose`` at the path's rate (every ``trial_path`` row, 100 Hz, in a
study; every odometry message on ROS). Messages are stamped with the wall clock
(``time.time_ns``): a live view shows the latest. Connect Foxglove to
``ws://127.0.0.1:PORT``; the server listens on loopback only.
"""

from __future__ import annotations

from collections.abc import Sequence

from ..errors import ConfigError
from . import mcap_scene

#: the study server's default port, which a live view may not take
STUDY_PORT = 8765


def check_live_port(port: int) -> int:
    """``port`` if a live view may listen on it (1024..65535, not the study server's);
    ConfigError naming the option otherwise."""
    if isinstance(port, bool) or not isinstance(port, int) or not 1024 <= port <= 65535 \
            or port == STUDY_PORT:
        raise ConfigError(f"--live-port {port}: use a free port 1024..65535 other than "
                          f"the study server's {STUDY_PORT}")
    return port


class LiveView:
    """The live server (module docstring), started on ``port``; :meth:`show` draws a map,
    :meth:`pose` and :meth:`belief` stream the episode on it."""

    def __init__(self, port: int):
        check_live_port(port)
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
        self.fx = mcap_scene.fx_type
        try:
            self.server = foxglove.start_server(host="127.0.0.1", port=port)
        except Exception as e:  # the SDK's own error type for a port in use
            raise ConfigError(f"--live-port {port}: cannot listen there ({str(e)[:100]}); "
                              "choose another port") from None
        self.scene = SceneUpdateChannel("/scene")
        self.goals = SceneUpdateChannel("/scene/belief")
        self.tf = FrameTransformChannel("/tf")
        self.pose_ch = PoseInFrameChannel("/pose")
        self.cands: list[list[int]] = []

    @property
    def port(self) -> int:
        """The port the server listens on."""
        return int(self.server.port)

    def show(self, ns: int, world, start: Sequence[int], goals: Sequence[Sequence[int]],
             goal: Sequence[int], route: Sequence[Sequence[int]] = ()) -> None:
        """Draw ``world``'s map with the ``start`` cell, the candidate ``goals`` and the true
        ``goal`` (cells ``(x, y)``), and the preferred ``route`` (cells) when known."""
        self.cands = [[int(v) for v in g] for g in goals]
        obstacles = [o.vertices.tolist() for o in world.spec.obstacles]
        self.scene.log(mcap_scene.scene_update(
            ns, (world.spec.width, world.spec.height), obstacles,
            [[int(v) for v in c] for c in route], [int(v) for v in start],
            [int(v) for v in goal]))

    def pose(self, ns: int, x: float, y: float, yaw: float) -> None:
        """The base's pose (m, rad): ``/tf`` and ``/pose``."""
        qz, qw = mcap_scene.quaternion_z(yaw)
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
