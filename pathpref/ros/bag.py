"""The planner's traffic as MCAP, and its offline replay.

:class:`Recorder` writes every message the planner node takes in (wrench, odometry, step
marks) and gives out (waypoint, route, belief, markers) as it goes: an MCAP file of the
``ros2`` profile, each topic's schema the type's ``ros2msg`` definition (the ``.msg`` text of
the installed message packages, with its dependencies after ``====`` separators, as rosbag2
writes it), each message its CDR bytes (``rclpy.serialization``), ``log_time`` the wall clock
(ns) at which the node took or gave it, ``publish_time`` its header stamp (the log time when
it has none). The episode's spec is the metadata record ``pathpref`` (``spec``: its fields
as JSON). rosbag2's MCAP storage and the ``mcap`` reader with ``mcap_ros2``'s decoder read it.

:func:`replay` feeds the recorded inputs, in the order the node took them, through a fresh
:class:`~.planner.PlannerCore` (a step mark decided on once the messages it counts have come,
as the node does) and compares every decision with the recorded outputs: the waypoint and the
belief published at each step mark must be equal bit for bit (the belief's doubles and the
waypoint's coordinates compared as floats, ``==``).
"""

from __future__ import annotations

import json
import re
import sys
import time
from dataclasses import asdict
from pathlib import Path

from ..episode.spec import EpisodeSpec
from ..errors import ConfigError
from .streams import TOPICS, BadMessage, read_odom, read_step, read_wrench

SEP = "=" * 80
#: builtin field types of the ``.msg`` language
_BUILTIN = {"bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16", "uint16",
            "int32", "uint32", "int64", "uint64", "string", "wstring"}


def _msg_text(name: str) -> str:
    """The ``.msg`` text of ``pkg/msg/Type`` from the installed package's share folder."""
    pkg, _, typ = name.split("/")
    path = Path(sys.prefix) / "share" / pkg / "msg" / f"{typ}.msg"  # the wheels' prefix
    if not path.exists():
        from ament_index_python.packages import get_package_share_directory

        path = Path(get_package_share_directory(pkg)) / "msg" / f"{typ}.msg"
    return path.read_text()


def _deps(pkg: str, text: str) -> list[str]:
    """The message types ``text`` (of package ``pkg``) names, as ``pkg/msg/Type``."""
    out = []
    for line in text.splitlines():
        tokens = line.split("#", 1)[0].split()
        if len(tokens) < 2:
            continue
        typ = re.sub(r"\[.*\]$", "", tokens[0]).split("<=")[0]
        if typ in _BUILTIN:
            continue
        if typ == "Header":
            out.append("std_msgs/msg/Header")
        elif "/" in typ:
            out.append(f"{typ.split('/')[0]}/msg/{typ.split('/')[-1]}")
        else:
            out.append(f"{pkg}/msg/{typ}")
    return out


def _with_deps(top: str, pkg: str, seen: set) -> str:
    """``top`` followed by each message type it uses (depth first, once, skipping ``seen``),
    each after a separator and ``MSG: pkg/Type``: the ``ros2msg`` schema's layout."""
    order, todo = [], _deps(pkg, top)
    while todo:
        dep = todo.pop(0)
        if dep in seen:
            continue
        seen.add(dep)
        text = _msg_text(dep)
        order.append((dep, text))
        todo = _deps(dep.split("/")[0], text) + todo
    return top + "".join(f"{SEP}\nMSG: {d.split('/')[0]}/{d.split('/')[2]}\n{t}"
                         for d, t in order)


def definition(name: str) -> str:
    """The ``ros2msg`` schema of ``pkg/msg/Type``: its text, then each type it uses."""
    return _with_deps(_msg_text(name), name.split("/")[0], {name})


#: ``tf2_msgs/msg/TFMessage``: its one field (the rest from geometry_msgs' installed files)
TF_MESSAGE = "tf2_msgs/msg/TFMessage"


def tf_definition() -> str:
    """The ``ros2msg`` schema of ``tf2_msgs/msg/TFMessage``."""
    return _with_deps("geometry_msgs/TransformStamped[] transforms\n", "tf2_msgs", set())


def type_name(msg) -> str:
    """``pkg/msg/Type`` of an ``rclpy`` message."""
    cls = type(msg)
    return f"{cls.__module__.split('.')[0]}/msg/{cls.__name__}"


