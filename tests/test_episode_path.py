"""The continuous path of ``--sim mujoco`` episodes, recorded on request (``--record-path``):
sampled at the stated rate from the start cell to the final cell, stored beside the episode in
``episode_path`` without changing any result, migrated, checked, salvaged, merged and exported
(``pathpref dataset --source paths``, read back with pyarrow)."""

from __future__ import annotations

import dataclasses
import json
import sqlite3
from pathlib import Path

import numpy as np
import pytest

from pathpref.apps.cli import main
from pathpref.episode import EpisodeSpec, cached_world, run_episode
from pathpref.errors import ConfigError
from pathpref.experiments.migrate import check_database, merge_databases, salvage_database
from pathpref.experiments.store import ResultStore

pytest.importorskip("mujoco")

#: a short physical sweep: two methods, one instance, one run
SWEEP = ["evaluate", "--map", "simple", "--sim", "mujoco", "--methods", "path_preference",
         "compliant", "--delta-t", "3", "--instances", "1", "--runs", "1", "--queries", "100",
         "--t-max", "8", "--workers", "1", "--no-progress"]
#: how far (m) the base may stand from its cell's centre once a move has settled (the
#: controller's settling tolerance is a few mm; a cell is 0.5 m)
SETTLED_M = 0.01


def _rows(db: Path, query: str, *params) -> list[dict]:
    with sqlite3.connect(f"file:{db}?mode=ro", uri=True) as c:
        cur = c.execute(query, params)
        names = [d[0] for d in cur.description]
        out = [dict(zip(names, r, strict=True)) for r in cur]
    c.close()
    return out


@pytest.fixture(scope="module")
def sweeps(tmp_path_factory) -> tuple[Path, Path]:
    """The same sweep without and with ``--record-path 100``."""
    folder = tmp_path_factory.mktemp("path")
    plain, recorded = folder / "plain.sqlite", folder / "recorded.sqlite"
    assert main([*SWEEP, "--db", str(plain)]) == 0
    assert main([*SWEEP, "--db", str(recorded), "--record-path", "100"]) == 0
    return plain, recorded


def _cell_centre(x: int, y: int) -> np.ndarray:
    from pathpref.sim.body import scene_for

    world = cached_world("simple")
    cell = int(np.flatnonzero((world.cells == (x, y)).all(axis=1))[0])
    return np.asarray(scene_for(world).cell_centre(cell))


def test_recording_changes_no_stored_result(sweeps):
    """The same seeds with and without the flag store equal episode and step rows (all but
    the wall time), under the same keys; only the recorded sweep has path rows."""
    plain, recorded = sweeps
    a = _rows(plain, "SELECT * FROM episodes ORDER BY key")
    b = _rows(recorded, "SELECT * FROM episodes ORDER BY key")
    assert len(a) == 2 and [r["status"] for r in a] == ["ok", "ok"]
    for r in a + b:
        r.pop("wall_s")
    assert a == b
    assert _rows(plain, "SELECT * FROM steps ORDER BY key, t") == \
        _rows(recorded, "SELECT * FROM steps ORDER BY key, t")
    assert _rows(plain, "SELECT count(*) AS n FROM episode_path")[0]["n"] == 0


def test_path_spans_the_episode_at_the_stated_rate(sweeps):
    """100 Hz: a sample every 10 ms of simulated time (the last one at the episode's end, at
    most 10 ms after the one before), from the start cell's centre (exactly: the reset) to the
    final cell's centre (within SETTLED_M), read back through the store's own reader."""
    _, recorded = sweeps
    with ResultStore(recorded, create=False) as store:
        for ep in store.episodes():
            path = store.recorded_path(ep["key"])
            steps = store.steps(ep["key"])
            t = np.array([r["time_s"] for r in path])
            assert [r["k"] for r in path] == list(range(len(path)))
            assert t[0] == 0.0
            gaps = np.diff(t)
            np.testing.assert_allclose(gaps[:-1], 0.01, atol=1e-9)
            assert 0 < gaps[-1] <= 0.01 + 1e-9
            metrics = json.loads(ep["metrics"])
            assert t[-1] == pytest.approx(metrics["sim_time_s"], abs=1e-9)
            start = json.loads(ep["start"])
            np.testing.assert_allclose([path[0]["x"], path[0]["y"]], _cell_centre(*start),
                                       atol=1e-12)
            end = steps[-1]["x"], steps[-1]["y"]
            assert np.hypot(*(np.array([path[-1]["x"], path[-1]["y"]]) - _cell_centre(*end))
                            ) <= SETTLED_M
            assert all(r["ee_x"] is None for r in path)  # the plain base has no end effector
            pushed = [np.hypot(r["fx"], r["fy"]) for r in path]
            assert max(pushed) > 1.0 and min(pushed) == 0.0  # the human's pushes are in it


