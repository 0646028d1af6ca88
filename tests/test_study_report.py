"""The study report: intervals that respect the quantity's range and say when n is too small,
route adherence, and ``--csv`` / ``--figure`` for a study database."""

from __future__ import annotations

import csv
import json
import math
import sqlite3
from pathlib import Path

import pytest

from pathpref.apps.cli import main
from pathpref.experiments.report import MIN_INTERVAL_N, range_interval, study_records

ROOT = Path(__file__).resolve().parents[1]
STUDY = ROOT / "examples" / "study_demo.json"
PUSHES = ROOT / "examples" / "pushes_demo.json"


def test_range_interval_by_hand():
    # [1, 2, 3, 10]: mean 4, s = sqrt(50/3) = 4.08248, t(0.975, 3) = 3.18245,
    # half = 3.18245 * 4.08248 / 2 = 6.49614: [-2.496, 10.496] clipped to [0, 10.496]
    m, lo, hi = range_interval([1.0, 2.0, 3.0, 10.0])
    assert m == 4.0 and lo == 0.0 and hi == pytest.approx(10.49614, abs=1e-4)
    # 58.5 at n = 2 (the effort): a mean and no interval
    m, lo, hi = range_interval([20.0, 97.0])
    assert m == 58.5 and math.isnan(lo) and math.isnan(hi) and MIN_INTERVAL_N == 3
    # n = 3 equal values: s = 0, the interval is the point
    assert range_interval([5.0, 5.0, 5.0]) == (5.0, 5.0, 5.0)
    # far from 0 nothing is clipped: [10, 11, 12]: half = 4.30265 * 1 / sqrt(3) = 2.48414
    m, lo, hi = range_interval([10.0, 11.0, 12.0])
    assert (lo, hi) == (pytest.approx(8.51586, abs=1e-4), pytest.approx(13.48414, abs=1e-4))


def row(p, k, success, violations, effort, pushes=3, time_s=10.0, belief="shown", peak=None):
    return {"participant": p, "trial": k, "success": success, "violations": violations,
            "push_peak_n": peak,
            "effort_ns": effort, "pushes": pushes, "time_s": time_s, "method": "path_preference",
            "condition": json.dumps({"belief": belief})}


def test_study_records_on_route_and_no_negative_interval():
    trials = [row("a", 1, 1, 0, 1.0, peak=30.0), row("a", 2, 0, 2, 2.0, peak=35.0),
              row("a", 3, 1, 0, 3.0, peak=40.0), row("a", 4, 1, 1, 10.0, pushes=0),
              row("b", 1, 1, 0, 50.0)]
    recs = {(r["by"], r["group"]): r for r in study_records(trials)}
    a = recs[("participant", "a")]
    assert a["n"] == 4 and a["success_rate"] == 0.75 and a["on_route"] == 0.5
    assert a["effort_ns_low"] == 0.0 and a["effort_ns_high"] == pytest.approx(10.49614, abs=1e-4)
    # peak push over the 3 trials with a push: 35 -+ 4.302653 * 5 / sqrt(3) = 35 -+ 12.42069
    assert a["push_peak_n"] == 35.0
    assert (a["push_peak_n_low"], a["push_peak_n_high"]) == (
        pytest.approx(22.57931, abs=1e-4), pytest.approx(47.42069, abs=1e-4))
    b = recs[("participant", "b")]
    assert math.isnan(b["push_peak_n"])
    assert b["n"] == 1 and math.isnan(b["effort_ns_low"])
    # on route: 3 of 5 trials without a violation; Wilson [0.231, 0.882]
    c = recs[("condition", "path_preference, belief=shown")]
    assert c["on_route"] == 0.6
    assert (c["on_route_low"], c["on_route_high"]) == (pytest.approx(0.2307, abs=1e-4),
                                                      pytest.approx(0.8824, abs=1e-4))
    for r in recs.values():
        for col in ("time_s", "pushes", "effort_ns"):
            assert math.isnan(r[f"{col}_low"]) or r[f"{col}_low"] >= 0.0


def test_report_writes_csv_and_figure_for_a_study_database(tmp_path, capsys):
    db = tmp_path / "s.sqlite"
    assert main(["study", "run", str(STUDY), "--participant", "demo", "--db", str(db),
                 "--script", str(PUSHES)]) == 0
    capsys.readouterr()
    out_csv, fig = tmp_path / "r.csv", tmp_path / "r.png"
    assert main(["report", str(db), "--csv", str(out_csv), "--figure", str(fig)]) == 0
    out = capsys.readouterr().out
    assert f"wrote {out_csv}" in out and f"wrote {fig}" in out
    assert "| on route |" in out
    with open(out_csv, newline="") as f:
        recs = list(csv.DictReader(f))
    # one per participant (demo) and per condition (belief shown, hidden)
    assert [(r["by"], r["group"], r["n"]) for r in recs] == [
        ("participant", "demo", "2"), ("condition", "path_preference, belief=hidden", "1"),
        ("condition", "path_preference, belief=shown", "1")]
    viol = [v for (v,) in sqlite3.connect(db).execute("SELECT violations FROM trials")]
    assert float(recs[0]["on_route"]) == sum(v == 0 for v in viol) / 2
    assert fig.stat().st_size > 5000 and fig.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_study_figure_keeps_every_point_off_its_frame():
    """``report --figure`` on a study: the top effort point (here a bare point, n < 3, above
    every interval) and rates of 0 and 1 lie inside their panels, at least 5% of the panel's
    height from its top and bottom edges."""
    from pathpref.viz.plots import study_axes

    nan = math.nan
    recs = [{"by": "condition", "group": g, "n": n, "success_rate": s, "ci_low": s - 0.1 * (s > 0),
             "ci_high": min(1.0, s + 0.1), "on_route": o, "on_route_low": max(0.0, o - 0.2),
             "on_route_high": min(1.0, o + 0.2), "effort_ns": e, "effort_ns_low": lo,
             "effort_ns_high": hi}
            for g, n, s, o, e, lo, hi in (("a", 5, 1.0, 0.0, 80.0, 60.0, 95.0),
                                          ("b", 2, 0.0, 1.0, 140.0, nan, nan))]
    fig = study_axes(recs)
    try:
        for ax, (col, hi_key, lo_key) in zip(fig.axes, (
                ("success_rate", "ci_high", "ci_low"), ("on_route", "on_route_high",
                                                        "on_route_low"),
                ("effort_ns", "effort_ns_high", "effort_ns_low")), strict=True):
            bottom, top = ax.get_ylim()
            room = 0.05 * (top - bottom)
            values = [v for r in recs for v in (r[col], r[hi_key], r[lo_key])
                      if not math.isnan(v)]
            assert max(values) <= top - room, (col, max(values), top)
            if col != "effort_ns":  # effort's axis starts at 0 N s, below every point here
                assert min(values) >= bottom + room, (col, min(values), bottom)
    finally:
        import matplotlib.pyplot as plt

        plt.close(fig)
