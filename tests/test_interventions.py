"""Minimal interventions: the corrective human's push rule (its spelling, its
need test on hand-picked moves, its reaction delay and misses on scripted episodes), the
per-step ``is_intervention`` log, keys that stay as they were for the periodic human, the
schema-5 columns added in place to older files and the report's pushes per episode.

The corridor (7 x 1, no obstacle, goal at its east end) has one polytope: a push is needed
exactly after a step that did not bring the robot east, so every expected step below is
counted by hand."""

from __future__ import annotations

import json
import shutil
import sqlite3

import numpy as np
import pytest

from pathpref.episode import FIG4, EpisodeRunner, EpisodeSpec, run_episode
from pathpref.episode.corrective import CorrectiveHuman, PushRule, miss_stream, parse_push_rule
from pathpref.errors import ConfigError
from pathpref.experiments.store import SCHEMA_VERSION, ResultStore, row_spec

CORRIDOR = {"name": "corridor", "width": 7, "height": 1, "obstacles": [],
            "preference": {"table": []}, "t_max": 12}
TO_EAST = json.dumps({"start": [1, 1], "goals": [[7, 1]], "true_goal": 0})
STAY, E, W = -1, 2, 6


def test_push_rule_spelling_and_limits():
    assert parse_push_rule("") is None
    assert parse_push_rule("corrective") == PushRule(0, 0.0)
    rule = parse_push_rule("corrective delay=2 miss=0.25")
    assert (rule.delay, rule.miss, rule.text) == (2, 0.25, "corrective delay=2 miss=0.25")
    for bad, what in (("periodic", "unknown push rule"), ("corrective miss=0.1 delay=1",
                                                          "unknown push rule"),
                      ("corrective delay=x", "delay must be an integer and miss a number"),
                      ("corrective delay=-1", "delay must be an integer in 0..1000"),
                      ("corrective miss=1.5", "miss must be a probability"),
                      ("corrective miss=nan", "miss must be a probability")):
        with pytest.raises(ConfigError, match=what) as e:
            parse_push_rule(bad)
        assert "\n" not in str(e.value)


def _spec(map_path, **fields) -> EpisodeSpec:
    return EpisodeSpec.single(str(map_path), "compliant", 1, fixed=TO_EAST, n_goals=1, **fields)


@pytest.fixture
def corridor(tmp_path):
    path = tmp_path / "corridor.json"
    path.write_text(json.dumps(CORRIDOR))
    return path


def test_keys_of_the_periodic_human_are_unchanged_and_bad_rules_refused(corridor):
    base = EpisodeSpec.single("simple", "path_preference", 5, seed=3)
    assert "push_rule" not in base.key()
    rule = EpisodeSpec.single("simple", "path_preference", 1, seed=3,
                              push_rule="corrective delay=1 miss=0.1")
    assert "|push_rule=corrective delay=1 miss=0.1|" in rule.key()
    with pytest.raises(ConfigError, match="use --delta-t 1"):
        EpisodeSpec.single("simple", "compliant", 5,
                           push_rule="corrective delay=0 miss=0.0").validate()
    with pytest.raises(ConfigError, match="write it 'corrective delay=0 miss=0.0'"):
        EpisodeSpec.single("simple", "compliant", 1, push_rule="corrective").validate()
    with pytest.raises(ConfigError, match="unknown push rule"):
        EpisodeSpec.single("simple", "compliant", 1, push_rule="often").validate()
    # a MuJoCo body pushing at times of its own cannot take the decision-step rule
    with pytest.raises(ConfigError, match="--timing interval pushes at times of its own; use "
                       "--timing decision"):
        EpisodeRunner(_spec(corridor, push_rule="corrective delay=0 miss=0.0", sim="mujoco",
                            physics=json.dumps({"timing": "interval"})))


def _scripted(spec: EpisodeSpec, actions: list[int]):
    r = EpisodeRunner(spec)
    r.begin()
    for a in actions:
        if r.done:
            break
        r.step(a)
    return r.result


