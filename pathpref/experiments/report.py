"""Tables from a results store: success rates (Table I) with 95% confidence intervals.

The interval of a success rate is the Wilson score interval (95%), which stays inside [0, 1]
and behaves at rates near 0 or 1, unlike the normal approximation. A failed episode (status not
``ok``: an error, a timeout, a crashed worker) counts as a failure of the mission by default: it
is in ``n`` and counts against the success, goal and preference rates, so 9 successes in 24
rows of which 3 failed read 0.38, never 9/21 = 0.43. Every record and every table says how many
rows failed. ``exclude_failed=True`` (``pathpref report --exclude-failed``) leaves them out of
the rates instead, still counted.

Beside the strict success (the paper's headline) every record gives the homotopy-level success
(goal reached in the human route's homotopy class, :mod:`pathpref.geometry.homotopy`) with its
interval, over the rows that measured it (rows written before schema 5 hold NULL: not
measured, and are left out of that rate only), and the pushes per episode: the mean of the
rows' ``inputs`` over the episodes that ran, and over the successful ones.

Every record also splits its failures by why they failed (time-out, wrong side, out-of-order
crossing, not run) and gives the success per slack bin (``T_max`` minus the moves of the human's
route), each with ``n`` and its Wilson interval (:mod:`.outcomes`).
"""

from __future__ import annotations

import csv
import math
import sqlite3
from collections import defaultdict
from pathlib import Path
from typing import Any

from ..errors import ConfigError
from .outcomes import (
    FAILURE_LABEL,
    SLACK_BINS,
    failure_split,
    slack_cell,
    slack_summary,
    split_cell,
)
from .paper import TABLE_I
from .store import RUNNING, ResultStore

#: row order of the tables: the paper's four, hindsight optimisation (from outside the paper), then
#: the reference rows (the ceiling), then any
#: registered method by name
METHOD_ORDER = ["compliant", "goal_only", "path_preference", "blended", "hindsight", "goal_known",
                "oracle"]
METHOD_LABEL = {
    "compliant": "compliant",
    "goal_only": "goal only",
    "path_preference": "path preference",
    "blended": "path preference + blend",
    "hindsight": "hindsight optimisation",
}


def wilson(successes: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """95% Wilson score interval of a binomial proportion: ``0 <= lo <= k/n <= hi <= 1``.

    The exact interval always contains ``p = k/n``; at ``k = 0`` or ``k = n`` one end equals
    ``p``, which floating point can miss by an ulp, so the ends are clipped to contain ``p``.
    """
    if n == 0:
        return (0.0, 1.0)
    p = successes / n
    den = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return (max(0.0, min(p, centre - half)), min(1.0, max(p, centre + half)))


def physics_label(text: str | None) -> str:
    """A row's physical parameters in words: ``legacy physics`` (an empty ``physics``),
    ``default physics``, or ``physics`` with every field that differs from
    :class:`~pathpref.episode.physics.Physics`'s defaults (``physics sensor_noise_n=50``)."""
    import json

    from ..episode.physics import Physics

    if not text:
        return "legacy physics"
    try:
        given = json.loads(text)
    except ValueError:
        return f"physics {text}"
    default = json.loads(Physics().to_json())
    diff = [f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}"
            for k, v in sorted(given.items()) if default.get(k, object()) != v]
    return "physics " + ", ".join(diff) if diff else "default physics"