def test_carry_records_the_end_effector(tmp_path, capsys):
    """The arm's tray is sampled with the base; 60 Hz takes every 8th 2 ms step (62.5 Hz),
    which a dataset refuses (not a whole number of frames per second); at 100 Hz the dataset
    has the end effector as a feature."""
    import pathpref.sim  # noqa: F401 - registers the mujoco body

    spec = EpisodeSpec.single("simple", "compliant", 3, sim="mujoco", robot="carry",
                              queries=50, t_max=3, record_path_hz=60)
    res = run_episode(spec)
    t = np.array([p[0] for p in res.path])
    np.testing.assert_allclose(np.diff(t)[:-1], 0.016, atol=1e-9)
    ee = np.array([p[4:7] for p in res.path], dtype=float)
    base = np.array([p[1:3] for p in res.path])
    assert np.isfinite(ee).all()
    assert 0.3 < ee[:, 2].min() and ee[:, 2].max() < 1.5  # a tray above the floor
    assert np.hypot(*(ee[:, :2] - base).T).max() < 1.0  # ... carried by the base
    db = tmp_path / "carry.sqlite"
    with ResultStore(db) as store:
        store.add(res)
    assert main(["dataset", str(db), "--out", str(tmp_path / "no"), "--source", "paths"]) == 2
    assert "whole frames per second for a dataset (found 62.5 Hz)" in capsys.readouterr().err
    res = run_episode(dataclasses.replace(spec, record_path_hz=100))
    with ResultStore(db) as store:
        store.add(res)  # the same key: the 60 Hz rows are replaced
    assert main(["dataset", str(db), "--out", str(tmp_path / "ds"), "--source", "paths"]) == 0
    info = json.loads((tmp_path / "ds" / "meta" / "info.json").read_text())
    assert info["features"]["observation.end_effector"]["names"] == ["x", "y", "z"]
    pq = pytest.importorskip("pyarrow.parquet")
    frames = pq.read_table(tmp_path / "ds" / "data" / "chunk-000" / "file-000.parquet")
    on_grid = [p for k, p in enumerate(res.path) if abs(p[0] - k / 100) < 1e-6]
    np.testing.assert_allclose(frames.column("observation.end_effector").to_pylist(),
                               [p[4:7] for p in on_grid], atol=1e-6)


def test_a_grid_episode_refuses_to_record():
    spec = EpisodeSpec.single("simple", "compliant", 3, t_max=3, record_path_hz=100)
    with pytest.raises(ConfigError, match="no continuous path"):
        run_episode(spec)
    assert main(["evaluate", "--map", "simple", "--methods", "compliant", "--delta-t", "3",
                 "--instances", "1", "--runs", "1", "--db", "/nonexistent/x.sqlite",
                 "--record-path", "100"]) == 2


def test_the_flag_is_no_part_of_the_key_and_is_range_checked():
    spec = EpisodeSpec.single("simple", "compliant", 3, sim="mujoco")
    assert dataclasses.replace(spec, record_path_hz=100).key() == spec.key()
    with pytest.raises(ConfigError, match="--record-path"):
        dataclasses.replace(spec, record_path_hz=20).validate()
    import pathpref.sim  # noqa: F401

    with pytest.raises(ConfigError, match="physics rate, 500 Hz"):
        run_episode(dataclasses.replace(spec, record_path_hz=1000, t_max=1))


def test_upgrade_check_salvage_and_merge_keep_the_path(sweeps, tmp_path, capsys):
    """A schema 5 file written before the table gets it from ``db upgrade`` (rows kept);
    ``db check`` counts path rows and finds an orphan; salvage and merge copy the rows."""
    plain, recorded = sweeps
    old = tmp_path / "old.sqlite"
    old.write_bytes(plain.read_bytes())
    with sqlite3.connect(old) as c:
        c.execute("DROP TABLE episode_path")
    c.close()
    assert main(["db", "upgrade", str(old)]) == 0
    assert _rows(old, "SELECT name FROM sqlite_master WHERE name = 'episode_path'")
    assert _rows(old, "SELECT * FROM episodes ORDER BY key") == \
        _rows(plain, "SELECT * FROM episodes ORDER BY key")
    n = _rows(recorded, "SELECT count(*) AS n FROM episode_path")[0]["n"]
    report = check_database(recorded)
    assert report["intact"] and report["path_rows"] == n and report["path_orphans"] == 0
    saved = tmp_path / "saved.sqlite"
    assert salvage_database(recorded, saved)["path_rows"] == n
    assert _rows(saved, "SELECT * FROM episode_path ORDER BY key, k") == \
        _rows(recorded, "SELECT * FROM episode_path ORDER BY key, k")
    merged = tmp_path / "merged.sqlite"
    assert merge_databases(merged, [recorded])["path_rows"] == n
    assert _rows(merged, "SELECT * FROM episode_path ORDER BY key, k") == \
        _rows(recorded, "SELECT * FROM episode_path ORDER BY key, k")
    with sqlite3.connect(saved) as c:
        c.execute("INSERT INTO episode_path VALUES ('nobody', 0, 0, 0, 0, 0, NULL, NULL, NULL, "
                  "0, 0)")
    c.close()
    report = check_database(saved)
    assert not report["intact"] and report["path_orphans"] == 1