def test_corrective_pushes_after_the_steps_that_need_one(corridor):
    # no delay: pushed right after each step that did not gain (stay, west), never before
    # step 1 and never after a step east
    res = _scripted(_spec(corridor, push_rule="corrective delay=0 miss=0.0"),
                    [STAY, E, W, E, E, E, E, E, E])
    flags = [s.is_intervention for s in res.log]
    assert flags == [0, 1, 0, 1, 0, 0, 0, 0, 0, 0]
    assert res.inputs == 2 and res.goal_reached
    # delay 2: the stay of step 1 is pushed after step 3; the west step 4 after step 6; the
    # stay of step 5 falls while that push is pending and is not noticed
    res = _scripted(_spec(corridor, push_rule="corrective delay=2 miss=0.0"),
                    [STAY, E, E, W, STAY, E, E, E, E, E])
    assert [s.t for s in res.log if s.is_intervention] == [3, 6]
    assert res.inputs == 2
    # miss 1: every need is missed
    res = _scripted(_spec(corridor, push_rule="corrective delay=0 miss=1.0"),
                    [STAY, STAY, W, E, E, E, E, E, E, E])
    assert res.inputs == 0 and not any(s.is_intervention for s in res.log)


def test_corrective_pushes_the_mujoco_base_at_the_same_steps(corridor):
    """The rule watches decision steps whatever the body: the MuJoCo base (timing
    ``decision``, the default physics) is pushed after the same scripted steps as the grid,
    and feels each push (its cue is the next step's heading)."""
    import pathpref.sim  # noqa: F401  (registers the mujoco body)

    res = _scripted(_spec(corridor, push_rule="corrective delay=0 miss=0.0", sim="mujoco"),
                    [STAY, E, W, E, E, E, E, E, E])
    assert [s.is_intervention for s in res.log] == [0, 1, 0, 1, 0, 0, 0, 0, 0, 0]
    assert res.inputs == 2 and res.goal_reached
    assert [s.t for s in res.log if s.heading >= 0] == [2, 4]  # the steps after the pushes


def test_misses_are_the_episodes_fourth_stream(corridor):
    """miss 0.5 on six needs in a row (the robot stays): the needs pushed are those whose draw
    from ``miss_stream(run_seed)`` is at least 0.5, one draw per need noticed, in order."""
    spec = _spec(corridor, push_rule="corrective delay=0 miss=0.5", t_max=6, seed=3)
    draws = miss_stream(spec.run_seed).random(6)
    res = _scripted(spec, [STAY] * 6)
    want = [t + 1 for t, u in enumerate(draws) if u >= 0.5 and t + 1 < 6]  # none after the end
    assert [s.t for s in res.log if s.is_intervention] == want
    assert 0 < len(want) < 5  # this seed both pushes and misses (else the test says nothing)


def test_periodic_pushes_are_logged_where_they_happen(corridor):
    res = _scripted(_spec(corridor), [STAY, STAY, E, E])
    assert [s.is_intervention for s in res.log] == [1, 1, 1, 1, 1]
    res = run_episode(EpisodeSpec.single("simple", "compliant", 5, seed=2))
    pushed = [s.t for s in res.log if s.is_intervention]
    assert pushed == [t for t in range(0, res.steps, 5)] and len(pushed) == res.inputs


def test_the_need_test_on_simple():
    """FIG4 on ``simple``: the human goes counter-clockwise round the table (from the
    west-middle polytope, cells x 1..4 and y 5..6, the preferred exit is south)."""
    r = EpisodeRunner(EpisodeSpec.single("simple", "compliant", 1, fixed=FIG4,
                                         push_rule="corrective delay=0 miss=0.0"))
    w = r.world
    c = CorrectiveHuman(PushRule(), w, r.pref, r.instance.goal_cell, np.random.default_rng(0))
    cell = lambda x, y: w.cell((x, y))  # noqa: E731
    N = 0
    # left the route: west-middle -> north-west (the goal's polytope, not the preferred exit)
    assert c.needs_push(cell(3, 6), N, cell(3, 7))
    # about to leave: north inside west-middle, north again leaves it northward
    assert c.needs_push(cell(3, 5), N, cell(3, 6))
    # along the route, east on the bottom row: no push
    assert not c.needs_push(cell(2, 1), E, cell(3, 1))
    # standing still: a push
    assert c.needs_push(cell(2, 1), STAY, cell(2, 1))