def variant(r: dict[str, Any], physics: bool = True) -> str:
    """The settings that make two sweeps of the same map not comparable cell by cell: the
    planner's (preset, queries, c, T_max, likelihood, coupling, prior where it is not the
    preset's, time budget), the instances' (goal candidates, the human) and, for a physical
    body, every physical parameter (:func:`physics_label`; left out with ``physics=False``).
    A cell never mixes two of them."""
    from ..planning.pomdp import PRESETS

    parts = [f"preset {r['preset']}", f"{r['queries']} queries", f"c={r['ucb_c']:g}",
             f"T_max={r['t_max']}"]
    if r.get("task", "navigate") != "navigate":
        parts.insert(0, f"task {r['task']}")
    if not r["normalize"]:
        parts.append("un-normalised likelihood")
    parts.append("coupling" if r["coupling"] else "no coupling")
    preset = PRESETS.get(r["preset"])
    prior = r.get("prior") or "independent"
    if preset is None or prior != preset.prior:
        parts.append(f"{prior} prior")
    if r.get("time_budget_ms"):
        parts.append(f"{r['time_budget_ms']:g} ms budget")
    if r.get("n_goals", 10) != 10:
        parts.append(f"{r['n_goals']} goals")
    if (r.get("human") or "map") != "map":
        parts.append(f"{r['human']} human")
    if r.get("push_rule"):
        parts.append(f"{r['push_rule']} pushes")
    grid = r.get("sim", "grid") == "grid"
    if physics and not grid:
        parts.append(physics_label(r.get("physics")))
    elif grid and r.get("physics"):  # a grid episode's human model (not the default one)
        parts.append(physics_label(r["physics"]).replace("physics", "human model", 1))
    return ", ".join(parts)


def success_table(rows: list[dict[str, Any]], exclude_failed: bool = False
                  ) -> list[dict[str, Any]]:
    """One record per (map, sim, variant, method, delta_t) with n, rate, CI and flag rates.

    ``n`` counts every row and a failed one (status not ``ok``) is a failure of the mission,
    unless ``exclude_failed``: then ``n`` counts the ``ok`` rows only. ``failed`` is the number
    of failed rows either way, ``failed_excluded`` says which rule the rates follow.
    """
    groups: dict[tuple, list[dict]] = defaultdict(list)
    label: dict[str, str] = {}  # a map is its content: rows of one hash share the first path
    for r in rows:
        if r["status"] == RUNNING:  # claimed by a sweep, not finished: not a result
            continue
        m = label.setdefault(r["map_hash"], r["map"])
        groups[(m, r["sim"], variant(r), r["method"], r["delta_t"])].append(r)
    out = []
    for (m, sim, var, method, dt), rs in sorted(groups.items(), key=lambda kv: (
            kv[0][0], kv[0][1], kv[0][2], _order(kv[0][3]), kv[0][4])):
        ok = [r for r in rs if r["status"] == "ok"]
        counted = ok if exclude_failed else rs
        n = len(counted)
        k = sum(r["success"] for r in ok)
        lo, hi = wilson(k, n)
        r0 = rs[0]
        out.append({
            "map": m, "map_hash": r0["map_hash"], "sim": sim, "variant": var,
            "settings": variant(r0, physics=False),
            "physics": physics_label(r0.get("physics")) if sim != "grid" else "",
            "method": method, "delta_t": dt,
            "n": n, "failed": len(rs) - len(ok), "success_rate": k / n if n else float("nan"),
            "ci_low": lo, "ci_high": hi,
            "goal_rate": sum(r["goal_reached"] for r in ok) / n if n else float("nan"),
            "pref_rate": sum(r["pref_followed"] for r in ok) / n if n else float("nan"),
            "instances": len({r["instance_seed"] for r in counted}),
            "failed_excluded": bool(exclude_failed),
            **homotopy_summary(counted),
            **failure_split(counted, exclude_failed),
            **slack_summary(counted),
            **push_summary(ok),
            **physical_summary(ok),
        })
    return out


