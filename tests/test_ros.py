"""pathpref as ROS 2 nodes (docs/ros.md): the two-node loop (``pathpref ros sim`` and ``pathpref
ros planner``) reaches the outcome of ``evaluate --sim mujoco`` for the same seed, inside a
network namespace of its own (``unshare -n``, loopback up, ``ROS_AUTOMATIC_DISCOVERY_RANGE=
LOCALHOST``: discovery cannot leave the machine); messages it cannot read are one line.

Without the ``ros`` extra the ROS tests are skipped with one line saying so; the readers and
the planner's core (no ROS) are tested either way."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace as N

import numpy as np
import pytest

from pathpref.episode.physics import Physics
from pathpref.episode.spec import EpisodeSpec
from pathpref.errors import ConfigError

ROOT = Path(__file__).resolve().parents[1]


def _spec(seed: int) -> EpisodeSpec:
    return EpisodeSpec.single("simple", "path_preference", 5, seed=seed, sim="mujoco",
                              physics=Physics().to_json())


def _reference(spec: EpisodeSpec) -> dict:
    """``evaluate --sim mujoco``'s episode, stepped by its own runner: the cells and actions
    at every decision, the cues felt (cell, heading, peak force)."""
    import pathpref.sim  # noqa: F401  (registers the MuJoCo body)
    from pathpref.episode.runner import EpisodeRunner

    r = EpisodeRunner(spec)
    cells, actions = [], []
    while not r.done:
        cells.append(r.cell)
        log = r.step()
        actions.append(log.action)
    cells.append(r.cell)
    felt = r.body.base.felt
    return {"steps": r.result.steps, "goal_reached": r.result.goal_reached,
            "violations": r.result.violations, "cells": cells, "actions": actions,
            "felt": [[f.cell, f.heading] for f in felt], "peaks": [f.peak_n for f in felt]}


def test_readers_refuse_malformed_messages():
    """A message missing a field, with a non-finite value or a non-unit quaternion is a
    BadMessage naming the topic's field (the node prints it as one line and goes on)."""
    from pathpref.ros.streams import BadMessage, read_odom, read_step, read_wrench

    stamp = N(sec=1, nanosec=5)
    ok = N(header=N(stamp=stamp, frame_id="map"),
           wrench=N(force=N(x=1.0, y=2.0, z=0.0), torque=N(x=0.0, y=0.0, z=0.1)))
    w = read_wrench(ok)
    assert (w.stamp_ns, w.frame, w.force) == (1_000_000_005, "map", (1.0, 2.0, 0.0))
    bad = [N(header=N(stamp=stamp, frame_id="map"), wrench=N(force=N(x=float("nan"), y=0,
                                                                     z=0), torque=N(x=0, y=0,
                                                                                    z=0))),
           N(header=N(stamp=stamp, frame_id="map")),  # a Twist-like message: no wrench
           N(header=N(stamp=N(sec=0, nanosec=2_000_000_000), frame_id="map"), wrench=None)]
    for msg in bad:
        with pytest.raises(BadMessage) as e:
            read_wrench(msg, "/w")
        assert e.value.args[0].startswith("/w") and "\n" not in e.value.args[0]
    pose = N(position=N(x=0.1, y=0.2, z=0.0), orientation=N(x=0.0, y=0.0, z=0.5, w=0.5))
    twist = N(linear=N(x=0.0, y=0.0, z=0.0), angular=N(x=0.0, y=0.0, z=0.0))
    with pytest.raises(BadMessage, match="unit quaternion"):
        read_odom(N(header=N(stamp=stamp, frame_id="map"), child_frame_id="base_link",
                    pose=N(pose=pose), twist=N(twist=twist)))
    with pytest.raises(BadMessage, match="5 values"):
        read_step(N(data=[1, 2, 3]))


