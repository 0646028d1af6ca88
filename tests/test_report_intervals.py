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