def homotopy_summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The homotopy-level success of ``rows`` (the rows a rate counts): its rate and 95%
    Wilson interval over the ``homotopy_n`` rows that measured it (``homotopy_success`` not
    NULL; a failed row holds 0); None and ``(0, 1)`` when none did."""
    measured = [r for r in rows if r.get("homotopy_success") is not None]
    n, k = len(measured), sum(r["homotopy_success"] for r in measured)
    lo, hi = wilson(k, n)
    return {"homotopy_n": n, "homotopy_rate": k / n if n else None,
            "homotopy_ci_low": lo, "homotopy_ci_high": hi}


def push_summary(ok: list[dict[str, Any]]) -> dict[str, Any]:
    """Pushes per episode (the mean of ``inputs``) over the episodes that ran (``ok``), and
    over the successful ones; None without such episodes."""
    won = [r["inputs"] for r in ok if r["success"]]
    return {"pushes_per_episode": sum(r["inputs"] for r in ok) / len(ok) if ok else None,
            "pushes_per_success": sum(won) / len(won) if won else None}


#: per-episode metrics of a physical body that a cell sums (:func:`physical_summary`)
PUSH_COUNTS = ("pushes", "pushes_missed", "pushes_misread", "collisions")
#: the person's effort per episode (:meth:`pathpref.sim.body.MujocoBody.effort_metrics`), a
#: cell's mean of each (the peak: its largest)
EFFORT = ("person_impulse_ns", "person_contact_s", "person_peak_n")


def physical_summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """What a cell's physical episodes measured (rows whose ``metrics`` hold them: episodes
    with physical parameters): the pushes made, missed and misread, the collisions (contacts
    with an obstacle or a wall begun), summed over the episodes, and the mean cue latency (ms,
    over the episodes with a cue); the person's effort (:data:`EFFORT`): the mean impulse
    ``integral |F| dt`` (N s) and contact time (s) per episode, the largest peak force (N),
    and the impulse per success (``person_impulse_per_success_ns``: the impulse of all the
    episodes over the successes; None without one). ``None`` for each when no row measured
    it."""
    import json

    out: dict[str, Any] = {k: None for k in (*PUSH_COUNTS, "cue_latency_ms", *EFFORT,
                                             "person_impulse_per_success_ns")}
    lat, effort, wins = [], {k: [] for k in EFFORT}, 0
    for r in rows:
        try:
            m = json.loads(r.get("metrics") or "{}")
        except ValueError:
            continue
        if not isinstance(m, dict):
            continue
        for k in PUSH_COUNTS:
            if isinstance(m.get(k), int | float):
                out[k] = (out[k] or 0) + int(m[k])
        if isinstance(m.get("cue_latency_ms"), int | float) and math.isfinite(
                m["cue_latency_ms"]):
            lat.append(float(m["cue_latency_ms"]))
        if all(isinstance(m.get(k), int | float) for k in EFFORT):
            for k in EFFORT:
                effort[k].append(float(m[k]))
            wins += bool(r.get("success"))
    if lat:
        out["cue_latency_ms"] = sum(lat) / len(lat)
    if effort["person_peak_n"]:
        for k in ("person_impulse_ns", "person_contact_s"):
            out[k] = sum(effort[k]) / len(effort[k])
        out["person_peak_n"] = max(effort["person_peak_n"])
        if wins:
            out["person_impulse_per_success_ns"] = sum(effort["person_impulse_ns"]) / wins
    return out


def physical_tables(records: list[dict[str, Any]]) -> str:
    """Markdown: for every (map, sim, variant) whose episodes measured how the robot read the
    pushes, methods x Delta_T cells ``missed m / misread r of n pushes, latency L ms, c
    collisions, effort J N s / episode`` (sums over the cell's episodes; latency and the
    person's impulse: the means over episodes; no effort for rows that did not measure it)."""
    blocks = []
    keys = sorted({(r["map"], r["sim"], r["variant"]) for r in records
                   if r.get("pushes") is not None})
    def cell(recs, meth, d) -> str:
        r = _find(recs, meth, d)
        if r is None or r.get("pushes") is None:
            return "–"
        lat = r.get("cue_latency_ms")
        effort = "" if r.get("person_impulse_ns") is None else \
            f", effort {r['person_impulse_ns']:.1f} N s / episode"
        return (f"missed {r['pushes_missed']} / misread {r['pushes_misread']} of "
                f"{r['pushes']}, " + ("no cue" if lat is None else f"latency {lat:.0f} ms")
                + f", {r['collisions']} collisions" + effort)

    for m, sim, var in keys:
        recs = [r for r in records if (r["map"], r["sim"], r["variant"]) == (m, sim, var)]
        blocks.append("\n".join(_grid(f"**{m}**, how the pushes were read ({sim}; {var})",
                                       recs, lambda meth, d, recs=recs: cell(recs, meth, d))))
    return "\n\n".join(blocks)


def failed_note(records: list[dict[str, Any]]) -> str:
    """How many rows of ``records`` failed and what the rates did with them, e.g. ``3 failed
    rows, counted as failures`` (the title of every table)."""
    failed = sum(r["failed"] for r in records)
    rows = "row" if failed == 1 else "rows"
    if any(r.get("failed_excluded") for r in records):
        return f"{failed} failed {rows}, left out of the rates (--exclude-failed)"
    return f"{failed} failed {rows}, counted as failures"


def _order(method: str) -> tuple[int, str]:
    return (METHOD_ORDER.index(method) if method in METHOD_ORDER else len(METHOD_ORDER), method)


def _grid(title: str, recs: list[dict[str, Any]], cell) -> list[str]:
    """A Markdown table of ``recs``: a row per method (in :func:`_order`), a column per
    Delta_T, each cell ``cell(method, delta_t)``, under ``title``."""
    dts = sorted({r["delta_t"] for r in recs})
    lines = [title, "", "| method | " + " | ".join(f"ΔT={d}" for d in dts) + " |",
             "|---|" + "---|" * len(dts)]
    for meth in sorted({r["method"] for r in recs}, key=_order):
        lines.append(f"| {METHOD_LABEL.get(meth, meth)} | "
                     + " | ".join(cell(meth, d) for d in dts) + " |")
    return lines


def _find(recs: list[dict[str, Any]], meth: str, dt: int) -> dict[str, Any] | None:
    """The record of ``recs`` for method ``meth`` at Delta_T ``dt`` (None: none)."""
    return next((x for x in recs if x["method"] == meth and x["delta_t"] == dt), None)


def markdown_tables(records: list[dict[str, Any]], with_paper: bool = True) -> str:
    """Markdown: one table per (map, sim, variant), methods x Delta_T, rate [95% CI]; under
    it the homotopy-level success [95% CI] and the pushes per episode of the same cells."""
    blocks = []
    keys = sorted({(r["map"], r["sim"], r["variant"]) for r in records})
    for m, sim, var in keys:
        recs = [r for r in records if (r["map"], r["sim"], r["variant"]) == (m, sim, var)]
        dts = sorted({r["delta_t"] for r in recs})
        methods = sorted({r["method"] for r in recs}, key=_order)
        ns = sorted({r["n"] for r in recs})
        title = (f"**{m}** ({sim}; {var}; n = {'/'.join(map(str, ns))} per cell; "
                 f"{failed_note(recs)})")

        def rate(meth, d, recs=recs) -> str:
            r = _find(recs, meth, d)
            if r is None or r["n"] == 0:
                return "–" if r is None or not r["failed"] else f"– ({r['failed']} failed)"
            return (f"{r['success_rate']:.2f} [{r['ci_low']:.2f}, {r['ci_high']:.2f}]"
                    + (f" ({r['failed']} failed)" if r["failed"] else ""))

        lines = _grid(title, recs, rate)

        def homotopy(meth, d, recs=recs) -> str:
            r = _find(recs, meth, d)
            if r is None:
                return "–"
            rate = ("not measured" if not r["homotopy_n"] else
                    f"{r['homotopy_rate']:.2f} [{r['homotopy_ci_low']:.2f}, "
                    f"{r['homotopy_ci_high']:.2f}]")
            pushes = r["pushes_per_episode"]
            return rate + ("" if pushes is None else f"; {pushes:.1f} pushes")

        if with_paper and m == "simple" and sim == "grid":
            lines += ["", "Paper (Table I, Map 1):", "",
                      "| method | " + " | ".join(f"ΔT={d}" for d in dts) + " |",
                      "|---|" + "---|" * len(dts)]
            for meth in methods:
                if meth in TABLE_I:
                    vals = [TABLE_I[meth].get(d) for d in dts]
                    lines.append(f"| {METHOD_LABEL[meth]} | " + " | ".join(
                        "–" if v is None else f"{v:.2f}" for v in vals) + " |")
        lines += [""] + _grid(f"**{m}**, homotopy-level success [95% CI]; pushes per episode",
                              recs, homotopy)
        lines += [""] + _grid(
            f"**{m}**, why episodes failed: {FAILURE_LABEL['time_out']}, "
            f"{FAILURE_LABEL['wrong_side']}, {FAILURE_LABEL['out_of_order']} "
            "(episodes)", recs,
            lambda meth, d, recs=recs: "–" if (r := _find(recs, meth, d)) is None
            else split_cell(r))
        lines += ["", slack_table(m, recs)]
        blocks.append("\n".join(lines))
    return "\n\n".join(blocks)


def slack_table(m: str, recs: list[dict[str, Any]]) -> str:
    """Markdown: success by slack bin (:data:`~.outcomes.SLACK_BINS`, ``T_max`` minus the
    moves of the human's route), a row per method and Delta_T, each cell ``k/n rate [95%
    Wilson]``; the rows without a slack counted under it."""
    lines = [f"**{m}**, success by slack (T_max minus the human route's moves): k/n rate "
             "[95% CI]", "",
             "| method | ΔT | " + " | ".join(f"slack {label}" for _, label, *_ in SLACK_BINS)
             + " |", "|---|---|" + "---|" * len(SLACK_BINS)]
    for r in sorted(recs, key=lambda r: (_order(r["method"]), r["delta_t"])):
        lines.append(f"| {METHOD_LABEL.get(r['method'], r['method'])} | {r['delta_t']} | "
                     + " | ".join(slack_cell(r, key) for key, *_ in SLACK_BINS) + " |")
    unmeasured = sum(r["slack_unmeasured_n"] for r in recs)
    if unmeasured:
        lines += ["", f"{unmeasured} episodes without a slack (not measured: written before "
                  "the column or not run; 'pathpref db upgrade' fills it where it can)"]
    return "\n".join(lines)


def side_by_side(records: list[dict[str, Any]]) -> str:
    """For every (map, variant) run in more than one simulator: one table, each cell
    ``sim1 rate / sim2 rate`` (e.g. grid / mujoco), so the two are read together."""
    blocks = []
    for m, var in sorted({(r["map"], r.get("settings", r["variant"])) for r in records}):
        recs = [r for r in records if (r["map"], r.get("settings", r["variant"])) == (m, var)]
        bodies = sorted({_body(r) for r in recs})
        if len(bodies) < 2:
            continue
        # one column per simulator, named by the simulator alone when each has one physics
        plain = len(bodies) == len({r["sim"] for r in recs})
        col = (lambda r: r["sim"]) if plain else _body
        sims = sorted({col(r) for r in recs})
        phys = sorted({r["physics"] for r in recs if r.get("physics")})
        if plain and phys:
            var = f"{var}; {'; '.join(phys)}"
        def both(meth, d, recs=recs, sims=sims, col=col) -> str:
            vals = []
            for sim in sims:
                r = next((x for x in recs if (x["method"], x["delta_t"], col(x)) ==
                          (meth, d, sim)), None)
                vals.append("–" if r is None or not r["n"] else f"{r['success_rate']:.2f}")
            return " / ".join(vals)

        lines = _grid(f"**{m}**: {' / '.join(sims)} side by side ({var}; {failed_note(recs)})",
                      recs, both)
        blocks.append("\n".join(lines))
    return "\n\n".join(blocks)


def _body(r: dict[str, Any]) -> str:
    """A record's simulator with its physics when it has one (``mujoco, default physics``):
    one column of :func:`side_by_side` each."""
    return f"{r['sim']}, {r['physics']}" if r.get("physics") else r["sim"]


def write_csv(records: list[dict[str, Any]], path: str | Path) -> None:
    """Write ``records`` (dicts with the same keys) as CSV to ``path``."""
    if not records:
        Path(path).write_text("")
        return
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(records[0]))
        w.writeheader()
        w.writerows(records)


