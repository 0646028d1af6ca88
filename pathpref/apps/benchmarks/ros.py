"""``ros`` section: pathpref as ROS 2 nodes over loopback, each figure in a network namespace
of its own (:mod:`pathpref.ros.measure`): ``ros_push_to_belief_ms_p50``/``_p99`` (a wrench
sample that ends a cue, published, to the belief it changed, published),
``ros_cpu_us_per_wrench_msg`` (the planner's CPU per wrench message) and
``ros_sim_loop_equal`` (the two-node loop reaches ``evaluate --sim mujoco``'s outcome on the
stated seeds). Left out of ``--quick`` (about two minutes); ``ros_skipped`` says why when the
extra, ``unshare`` or root is missing."""

from __future__ import annotations

from typing import Any


def bench_ros(quick: bool = False) -> dict[str, Any]:
    """The ``ros`` figures (module docstring)."""
    from ...ros.measure import push_to_belief, sim_loop_equal

    out = push_to_belief(pushes=30)
    if "ros_skipped" in out:
        return out
    return {**out, **sim_loop_equal()}
