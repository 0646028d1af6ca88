"""The ROS figures of ``pathpref bench --json`` (docs/ros.md), each measured inside a network
namespace of its own (``unshare -n``, loopback up, ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``):

* :func:`push_to_belief`: a publisher process streams the handle's wrench at 500 Hz in real
  time (and odometry at 100 Hz), stamped with the wall clock, with a push every
  :data:`PUSH_EVERY_S` (a half-sine of :data:`PUSH_N` for :data:`PUSH_S`); the planner node
  measures, per cue, the wall time from the stamp of the wrench sample that ended the cue (the
  moment it was published) to the publication of the belief it changed
  (``ros_push_to_belief_ms_p50``/``_p99``), and its own process CPU time over the stream per
  wrench message (``ros_cpu_us_per_wrench_msg``: rclpy's receive and deserialisation, the
  detector, the belief when a cue ends, the executor's idle wake-ups);
* :func:`sim_loop_equal`: ``pathpref ros sim`` and ``pathpref ros planner`` on the stated
  seeds against the same episodes run by ``evaluate --sim mujoco``'s runner (the same steps,
  goal, violations, cells and cues): ``ros_sim_loop_equal``.

Both need root (``unshare``); the figures are absent when it cannot run (the reason is given).
"""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

PUSH_N, PUSH_S, PUSH_EVERY_S = 25.0, 0.3, 1.0
#: the seeds of ``ros_sim_loop_equal`` (simple, path_preference, delta_t 5, default physics)
LOOP_SEEDS = (4,)
RATE_HZ, ODOM_EVERY = 500.0, 5


def namespace_problem() -> str | None:
    """Why the measurements cannot run here (None: they can)."""
    from . import ros_available

    if not ros_available():
        return "the ROS 2 extra is absent (pip install 'pathpref[ros]')"
    if not (shutil.which("unshare") and shutil.which("ip")) or os.geteuid() != 0:
        return "unshare/ip or root is missing (a network namespace of its own)"
    return None


def in_namespace(script: str, env: dict, timeout_s: float) -> subprocess.CompletedProcess:
    """``script`` (sh) in a new network namespace with loopback up."""
    env = {**os.environ, **env, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
           "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl"), "PY": sys.executable}
    return subprocess.run(["unshare", "-n", "sh", "-c", "ip link set lo up || exit 3\n" + script],
                          env=env, timeout=timeout_s, capture_output=True, text=True,
                          cwd=Path(__file__).resolve().parents[2])


def stream_pushes(pushes: int) -> None:
    """The publisher of :func:`push_to_belief` (runs in the namespace): waits for the planner,
    then ``pushes`` pushes in real time toward the eight headings in turn."""
    import rclpy
    from geometry_msgs.msg import WrenchStamped
    from nav_msgs.msg import Odometry

    from . import messages as mk
    from .streams import TOPICS

    rclpy.init()
    node = rclpy.create_node("pathpref_bench_pusher")
    pw = node.create_publisher(WrenchStamped, TOPICS["wrench"], mk.STREAM_QOS)
    po = node.create_publisher(Odometry, TOPICS["odom"], mk.STREAM_QOS)
    end = time.monotonic() + 30
    while time.monotonic() < end and not (pw.get_subscription_count()
                                          and po.get_subscription_count()):
        rclpy.spin_once(node, timeout_sec=0.05)
    time.sleep(1.0)  # the planner's subscriptions matched on its side too
    x, y = 1.5, 1.5  # a free cell's centre of 'simple' (cell (2, 2))
    dt = 1.0 / RATE_HZ
    n = int(round(pushes * PUSH_EVERY_S * RATE_HZ + RATE_HZ))
    t0 = time.perf_counter()
    for k in range(n):
        due = t0 + k * dt
        wait = due - time.perf_counter()
        if wait > 0:  # (sleeping, not spinning: the machine's cores are the planner's too)
            time.sleep(wait)
        t = k * dt - 0.5  # half a second at rest first (the detector calibrates)
        f = 0.0
        i = math.floor(t / PUSH_EVERY_S) if t >= 0 else -1
        if 0 <= i < pushes and t - i * PUSH_EVERY_S < PUSH_S:
            f = PUSH_N * math.sin(math.pi * (t - i * PUSH_EVERY_S) / PUSH_S)
        a = 2 * math.pi * (i % 8) / 8
        ns = time.time_ns()
        if k % ODOM_EVERY == 0:
            po.publish(mk.odometry(ns, x, y, 0.0, 0.0, 0.0, 0.0))
        pw.publish(mk.wrench(ns, "map", (f * math.cos(a), f * math.sin(a), 0.0),
                             (0.0, 0.0, 0.0)))
    po.publish(mk.odometry(time.time_ns(), x, y, 0.0, 0.0, 0.0, 0.0))
    time.sleep(1.0)
    node.destroy_node()
    rclpy.try_shutdown()


