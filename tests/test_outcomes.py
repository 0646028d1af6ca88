"""Why episodes fail (time-out, wrong side, out-of-order crossing, not run) and success by
slack, in the records and tables of ``pathpref report`` (:mod:`pathpref.experiments.outcomes`),
and the ``slack`` column: stored per episode, NULL in older files, filled by ``db upgrade``."""

from __future__ import annotations

import re
import shutil
import sqlite3

import pytest

from pathpref.apps.cli import main
from pathpref.episode.runner import EpisodeRunner
from pathpref.experiments.outcomes import (
    FAILURE_KINDS,
    SLACK_BINS,
    failure_kind,
    failure_split,
    slack_bin,
    slack_summary,
)
from pathpref.experiments.report import load_records, markdown_tables
from pathpref.experiments.store import ResultStore, row_spec

#: a contact pressed at 30 N (over the 20 N limit of pathpref/episode/safety.py)
HIT = '{"collisions": 1.0, "contact_impact_speed": 0.01, "contact_peak_force_n": 30.0}'


def _row(status="ok", goal=1, violations=0, homotopy=1, slack=25, metrics="{}"):
    safe = metrics == "{}"
    return {"status": status, "goal_reached": goal, "violations": violations,
            "pref_followed": int(violations == 0), "homotopy_success": homotopy,
            "success": int(status == "ok" and goal and violations == 0 and safe),
            "slack": slack, "metrics": metrics}


def test_every_failure_falls_in_one_kind_decided_in_order():
    cases = [
        (_row(), None),  # reached, no violation: a success
        (_row(homotopy=0), None),  # strict success though the class differs: not a failure
        (_row(status="failed", goal=0, homotopy=0), "not_run"),
        (_row(status="failed", goal=1, violations=3, homotopy=0), "not_run"),
        (_row(metrics=HIT), "contact"),  # reached in order, but struck an obstacle
        (_row(goal=0, violations=2, homotopy=0, metrics=HIT), "contact"),
        (_row(status="failed", goal=0, metrics=HIT), "not_run"),
        (_row(goal=0, violations=2, homotopy=0), "time_out"),
        (_row(goal=0, violations=0, homotopy=None), "time_out"),
        (_row(goal=1, violations=1, homotopy=0), "wrong_side"),
        (_row(goal=1, violations=4, homotopy=1), "out_of_order"),
        (_row(goal=1, violations=1, homotopy=None), "unclassified"),
    ]
    for row, kind in cases:
        assert failure_kind(row) == kind, row
    rows = [r for r, _ in cases]
    split = failure_split(rows)
    assert split == {"not_run": 3, "contact": 2, "time_out": 2, "wrong_side": 1,
                     "out_of_order": 1, "unclassified": 1}
    assert sum(split.values()) == sum(not r["success"] for r in rows) == 10
    assert failure_split(rows, exclude_failed=True)["not_run"] == 0
    assert tuple(split) == FAILURE_KINDS


def test_slack_bins_bounds_and_the_success_per_bin():
    assert [slack_bin(s) for s in (-3, 0, 9, 10, 19, 20, 39, 40, 300, None)] == [
        "lt10", "lt10", "lt10", "10_19", "10_19", "20_39", "20_39", "ge40", "ge40",
        "unmeasured"]
    assert [b[0] for b in SLACK_BINS] == ["lt10", "10_19", "20_39", "ge40"]
    rows = [_row(slack=5), _row(goal=0, slack=7), _row(goal=0, slack=12),
            _row(status="failed", goal=0, slack=None), _row(slack=None), _row(slack=45)]
    s = slack_summary(rows)
    assert (s["slack_lt10_n"], s["slack_lt10_k"], s["slack_lt10_rate"]) == (2, 1, 0.5)
    assert (s["slack_10_19_n"], s["slack_10_19_k"], s["slack_10_19_rate"]) == (1, 0, 0.0)
    assert (s["slack_20_39_n"], s["slack_20_39_rate"]) == (0, None)
    assert (s["slack_ge40_n"], s["slack_ge40_k"]) == (1, 1)
    assert s["slack_unmeasured_n"] == 2
    # Wilson 95% of 1/2: 0.0945, 0.9055
    assert s["slack_lt10_ci_low"] == pytest.approx(0.0945, abs=1e-3)
    assert s["slack_lt10_ci_high"] == pytest.approx(0.9055, abs=1e-3)


SWEEP = ["evaluate", "--map", "simple", "--preset", "paper", "--queries", "200", "--methods",
         "compliant", "goal_only", "path_preference", "oracle", "--delta-t", "5", "20",
         "--instances", "2", "--runs", "2", "--no-progress"]