def test_paths_export_as_a_lerobot_dataset(sweeps, tmp_path):
    """``dataset --source paths``: one frame per sample on the 100 Hz grid (an episode's
    last sample, when it falls between two instants, left out), the state, push and flag
    equal to the stored rows."""
    pq = pytest.importorskip("pyarrow.parquet")
    _, recorded = sweeps
    out = tmp_path / "ds"
    assert main(["dataset", str(recorded), "--out", str(out), "--source", "paths"]) == 0
    info = json.loads((out / "meta" / "info.json").read_text())
    assert info["fps"] == 100 and "observation.end_effector" not in info["features"]
    frames = pq.read_table(out / "data" / "chunk-000" / "file-000.parquet").to_pylist()
    meta = pq.read_table(out / "meta" / "episodes" / "chunk-000" / "file-000.parquet")
    keys = meta.column("source_key").to_pylist()
    assert keys == sorted(r["key"] for r in _rows(recorded, "SELECT key FROM episodes"))
    assert info["total_episodes"] == 2 and info["total_frames"] == len(frames)
    for i, key in enumerate(keys):
        path = [r for r in _rows(recorded, "SELECT * FROM episode_path WHERE key = ? "
                                 "ORDER BY k", key) if abs(r["time_s"] - r["k"] / 100) < 1e-6]
        assert len(path) >= 300  # 100 Hz over the episode's 3.6 s and more
        mine = [f for f in frames if f["episode_index"] == i]
        assert len(mine) == len(path) == meta.column("length").to_pylist()[i]
        np.testing.assert_allclose([f["observation.state"] for f in mine],
                                   [[r["x"], r["y"], r["yaw"]] for r in path], atol=1e-6)
        np.testing.assert_allclose([f["intervention"] for f in mine],
                                   [[r["fx"], r["fy"]] for r in path], rtol=1e-6, atol=1e-6)
        assert [f["is_intervention"][0] if isinstance(f["is_intervention"], list)
                else f["is_intervention"] for f in mine] == \
            [bool(np.hypot(r["fx"], r["fy"]) > 0.5) for r in path]
        assert any(f["is_intervention"] for f in mine)
        np.testing.assert_allclose(mine[0]["action"], [(path[1]["x"] - path[0]["x"]) * 100,
                                                       (path[1]["y"] - path[0]["y"]) * 100],
                                   rtol=1e-5, atol=1e-6)


def test_paths_export_without_recorded_paths_is_one_line(sweeps, tmp_path, capsys):
    plain, _ = sweeps
    assert main(["dataset", str(plain), "--out", str(tmp_path / "ds"), "--source",
                 "paths"]) == 2
    assert "no --sim mujoco episodes with a recorded path" in capsys.readouterr().err


def test_path_rows_are_written_in_their_episode_transaction(tmp_path):
    """An episode and its path rows are stored together or not at all (a sweep killed
    mid-write resumes exactly), and a rerun of the episode replaces its rows."""
    res = run_episode(EpisodeSpec.single("simple", "compliant", 3, t_max=3))
    good = (0.0, 1.25, 1.75, 0.0, None, None, None, 0.0, 0.0)
    res.path = [good, (0.01, 1.25)]  # the second sample cannot be written
    db = tmp_path / "r.sqlite"
    with ResultStore(db) as store:
        with pytest.raises(ConfigError):
            store.add(res)
        assert store.done_keys() == set()
        assert store.recorded_path(res.spec.key()) == []
        res.path = [good, good]
        store.add(res)
        assert [r["k"] for r in store.recorded_path(res.spec.key())] == [0, 1]
        res.path = []
        store.add(res)
        assert store.recorded_path(res.spec.key()) == []
        assert store.done_keys() == {res.spec.key()}


def test_a_path_table_pathpref_did_not_define_is_refused(sweeps, tmp_path):
    """The store's check knows the table: another definition of it makes the file foreign."""
    plain, _ = sweeps
    other = tmp_path / "other.sqlite"
    other.write_bytes(plain.read_bytes())
    with sqlite3.connect(other) as c:
        c.execute("DROP TABLE episode_path")
        c.execute("CREATE TABLE episode_path (key TEXT, k INTEGER, note TEXT, "
                  "PRIMARY KEY (key, k))")
    c.close()
    with pytest.raises(ConfigError, match="table episode_path is not defined as pathpref"):
        ResultStore(other)