class Recorder:
    """Writes the node's messages to ``path`` (module docstring)."""

    def __init__(self, path: str | Path, spec: EpisodeSpec):
        from mcap.writer import Writer

        self._file = open(path, "wb")  # noqa: SIM115 - closed by close()
        self.w = Writer(self._file)
        self.w.start(profile="ros2", library="pathpref")
        self.w.add_metadata("pathpref", {"spec": json.dumps(asdict(spec))})
        self._channels: dict[str, int] = {}
        self._seq: dict[str, int] = {}
        self._schemas: dict[str, int] = {}

    def write(self, topic: str, msg) -> None:
        """One message of ``topic``, now."""
        from rclpy.serialization import serialize_message

        cid = self._channels.get(topic)
        if cid is None:
            name = type_name(msg)
            sid = self._schemas.get(name)
            if sid is None:
                sid = self._schemas[name] = self.w.register_schema(
                    name, "ros2msg", definition(name).encode())
            cid = self._channels[topic] = self.w.register_channel(topic, "cdr", sid)
            self._seq[topic] = 0
        now = time.time_ns()
        stamp = getattr(getattr(msg, "header", None), "stamp", None)
        pub = now if stamp is None else stamp.sec * 1_000_000_000 + stamp.nanosec
        self.w.add_message(cid, log_time=now, publish_time=pub, data=serialize_message(msg),
                           sequence=self._seq[topic])
        self._seq[topic] += 1

    def pose(self, ns: int, x: float, y: float, yaw: float) -> None:
        """The base's pose at an odometry message: ``/pose`` (``geometry_msgs/PoseStamped``)
        and ``/tf`` (``tf2_msgs/TFMessage``, ``map -> base_link``; encoded from its
        definition, the registry has no ``tf2_msgs`` wheel), at the odometry's rate."""
        from . import messages as mk
        from .streams import BASE_FRAME, MAP_FRAME, quaternion_z

        self.write(TOPICS["pose"], mk.pose(ns, x, y, yaw))
        if "/tf" not in self._channels:
            sid = self.w.register_schema(TF_MESSAGE, "ros2msg", tf_definition().encode())
            self._channels["/tf"] = self.w.register_channel("/tf", "cdr", sid)
            self._seq["/tf"] = 0
            from mcap_ros2._dynamic import serialize_dynamic

            self._tf = serialize_dynamic(TF_MESSAGE, tf_definition())[TF_MESSAGE]
        qz, qw = quaternion_z(yaw)
        stamp = {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}
        msg = {"transforms": [{"header": {"stamp": stamp, "frame_id": MAP_FRAME},
                               "child_frame_id": BASE_FRAME, "transform": {
                                   "translation": {"x": x, "y": y, "z": 0.0},
                                   "rotation": {"x": 0.0, "y": 0.0, "z": qz, "w": qw}}}]}
        self.w.add_message(self._channels["/tf"], log_time=time.time_ns(), publish_time=ns,
                           data=self._tf(msg), sequence=self._seq["/tf"])
        self._seq["/tf"] += 1

    def close(self) -> None:
        """Finish the file (summary, index)."""
        self.w.finish()
        self._file.close()


def read(path: str | Path):
    """The spec and every message of a recording, in log-time order: ``(topic, decoded)``."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    try:
        f = open(path, "rb")  # noqa: SIM115
    except OSError as e:
        raise ConfigError(f"cannot read the recording {path}: {e.strerror}") from None
    with f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        spec = None
        for m in reader.iter_metadata():
            if m.name == "pathpref":
                spec = EpisodeSpec(**json.loads(m.metadata["spec"]))
        if spec is None:
            raise ConfigError(f"{path}: no 'pathpref' metadata (not written by 'pathpref ros "
                              "planner --record')")
        msgs = [(c.topic, d) for _, c, _, d in reader.iter_decoded_messages(log_time_order=True)]
    return spec, msgs


def replay(path: str | Path, topics: dict | None = None) -> dict:
    """Replay a recording through the planner offline (module docstring): the decisions and
    whether each equals the recorded one bit for bit."""
    from .planner import PlannerCore

    t = {**TOPICS, **(topics or {})}
    spec, msgs = read(path)
    lines: list[str] = []
    core = PlannerCore(spec, warn=lines.append)
    marks, decisions = [], []
    recorded_wp = []
    for topic, m in msgs:
        try:
            if topic == t["wrench"]:
                core.wrench(read_wrench(m, topic))
            elif topic == t["odom"]:
                core.odom(read_odom(m, topic))
            elif topic == t["step"]:
                marks.append(read_step(m, topic))
        except BadMessage as e:
            lines.append(str(e))
            core.n_wrench += topic == t["wrench"]
            core.n_odom += topic == t["odom"]
        if topic == t["waypoint"]:
            p = m.pose.position
            recorded_wp.append((m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec,
                                float(p.x), float(p.y)))
        while marks and core.n_wrench >= marks[0].wrenches and core.n_odom >= marks[0].odoms:
            decisions.append(core.step(marks.pop(0)))
    for mark in marks:  # (a recording cut short: decide on what came)
        decisions.append(core.step(mark))
    moves = [d for d in decisions if not d.done]
    replayed_wp = [(d.stamp_ns, d.target_xy[0], d.target_xy[1]) for d in moves]
    recorded_belief = [list(m.data) for topic, m in msgs if topic == t["belief"]]
    return {"decisions": len(decisions), "actions": [d.action for d in moves],
            "cells": [d.cell for d in decisions], "warnings": lines,
            "waypoints_equal": replayed_wp == recorded_wp,
            "beliefs_equal": _beliefs_equal(moves, recorded_belief),
            "spec": asdict(spec)}


def _beliefs_equal(moves, recorded: list[list[float]]) -> bool:
    """Whether the belief of every replayed decision (goal marginal, route probabilities) is
    among the recorded beliefs in order (the node also publishes the belief after each cue)."""
    want = [list(d.goal_marginal) + list(d.route_probs) for d in moves]
    i = 0
    for b in recorded:
        if i < len(want) and b == want[i]:
            i += 1
    return i == len(want)
