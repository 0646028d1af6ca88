"""scripts/results.py on a small real sweep: every Markdown row's counts and rates agree with the
database's own columns, counted here independently, and the Wilson interval with its closed form
worked out here."""

from __future__ import annotations

import json
import math
import sqlite3
import sys
from pathlib import Path

from pathpref.experiments.sweep import run_sweep, sweep_specs

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
import results  # noqa: E402


def _wilson(k: int, n: int) -> tuple[float, float]:
    z, p = 1.96, k / n
    c = (p + z * z / (2 * n)) / (1 + z * z / n)
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, c - h), min(1.0, c + h)


def test_rate_cell_by_hand():
    # 3 of 4: p = 0.75, centre (0.75 + 0.4802) / 1.9604 = 0.6275, half 0.3324 -> [0.30, 0.95]
    assert results.rate(3, 4) == "3/4 = 0.75 [0.30, 0.95]"
    assert results.rate(0, 0) == "–"


def test_page_rows_match_the_database(tmp_path):
    db = tmp_path / "r.sqlite"
    specs = sweep_specs("simple", ["compliant", "oracle"], [5], instances=2, runs=2, seed=5,
                        preset="robust", human="consistent", queries=50)
    specs += sweep_specs("simple", ["compliant"], [1], instances=1, runs=3, seed=5,
                         preset="robust", human="consistent", queries=50)
    run_sweep(specs, str(db), workers=1, progress=False)
    out = tmp_path / "results.md"
    assert results.main(["--only-given", "--db", str(db), "--db-command", "CMD X",
                         "--out", str(out)]) == 0
    page = out.read_text()
    assert "CMD X" in page and "11 episodes" in page

    con = sqlite3.connect(db)
    rows = con.execute("SELECT method, delta_t, success, homotopy_success, goal_reached, "
                       "inputs, violations FROM episodes").fetchall()
    con.close()
    assert len(rows) == 11
    for method, label, dt, n in (("compliant", "compliant", 5, 4), ("oracle", "oracle", 5, 4),
                                 ("compliant", "compliant", 1, 3)):
        mine = [r for r in rows if r[0] == method and r[1] == dt]
        assert len(mine) == n
        k, h, g = (sum(r[i] for r in mine) for i in (2, 3, 4))
        lo, hi = _wilson(k, n)
        hlo, hhi = _wilson(h, n)
        row = (f"| {label} | {n} | {k}/{n} = {k / n:.2f} [{lo:.2f}, {hi:.2f}] | "
               f"{h}/{n} = {h / n:.2f} [{hlo:.2f}, {hhi:.2f}] | {g}/{n} | "
               f"{sum(r[5] for r in mine) / n:.2f} | "
               # failed: time-out / wrong side / out-of-order, counted from the flags
               f"{sum(not r[4] for r in mine)} / "
               f"{sum(r[4] and r[6] > 0 and not r[3] for r in mine)} / "
               f"{sum(r[4] and r[6] > 0 and r[3] == 1 for r in mine)} |")
        section = page.split(f"a push every ΔT = {dt} steps")[1].split("###")[0]
        assert row in section, (row, section)
    assert "| oracle | 4 | 4/4 = 1.00" in page  # the consistent human's oracle never fails


def test_a_database_kept_as_its_cells_json(tmp_path):
    """Without the database, its section is read from ``<stem>.json`` (the cells results.py
    wrote): the same rows, the source says so; with neither, the section is left out."""
    cell = {"setting": "S1", "map": "simple", "sim": "grid", "preset": "paper", "human": "map",
            "push_rule": "", "delta_t": 5, "method": "goal_only", "n": 4, "success": 3,
            "homotopy": 4, "homotopy_n": 4, "goal_reached": 4, "pushes_per_episode": 2.5,
            "failed": 1}
    (tmp_path / "big.json").write_text(json.dumps({"source": "docs/results/big.sqlite",
                                                   "cells": [cell]}))
    page = results.build([(tmp_path / "big.sqlite", "Big", "CMD"),
                          (tmp_path / "gone.sqlite", "Gone", "CMD")], [])
    assert "(the cells of `docs/results/big.sqlite`; the database is not in" in page
    assert "| goal only | 4 | 3/4 = 0.75 [0.30, 0.95] | 4/4 = 1.00 [0.51, 1.00] | 4/4 | 2.50 |" \
        in page
    assert "1 failed (counted as failures)" in page
    assert "Gone" not in page


def test_stored_sources_exist():
    for path, *_ in results.DB_SOURCES:  # the database, or the JSON of its cells
        p = results.ROOT / path
        assert p.exists() or results.cells_file(p).exists(), path
    for path, *_ in results.JSON_SOURCES:
        assert (results.ROOT / path).exists(), path
