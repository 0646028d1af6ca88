"""The figures of the README and docs/ against what produces them: each check formats the text a
page must contain from its source (a command's live output, the stored sweep the demo ships,
the planner's preset registry, docs/benchmarks.md's current measurement, or the JSON
``scripts/doc_figures.py`` writes by running a command too slow for a test), so a change of
default, preset or speed that moves a figure fails here until the page says the new one.

Adding a checked figure is one line in :data:`CHECKS`: the page and a function giving the text
(whitespace is compared collapsed, so line breaks in the page do not matter)."""

from __future__ import annotations

import json
import re
import sys
from collections.abc import Callable
from functools import cache
from pathlib import Path

import pytest

from pathpref.apps.demo import load_sweep, sweep_cell, sweep_preset
from pathpref.planning.pomdp import DEFAULT_PRESET, PRESETS

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))
import errors_doc  # noqa: E402

#: written by scripts/doc_figures.py (each figure with its command and commit)
STORED = ROOT / "docs" / "results" / "doc_figures.json"


def stored(name: str) -> float:
    """A figure ``scripts/doc_figures.py`` measured by running its command."""
    return json.loads(STORED.read_text())[name]["value"]


@cache
def _sweep() -> dict:
    return load_sweep()


def frac(method: str, what: str = "success") -> str:
    """``k/n`` of ``method`` in the demo's setting of the stored sweep (shipped, package data)."""
    c = sweep_cell(_sweep(), method)
    return f"{c[what]}/{c['n']}"


def rate(method: str) -> str:
    """``k/n [lo, hi]``: strict success with its 95% Wilson interval, as the demo prints it."""
    lo, hi = sweep_cell(_sweep(), method)["success_ci"]
    return f"{frac(method)} [{lo:.2f}, {hi:.2f}]"


def bench(key: str) -> str:
    """The first figure (a number or a range) of ``key``'s row of docs/benchmarks.md's tables:
    its current measurement."""
    for line in (ROOT / "docs" / "benchmarks.md").read_text().splitlines():
        cells = [c.strip() for c in line.split("|")]
        if len(cells) > 3 and cells[1].startswith(f"`{key}`"):
            found = re.search(r"\d+(?:\.\d+)?(?:\s*[–-]\s*\d+(?:\.\d+)?)?", cells[3])
            assert found, line
            return found[0]
    raise AssertionError(f"docs/benchmarks.md has no row of {key}")


def ppo(key: str) -> str:
    """``k/n`` successes of the stored PPO runs (docs/results/ppo_v1_seed*.json, both seeds
    pooled) on the evaluation set ``key``, or ``steps`` (their step budget, the same in each)."""
    runs = [json.loads(p.read_text()) for p in
            sorted((ROOT / "docs" / "results").glob("ppo_v1_seed*.json"))]
    assert len(runs) >= 2, "docs/results holds the PPO runs of two seeds"
    if key == "steps":
        assert len({r["steps"] for r in runs}) == 1
        return str(runs[0]["steps"])
    return f"{sum(r['eval'][key]['successes'] for r in runs)}/" \
        f"{sum(r['eval'][key]['n'] for r in runs)}"


def demo_episodes() -> int:
    return _sweep()["episodes"]


#: (page, the text it must contain); one line per checked figure
CHECKS: list[tuple[str, Callable[[], str]]] = [
    ("docs/errors.md", errors_doc.block),
    ("README.md", lambda: f"`sh scripts/demo_sweep.sh`, {demo_episodes()} grid episodes, 30 per "
     f"point, preset `{sweep_preset(_sweep())}`"),
    ("README.md", lambda: f"path preference on `simple` succeeds in {rate('path_preference')} "
     f"against goal only's {frac('goal_only')} and compliant's {frac('compliant')}, next to "
     f"the oracle's {frac('oracle')}"),
    ("README.md", lambda: f"goal only goes the same way round the table in "
     f"{frac('goal_only', 'homotopy')}"),
    ("README.md", lambda: f"(Javdani et al., IJRR 2018), succeeds in {frac('hindsight')} there"),
    ("README.md", lambda: f"`{DEFAULT_PRESET}` (the default:"),
    ("README.md", lambda: f"The default preset, `{DEFAULT_PRESET}`,"),
    ("docs/robust.md", lambda: f"`{DEFAULT_PRESET}`, the default outside reproduction"),
    ("README.md", lambda: f"The `carry` episode (the Jaco) costs "
     f"{bench('arm.carry_episode_vs_bare')} times"),
    ("README.md", lambda: f"`navigate_control` {bench('physics.overhead_vs_bare_mujoco_control')}"
     " times bare stepping"),
    ("README.md", lambda: f"A physical episode costs {bench('physics.overhead_vs_bare_mujoco')} "
     "times bare MuJoCo stepping"),
    ("docs/study.md", lambda: f"the 2-trial demo: {stored('study_demo_simulated_s'):.1f} "
     "simulated seconds"),
    *(("README.md", lambda p=p: f"`{p}`") for p in sorted(PRESETS) if p != "original"),
    ("README.md", lambda: f"{ppo('steps')} decisions per seed"),
    ("README.md", lambda: f"held-out instances of the training plans {ppo('held_out_plans')}"),
    ("README.md", lambda: f"`office`, never seen, {ppo('office')}"),
]


def _collapsed(text: str) -> str:
    return " ".join(text.split())


@pytest.mark.parametrize("page,text", CHECKS, ids=[f"{p}:{k}" for k, (p, _) in
                                                   enumerate(CHECKS)])
def test_the_page_says_what_its_source_gives(page, text):
    wanted = _collapsed(text())
    assert wanted in _collapsed((ROOT / page).read_text()), f"{page} should say: {wanted}"


def test_no_page_calls_another_preset_the_default():
    """Only the planner's default is called "the default" (a heading "(`--preset X`, the
    default)" or "`X`, the default"), in the README and every page of docs/."""
    said = []
    for page in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        for name in re.findall(r"`(?:--preset )?([a-z][a-z-]*)`,? (?:is )?the default\b"
                               r"(?! before| until)", page.read_text()):
            if name in PRESETS and name != DEFAULT_PRESET:
                said.append(f"{page.relative_to(ROOT)}: {name}")
    assert not said, said


def test_the_stored_figures_name_their_commands():
    """Each stored figure carries the command that measured it and the commit it ran at."""
    data = json.loads(STORED.read_text())
    for name, f in data.items():
        assert f["command"].startswith("pathpref ") and f["commit"], name


def test_no_page_points_at_an_issue_its_reader_cannot_see():
    """The docs say what a target or a question was, not "the issue's" (a tracker the reader of
    the page does not have)."""
    said = [f"{p.relative_to(ROOT)}:{k}" for p in [ROOT / "README.md",
                                                   *sorted((ROOT / "docs").glob("*.md"))]
            for k, line in enumerate(p.read_text().splitlines(), 1)
            if re.search(r"\bthe issue\b", line, flags=re.I)]
    assert not said, said