def test_core_refuses_a_wrench_in_another_frame():
    """A wrench in a frame the planner cannot turn into the map's is refused with one line
    and changes nothing; one in ``base_link`` is turned by the base's yaw."""
    from pathpref.ros.planner import PlannerCore
    from pathpref.ros.streams import Odom, Wrench

    lines: list[str] = []
    core = PlannerCore(_spec(0), warn=lines.append)
    core.wrench(Wrench(0, "camera", (30.0, 0.0, 0.0), (0.0, 0.0, 0.0)))
    assert len(lines) == 1 and "'camera'" in lines[0] and core.n_wrench == 1
    core.odom(Odom(0, "odom", "base_link", 0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
    assert len(lines) == 2 and "odom_frame" in lines[1]
    core.odom(Odom(0, "map", "base_link", *core.pose[:2], np.pi / 2, 0.0, 0.0, 0.0))
    core.wrench(Wrench(0, "base_link", (10.0, 0.0, 0.0), (0.0, 0.0, 0.0)))
    assert np.allclose(core.force_estimate, [0.0, 10.0], atol=1e-12)


def test_missing_extra_is_one_line(monkeypatch):
    """Without rclpy the ``ros`` commands stop with one line naming the extra."""
    import pathpref.ros as ros

    monkeypatch.setitem(sys.modules, "rclpy", None)
    with pytest.raises(ConfigError) as e:
        ros.require_ros()
    assert "pathpref[ros]" in str(e.value) and "\n" not in str(e.value)
    assert not ros.ros_available()


def _namespace_ready() -> str | None:
    from pathpref.ros import ros_available

    if not ros_available():
        return "the ROS 2 extra is absent (pip install 'pathpref[ros]'): ROS node tests skipped"
    if not (shutil.which("unshare") and shutil.which("ip")) or os.geteuid() != 0:
        return "unshare/ip or root missing: the ROS node tests need a network namespace"
    return None


#: the two nodes in a network namespace of their own (loopback up, discovery on localhost)
PAIR = """
ip link set lo up || exit 3
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST MUJOCO_GL=egl
"$PY" -m pathpref ros sim --json --timeout 100 $ARGS > "$OUT/sim.json" 2> "$OUT/sim.err" &
"$PY" -m pathpref ros planner --json --timeout 100 $ARGS --record "$OUT/planner.mcap" \
    > "$OUT/planner.json" \
    2> "$OUT/planner.err"
wait
"""


def test_two_nodes_reach_evaluates_outcome(tmp_path):
    """Seed 4 of ``simple`` (path_preference, delta_t 5, default physics; 8 steps, 2 cues):
    the planner's decisions (cells and actions), the cues (cell and heading) and the outcome
    (steps, goal, violations) equal those of the same episode run by ``evaluate --sim
    mujoco``'s runner; the cues' peak forces agree to 1e-6 relative (the remote detector's
    rest rule reads the odometry's twist, not the estimator's joint velocities)."""
    why = _namespace_ready()
    if why:
        pytest.skip(why)
    env = {**os.environ, "PY": sys.executable, "OUT": str(tmp_path), "ARGS": "--seed 4"}
    done = subprocess.run(["unshare", "-n", "sh", "-c", PAIR], cwd=ROOT, env=env,
                          timeout=180, capture_output=True, text=True)
    errs = (tmp_path / "sim.err").read_text() + (tmp_path / "planner.err").read_text()
    assert done.returncode == 0, done.stderr + errs
    sim = json.loads((tmp_path / "sim.json").read_text())
    planner = json.loads((tmp_path / "planner.json").read_text())
    ref = _reference(_spec(4))
    assert ref["steps"] == 8 and len(ref["felt"]) == 2  # the episode the docstring names
    for out in (sim, planner):
        assert out["done"] and (out["steps"], out["goal_reached"], out["violations"]) == (
            ref["steps"], ref["goal_reached"], ref["violations"])
        assert out["felt"] == ref["felt"]
    assert sim["cells"] == ref["cells"]
    assert planner["cells"] == ref["cells"] and planner["actions"] == ref["actions"]
    assert np.allclose(planner["peaks"], ref["peaks"], rtol=1e-6, atol=0)
    assert planner["wrenches"] == sim["wrenches"]  # no sample lost on the way
    assert "deciding without" not in errs
    # the recording: rosbag2's profile, and the planner's decisions again offline
    from mcap.reader import make_reader

    from pathpref.ros.bag import replay

    with open(tmp_path / "planner.mcap", "rb") as f:
        reader = make_reader(f)
        assert reader.get_header().profile == "ros2"
        summary = reader.get_summary()
        encodings = {s.encoding for s in summary.schemas.values()}
        topics = {c.topic: summary.statistics.channel_message_counts[i]
                  for i, c in summary.channels.items()}
    assert encodings == {"ros2msg"}
    assert topics["/pathpref/handle/wrench"] == sim["wrenches"]
    # /tf and /pose at the odometry's rate (sim time: at least 50 Hz), the push's torque
    assert topics["/tf"] == topics["/pose"] == topics["/odom"] == planner["odoms"]
    from mcap_ros2.decoder import DecoderFactory

    stamps, torques = [], []
    with open(tmp_path / "planner.mcap", "rb") as f:
        for _, ch, _, m in make_reader(f, decoder_factories=[DecoderFactory()]) \
                .iter_decoded_messages(topics=["/pose", "/pathpref/handle/wrench"]):
            t = m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec
            if ch.topic == "/pose":
                stamps.append(t)
            elif np.hypot(m.wrench.force.x, m.wrench.force.y) > 8.0:  # a push under way
                torques.append(np.hypot(m.wrench.torque.x, m.wrench.torque.y))
    assert max(np.diff(stamps)) <= 0.02 + 1e-9  # >= 50 Hz everywhere
    assert torques and min(torques) > 0.05 * 8.0 * 0.99  # 5 cm below the sensor: 0.05 |F|
    again = replay(tmp_path / "planner.mcap")
    assert again["waypoints_equal"] and again["beliefs_equal"]
    assert again["actions"] == ref["actions"] and again["cells"] == ref["cells"]


#: a publisher of messages the planner must refuse with one line each: a wrench in the frame
#: 'camera', odometry with a non-unit quaternion, a step mark of two values; then a String on
#: the wrench topic's name under another type is simply not delivered (DDS matches types)
BAD = r"""
import time, rclpy
from geometry_msgs.msg import WrenchStamped
from nav_msgs.msg import Odometry
from std_msgs.msg import UInt64MultiArray
from pathpref.ros import messages as mk
rclpy.init()
n = rclpy.create_node("bad")
pw = n.create_publisher(WrenchStamped, "/pathpref/handle/wrench", mk.STREAM_QOS)
po = n.create_publisher(Odometry, "/odom", mk.STREAM_QOS)
ps = n.create_publisher(UInt64MultiArray, "/pathpref/step", mk.MARK_QOS)
end = time.monotonic() + 20
while time.monotonic() < end and not (pw.get_subscription_count() and
                                      po.get_subscription_count()):
    rclpy.spin_once(n, timeout_sec=0.05)
time.sleep(0.5)
pw.publish(mk.wrench(1, "camera", (30.0, 0.0, 0.0), (0.0, 0.0, 0.0)))
o = mk.odometry(2, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0)
o.pose.pose.orientation.w = 2.0
po.publish(o)
m = UInt64MultiArray(); m.data = [1, 2]
ps.publish(m)
time.sleep(2.0)
"""


def test_planner_node_survives_malformed_messages(tmp_path):
    """The planner node, sent a wrench in a frame it cannot use, odometry with a non-unit
    quaternion and a step mark of the wrong length, prints one line for each and keeps
    running until its timeout (exit 1: no episode ended; no traceback)."""
    why = _namespace_ready()
    if why:
        pytest.skip(why)
    (tmp_path / "bad.py").write_text(BAD)
    script = ('export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST MUJOCO_GL=egl\n'
              'ip link set lo up || exit 3\n'
              '"$PY" "$OUT/bad.py" > "$OUT/bad.out" 2>&1 &\n'
              '"$PY" -m pathpref ros planner --timeout 8 --seed 0 > "$OUT/pl.out" '
              '2> "$OUT/pl.err"\necho "rc=$?" >> "$OUT/pl.out"\nwait\n')
    env = {**os.environ, "PY": sys.executable, "OUT": str(tmp_path),
           "PYTHONPATH": str(ROOT)}
    subprocess.run(["unshare", "-n", "sh", "-c", script], cwd=ROOT, env=env, timeout=120)
    err = (tmp_path / "pl.err").read_text()
    assert "rc=1" in (tmp_path / "pl.out").read_text(), err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert any("'camera'" in x and "refused" in x for x in lines), err
    assert any("unit quaternion" in x for x in lines), err
    assert any("5 values" in x for x in lines), err
    assert all(x.startswith("pathpref ros planner: ") for x in lines), err


def test_sim_follows_the_velocity_command(tmp_path):
    """``pathpref ros sim --drive cmd_vel --realtime 1``: the base drives by the planner's
    ``/cmd_vel`` (held by its drive within ``a_max``) instead of its own tracking controller;
    on seed 0 (2 steps, 1 cue) the two nodes end the episode together at the goal, the robot
    in the cells the planner saw, after taking hundreds of velocity commands."""
    why = _namespace_ready()
    if why:
        pytest.skip(why)
    script = ('export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST MUJOCO_GL=egl\n'
              'ip link set lo up || exit 3\n'
              '"$PY" -m pathpref ros sim --json --timeout 60 --seed 0 --drive cmd_vel '
              '--realtime 1 > "$OUT/sim.json" 2> "$OUT/sim.err" &\n'
              '"$PY" -m pathpref ros planner --json --timeout 60 --seed 0 '
              '> "$OUT/planner.json" 2> "$OUT/planner.err"\nwait\n')
    env = {**os.environ, "PY": sys.executable, "OUT": str(tmp_path)}
    subprocess.run(["unshare", "-n", "sh", "-c", script], cwd=ROOT, env=env, timeout=150)
    errs = (tmp_path / "sim.err").read_text() + (tmp_path / "planner.err").read_text()
    sim = json.loads((tmp_path / "sim.json").read_text())
    planner = json.loads((tmp_path / "planner.json").read_text())
    assert sim["done"] and planner["done"] and sim["goal_reached"], errs
    assert sim["steps"] == planner["steps"] and sim["cells"] == planner["cells"]
    assert sim["felt"] == planner["felt"] and len(sim["felt"]) >= 1
    assert sim["cmd_vel"] > 100



def _streams(core_cls, spec, lag: int):
    """Feed a planner core 500 Hz map-frame wrenches (two 25 N, 0.3 s pushes) and 100 Hz
    odometry of a base creeping along x, each odometry message delivered ``lag`` wrench
    samples after its stamp (negative: before); returns the core and, per wrench delivered,
    the number of cues felt so far."""
    from pathpref.ros.streams import Odom, Wrench

    core = core_cls(spec, warn=lambda line: None)
    x0, y0 = core.pose[:2]
    dt_ns, n = 2_000_000, 1500
    odoms = [Odom((k + 1) * dt_ns, "map", "base_link", x0 + 1e-4 * k, y0, 0.0, 0.05, 0.0,
                  0.0) for k in range(0, n, 5)]
    felt_after = []
    for k in range(n):
        ns = (k + 1) * dt_ns
        t = k * 0.002 - 0.5
        f = 0.0
        for start in (0.0, 1.5):
            if 0.0 <= t - start < 0.3:
                f = 25.0 * np.sin(np.pi * (t - start) / 0.3)
        while odoms and odoms[0].stamp_ns <= ns - lag * dt_ns:
            core.odom(odoms.pop(0))
        a = 2.0 if t > 1.0 else 0.0
        core.wrench(Wrench(ns, "map", (f * np.cos(a), f * np.sin(a), 0.0), (0.0, 0.0, 0.0)))
        felt_after.append(len(core.cue_stamps))
    for o in odoms:
        core.odom(o)
    return core, felt_after


@pytest.mark.parametrize("physical", [False, True])
def test_a_cue_ends_without_waiting_for_the_odometry(physical):
    """A map-frame wrench while a cue is under way is taken before the odometry reaches its
    stamp, with the outcome of stamp order: with the odometry 10 samples (20 ms) late, the
    cues (cells, headings, times, peaks), the belief and the state the streams leave are
    those of odometry delivered ahead of every wrench, and each cue is felt at the wrench
    sample that ends it (it waited up to an odometry period before). ``physical``: the
    default physics' filtered detector, whose rest rule reads the odometry; else the ideal
    sensor's."""
    from pathpref.ros.planner import PlannerCore

    spec = _spec(0) if physical else EpisodeSpec.single("simple", "path_preference", 5, seed=0)
    ahead, felt_a = _streams(PlannerCore, spec, lag=-5)
    late, felt_b = _streams(PlannerCore, spec, lag=10)
    assert len(ahead.felt) == 2  # both pushes read
    assert ahead.n_ahead == 0 and late.n_ahead > 0
    assert [(f.cell, f.heading, f.t_felt, f.t_cue, f.peak_n) for f in late.felt] == \
        [(f.cell, f.heading, f.t_felt, f.t_cue, f.peak_n) for f in ahead.felt]
    assert late.cue_stamps == ahead.cue_stamps
    assert felt_b == felt_a  # each cue felt when its last sample arrived, not 20 ms later
    assert np.array_equal(late.runner.policy.belief.goal_marginal(),
                          ahead.runner.policy.belief.goal_marginal())
    assert (late.cell, late.pose, late._quiet) == (ahead.cell, ahead.pose, ahead._quiet)
