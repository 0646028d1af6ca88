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
