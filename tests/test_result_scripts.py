"""The results pages' table scripts (scripts/outcome_table.py, scripts/back_crossings.py,
scripts/paired_presets.py) on a small real sweep: their figures agree with the database's own
columns, counted here independently."""

from __future__ import annotations

import json
import sqlite3
import sys
from pathlib import Path

from pathpref.experiments.sweep import run_sweep, sweep_specs

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
import back_crossings  # noqa: E402
import outcome_table  # noqa: E402
import paired_presets  # noqa: E402


def _sweep(tmp_path) -> Path:
    db = tmp_path / "r.sqlite"
    specs = sweep_specs("simple", ["compliant", "oracle"], [5], instances=2, runs=2, seed=5,
                        preset="robust", human="consistent", queries=50)
    run_sweep(specs, str(db), workers=1, progress=False)
    return db


def test_outcome_table_and_back_crossings_match_the_database(tmp_path, capsys):
    db = _sweep(tmp_path)
    con = sqlite3.connect(db)
    rows = con.execute("SELECT method, success, goal_reached, back_crossings FROM episodes"
                       ).fetchall()
    con.close()
    comp = [r for r in rows if r[0] == "compliant"]
    assert len(comp) == 4 and len(rows) == 8
    want = (f"{sum(r[1] for r in comp) / 4:.2f} / {sum(r[2] for r in comp) / 4:.2f} / "
            f"{sum(r[3] for r in comp) / 4:.2f}")

    assert outcome_table.main([str(db)]) == 0
    out = capsys.readouterr().out
    assert f"| compliant | {want} |" in out
    assert "| oracle | 1.00 / 1.00 / 0.00 |" in out  # the consistent human's oracle

    # the split is checked against the stored column inside main (SystemExit if it differs)
    assert back_crossings.main([str(db), "--map", "simple"]) == 0
    out = capsys.readouterr().out
    total = sum(r[3] for r in comp)
    assert total > 0  # compliant turns back at ΔT = 5: the split is not vacuous
    line = next(ln for ln in out.splitlines() if ln.startswith("| compliant | 5 |"))
    cells = [c.strip() for c in line.strip("|").split("|")]
    assert int(cells[3]) == total
    assert int(cells[4]) + int(cells[5]) + int(cells[6]) == total


def test_outcome_table_counts_failed_episodes_as_failures(tmp_path, capsys):
    from .store_helpers import synthetic_db
    from .test_report_intervals import _fail_rows

    db = synthetic_db(tmp_path / "r.sqlite", {("compliant", 1): (9, 24)})
    _fail_rows(db, "compliant", 3)
    assert outcome_table.main([str(db)]) == 0
    out = capsys.readouterr().out
    assert "| compliant | 0.38 / 0.38 / 0.00 |" in out and "n = [24]" in out
    assert "3 failed episodes, counted as failures" in out
    assert outcome_table.main([str(db), "--exclude-failed"]) == 0
    out = capsys.readouterr().out
    assert "| compliant | 0.43 / 0.43 / 0.00 |" in out and "3 failed episodes, left out" in out


def test_paired_presets_counts_a_failed_episode_as_a_failure(tmp_path, capsys):
    """Two presets on the same two episodes of ``simple``; then one episode of the second is
    marked failed (as the sweep records an error): the pair table counts it as a failure on
    every measure and names it, and ``--retry-failed`` runs it again."""
    db = tmp_path / "p.sqlite"
    argv = ["--maps", "simple", "--delta-t", "1", "--instances", "1", "--runs", "2",
            "--workers", "1", "--db", str(db)]
    assert paired_presets.main(argv) == 0
    con = sqlite3.connect(db)
    ok = dict(con.execute("SELECT preset || run, success FROM episodes").fetchall())
    assert len(ok) == 4
    con.execute("UPDATE episodes SET status = 'failed', success = 0, goal_reached = 0, "
                "homotopy_success = 0, reason = 'EpisodeError: injected' "
                "WHERE preset = 'robust-wait' AND run = 0")
    con.commit()
    con.close()
    capsys.readouterr()
    assert paired_presets.main(argv) == 0
    out = capsys.readouterr().out
    assert "failed episode (counted as a failure): robust-wait simple ΔT=1 instance 0 run 0" \
        in out
    wait_ok = ok["robust-wait1"]
    assert f"strict {ok['robust0'] + ok['robust1']:3d} -> {wait_ok:3d}," in out
    assert paired_presets.main([*argv, "--retry-failed"]) == 0
    out = capsys.readouterr().out
    assert "failed episode" not in out
    con = sqlite3.connect(db)
    assert con.execute("SELECT count(*) FROM episodes WHERE status != 'ok'").fetchone()[0] == 0
    con.close()


def test_heldout_eval_splits_every_failure(tmp_path):
    """scripts/heldout_eval.py on one generated plan (compliant and oracle, 2 x 2, ΔT = 5):
    the plan file is the generator's, and per method the outcome columns add up to n and
    equal the database's own flags, counted here."""
    import heldout_eval

    db, out = tmp_path / "h.sqlite", tmp_path / "h.md"
    assert heldout_eval.main(["--open", "9001", "--plans", str(tmp_path / "plans"),
                              "--presets", "robust", "--methods", "compliant", "oracle",
                              "--delta-t", "5", "--instances", "2", "--runs", "2",
                              "--workers", "1", "--db", str(db), "--out", str(out)]) == 0
    stored = Path(__file__).resolve().parents[1] / "docs/results/heldout_plans/heldout_9001.json"
    assert json.loads((tmp_path / "plans/heldout_open_9001.json").read_text())["obstacles"] == \
        json.loads(stored.read_text())["obstacles"]
    con = sqlite3.connect(db)
    rows = con.execute("SELECT method, success, goal_reached, homotopy_success FROM episodes"
                       ).fetchall()
    con.close()
    text = out.read_text()
    for method in ("compliant", "oracle"):
        rs = [r for r in rows if r[0] == method]
        timeout = sum(1 for r in rs if not r[2])
        wrong = sum(1 for r in rs if r[2] and not r[3])
        order = sum(1 for r in rs if r[2] and r[3] and not r[1])
        assert len(rs) == 4 and timeout + wrong + order + sum(r[1] for r in rs) == 4
        line = next(x for x in text.splitlines() if x.startswith(f"| 5 | {method} |"))
        cols = [c.strip() for c in line.strip("|").split("|")]
        assert cols[2] == "4" and [int(c) for c in cols[6:10]] == [timeout, wrong, order, 0]


def test_demo_sweep_keys_exports_cells_and_digests(tmp_path):
    """``scripts/demo_sweep_keys.py`` on a two-episode sweep: one line per cell with its
    count and the SHA-256 of its sorted keys (computed here independently), read back."""
    import hashlib

    import demo_sweep_keys

    db = tmp_path / "d.sqlite"
    specs = sweep_specs("simple", ["compliant", "goal_only"], [5], 1, 1, seed=0, t_max=4,
                        queries=20)
    run_sweep(specs, str(db), workers=1, progress=False)
    out = tmp_path / "keys.tsv"
    assert demo_sweep_keys.main([str(db), str(out)]) == 0
    got = demo_sweep_keys.read_export(out)
    want = {("simple", s.method, "5", "", s.preset):
            (1, hashlib.sha256(s.key().encode()).hexdigest()) for s in specs}
    assert got == want
