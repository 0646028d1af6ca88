"""Every results table of docs/results.md, generated from the stored databases and JSON files.

    .venv/bin/python scripts/results.py                       # writes docs/results.md
    .venv/bin/python scripts/results.py --db table1_simple.sqlite --db-command "pathpref ..."

Sources (:data:`SOURCES`): each stored sweep database (``*.sqlite``) and each result JSON the
repository keeps, with the command that wrote it. A database becomes one table per setting
(map, simulator, preset, human, push rule, ΔT): per method the episodes ``n``, strict success
``k/n`` with its 95% Wilson interval, homotopy-level success (the goal reached through the
preferred homotopy class) with its Wilson interval, the goal reached ``k/n`` and the mean
pushes per episode (the ``inputs`` column), and the failures by why they failed (time-out /
wrong side / out-of-order crossing, + not run: :mod:`pathpref.experiments.outcomes`). A failed
episode (an error, a timeout) counts as a
failure and the table says how many failed. A result JSON becomes its own table with the
intervals it stores. Every table names its command, ``n`` and its date: the date of the file's
last commit (``git log -1 --format=%cs``), else its modification date marked "not committed".
The stored database sources also get a JSON of every cell beside them (``<db stem>.json``;
the demo's sweep's in the package, :data:`CELLS_HOME`, naming its command and preset)
and a figure of success against pushes per episode (``<db stem>.png``). A database too large to
commit (Table I's 6000 episodes, office, classroom) is kept as that JSON only: its section is
then read from it.
"""

from __future__ import annotations

import argparse
import datetime
import json
import sqlite3
import subprocess
import sys
from pathlib import Path
from typing import Any

from pathpref.experiments.outcomes import FAILURE_LABEL, failure_split
from pathpref.experiments.report import METHOD_LABEL, METHOD_ORDER, wilson
from pathpref.viz.plots import success_pushes_figure

ROOT = Path(__file__).resolve().parents[1]

#: the stored sweep databases: path (repository-relative), title, command that wrote it
DB_SOURCES: list[tuple[str, str, str]] = [
    ("docs/results/table1_simple.sqlite", "Table I: success rates on simple (Map 1)",
     "pathpref evaluate --map simple --preset paper --methods all --delta-t 1 5 10 20 30 "
     "--instances 6 --runs 50 --db docs/results/table1_simple.sqlite --workers 2"),
    ("docs/results/office_paper.sqlite", "Office, the paper's planner (not in the paper)",
     "pathpref evaluate --map office --preset paper --methods all --delta-t 1 5 10 20 30 "
     "--instances 6 --runs 20 --db docs/results/office_paper.sqlite --workers 2"),
    ("docs/results/classroom_paper.sqlite", "Classroom, the paper's planner (not in the paper)",
     "pathpref evaluate --map classroom --preset paper --methods all --delta-t 1 5 10 20 30 "
     "--instances 6 --runs 10 --db docs/results/classroom_paper.sqlite --workers 2"),
    ("docs/results/demo_sweep.sqlite",
     "When inferring the preference matters (the demo's sweep)",
     "sh scripts/demo_sweep.sh docs/results/demo_sweep.sqlite {preset}"),
]

#: where a database's cells JSON lives when not beside its figure in docs/results: the demo's
#: sweep is package data (``pathpref demo`` reads it, and the wheel ships it)
CELLS_HOME: dict[str, str] = {
    "docs/results/demo_sweep.sqlite": "pathpref/apps/demo_sweep.json",
}



def cells_file(path: Path) -> Path:
    """Where the cells JSON of database ``path`` lives: :data:`CELLS_HOME`, else beside it
    (the stored copy of a database not in the repository)."""
    home = CELLS_HOME.get(_rel(path))
    return ROOT / home if home is not None else path.with_suffix(".json")


_STUDY = ("python scripts/physics_study.py --episodes {episodes} --map {map} --method {method} "
          "--delta-t {delta_t} --seed {seed} --preset {preset} --conditions {conditions}")

