"""``pathpref ros planner``: the planner as a ROS 2 node (:class:`~.planner.PlannerCore` on
the robot's topics; docs/ros.md).

In: the handle's ``WrenchStamped``, the base's ``Odometry`` and the base's step marks
(``UInt64MultiArray``, :class:`~.streams.StepMark`). Out, at every step mark: the next waypoint
(``PoseStamped``, stamped with the mark it answers), the planned route (``nav_msgs/Path``),
the belief (``Float64MultiArray``: :func:`.messages.belief`) and the scene
(``visualization_msgs/MarkerArray``); after every cue the belief again; at every odometry
message while a waypoint is pending, the velocity command toward it (``Twist`` in
``base_link``). A message that cannot be read, in the wrong frame or of the wrong type is one
line on stderr; the node goes on.

Topics and frames are ROS parameters (``--ros-args -p wrench_topic:=/ft/wrench ...``):
``wrench_topic``, ``odom_topic``, ``step_topic``, ``path_topic``, ``waypoint_topic``,
``cmd_vel_topic``, ``belief_topic``, ``markers_topic``, ``odom_frame`` and ``map`` (the map file
or built-in name, shown in the parameter list; the episode is the command line's).
"""

from __future__ import annotations

import sys
import time

from ..episode.spec import EpisodeSpec
from .planner import Decision, PlannerCore
from .streams import TOPICS, BadMessage, read_odom, read_step, read_wrench


def _warn(text: str) -> None:
    print(f"pathpref ros planner: {text}", file=sys.stderr, flush=True)


