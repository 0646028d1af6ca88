"""Benchmarks behind ``pathpref bench --json`` and ``scripts/bench.py``, in sections:

* ``maps``: per map, setup (arrangement, cost tables), belief updates, POMCP decisions (paper
  and robust search) against the paper's Table II;
* ``scale``: the 200 x 200 floor plan (fresh process), Ray throughput, rotated 40 x 40 maps;
  the sweep coordinator's ceiling and a sweep on a two-node Ray cluster (:mod:`.cluster`);
* ``physics`` and ``arm``: MuJoCo cue detection, false cues, episode time, rendering, IK;
  the dm_control tasks' step rates (``control_steps_per_s``, :mod:`.tasks`);
* ``tidybot``: the Stanford TidyBot carrying the tray, whole-body IK (:mod:`.tidybot`);
* ``study``: browser front end, WebSocket push to the cue in the belief (``study_latency_ms``);
* ``ros``: the ROS 2 nodes over loopback: push to belief, CPU per wrench message, the two-node
  loop against ``evaluate --sim mujoco`` (:mod:`.ros`; not with ``quick``).

They report numbers; they assert nothing (tests check behaviour). The JSON keys named in the
issues are a contract: add keys, never rename them. Layout::

    {"machine": {...},
     "maps": {"simple": {"arrangement_build_s": ..., "cost_tables_s": ...,
                         "belief_update_ms": ..., "goal_belief_update_ms": ..., ...}, ...},
     "physics": {...}, "arm": {...}, "tidybot": {...},
     "study": {"study_latency_ms": ...}, "ros": {"ros_push_to_belief_ms_p50": ...},
     "scale": {...}}
"""

from __future__ import annotations

from typing import Any

from .cluster import bench_coordinator, bench_ray_cluster
from .maps import bench_map, bench_pomcp, machine_info
from .physics import bench_arm, bench_physics
from .scale import bench_ray, bench_robust_40, bench_scale
from .study import bench_study
from .tasks import bench_tasks
from .tidybot import bench_tidybot

__all__ = ["bench_arm", "bench_coordinator", "bench_map", "bench_physics", "bench_pomcp",
           "bench_ray", "bench_ray_cluster", "bench_robust_40", "bench_scale",
           "bench_study", "bench_tasks", "bench_tidybot", "machine_info", "run_benchmarks"]


def run_benchmarks(maps: list[str] | None = None, quick: bool = False,
                   physics: bool = True) -> dict[str, Any]:
    """All benchmarks as one JSON-ready dictionary (``scale`` is skipped with ``quick``)."""
    maps = maps or ["simple", "office", "classroom"]
    out = {"machine": machine_info(), "maps": {m: bench_map(m, quick=quick) for m in maps}}
    if physics:
        out["physics"] = {**bench_physics(quick=quick), **bench_tasks(quick=quick)}
        out["arm"] = bench_arm(quick=quick)
        out["tidybot"] = bench_tidybot(quick=quick)
        out["study"] = bench_study(quick=quick)
    if physics and not quick:
        from .ros import bench_ros

        out["ros"] = bench_ros()
    if not quick:
        out["scale"] = {**bench_ray(), **bench_coordinator(), **bench_ray_cluster(),
                        **bench_robust_40(), **bench_scale()}
    return out

