"""docs/demo.md's statements against what they state: the block of numbers written by
``scripts/demo_doc.py`` agrees with the stored sweep the wheel ships (same preset, same
verdicts, the demo's re-run counts equal to the sweep's cell because its episodes are the
sweep's), the prose's "where it matters" is the sweep's verdict, the film pair is where the
method wins, and the README's picture is a strict success. The episodes run are grid episodes
(the 90 of the film rule's pair and oracle, and the README's tour episode)."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

from pathpref.apps.demo import (
    DEMO_METHODS,
    DEMO_RUNS,
    DOC_BEGIN,
    DOC_END,
    FILM_METHOD,
    FILM_RULE,
    SWEEP_JSON,
    cell_rate_line,
    demo_specs,
    filmed_setting,
    load_sweep,
    sweep_cell,
    sweep_preset,
    sweep_statement,
    worth_filming,
)
from pathpref.episode import run_episode
from pathpref.experiments.report import wilson
from pathpref.planning.pomdp import DEFAULT_PRESET

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
from demo_sweep_keys import keys_digest, read_export  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "demo.md"
#: the sweep database's text export (scripts/demo_sweep_keys.py; the database is not kept)
KEYS = ROOT / "docs" / "results" / "demo_sweep_keys.tsv"


@pytest.fixture(scope="module")
def block() -> list[str]:
    text = DOC.read_text()
    assert text.count(DOC_BEGIN) == 1 and text.count(DOC_END) == 1
    return text.split(DOC_BEGIN, 1)[1].split(DOC_END, 1)[0].strip().splitlines()


@pytest.fixture(scope="module")
def sweep() -> dict:
    data = load_sweep()
    assert data is not None, SWEEP_JSON
    return data


def test_the_block_names_the_sweeps_preset_and_command(block, sweep):
    preset = sweep_preset(sweep)
    assert block[0] == f"Preset `{preset}` (the planner's default when this was written; " \
        "`pathpref demo` computes every number below again when it runs, under its `--preset`)."
    assert sweep["command"] == f"sh scripts/demo_sweep.sh docs/results/demo_sweep.sqlite {preset}"
    assert {c["preset"] for c in sweep["cells"]} == {preset}
    assert sum(c["n"] for c in sweep["cells"]) == sweep["episodes"] == 1260  # 2 x 7 x 3 x 30


def test_the_stored_sweep_is_the_default_presets():
    """The demo re-runs under DEFAULT_PRESET: when the planner's default changes, re-make the
    sweep (sh scripts/demo_sweep.sh; python scripts/results.py) and the numbers (python
    scripts/demo_doc.py), or the demo's header and re-run disagree (it then says so)."""
    assert sweep_preset(load_sweep()) == DEFAULT_PRESET


def test_the_verdicts_are_the_sweeps(block):
    lines = sweep_statement()
    assert [ln for ln in block if ln.startswith("- ") and " -> " in ln] == lines
    matters = [ln for ln in lines if ln.endswith("MATTERS")]
    # the prose: it matters with the corrective human on simple, nowhere else
    assert len(matters) == 1 and matters[0].startswith(
        "- simple, grid, ") and "corrective delay=1 miss=0.2 (ΔT = 1)" in matters[0]
    assert "path preference reaches the goal by\nthe preferred route far more often" in \
        DOC.read_text()


def test_the_reruns_counts_are_the_sweeps_cell(block, sweep):
    """With the sweep's preset and 30 runs the demo's episodes are the sweep's: the same
    keys, so the same counts (the block's lines equal the cell's). The sweep's keys are read
    from the database's text export: per cell their number and digest."""
    want = [cell_rate_line(sweep_cell(sweep, m)) for m in DEMO_METHODS]
    assert [ln for ln in block if ln.startswith("- ") and "runs (" in ln] == want
    preset = sweep_preset(sweep)
    cells = read_export(KEYS)
    for m in DEMO_METHODS:
        keys = {s.key() for s in demo_specs(m, DEMO_RUNS, 0, preset)}
        cell = ("simple", m, "1", "corrective delay=1 miss=0.2", preset)
        assert cells[cell] == (len(keys), keys_digest(keys)), m


def test_the_filmed_setting_and_instance(block, sweep):
    """The block's filmed setting is the sweep's cell; its film pair is on an episode of the
    rule: one where, in the grid, path preference succeeds strictly and goal only does not (the
    rule's candidates, worked out here from the demo's grid episodes), and the block's MuJoCo
    pair shows the same: path preference a strict success, goal only not."""
    cell = sweep_cell(sweep, FILM_METHOD)
    k, n = cell["success"], cell["n"]
    lo, hi = wilson(k, n)
    line = (f"The filmed setting ({filmed_setting(sweep_preset(sweep))}) succeeds in {k}/{n} "
            f"grid episodes, {k / n:.2f} [95% Wilson {lo:.2f}, {hi:.2f}].")
    assert line in block
    specs = demo_specs("oracle")
    oracle = [run_episode(s) for s in specs]
    pp = [run_episode(s) for s in demo_specs("path_preference")]
    go = [run_episode(s) for s in demo_specs("goal_only")]
    alone = [i for i in range(len(specs)) if pp[i].success and not go[i].success]
    reverse = sum(go[i].success and not pp[i].success for i in range(len(specs)))
    assert (f"Path preference and goal only differ in {len(alone) + reverse}/{len(specs)} of "
            f"these episodes: path preference succeeds strictly and goal only does not in "
            f"{len(alone)}, the reverse in {reverse}.") in block
    assert alone, "the demo has no episode to film where the method wins"
    film = next(ln for ln in block if ln.startswith("The filmed episode"))
    got = re.match(r"The filmed episode: instance (\d+), run (\d+) \((.*); (\d+) filmed\)\.",
                   film)
    assert got and got[3] == FILM_RULE, film
    chosen = next(i for i in range(len(specs)) if (specs[i].instance, specs[i].run)
                  == (int(got[1]), int(got[2])))
    assert chosen in alone
    good = [i for i in alone if worth_filming(specs[i], oracle[i])]
    order = good + [i for i in alone if i not in good]
    assert chosen == order[int(got[4]) - 1]
    table = [ln for ln in block if ln.startswith("| ") and not ln.startswith("| method")]
    rows = {re.match(r"\| (\w+) \| (\w+) \|", r).group(1): r.split(" | ")[1] for r in table}
    assert rows == {"path_preference": "True", "goal_only": "False"}, table


def test_the_readme_picture_and_tour_show_a_strict_success():
    """The README's tour ``render`` line names a seed the picture's rule accepts
    (:func:`tour_ok`: a route the film rule accepts and a strict success in the grid, under the
    default preset; ``scripts/video_grid.py`` films it and writes the seed), and its caption
    says so in at most three lines."""
    from pathpref.apps.demo import DEMO_PUSH_RULE, tour_ok, tour_spec

    text = (ROOT / "README.md").read_text()
    readme = " ".join(text.split())
    got = re.search(r'pathpref render --map simple --method path_preference --delta-t 1 \\ '
                    rf'--push-rule "{DEMO_PUSH_RULE}" --seed (\d+) \\', readme)
    assert got, "the tour's render line"
    seed = int(got[1])
    assert tour_ok(seed)
    r = run_episode(tour_spec(seed))
    assert r.success and r.goal_reached and r.violations == 0
    caption = text.split("](docs/video_grid.png)", 1)[1].strip().split("\n\n", 1)[0]
    assert caption.startswith("*") and caption.endswith("*") and caption.count("\n") <= 2, \
        caption