class PlannerNode:
    """The node around a :class:`PlannerCore` (module docstring); ``recorder`` (a
    :class:`~.bag.Recorder`) writes every message in and out."""

    def __init__(self, node, core: PlannerCore, topics: dict, recorder=None, live=None):
        from geometry_msgs.msg import PoseStamped, Twist, WrenchStamped
        from nav_msgs.msg import Odometry, Path
        from std_msgs.msg import Float64MultiArray, UInt64MultiArray
        from visualization_msgs.msg import MarkerArray

        from . import messages as mk

        self.node, self.core, self.mk, self.recorder, self.live = node, core, mk, recorder, live
        for key in ("wrench", "odom", "step", "path", "waypoint", "cmd_vel", "belief",
                    "markers"):
            node.declare_parameter(f"{key}_topic", topics[key])
        node.declare_parameter("odom_frame", core.odom_frame)
        node.declare_parameter("map", core.spec.map)
        self.topics = {k: node.get_parameter(f"{k}_topic").value for k in
                       ("wrench", "odom", "step", "path", "waypoint", "cmd_vel", "belief",
                        "markers")}
        core.odom_frame = node.get_parameter("odom_frame").value
        self._check_types({"wrench": "geometry_msgs/msg/WrenchStamped",
                           "odom": "nav_msgs/msg/Odometry",
                           "step": "std_msgs/msg/UInt64MultiArray"})
        t = self.topics
        node.create_subscription(WrenchStamped, t["wrench"], self.on_wrench, mk.STREAM_QOS)
        node.create_subscription(Odometry, t["odom"], self.on_odom, mk.STREAM_QOS)
        node.create_subscription(UInt64MultiArray, t["step"], self.on_step, mk.MARK_QOS)
        self.pub = {"path": node.create_publisher(Path, t["path"], mk.MARK_QOS),
                    "waypoint": node.create_publisher(PoseStamped, t["waypoint"], mk.MARK_QOS),
                    "cmd_vel": node.create_publisher(Twist, t["cmd_vel"], 10),
                    "belief": node.create_publisher(Float64MultiArray, t["belief"],
                                                    mk.MARK_QOS),
                    "markers": node.create_publisher(MarkerArray, t["markers"], mk.MARK_QOS)}
        self.marks: list = []
        self.waypoint: Decision | None = None
        #: wall time (s) from the arrival of the wrench sample that ended a cue to its belief's
        #: publication, and from its stamp (when the stamps are wall clock: the bench)
        self.cue_latency_s: list[float] = []
        self.cue_stamp_latency_s: list[float] = []
        self.done = False
        #: the process CPU time (s) at the first wrench message, and at the ``cpu_n``-th
        self.cpu_first: float | None = None
        self.cpu_last, self.cpu_n, self._n_in = 0.0, 1, 0

    def _check_types(self, expected: dict) -> None:
        """A topic already carrying another type: one line (the node still subscribes)."""
        for key, want in expected.items():
            for name, types in self.node.get_topic_names_and_types():
                if name == self.topics[key] and want not in types:
                    _warn(f"topic {name} carries {', '.join(types)}; the planner reads {want} "
                          f"there (parameter {key}_topic)")

    def _record(self, topic: str, msg) -> None:
        if self.recorder is not None:
            self.recorder.write(topic, msg)

    def on_wrench(self, msg) -> None:
        """A wrench sample through the detector; the belief when a cue ended."""
        t_in = time.perf_counter()
        self._n_in += 1
        if self.cpu_first is None:
            self.cpu_first = time.process_time()
            self._n_in = 1
        elif self._n_in % 250 == 1:  # (reading a process's CPU clock is costly: 3 ms here)
            self.cpu_last, self.cpu_n = time.process_time(), self._n_in
        self._on_wrench(msg, t_in)

    def _on_wrench(self, msg, t_in: float) -> None:
        self._record(self.topics["wrench"], msg)
        try:
            w = read_wrench(msg, self.topics["wrench"])
        except BadMessage as e:
            self.core.n_wrench += 1  # (counted: the step marks count what was sent)
            _warn(str(e))
            return
        cues = len(self.core.cue_stamps)
        self.core.wrench(w)
        self._after(cues, t_in)

    def _after(self, cues: int, t_in: float) -> None:
        """The belief, when a message just taken (a wrench, or an odometry message that let
        waiting wrenches through) ended a cue; its latencies."""
        if len(self.core.cue_stamps) > cues:
            self.publish_belief(self.core.cue_stamps[-1])
            now = time.perf_counter()
            self.cue_latency_s.append(now - t_in)
            self.cue_stamp_latency_s.append(time.time() - 1e-9 * self.core.cue_stamps[-1])

    def on_odom(self, msg) -> None:
        """An odometry message; the velocity command toward a pending waypoint."""
        self._record(self.topics["odom"], msg)
        try:
            o = read_odom(msg, self.topics["odom"])
        except BadMessage as e:
            self.core.n_odom += 1
            _warn(str(e))
            return
        cues, t_in = len(self.core.cue_stamps), time.perf_counter()
        self.core.odom(o)
        self._after(cues, t_in)
        if self.live is not None:
            self.live.pose(o.stamp_ns, o.x, o.y, o.yaw)
        if self.recorder is not None:
            self.recorder.pose(o.stamp_ns, o.x, o.y, o.yaw)
        if self.waypoint is not None and not self.waypoint.done:
            self.pub["cmd_vel"].publish(self.mk.twist(
                *self.core.velocity_command(self.waypoint.target_xy)))

    def on_step(self, msg) -> None:
        """A step mark, decided on once the streams have reached its counts
        (:meth:`poll`)."""
        self._record(self.topics["step"], msg)
        try:
            self.marks.append((read_step(msg, self.topics["step"]), time.monotonic()))
        except BadMessage as e:
            _warn(str(e))

    def poll(self, wait_s: float = 2.0) -> None:
        """Decide on the first waiting mark whose messages have all arrived (or after
        ``wait_s``: one line naming what is missing)."""
        while self.marks:
            mark, since = self.marks[0]
            c = self.core
            short = c.n_wrench < mark.wrenches or c.n_odom < mark.odoms
            if short and time.monotonic() - since < wait_s:
                return
            if short:
                _warn(f"step {mark.step}: {c.n_wrench}/{mark.wrenches} wrench and "
                      f"{c.n_odom}/{mark.odoms} odometry messages arrived; deciding without "
                      "the rest")
            self.marks.pop(0)
            self.publish(c.step(mark))

    def publish_belief(self, ns: int) -> None:
        """The belief now: the goal marginal now and the route probabilities of the last
        decision (a route belief's preference marginals take 0.1 s per polytope on this
        machine: they are computed at decisions, not at every cue)."""
        probs = self.core.planned_probs
        g = [float(p) for p in self.core.runner.policy.belief.goal_marginal()]
        msg = self.mk.belief(g, probs)
        self.pub["belief"].publish(msg)
        self._record(self.topics["belief"], msg)
        if self.live is not None:
            self.live.belief(ns, g)

    def publish(self, d: Decision) -> None:
        """A decision's messages."""
        mk, core = self.mk, self.core
        if d.done:
            self.done, self.waypoint = True, None
            self.publish_belief(d.stamp_ns)
            return
        self.waypoint = d
        scene = core.scene
        pts = [tuple(float(v) for v in scene.cell_centre(c)) for c in d.route]
        wp = mk.pose(d.stamp_ns, *d.target_xy, 0.0)
        for key, msg in (("path", mk.path(d.stamp_ns, pts)),
                         ("belief", mk.belief(d.goal_marginal, d.route_probs)),
                         ("markers", self.scene_markers(d, pts)),
                         ("waypoint", wp)):
            self.pub[key].publish(msg)
            self._record(self.topics[key], msg)
        if self.live is not None:
            self.live.belief(d.stamp_ns, d.goal_marginal)

    def scene_markers(self, d: Decision, pts):
        """The map, goals and route as a ``MarkerArray``."""
        w = self.core.world
        width, height = w.spec.width, w.spec.height
        cells = [tuple(int(v) for v in w.cells[g]) for g in self.core.runner.instance.goals]
        obstacles = [[tuple(float(c) for c in v) for v in o.vertices] for o in w.spec.obstacles]
        return self.mk.markers(d.stamp_ns, [(0, 0), (width, 0), (width, height), (0, height)],
                               obstacles, cells, d.goal_marginal, pts, self.core.scene.cell_size)