#: the stored result JSON files: path, title, kind (renderer), command ("" for the physics
#: study, whose command is rebuilt from the arguments it stores)
JSON_SOURCES: list[tuple[str, str, str, str]] = [
    ("docs/results/physics_study_simple.json", "What physics changes (physics study)",
     "physics", ""),
    ("docs/results/guidance_office.json", "Guidance against taps on office", "physics", ""),
    ("docs/results/thermal_simple.json", "Sensor thermal warm-up", "physics", ""),
    ("docs/results/physics_study_tidybot.json",
     "The Stanford TidyBot against the disk base (physics study)", "physics", ""),
    ("docs/pushes.json", "Success against pushes per episode", "pushes",
     "python scripts/pushes_figure.py --out docs/pushes.png --db-dir /tmp/pushes "
     "--instances 4 --queries 200"),
    ("docs/results/pushes_6x20.json",
     "Success against pushes per episode at full size (6 x 20 per map)", "pushes",
     "python scripts/pushes_figure.py --out docs/results/pushes_6x20.png --db-dir /tmp/pushes "
     "--instances 6 --runs 20 --queries 0"),
    ("docs/budget.json", "Success against planning time", "budget",
     "python scripts/budget_figure.py --maps simple office classroom"),
    ("docs/gamma_sweep.json", "The human's rationality: assumed against learned", "gamma",
     "python scripts/gamma_sweep.py --json docs/gamma_sweep.json"),
]


def file_date(path: Path) -> str:
    """The date of ``path``'s last commit (YYYY-MM-DD), else its modification date followed
    by "(not committed)"."""
    try:
        out = subprocess.run(["git", "log", "-1", "--format=%cs", "--", str(path)],
                             cwd=path.parent, capture_output=True, text=True, timeout=30)
        if out.returncode == 0 and out.stdout.strip():
            return out.stdout.strip()
    except (OSError, subprocess.SubprocessError):
        pass
    day = datetime.date.fromtimestamp(path.stat().st_mtime).isoformat()
    return f"{day} (not committed)"


def rate(k: int, n: int) -> str:
    """``k/n = rate [lo, hi]`` with the 95% Wilson interval."""
    lo, hi = wilson(k, n)
    return f"{k}/{n} = {k / n:.2f} [{lo:.2f}, {hi:.2f}]" if n else "–"


def _ci(p: float | None, ci: list[float] | None) -> str:
    if p is None:
        return "–"
    return f"{p:.2f} [{ci[0]:.2f}, {ci[1]:.2f}]" if ci else f"{p:.2f}"


def _num(x: float | None, digits: int = 2) -> str:
    return "–" if x is None else f"{x:.{digits}f}"


