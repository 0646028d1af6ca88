"""A sweep on a two-node Ray cluster (both nodes on this machine, ``ray.cluster_utils``): its map
exists only in the driver's memory (the file is moved away before any worker starts), a worker
node is killed while it runs chunks, and a resume finishes the sweep: the database then equals
a clean local run's, row for row and step for step (nothing lost, duplicated or changed)."""

from __future__ import annotations

import json
import sqlite3
import threading
import time

import pytest

from pathpref.episode import cached_map
from pathpref.experiments.sweep import run_sweep, sweep_specs

ROWS = "key, status, success, goal_reached, violations, steps, inputs, start, goals"
STEPS = "key, t, x, y, action, heading"


def table(db, what, name):
    with sqlite3.connect(db) as c:
        return c.execute(f"SELECT {what} FROM {name} ORDER BY {what}").fetchall()


def finished(db) -> int:
    try:
        with sqlite3.connect(db, timeout=5) as c:
            return c.execute("SELECT COUNT(*) FROM episodes WHERE status != 'running'"
                             ).fetchone()[0]
    except sqlite3.OperationalError:  # not created yet
        return 0


def test_cluster_sweep_with_a_driver_only_map_survives_a_killed_node(tmp_path):
    ray = pytest.importorskip("ray")
    from ray.cluster_utils import Cluster

    home = tmp_path / "driver"
    home.mkdir()
    path = home / "plan.json"
    plan = cached_map("simple").to_dict()
    plan["name"] = "plan"
    path.write_text(json.dumps(plan))
    specs = sweep_specs(str(path), ["compliant", "goal_only"], [1, 5], instances=3, runs=4,
                        queries=300)
    clean = tmp_path / "clean.sqlite"
    run_sweep(specs, str(clean), workers=1, progress=False)
    home.rename(tmp_path / "moved")  # from now on only the driver's memory holds the map

    # node deaths noticed within about a second (Ray's default is tens of seconds)
    cluster = Cluster(initialize_head=True, head_node_args={
        "num_cpus": 1, "_system_config": {"health_check_initial_delay_ms": 0,
                                          "health_check_period_ms": 300,
                                          "health_check_failure_threshold": 3}})
    worker = cluster.add_node(num_cpus=2)
    cluster.wait_for_nodes()
    ray.init(address=cluster.address, include_dashboard=False, log_to_driver=False,
             configure_logging=False)
    db = tmp_path / "cluster.sqlite"
    try:
        assert len([n for n in ray.nodes() if n["Alive"]]) == 2
        out: dict = {}

        def sweep() -> None:
            out["first"] = run_sweep(specs, str(db), workers=3, progress=False,
                                     backend="ray")

        t = threading.Thread(target=sweep)
        t.start()
        deadline = time.monotonic() + 120
        while finished(db) == 0 and t.is_alive() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert 0 < finished(db) < len(specs), "the node must die while the sweep runs"
        cluster.remove_node(worker, allow_graceful=False)
        t.join(timeout=180)
        assert not t.is_alive()
        # the sweep may finish on the head before the health check marks the node dead:
        # wait (bounded) for Ray to notice rather than race it
        deadline = time.monotonic() + 60
        while (len([n for n in ray.nodes() if n["Alive"]]) != 1
               and time.monotonic() < deadline):
            time.sleep(0.2)
        assert len([n for n in ray.nodes() if n["Alive"]]) == 1
        first = out["first"]
        assert first["ran"] == len(specs) and first["skipped"] == 0
        # Ray reruns the killed node's chunks; any that failed past its retries are recorded
        # failed and run again by the resume
        resumed = run_sweep(specs, str(db), workers=1, progress=False, backend="ray",
                            retry_failed=True)
        assert resumed["ran"] == first["failed"]
    finally:
        ray.shutdown()
        cluster.shutdown()
    assert table(db, ROWS, "episodes") == table(clean, ROWS, "episodes")
    assert table(db, STEPS, "steps") == table(clean, STEPS, "steps")
    assert {r[1] for r in table(db, ROWS, "episodes")} == {"ok"}
