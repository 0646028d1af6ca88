"""docs/demo.md's statements against what they state: the block of numbers written by
``scripts/demo_doc.py`` agrees with the stored sweep the wheel ships (same preset, same
verdicts, the demo's re-run counts equal to the sweep's cell because its episodes are the
sweep's), and the prose's "where it matters" is the sweep's verdict. No episode is run except
the five grid oracle episodes of the film rule."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

from pathpref.apps.demo import (
    DEMO_RUNS,
    DOC_BEGIN,
    DOC_END,
    FILM_METHOD,
    FILM_RULE,
    SWEEP_JSON,
    cell_rate_line,
    demo_specs,
    film_index,
    filmed_setting,
    load_sweep,
    sweep_cell,
    sweep_preset,
    sweep_statement,
)
from pathpref.episode import run_episode
from pathpref.experiments.report import wilson
from pathpref.planning.policies import METHODS
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
    assert sum(c["n"] for c in sweep["cells"]) == sweep["episodes"] == 1080


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
    want = [cell_rate_line(sweep_cell(sweep, m)) for m in METHODS]
    assert [ln for ln in block if ln.startswith("- ") and "runs (" in ln] == want
    preset = sweep_preset(sweep)
    cells = read_export(KEYS)
    for m in METHODS:
        keys = {s.key() for s in demo_specs(m, DEMO_RUNS, 0, preset)}
        cell = ("simple", m, "1", "corrective delay=1 miss=0.2", preset)
        assert cells[cell] == (len(keys), keys_digest(keys)), m


def test_the_filmed_setting_and_instance(block, sweep):
    cell = sweep_cell(sweep, FILM_METHOD)
    k, n = cell["success"], cell["n"]
    lo, hi = wilson(k, n)
    line = (f"The filmed setting ({filmed_setting(sweep_preset(sweep))}) succeeds in {k}/{n} "
            f"grid episodes, {k / n:.2f} [95% Wilson {lo:.2f}, {hi:.2f}].")
    assert line in block
    specs = [s for s in demo_specs("oracle") if s.run == 0]
    chosen = specs[film_index(specs, [run_episode(s) for s in specs])].instance
    film = next(ln for ln in block if ln.startswith("The filmed instance"))
    assert film.startswith(f"The filmed instance: instance {chosen}, run 0 ({FILM_RULE}).")
    table = [ln for ln in block if ln.startswith("| ") and not ln.startswith("| method")]
    assert [re.match(r"\| (\w+) \|", r).group(1) for r in table] == [
        "compliant", "goal_only", "path_preference", "blended"]


def test_the_readme_picture_and_tour_show_the_rules_episode():
    """The README's picture and the tour's ``render`` line are the episode of
    :func:`tour_seed` (the film rule on the route), and what the caption says of it holds:
    under the default preset it reaches the goal in 27 steps with 7 pushes after one crossing
    the person did not prefer (the grid episode; the MuJoCo base, whose moves reach the same
    cells, rendered the same: ``scripts/video_grid.py`` prints it)."""
    from pathpref.apps.demo import DEMO_PUSH_RULE, tour_seed, tour_spec

    seed = tour_seed()
    readme = " ".join((ROOT / "README.md").read_text().split())
    assert (f'pathpref render --map simple --method path_preference --delta-t 1 \\ '
            f'--push-rule "{DEMO_PUSH_RULE}" --seed {seed} \\') in readme
    assert f"seed {seed}, the first seed whose preferred route the demo's film rule accepts" \
        in readme
    r = run_episode(tour_spec(seed))
    assert (r.success, r.goal_reached, r.violations, r.steps, r.inputs) == (False, True, 1, 27, 7)
    assert "it reaches the goal in 27 steps with 7 pushes" in readme
