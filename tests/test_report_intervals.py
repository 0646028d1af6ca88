"""Wilson intervals contain the rate exactly, so figures never get negative error bars."""

from __future__ import annotations

from pathpref.apps.cli import main
from pathpref.experiments.report import wilson

from .store_helpers import synthetic_db


def test_all_success_and_all_failure_intervals_contain_the_rate():
    for n in range(1, 401):
        for k in (0, n):
            p = k / n
            lo, hi = wilson(k, n)
            assert 0.0 <= lo <= p <= hi <= 1.0, (k, n, lo, hi)
            assert p - lo >= 0 and hi - p >= 0, (k, n, lo, hi)


def test_intervals_contain_the_rate_for_every_count():
    for n in range(1, 120):
        for k in range(n + 1):
            lo, hi = wilson(k, n)
            assert 0.0 <= lo <= k / n <= hi <= 1.0


def test_report_figure_of_all_success_and_all_failure_cells(tmp_path, capsys):
    """n = 6 is one of the sizes whose unclipped interval missed p by an ulp."""
    db = synthetic_db(tmp_path / "r.sqlite", {("compliant", 1): (6, 6), ("compliant", 5): (0, 6),
                                              ("goal_only", 1): (0, 6), ("goal_only", 5): (6, 6)})
    fig = tmp_path / "f.png"
    assert main(["report", str(db), "--figure", str(fig)]) == 0, capsys.readouterr().err
    out = capsys.readouterr().out
    assert "1.00 [0.61, 1.00]" in out and "0.00 [0.00, 0.39]" in out
    assert fig.stat().st_size > 1000


def test_table_rows_come_in_a_fixed_order_whatever_order_the_episodes_were_stored(tmp_path,
                                                                               capsys):
    """The paper's four, then the reference rows (goal_known before oracle), then registered
    methods by name: a sweep whose oracle finished first printed the oracle row first."""
    cells = {("oracle", 1): (6, 6), ("zz_custom", 1): (1, 6), ("goal_known", 1): (3, 6),
             ("aa_custom", 1): (2, 6), ("path_preference", 1): (4, 6), ("compliant", 1): (1, 6)}
    db = synthetic_db(tmp_path / "r.sqlite", cells)
    assert main(["report", str(db)]) == 0, capsys.readouterr().err
    rows = [line.split("|")[1].strip() for line in capsys.readouterr().out.splitlines()
            if line.startswith("| ") and "method" not in line]
    assert rows[:6] == ["compliant", "path preference", "goal_known", "oracle", "aa_custom",
                        "zz_custom"], rows


def _fail_rows(db, method: str, count: int) -> None:
    """Mark ``count`` of ``method``'s unsuccessful rows as failed episodes (as a sweep writes
    them: status 'failed', every flag 0 but pref_followed, no step rows)."""
    import sqlite3

    with sqlite3.connect(db) as c:
        keys = [r[0] for r in c.execute("SELECT key FROM episodes WHERE method = ? AND "
                                        "success = 0 ORDER BY key LIMIT ?", (method, count))]
        for k in keys:
            c.execute("UPDATE episodes SET status = 'failed', reason = 'EpisodeError: x', "
                      "goal_reached = 0, success = 0, pref_followed = 1 WHERE key = ?", (k,))
            c.execute("DELETE FROM steps WHERE key = ?", (k,))
    c.close()


def test_failed_episodes_count_as_failures_by_default(tmp_path, capsys):
    """9 successes in 24 rows of which 3 failed: 0.38 (9/24), never 0.43 (9/21); every table
    says how many rows failed; --exclude-failed is the explicit alternative."""
    import csv

    from pathpref.experiments.report import load_records

    db = synthetic_db(tmp_path / "r.sqlite", {("compliant", 1): (9, 24),
                                              ("goal_only", 1): (4, 24)})
    _fail_rows(db, "compliant", 3)
    rec = {r["method"]: r for r in load_records(db)}
    assert (rec["compliant"]["n"], rec["compliant"]["failed"]) == (24, 3)
    assert rec["compliant"]["success_rate"] == 9 / 24 and rec["compliant"]["goal_rate"] == 9 / 24
    assert rec["compliant"]["pref_rate"] == 21 / 24  # a failed row followed nothing
    assert (rec["goal_only"]["n"], rec["goal_only"]["failed"]) == (24, 0)
    assert main(["report", str(db)]) == 0, capsys.readouterr().err
    out = capsys.readouterr().out
    assert "0.38 [" in out and "0.43" not in out and "(3 failed)" in out
    assert "3 failed rows, counted as failures" in out
    rows = list(csv.DictReader(open(tmp_path / "r.csv")))
    keys = {"map", "map_hash", "sim", "variant", "method", "delta_t", "n", "failed",
            "success_rate", "ci_low", "ci_high", "goal_rate", "pref_rate", "instances"}
    assert keys <= set(rows[0]) and rows[0]["failed_excluded"] == "False"
    # the explicit opt-out: failed rows left out of the rates, still counted
    assert main(["report", str(db), "--exclude-failed"]) == 0
    out = capsys.readouterr().out
    assert "0.43 [" in out and "3 failed rows, left out of the rates" in out
    ex = {r["method"]: r for r in load_records(db, exclude_failed=True)}
    assert (ex["compliant"]["n"], ex["compliant"]["failed"]) == (21, 3)


