"""``scale`` section, sweeps past one machine: the coordinator's ceiling (rows committed per
second from synthetic results) and a sweep on a two-node Ray cluster on this machine."""

from __future__ import annotations

import os
import tempfile
import time
from dataclasses import replace
from typing import Any

from ...episode import run_episode


def bench_coordinator(n: int = 2000, chunk: int = 16) -> dict[str, Any]:
    """What the coordinator of a sweep does per episode, without running any: ``n`` synthetic
    results (one compliant episode on ``classroom``, 61 steps, copied under ``n`` keys) claimed
    and written a chunk of ``chunk`` at a time (:meth:`~.store.ResultStore.claim_many`, then
    :meth:`~.store.ResultStore.add_many`: two write transactions per chunk), with and without
    the per-step rows; and the file's size per episode both ways.

    ``coordinator_episodes_per_s`` (and ``_no_steps``) divide by the wall time, which waits for
    the disk and for the other processes on the machine; ``coordinator_episodes_per_s_cpu``
    (and ``_no_steps_cpu``) by this process's CPU time: the ceiling of one coordinator that has
    a CPU to itself."""
    from ...experiments.backends import failed
    from ...experiments.store import ResultStore
    from ...experiments.sweep import sweep_specs

    spec = sweep_specs("classroom", ["compliant"], [5], instances=1, runs=1, queries=200)[0]
    res = run_episode(spec)
    results = [replace(res, spec=replace(spec, run=i)) for i in range(n)]
    out: dict[str, Any] = {"coordinator_episodes": n, "coordinator_chunk": chunk,
                           "coordinator_steps_per_episode": len(res.log)}
    with tempfile.TemporaryDirectory() as tmp:
        for steps, suffix in ((True, ""), (False, "_no_steps")):
            db = os.path.join(tmp, f"c{suffix}.sqlite")
            with ResultStore(db, steps=steps) as store:
                t, c = time.perf_counter(), time.process_time()
                for i in range(0, n, chunk):
                    part = results[i:i + chunk]
                    store.claim_many([failed(r.spec, "") for r in part])
                    store.add_many(part)
                took, cpu = time.perf_counter() - t, time.process_time() - c
                store.conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
            out[f"coordinator_episodes_per_s{suffix}"] = n / took
            out[f"coordinator_episodes_per_s{suffix}_cpu"] = n / cpu
            out[f"db_kb_per_episode{suffix}"] = os.path.getsize(db) / n / 1024
    return out


def bench_ray_cluster(n: int = 48, queries: int = 5000, map_name: str = "simple",
                      methods: tuple[str, ...] = ("goal_only",)) -> dict[str, Any]:
    """A sweep on a Ray cluster of two nodes of one CPU each, both on this machine
    (``ray.cluster_utils.Cluster``): ``n`` instances of ``methods`` on ``map_name`` (by
    default goal-only episodes on ``simple``, the paper's 5000 queries per decision), the
    coordinator writing a results database as on a real cluster. Start-up and a warm-up sweep
    (each node's workers importing pathpref) are not timed."""
    try:
        import ray
        from ray.cluster_utils import Cluster
    except ImportError:
        return {"ray_cluster_nodes": None, "ray_note": "ray not installed (pip install "
                                                      "pathpref[ray])"}
    from ...experiments.sweep import run_sweep, sweep_specs

    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1})
    cluster.add_node(num_cpus=1)
    cluster.wait_for_nodes()
    ray.init(address=cluster.address, include_dashboard=False, log_to_driver=False,
             configure_logging=False)
    try:
        nodes = sum(1 for node in ray.nodes() if node["Alive"])
        with tempfile.TemporaryDirectory() as tmp:
            warm = sweep_specs(map_name, list(methods), [5], instances=2, runs=1, seed=99,
                               queries=queries)
            run_sweep(warm, os.path.join(tmp, "warm.sqlite"), workers=2, progress=False,
                      backend="ray")
            specs = sweep_specs(map_name, list(methods), [5], instances=n, runs=1, seed=3,
                                queries=queries)
            counts = run_sweep(specs, os.path.join(tmp, "r.sqlite"), workers=2,
                               progress=False, backend="ray")
    finally:
        ray.shutdown()
        cluster.shutdown()
    rate = counts["episodes_per_s"] or None
    return {"ray_cluster_nodes": nodes, "ray_cluster_episodes": counts["ran"],
            "ray_cluster_failed": counts["failed"], "ray_cluster_episodes_per_s": rate,
            "ray_cluster_episodes_per_s_per_node": rate / nodes if rate else None}