def _schema4_file(path) -> None:
    """A schema-4 database as pathpref wrote it before schema 5 (one episode, one step)."""
    from pathpref.experiments.store import EPISODE_COLUMNS, STEP_COLUMNS, episodes_sql
    from pathpref.experiments.trials import create_study_tables

    old = [c for c in EPISODE_COLUMNS if c not in ("homotopy_success", "push_rule", "slack")]
    steps = [c for c in STEP_COLUMNS if c != "is_intervention"]
    c = sqlite3.connect(path)
    with c:
        c.execute("CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT)")
        c.execute("INSERT INTO meta VALUES ('schema_version', '4')")
        c.execute(episodes_sql(old))
        c.execute(f"CREATE TABLE steps ({', '.join(f'{s} {STEP_COLUMNS[s]}' for s in steps)}, "
                  "PRIMARY KEY (key, t))")
        create_study_tables(c)
        row = {k: None for k in old} | {
            "key": "k1", "map": "simple", "map_hash": "h", "sim": "grid", "task": "navigate",
            "method": "compliant", "delta_t": 1, "preset": "paper", "queries": 10, "t_max": 30,
            "instance_seed": 1, "ucb_c": 1.0, "normalize": 1, "coupling": 1, "status": "ok",
            "success": 1, "goal_reached": 1, "pref_followed": 1, "inputs": 3, "steps": 0,
            "violations": 0}
        c.execute(f"INSERT INTO episodes ({', '.join(old)}) VALUES ({', '.join('?' * len(old))})",
                  [row[k] for k in old])
        c.execute("INSERT INTO steps VALUES ('k1', 0, 1, 1, -1, -1, 0.1, 2.3)")
    c.close()


def test_older_files_get_the_new_columns_in_place_null_in_their_rows(tmp_path):
    from pathpref.experiments.report import load_records, markdown_tables

    db = tmp_path / "four.sqlite"
    _schema4_file(db)
    recs = load_records(db)  # read as it is
    assert recs[0]["homotopy_n"] == 0 and recs[0]["pushes_per_episode"] == 3.0
    assert "not measured; 3.0 pushes" in markdown_tables(recs)
    with ResultStore(db) as st:  # opened for writing: schema 5
        res = run_episode(EpisodeSpec.single("simple", "compliant", 1, seed=5, queries=10))
        st.add(res)
        rows = {r["key"]: r for r in st.episodes()}
        assert rows["k1"]["homotopy_success"] is None and rows["k1"]["push_rule"] is None
        assert st.steps("k1")[0]["is_intervention"] is None
        new = rows[res.spec.key()]
        assert new["homotopy_success"] == int(res.homotopy_success)
        assert [s["is_intervention"] for s in st.steps(res.spec.key())] == \
            [s.is_intervention for s in res.log]
    c = sqlite3.connect(db)
    assert c.execute("SELECT value FROM meta").fetchone()[0] == str(SCHEMA_VERSION) == "5"
    c.close()
    with ResultStore(db) as st:  # and opens again as an intact schema-5 file
        assert len(st.episodes()) == 2
    # the saved schema-3 sweep: its rows replay under the same keys (row_spec: periodic)
    saved = tmp_path / "saved.sqlite"
    shutil.copy("tests/data/saved_sweep.sqlite", saved)
    with ResultStore(saved) as st:
        rows = st.episodes()
    assert {r["homotopy_success"] for r in rows} == {None}
    assert all(row_spec(r).push_rule == "" and row_spec(r).key() == r["key"] for r in rows)


def test_a_stored_homotopy_success_that_contradicts_its_row_is_refused(tmp_path):
    db = tmp_path / "r.sqlite"
    with ResultStore(db) as st:
        st.add(run_episode(EpisodeSpec.single("simple", "compliant", 5, seed=1, t_max=2)))
    c = sqlite3.connect(db)
    with c:
        c.execute("UPDATE episodes SET homotopy_success = 1, goal_reached = 0, success = 0")
    c.close()
    with pytest.raises(ConfigError, match="homotopy_success = 1 but goal_reached = 0"):
        ResultStore(db, create=False).episodes()


def test_a_body_that_pushes_on_its_own_clock_leaves_is_intervention_unmeasured(tmp_path):
    """MuJoCo pushes at any moment (timing 'interval'): the runner does not give them, so the
    step rows hold NULL (not measured), never a 0 that would read as 'no push'."""
    pytest.importorskip("mujoco")
    import pathpref.sim  # noqa: F401 - registers the MuJoCo bodies
    from pathpref.episode import Physics

    spec = EpisodeSpec.single("simple", "compliant", 1, seed=0, sim="mujoco", t_max=4,
                              physics=Physics(timing="interval").to_json())
    res = run_episode(spec)
    assert res.inputs > 0 and {s.is_intervention for s in res.log} == {None}
    with ResultStore(tmp_path / "m.sqlite") as st:
        st.add(res)
        assert {s["is_intervention"] for s in st.steps(spec.key())} == {None}