def load_records(db: str | Path, exclude_failed: bool = False) -> list[dict[str, Any]]:
    """The records of :func:`success_table` over every episode row of the results database
    ``db`` (damage found while reading: one ConfigError line)."""
    with ResultStore(db, create=False) as store:
        try:
            return success_table(store.episodes(), exclude_failed)
        except sqlite3.DatabaseError as e:
            raise ConfigError(f"cannot read results from {db}: {e} (the file is damaged)"
                              ) from None


# --- force-interaction studies (the study tables, schema 4) ----------------------------------
def mean_interval(values: list[float], z_level: float = 0.975) -> tuple[float, float, float]:
    """Mean and its 95% Student-t interval ``mean -+ t_{n-1} s / sqrt(n)`` (``s`` the sample
    standard deviation); a single value has the interval ``(nan, nan)``."""
    from scipy.stats import t as student

    n = len(values)
    if n == 0:
        return float("nan"), float("nan"), float("nan")
    m = sum(values) / n
    if n == 1:
        return m, float("nan"), float("nan")
    s = math.sqrt(sum((v - m) ** 2 for v in values) / (n - 1))
    h = float(student.ppf(z_level, n - 1)) * s / math.sqrt(n)
    return m, m - h, m + h


def load_trials(db: str | Path) -> list[dict[str, Any]]:
    """Every finished study trial of ``db`` (none when it has no study tables), each with
    ``push_peak_n``: the mean peak force of its pushes (N; None without a push). A row
    changed outside pathpref is one error line (:mod:`.trial_rows`)."""
    from .trial_rows import check_trial_row
    from .trials import has_study_tables, read_rows

    with ResultStore(db, create=False) as store:
        try:
            if not has_study_tables(store.conn):
                return []
            rows = [check_trial_row(r, db) for r in read_rows(
                store.conn, "trials", "WHERE status = 'done' ORDER BY participant, trial")]
            peaks = {(p, k): v for p, k, v in store.conn.execute(
                "SELECT participant, trial, avg(peak_n) FROM trial_pushes "
                "GROUP BY participant, trial")}
            return [r | {"push_peak_n": peaks.get((r["participant"], r["trial"]))}
                    for r in rows]
        except sqlite3.DatabaseError as e:
            raise ConfigError(f"cannot read trials from {db}: {e} (the file is damaged)"
                              ) from None