def run_planner(spec: EpisodeSpec, topics: dict | None = None, timeout_s: float = 120.0,
                record: str | None = None, live_port: int | None = None,
                ros_args=None, mark_wait_s: float = 30.0) -> dict:
    """Run the planner node until the episode ends (or ``timeout_s`` of wall time); its
    outcome: the decisions, cues, latencies. A step mark waits up to ``mark_wait_s`` for the
    messages it counts."""
    from . import require_ros

    rclpy = require_ros()
    topics = {**TOPICS, **(topics or {})}
    core = PlannerCore(spec, warn=_warn)
    recorder = None
    if record:
        from .bag import Recorder

        recorder = Recorder(record, spec)
    live = None
    if live_port is not None:
        from ..study.live import LiveView

        inst = core.runner.instance
        live = LiveView(live_port)
        w = core.world
        live.show(time.time_ns(), w, w.cells[inst.start], w.cells[list(inst.goals)],
                  w.cells[inst.goal_cell])
    rclpy.init(args=ros_args)
    try:
        node = rclpy.create_node("pathpref_planner")
        pn = PlannerNode(node, core, topics, recorder, live)
        from .messages import executor

        ex = executor()
        ex.add_node(node)
        end = time.monotonic() + timeout_s
        while not pn.done and time.monotonic() < end:
            ex.spin_once(timeout_sec=0.02)
            pn.poll(mark_wait_s)
        if not pn.done:
            _warn(f"stopped after {timeout_s:g} s: no step mark ended the episode")
        t_flush = time.monotonic() + 0.5  # let the last messages go out
        while time.monotonic() < t_flush:
            ex.spin_once(timeout_sec=0.05)
        ex.shutdown()
        node.destroy_node()
    finally:
        rclpy.try_shutdown()
        if recorder is not None:
            recorder.close()
        if live is not None:
            live.close()
    r = core.runner.result
    return {"done": pn.done, "steps": r.steps, "goal_reached": r.goal_reached,
            "violations": r.violations,
            "cells": [d.cell for d in core.decisions],
            "actions": [d.action for d in core.decisions if not d.done],
            "headings": [d.heading for d in core.decisions if not d.done],
            "felt": [(f.cell, f.heading) for f in core.felt],
            "peaks": [f.peak_n for f in core.felt],
            "log": [(s.t, s.x, s.y, s.action, s.heading, s.p_true_goal, s.goal_entropy)
                    for s in r.log],
            "wrenches": core.n_wrench, "odoms": core.n_odom,
            "cue_latency_s": pn.cue_latency_s, "cue_stamp_latency_s": pn.cue_stamp_latency_s,
            "cpu_s_per_wrench": (pn.cpu_last - pn.cpu_first) / (pn.cpu_n - 1)
            if pn.cpu_n > 1 else None}