def push_to_belief(pushes: int = 20) -> dict:
    """The latency and CPU figures (module docstring)."""
    why = namespace_problem()
    if why:
        return {"ros_skipped": why}
    dur = pushes * PUSH_EVERY_S + 8
    script = (f'"$PY" -c "from pathpref.ros.measure import stream_pushes; '
              f'stream_pushes({int(pushes)})" > /dev/null 2>&1 &\n'
              f'"$PY" -m pathpref ros planner --json --seed 0 --timeout {dur:g} 2> /dev/null\n'
              "wait\n")
    done = in_namespace(script, {}, dur + 60)
    try:
        out = json.loads(done.stdout.strip().splitlines()[-1])
    except (IndexError, ValueError):
        return {"ros_skipped": f"the planner gave no result ({done.stderr.strip()[-200:]})"}
    lat = sorted(1e3 * v for v in out["cue_stamp_latency_s"])
    if not lat:
        return {"ros_skipped": "no cue was felt"}

    def q(p: float) -> float:
        return lat[min(len(lat) - 1, int(math.ceil(p * len(lat))) - 1)]

    return {"ros_push_to_belief_ms_p50": round(q(0.5), 3),
            "ros_push_to_belief_ms_p99": round(q(0.99), 3),
            "ros_cues_measured": len(lat),
            "ros_cpu_us_per_wrench_msg": round(1e6 * out["cpu_s_per_wrench"], 1)}


def loop_outcome(seed: int, folder: Path, timeout_s: float = 150.0) -> tuple[dict, dict]:
    """The sim node's and the planner node's outcomes for ``seed`` (in the namespace)."""
    script = (f'"$PY" -m pathpref ros sim --json --timeout {timeout_s:g} --seed {seed} '
              f'> "{folder}/sim.json" 2> "{folder}/sim.err" &\n'
              f'"$PY" -m pathpref ros planner --json --timeout {timeout_s:g} --seed {seed} '
              f'> "{folder}/planner.json" 2> "{folder}/planner.err"\nwait\n')
    in_namespace(script, {}, timeout_s + 60)
    return (json.loads((folder / "sim.json").read_text()),
            json.loads((folder / "planner.json").read_text()))


def reference(seed: int) -> dict:
    """The episode of ``seed`` as ``evaluate --sim mujoco`` runs it: steps, goal, violations,
    the cells at every decision and the cues (cell, heading)."""
    import pathpref.sim  # noqa: F401  (registers the MuJoCo body)

    from ..episode.physics import Physics
    from ..episode.runner import EpisodeRunner
    from ..episode.spec import EpisodeSpec

    r = EpisodeRunner(EpisodeSpec.single("simple", "path_preference", 5, seed=seed,
                                         sim="mujoco", physics=Physics().to_json()))
    cells = [r.cell]
    while not r.done:
        r.step()
        cells.append(r.cell)
    return {"steps": r.result.steps, "goal_reached": r.result.goal_reached,
            "violations": r.result.violations, "cells": cells,
            "felt": [[f.cell, f.heading] for f in r.body.base.felt]}


def sim_loop_equal(seeds=LOOP_SEEDS) -> dict:
    """``ros_sim_loop_equal`` (module docstring) and the seeds it was judged on."""
    why = namespace_problem()
    if why:
        return {"ros_skipped": why}
    equal = True
    for seed in seeds:
        with tempfile.TemporaryDirectory() as tmp:
            try:
                sim, planner = loop_outcome(seed, Path(tmp))
            except (OSError, ValueError, subprocess.TimeoutExpired):
                equal = False
                continue
        ref = reference(seed)
        for out in (sim, planner):
            equal &= bool(out["done"]) and all(out[k] == ref[k] for k in (
                "steps", "goal_reached", "violations", "cells", "felt"))
    return {"ros_sim_loop_equal": bool(equal), "ros_sim_loop_seeds": list(seeds)}