def condition_label(row: dict[str, Any]) -> str:
    """A trial's condition as ``method, label=value, ...`` (the labels of the study file),
    then the physics and robot when they are not the defaults (:func:`physics_label`, e.g.
    ``physics sensor=ideal``; ``robot=carry``), so trials that ran different physics or robots
    never share a group. A row written before the columns existed (NULL) ran the defaults."""
    import json

    labels = json.loads(row["condition"] or "{}")
    parts = [row["method"], *(f"{k}={v}" for k, v in sorted(labels.items()))]
    if row.get("physics") is not None:  # NULL: a row written before the column, default
        physics = physics_label(row["physics"])
        if physics != "default physics":
            parts.append(physics)
    if row.get("robot") not in (None, "navigate"):
        parts.append(f"robot={row['robot']}")
    return ", ".join(parts)


#: fewer values than this get a mean and no interval (a t interval at n = 2 spans
#: 12.7 standard deviations either side: effort 58.5 [-684.7, 801.7] N s)
MIN_INTERVAL_N = 3


def range_interval(values: list[float], low: float = 0.0, high: float = math.inf
                   ) -> tuple[float, float, float]:
    """Mean and 95% interval of a quantity that lies in ``[low, high]`` (time, pushes and
    effort: ``[0, inf)``): the Student-t interval (:func:`mean_interval`) clipped to the range,
    so it never claims an impossible value (no negative effort); with fewer than
    :data:`MIN_INTERVAL_N` values, no interval ``(nan, nan)`` (shown as ``n < 3``). Clipping
    keeps the t interval's coverage for every mean inside the range (the dropped part held
    no possible mean)."""
    m, lo, hi = mean_interval(values)
    if len(values) < MIN_INTERVAL_N:
        return m, float("nan"), float("nan")
    return m, max(low, lo), min(high, hi)