def test_a_real_sweep_splits_its_failures_as_its_rows_say(tmp_path, capsys):
    db = tmp_path / "split.sqlite"
    assert main([*SWEEP, "--db", str(db)]) == 0
    with ResultStore(db, create=False) as st:
        rows = st.episodes()
    assert len(rows) == 32
    recs = load_records(db)
    kinds_seen = set()
    for rec in recs:
        cell = [r for r in rows if (r["method"], r["delta_t"]) == (rec["method"],
                                                                     rec["delta_t"])]
        # counted independently of the categoriser, from the stored flags
        time_out = sum(not r["goal_reached"] for r in cell)
        wrong = sum(r["goal_reached"] and r["violations"] > 0 and not r["homotopy_success"]
                    for r in cell)
        order = sum(r["goal_reached"] and r["violations"] > 0 and r["homotopy_success"] == 1
                    for r in cell)
        assert (rec["time_out"], rec["wrong_side"], rec["out_of_order"], rec["not_run"],
                rec["unclassified"]) == (time_out, wrong, order, 0, 0)
        assert time_out + wrong + order == rec["n"] - round(rec["success_rate"] * rec["n"])
        kinds_seen |= {k for k in ("time_out", "wrong_side", "out_of_order") if rec[k]}
        # every row has its slack, and the bins hold them all
        assert sum(rec[f"slack_{k}_n"] for k, *_ in SLACK_BINS) == rec["n"]
        assert rec["slack_unmeasured_n"] == 0
    assert kinds_seen == {"time_out", "wrong_side", "out_of_order"}
    # the oracle walks the human's route: a success takes T_max - slack steps exactly
    oracle = [r for r in rows if r["method"] == "oracle"]
    assert all(r["success"] and r["steps"] == r["t_max"] - r["slack"] for r in oracle)
    assert sorted({r["slack"] for r in rows}) == [17, 28]
    text = markdown_tables(recs)
    assert "why episodes failed: time-out, wrong side, out-of-order crossing" in text
    assert "success by slack" in text and "| slack 10-19 |" in text
    out = tmp_path / "split.csv"
    capsys.readouterr()
    assert main(["report", str(db), "--csv", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "why episodes failed" in printed and "success by slack" in printed
    header = out.read_text().splitlines()[0].split(",")
    assert {"time_out", "wrong_side", "out_of_order", "not_run", "slack_lt10_rate",
            "slack_ge40_ci_high", "slack_unmeasured_n"} <= set(header)


def test_older_files_report_slack_not_measured_and_upgrade_fills_it(tmp_path, capsys):
    db = tmp_path / "saved.sqlite"
    shutil.copy("tests/data/saved_sweep.sqlite", db)  # schema 3, 39 episodes, no slack
    recs = load_records(db)  # read as it is
    assert sum(r["slack_unmeasured_n"] for r in recs) == 39
    shown = re.findall(r"(\d+) episodes without a slack \(not measured", markdown_tables(recs))
    assert sum(map(int, shown)) == 39
    assert main(["db", "upgrade", str(db)]) == 0
    assert "slack filled in for 39 older episodes" in capsys.readouterr().out
    with ResultStore(db, create=False) as st:
        rows = st.episodes()
    assert all(r["slack"] is not None for r in rows)
    # exactly what the episode stores today (the runner computes it before any step)
    for r in [r for r in rows if r["sim"] == "grid"][::7]:
        assert EpisodeRunner(row_spec(r)).result.slack == r["slack"]


def _one_oracle_episode(db) -> None:
    """One paper-preset oracle episode on ``simple`` (ΔT = 5) into ``db``."""
    assert main(["evaluate", "--map", "simple", "--preset", "paper", "--methods", "oracle",
                 "--delta-t", "5", "--instances", "1", "--runs", "1", "--no-progress",
                 "--db", str(db)]) == 0


def test_a_schema5_file_without_the_slack_column_reads_and_gets_it(tmp_path):
    db = tmp_path / "five.sqlite"
    _one_oracle_episode(db)
    c = sqlite3.connect(db)
    c.execute("ALTER TABLE episodes DROP COLUMN slack")  # as schema 5 was first released
    c.close()
    recs = load_records(db)
    assert recs[0]["slack_unmeasured_n"] == 1
    with ResultStore(db) as st:  # opened for writing: the column is added, NULL
        assert [r["slack"] for r in st.episodes()] == [None]
    assert main(["db", "upgrade", str(db)]) == 0  # fills it, as the episode stores it now
    with ResultStore(db, create=False) as st:
        (row,) = st.episodes()
    assert row["slack"] == EpisodeRunner(row_spec(row)).result.slack
    assert row["slack"] == row["t_max"] - row["steps"]  # the oracle walks the route


def test_a_slack_pathpref_cannot_have_written_is_refused(tmp_path):
    from pathpref.errors import ConfigError

    db = tmp_path / "bad.sqlite"
    _one_oracle_episode(db)
    c = sqlite3.connect(db)
    with c:
        c.execute("UPDATE episodes SET slack = 'x'")
    c.close()
    with pytest.raises(ConfigError, match="has slack = 'x', not an integer or NULL"):
        load_records(db)