def _table(header: list[str], rows: list[list[str]]) -> list[str]:
    return (["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
            + ["| " + " | ".join(r) + " |" for r in rows])


def _method_key(m: str) -> tuple[int, str]:
    return (METHOD_ORDER.index(m) if m in METHOD_ORDER else len(METHOD_ORDER), m)


def setting_label(map_: str, sim: str, preset: str, human: str | None, push_rule: str | None,
                  delta_t: int) -> str:
    """One line naming a sweep setting, e.g. ``simple, grid, robust preset, corrective delay=1
    miss=0.2 (ΔT = 1)``."""
    who = f"{push_rule} (ΔT = {delta_t})" if push_rule else f"a push every ΔT = {delta_t} steps"
    return f"{map_}, {sim}, {preset} preset, {human or 'map'} human, {who}"


def db_cells(db: Path) -> list[dict[str, Any]]:
    """Per setting and method, the counts of the database's episodes (see module docstring)."""
    # immutable: no -shm/-wal files left beside a stored database (unless a WAL is pending)
    pending = Path(f"{db}-wal").exists()
    con = sqlite3.connect(f"file:{db}?mode=ro{'' if pending else '&immutable=1'}", uri=True)
    try:
        rows = con.execute(
            "SELECT map, sim, preset, human, push_rule, delta_t, method, COUNT(*), "
            "SUM(success), SUM(homotopy_success), COUNT(homotopy_success), SUM(goal_reached), "
            "AVG(inputs), SUM(status != 'ok') FROM episodes "
            "GROUP BY map, sim, preset, human, push_rule, delta_t, method").fetchall()
        con.row_factory = sqlite3.Row
        split: dict[tuple, list[dict[str, Any]]] = {}
        for r in con.execute(
                "SELECT map, sim, preset, human, push_rule, delta_t, method, status, "
                "goal_reached, violations, pref_followed, homotopy_success, success "
                "FROM episodes"):
            split.setdefault(tuple(r)[:7], []).append(dict(r))
    finally:
        con.close()
    cells = []
    for (map_, sim, preset, human, rule, dt, method, n, succ, hom, hom_n, reached, pushes,
         failed) in rows:
        why = failure_split(split.get((map_, sim, preset, human, rule, dt, method), []))
        lo, hi = wilson(int(succ or 0), n)
        hlo, hhi = wilson(int(hom or 0), hom_n)
        cells.append({
            "setting": setting_label(map_, sim, preset, human, rule, dt), "map": map_,
            "human_setting": f"{rule} (ΔT = {dt})" if rule else f"every ΔT = {dt} steps",
            "sim": sim, "preset": preset, "human": human or "map", "push_rule": rule or "",
            "delta_t": dt, "method": method, "n": n, "success": int(succ or 0),
            "success_ci": [lo, hi], "homotopy": int(hom or 0), "homotopy_n": hom_n,
            "homotopy_ci": [hlo, hhi], "goal_reached": int(reached or 0),
            "pushes_per_episode": pushes, "failed": int(failed or 0), "why_failed": why})
    cells.sort(key=lambda c: (c["map"], c["sim"], c["preset"], c["human"], c["push_rule"],
                              c["delta_t"], _method_key(c["method"])))
    return cells


def db_section(cells: list[dict[str, Any]], source: str, date: str, title: str,
               command: str) -> list[str]:
    """The Markdown section of one sweep's cells: per group of settings that differ only in
    ΔT, a method x ΔT grid of success when there are several ΔT, then a table per setting."""
    lines = [f"## {title}", "", f"Source {source}, {sum(c['n'] for c in cells)} episodes, "
             f"dated {date}; command:", "", "```", command, "```", ""]
    groups: dict[tuple, list[dict[str, Any]]] = {}
    for c in cells:
        groups.setdefault((c["map"], c["sim"], c["preset"], c["human"], c["push_rule"]),
                          []).append(c)
    for (map_, sim, preset, human, rule), group in groups.items():
        dts = sorted({c["delta_t"] for c in group})
        if len(dts) < 2:
            continue
        lines += [f"### {map_}, {sim}, {preset} preset, {human} human"
                  + (f", {rule}" if rule else "") + ": success against ΔT", ""]
        at = {(c["method"], c["delta_t"]): c for c in group}
        methods = sorted({c["method"] for c in group}, key=_method_key)
        lines += _table(["method"] + [f"ΔT={d}" for d in dts],
                        [[METHOD_LABEL.get(m, m)] + [
                            rate(at[m, d]["success"], at[m, d]["n"]) if (m, d) in at else "–"
                            for d in dts] for m in methods])
        lines.append("")
    for setting in dict.fromkeys(c["setting"] for c in cells):
        group = [c for c in cells if c["setting"] == setting]
        n = sorted({c["n"] for c in group})
        failed = sum(c["failed"] for c in group)
        lines += [f"### {setting}", "", f"n = {'/'.join(map(str, n))} episodes per method"
                  + (f", {failed} failed (counted as failures)" if failed else "") + ".", ""]
        lines += _table(
            ["method", "n", "success [95% CI]", "homotopy-level success [95% CI]",
             "goal reached", "pushes/episode",
             "failed: time-out / wrong side / out-of-order (+ not run)"],
            [[METHOD_LABEL.get(c["method"], c["method"]), str(c["n"]),
              rate(c["success"], c["n"]), rate(c["homotopy"], c["homotopy_n"]),
              f"{c['goal_reached']}/{c['n']}", _num(c["pushes_per_episode"]),
              why_cell(c.get("why_failed"))] for c in group])
        lines.append("")
    return lines


def why_cell(why: dict[str, int] | None) -> str:
    """A cell's failures by kind (:mod:`pathpref.experiments.outcomes`): ``t / w / o`` and the
    rows not run or unclassified when there are any; ``–`` for cells stored before the split
    (a database kept as its cells JSON)."""
    if why is None:
        return "–"
    text = f"{why['time_out']} / {why['wrong_side']} / {why['out_of_order']}"
    extra = [f"{why[k]} {FAILURE_LABEL[k]}" for k in ("not_run", "unclassified") if why[k]]
    return text + (f" (+ {', '.join(extra)})" if extra else "")


def _rel(path: Path) -> str:
    try:
        return str(path.resolve().relative_to(ROOT))
    except ValueError:
        return str(path)


def physics_section(data: dict[str, Any]) -> tuple[str, list[str]]:
    """Command and table of a ``scripts/physics_study.py`` JSON."""
    a = data["args"]
    command = _STUDY.format(**{**a, "conditions": " ".join(a["conditions"])})
    rows = []
    for name, c in data["conditions"].items():
        rows.append([name, str(c["n"]), _ci(c["success"], c["success_ci"]),
                     _ci(c["cue_accuracy"], c["cue_accuracy_ci"]),
                     _num(c["pushes_per_episode"]),
                     f"{_num(c['pushes_missed'], 0)} / {_num(c['pushes_misread'], 0)}",
                     _num(c["cue_latency_ms"], 0), _num(c["p_true_goal_mean"]),
                     str(c.get("same_as_control", "–"))])
    return command, _table(["condition", "n", "success [95% CI]", "cue accuracy [95% CI]",
                            "pushes/episode", "missed / misread pushes", "cue latency (ms)",
                            "mean P(true goal)", "same path as the first condition"], rows)


def pushes_section(data: dict[str, Any]) -> list[str]:
    """The table behind a success-against-pushes figure (``scripts/pushes_figure.py``), with
    all pushes over the successes where the file has them."""
    rows = [[panel, METHOD_LABEL.get(p["method"], p["method"]), p["setting"], str(p["n"]),
             _num(p["pushes"]), _num(p.get("pushes_for_one_success"), 1),
             _ci(p["success"], p["ci"]), _ci(p["homotopy"], p["homotopy_ci"])]
            for panel, points in data["panels"].items() for p in points]
    return [data["title"] + ".", ""] + _table(
        ["map", "method", "human", "n", "pushes/episode", "pushes/success",
         "success [95% CI]", "homotopy-level success [95% CI]"], rows)


def budget_section(data: list[dict[str, Any]]) -> list[str]:
    """The table behind docs/budget.png."""
    return _table(["map", "budget (ms)", "method", "n", "success [95% CI]",
                   "queries at the first decision"],
                  [[p["map"], str(p["budget_ms"]), METHOD_LABEL.get(p["method"], p["method"]),
                    str(p["n"]), _ci(p["success"], p["ci"]), _num(p["queries"], 0)]
                   for p in data])


def gamma_section(data: dict[str, Any]) -> list[str]:
    """The table of scripts/gamma_sweep.py."""
    head = (f"Maps {', '.join(data['maps'])}; {data['instances']} instances x {data['runs']} "
            "runs per map.")
    return [head, ""] + _table(
        ["human gamma", "ΔT", "rationality", "n", "success [95% CI]",
         "homotopy-level success [95% CI]"],
        [[str(c["gamma_h"]), str(c["delta_t"]), c["belief"], str(c["n"]),
          _ci(c["success"], c["success_ci"]), _ci(c["homotopy"], c["homotopy_ci"])]
         for c in data["cells"]])


def json_section(path: Path, title: str, kind: str, command: str) -> list[str]:
    """The Markdown section of one result JSON."""
    data = json.loads(path.read_text())
    if kind == "physics":
        command, body = physics_section(data)
        n = sum(c["n"] for c in data["conditions"].values())
    elif kind == "pushes":
        body = pushes_section(data)
        n = sum(p["n"] for pts in data["panels"].values() for p in pts)
    elif kind == "budget":
        body, n = budget_section(data), sum(p["n"] for p in data)
    elif kind == "gamma":
        body, n = gamma_section(data), sum(c["n"] for c in data["cells"])
    else:
        raise ValueError(f"unknown result kind {kind!r} for {path}; use physics, pushes, "
                         "budget or gamma")
    return ([f"## {title}", "", f"Source `{_rel(path)}`, {n} episodes in all, dated "
             f"{file_date(path)}; command:", "", "```", command, "```", ""] + body + [""])


def build(dbs: list[tuple[Path, str, str]], jsons: list[tuple[Path, str, str, str]],
          cells_dir: Path | None = None) -> str:
    """The whole page; with ``cells_dir``, each database's cells also go to
    ``cells_dir/<db stem>.json``."""
    lines = ["# Results", "",
             "Generated by `python scripts/results.py` from the stored databases and result "
             "files; do not edit by hand. Success is strict (the goal reached by the human's "
             "preferred route), homotopy-level success counts any route in the preferred "
             "homotopy class; intervals are 95% Wilson intervals unless a table says "
             "otherwise.", ""]
    for path, title, command in dbs:
        stored = cells_file(path)
        if path.exists():
            cells, date, source = db_cells(path), file_date(path), f"`{_rel(path)}`"
        elif stored.exists():
            data = json.loads(stored.read_text())
            cells, date = data["cells"], file_date(stored)
            source = (f"`{_rel(stored)}` (the cells of `{data['source']}`; the database is not "
                      "in the repository)")
        else:
            print(f"results: {path} not found; its section is left out", file=sys.stderr)
            continue
        presets = sorted({c["preset"] for c in cells})
        command = command.replace("{preset}", " ".join(presets))  # the preset that made it
        lines += db_section(cells, source, date, title, command)
        if cells_dir is not None:
            if path.exists():
                head: dict[str, Any] = {"command": command, "source": _rel(path)}
                if len(presets) == 1:
                    head["preset"] = presets[0]
                head["episodes"] = sum(c["n"] for c in cells)
                out = stored if _rel(path) in CELLS_HOME else cells_dir / f"{path.stem}.json"
                out.write_text(json.dumps({**head, "cells": cells}, indent=1) + "\n")
            success_pushes_figure(cells, cells_dir / f"{path.stem}.png")
            lines += [f"![success against pushes]({cells_dir.name}/{path.stem}.png)", ""]
    for path, title, kind, command in jsons:
        if path.exists():
            lines += json_section(path, title, kind, command)
    return "\n".join(lines).rstrip() + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default=str(ROOT / "docs" / "results.md"))
    ap.add_argument("--db", action="append", default=[],
                    help="another sweep database to add (repeatable)")
    ap.add_argument("--db-command", action="append", default=[],
                    help="the command that wrote each --db, in order")
    ap.add_argument("--only-given", action="store_true",
                    help="only the --db files, not the stored sources")
    a = ap.parse_args(argv)
    if len(a.db_command) != len(a.db):
        print("results: --db-command must be given once per --db (the command that wrote it)",
              file=sys.stderr)
        return 2
    dbs = [] if a.only_given else [(ROOT / p, t, c) for p, t, c in DB_SOURCES]
    dbs += [(Path(p), f"Sweep {Path(p).name}", c) for p, c in zip(a.db, a.db_command, strict=True)]
    jsons = [] if a.only_given else [(ROOT / p, t, k, c) for p, t, k, c in JSON_SOURCES]
    out = Path(a.out)
    out.write_text(build(dbs, jsons, cells_dir=None if a.only_given else ROOT / "docs" / "results"))
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