def study_records(trials: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One record per participant and per condition (``by``: ``participant`` or
    ``condition``): trials ``n``; success rate and the share of trials *on route* (no
    violation of the route's preference) and homotopy-level success (the goal reached the
    route's way round every obstacle; over the trials that measured it, ``None`` without
    one), each with its 95% Wilson interval; the means of
    time (s; a timed-out trial counts its full time), pushes and effort (integral of |F| dt,
    N s), and of the trials' mean peak push force (N, ``push_peak_n``; over the trials with a
    push), with :func:`range_interval` (``nan`` when fewer than 3 values)."""
    out = []
    for by, key in (("participant", lambda r: r["participant"]),
                    ("condition", condition_label)):
        groups: dict[str, list[dict]] = defaultdict(list)
        for r in trials:
            groups[key(r)].append(r)
        for g, rs in sorted(groups.items()):
            n = len(rs)
            k = sum(r["success"] for r in rs)
            on = sum((r["violations"] or 0) == 0 for r in rs)
            rec = {"by": by, "group": g, "n": n, "success_rate": k / n}
            rec["ci_low"], rec["ci_high"] = wilson(k, n)
            rec["on_route"] = on / n
            rec["on_route_low"], rec["on_route_high"] = wilson(on, n)
            measured = [r["homotopy_success"] for r in rs if r.get("homotopy_success") is not None]
            rec["homotopy"] = sum(measured) / len(measured) if measured else None
            rec["homotopy_low"], rec["homotopy_high"] = wilson(sum(measured), len(measured)) \
                if measured else (None, None)
            for col in ("time_s", "pushes", "effort_ns", "push_peak_n"):
                vals = [float(r[col]) for r in rs if r.get(col) is not None]
                m, lo, hi = range_interval(vals) if vals else (math.nan,) * 3
                rec[col], rec[f"{col}_low"], rec[f"{col}_high"] = m, lo, hi
            out.append(rec)
    return out


def study_tables(trials: list[dict[str, Any]]) -> str:
    """Markdown of :func:`study_records`: per participant and per condition, success rate
    [95% Wilson], the means [95% t interval clipped to the quantity's range; ``n < 3``: none]
    of time, pushes and effort, the share of trials on route [95% Wilson] and the mean peak
    push force."""
    def fmt(m: float, lo: float, hi: float, digits: int = 1) -> str:
        if math.isnan(m):
            return "-"
        if math.isnan(lo):
            return f"{m:.{digits}f} (n < {MIN_INTERVAL_N})"
        return f"{m:.{digits}f} [{lo:.{digits}f}, {hi:.{digits}f}]"

    recs = study_records(trials)
    lines: list[str] = []
    for by, title in (("participant", "Study trials per participant"),
                      ("condition", "Study trials per condition")):
        if lines:
            lines.append("")
        lines += [f"**{title}**", "", f"| {by} | n | success | time (s) | pushes | "
                  "effort (N s) | on route | homotopy-level | peak push (N) |",
                  "|---|---|---|---|---|---|---|---|---|"]
        for r in (r for r in recs if r["by"] == by):
            lines.append(
                f"| {r['group']} | {r['n']} | {r['success_rate']:.2f} [{r['ci_low']:.2f}, "
                f"{r['ci_high']:.2f}] | "
                + " | ".join(fmt(r[c], r[f"{c}_low"], r[f"{c}_high"])
                             for c in ("time_s", "pushes", "effort_ns"))
                + f" | {r['on_route']:.2f} [{r['on_route_low']:.2f}, "
                f"{r['on_route_high']:.2f}] | "
                + ("not measured" if r["homotopy"] is None else
                   f"{r['homotopy']:.2f} [{r['homotopy_low']:.2f}, {r['homotopy_high']:.2f}]")
                + " | " + fmt(r["push_peak_n"], r["push_peak_n_low"], r["push_peak_n_high"]) + " |")
    return "\n".join(lines)
