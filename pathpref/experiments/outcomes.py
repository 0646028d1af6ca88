"""Why episodes fail, and how success depends on the time to spare.

**Failure kinds.** An episode row that is not a success falls in exactly one kind, decided in
this order from its stored flags (``status``, ``metrics``, ``goal_reached``,
``homotopy_success``, ``violations``):

- ``not_run``: the episode did not run to its end (``status != 'ok'``: an error, a timeout, a
  crashed worker); counted as a failure of the mission;
- ``contact``: the robot struck an obstacle or a wall beyond the limits of
  :mod:`pathpref.episode.safety` (from the contact measurements in ``metrics``), whatever else
  the episode achieved;
- ``time_out``: the goal was not reached within ``T_max`` (``goal_reached = 0``);
- ``wrong_side``: the goal was reached, but not in the human route's homotopy class
  (``homotopy_success = 0``: the robot went the other way round some obstacle);
- ``out_of_order``: the goal was reached in the route's class, but some polytope transition
  left a polytope by a face the human's preference forbids (``violations > 0``);
- ``unclassified``: the goal was reached with violations and the row does not say on which
  side (``homotopy_success`` NULL: a row written before schema 5, not measured).

A row that ran, stayed contact-safe and reached the goal with no violation is a success (the
strict rule), so the kinds partition the failures: ``not_run + contact + time_out + wrong_side +
out_of_order + unclassified = n - successes`` (with ``exclude_failed`` the ``not_run`` rows are
out of ``n`` and counted 0).

**Slack.** An episode's slack is ``T_max`` minus the moves of the human's route from the start
to the true goal (:func:`~pathpref.episode.results.route_slack`, stored per episode in the
``slack`` column): the decision steps a method may lose to inference and still succeed. Success
is reported per slack bin (:data:`SLACK_BINS`), each with its rate, ``n`` and 95% Wilson
interval; a row without a slack (NULL: written before the column, or not run) is counted
*not measured*.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

from ..episode.safety import contact_safe

#: failure kinds, in the order they are decided and shown (module docstring)
FAILURE_KINDS = ("not_run", "contact", "time_out", "wrong_side", "out_of_order",
                 "unclassified")
FAILURE_LABEL = {"not_run": "not run", "contact": "unsafe contact", "time_out": "time-out",
                 "wrong_side": "wrong side",
                 "out_of_order": "out-of-order crossing", "unclassified": "unclassified"}

#: slack bins ``(key, label, low, high)``: slack ``s`` falls in the bin with ``low <= s <
#: high`` (decision steps); the one home of these bounds
SLACK_BINS = (
    ("lt10", "< 10", -math.inf, 10),
    ("10_19", "10-19", 10, 20),
    ("20_39", "20-39", 20, 40),
    ("ge40", ">= 40", 40, math.inf),
)
#: the key of the rows whose slack was not measured (NULL)
SLACK_UNMEASURED = "unmeasured"


def failure_kind(row: dict[str, Any]) -> str | None:
    """The failure kind of an episode row (module docstring), None for a success."""
    if row["status"] != "ok":
        return "not_run"
    if not contact_safe(row.get("metrics")):
        return "contact"
    if not row["goal_reached"]:
        return "time_out"
    if not row["violations"] and row.get("pref_followed", 1):
        return None
    h = row.get("homotopy_success")
    if h is None:
        return "unclassified"
    return "out_of_order" if h else "wrong_side"


def failure_split(rows: Iterable[dict[str, Any]], exclude_failed: bool = False
                  ) -> dict[str, int]:
    """``{kind: count}`` over ``rows`` for every kind of :data:`FAILURE_KINDS` (``not_run``
    0 with ``exclude_failed``, as those rows are out of the rates then)."""
    out = dict.fromkeys(FAILURE_KINDS, 0)
    for r in rows:
        kind = failure_kind(r)
        if kind is not None and not (exclude_failed and kind == "not_run"):
            out[kind] += 1
    return out


def slack_bin(slack: int | float | None) -> str:
    """The key of the :data:`SLACK_BINS` bin of ``slack`` (:data:`SLACK_UNMEASURED` for
    None)."""
    if slack is None:
        return SLACK_UNMEASURED
    return next(key for key, _, lo, hi in SLACK_BINS if lo <= slack < hi)


def slack_summary(rows: Iterable[dict[str, Any]]) -> dict[str, Any]:
    """Per slack bin ``key`` of :data:`SLACK_BINS`: ``slack_{key}_n`` (rows), ``_k``
    (successes), ``_rate`` (None without rows) and the 95% Wilson interval ``_ci_low``,
    ``_ci_high``; and ``slack_unmeasured_n``, the rows without a slack (they are in no bin)."""
    from .report import wilson

    n = {key: 0 for key, *_ in SLACK_BINS} | {SLACK_UNMEASURED: 0}
    k = dict.fromkeys(n, 0)
    for r in rows:
        b = slack_bin(r.get("slack"))
        n[b] += 1
        k[b] += int(bool(r["success"]) and r["status"] == "ok")
    out: dict[str, Any] = {}
    for key, *_ in SLACK_BINS:
        lo, hi = wilson(k[key], n[key])
        out |= {f"slack_{key}_n": n[key], f"slack_{key}_k": k[key],
                f"slack_{key}_rate": k[key] / n[key] if n[key] else None,
                f"slack_{key}_ci_low": lo, f"slack_{key}_ci_high": hi}
    out[f"slack_{SLACK_UNMEASURED}_n"] = n[SLACK_UNMEASURED]
    return out


def slack_cell(rec: dict[str, Any], key: str) -> str:
    """A Markdown cell of one slack bin of a record: ``k/n rate [lo, hi]``, ``–`` without
    rows."""
    n = rec[f"slack_{key}_n"]
    if not n:
        return "–"
    return (f"{rec[f'slack_{key}_k']}/{n} {rec[f'slack_{key}_rate']:.2f} "
            f"[{rec[f'slack_{key}_ci_low']:.2f}, {rec[f'slack_{key}_ci_high']:.2f}]")


def split_cell(rec: dict[str, Any]) -> str:
    """A Markdown cell of a record's failure split: ``t, w, o`` (time-out, wrong side,
    out-of-order crossing) and the rows that did not run or could not be classified when there
    are any."""
    text = f"{rec['time_out']}, {rec['wrong_side']}, {rec['out_of_order']}"
    extra = [f"{rec[k]} {FAILURE_LABEL[k]}" for k in ("not_run", "unclassified") if rec[k]]
    return text + (f" (+{', '.join(extra)})" if extra else "")