def test_a_cell_of_failed_rows_only_shows_them(tmp_path, capsys):
    db = synthetic_db(tmp_path / "r.sqlite", {("compliant", 1): (0, 2), ("compliant", 5): (1, 2)})
    _fail_rows(db, "compliant", 2)  # both of ΔT=1 (keys sort by ΔT first)
    assert main(["report", str(db), "--exclude-failed"]) == 0
    assert "– (2 failed)" in capsys.readouterr().out
    assert main(["report", str(db)]) == 0
    assert "0.00 [0.00, 0.66] (2 failed)" in capsys.readouterr().out


def _row(**kw):
    from .store_helpers import BASE

    return {**BASE, "key": kw.pop("key"), "instance_seed": 0, "run_seed": 0, "instance": 0,
            "delta_t": 5, "method": "path_preference", "success": 1, "goal_reached": 1,
            "steps": 5, **kw}


def test_cells_never_mix_physics_human_or_prior():
    """Rows that differ only in their physics, their human or their prior land in separate
    cells (two sensor noises, 2/6 and 5/6 successes, were printed as 0.50); the physical
    cells sum how the pushes were read."""
    import json

    from pathpref.episode import Physics
    from pathpref.experiments.report import physical_tables, success_table

    noisy = Physics.of(sensor_noise_n=50.0).to_json()
    rows = []
    for i in range(6):
        for phys, wins, missed in ((Physics().to_json(), 5, 0), (noisy, 2, 3)):
            rows.append(_row(key=f"m{i}{wins}", sim="mujoco", physics=phys,
                             success=int(i < wins), goal_reached=int(i < wins),
                             metrics=json.dumps({"pushes": 3.0, "pushes_missed": float(missed),
                                                 "pushes_misread": 0.0, "collisions": 1.0,
                                                 "cue_latency_ms": 300.0 + 10 * i})))
    rows += [_row(key=f"h{i}", human=h, success=int(h == "map")) for i in range(4)
             for h in ("map", "consistent")]
    rows += [_row(key=f"p{i}{p}", prior=p, map="office", map_hash="h1") for i in range(3)
             for p in ("independent", "routes")]
    recs = success_table(rows)
    phys = [r for r in recs if r["sim"] == "mujoco"]
    assert sorted((r["n"], r["success_rate"]) for r in phys) == [(6, 2 / 6), (6, 5 / 6)]
    noisy_rec = next(r for r in phys if r["success_rate"] == 2 / 6)
    assert "sensor_noise_n=50" in noisy_rec["variant"]
    assert "default physics" in next(r for r in phys if r is not noisy_rec)["variant"]
    assert (noisy_rec["pushes"], noisy_rec["pushes_missed"], noisy_rec["collisions"]) == \
        (18, 18, 6)
    assert noisy_rec["cue_latency_ms"] == 325.0  # the mean of 300 .. 350
    grid = [r for r in recs if r["sim"] == "grid"]
    humans = {r["variant"]: r["success_rate"] for r in grid if r["n"] == 4}
    assert sorted(humans.values()) == [0.0, 1.0] and any("consistent human" in v
                                                         for v in humans)
    priors = [r for r in grid if r["map"] == "office"]
    assert [r["n"] for r in priors] == [3, 3]
    assert sum("routes prior" in r["variant"] for r in priors) == 1
    table = physical_tables(recs)
    assert "missed 18 / misread 0 of 18, latency 325 ms, 6 collisions" in table


def test_physical_episodes_count_missed_pushes_and_collisions():
    """Measured on MuJoCo episodes: a 50 N-noise sensor misses every push that the default
    sensor reads; a base driven into a wall counts one collision per contact begun."""
    import os

    os.environ.setdefault("MUJOCO_GL", "egl")
    import numpy as np

    import pathpref.sim  # noqa: F401 - registers the MuJoCo body
    from pathpref.episode import EpisodeSpec, Physics, run_episode
    from pathpref.geometry.world import load_world
    from pathpref.sim.mobile_base import MobileBase
    from pathpref.sim.scene import build_scene

    out = {}
    for name, phys in (("default", Physics()), ("noisy", Physics.of(sensor_noise_n=50.0))):
        spec = EpisodeSpec.single("simple", "compliant", 1, sim="mujoco", queries=50,
                                  t_max=6, physics=phys.to_json(), seed=3)
        out[name] = run_episode(spec).metrics
    assert out["noisy"]["pushes"] >= 2
    assert out["noisy"]["pushes_missed"] == out["noisy"]["pushes"]
    assert "cue_latency_ms" not in out["noisy"]  # no cue, no latency (no NaN stored)
    assert out["default"]["pushes"] >= 1 and out["default"]["pushes_missed"] == 0
    assert 100 < out["default"]["cue_latency_ms"] < 2000
    world = load_world("simple")
    base = MobileBase(build_scene(world))
    base.measure = True
    base.reset(world.cell((1, 1)))
    for target in ((-1.0, 0.5), (0.5, 0.5), (-1.0, 0.5)):  # into the west wall, away, again
        base.target = np.array(target)
        for _ in range(1500):
            base.substep()
    m = base.physical_metrics()
    assert m["collisions"] == 2
    # contact safety: the legacy base tracks at its 0.8 m/s limit into the wall, so it meets
    # the wall at no more than that and at a good part of it; the contact is resolved with
    # a few millimetres' penetration at most (MuJoCo's soft contact) and a normal force
    # between the drive's push and its 120 N limit plus the impact's
    assert 0.3 < m["contact_impact_speed"] <= 0.8 + 1e-6
    assert 0.0 < m["contact_penetration_mm"] < 10.0
    assert 10.0 < m["contact_peak_force_n"] < 5000.0
