"""The README's promises: its Python example runs and prints what it says, every relative link
of the README and of the pages in docs/ names a file that exists, and it stays short."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def test_readme_python_example_runs_as_written(capsys):
    text = (ROOT / "README.md").read_text()
    block = text.split("```python", 1)[1].split("```", 1)[0]
    exec(block, {})
    out = capsys.readouterr().out.split("\n")
    marginal = np.array(out[0].strip("[] ").split(), dtype=float)
    said = re.search(r"P\(goal \| nudge\): \[([\d.]+) ([\d.]+)\]", block)
    assert np.allclose(marginal, [float(said[1]), float(said[2])], atol=0.006)
    assert out[1] in ("True", "False")


def test_every_relative_link_resolves():
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    missing = []
    for page in pages:
        for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", page.read_text()):
            if target.startswith(("http://", "https://", "mailto:")):
                continue
            if not (page.parent / target).exists():
                missing.append(f"{page.relative_to(ROOT)} -> {target}")
    assert not missing, missing


def test_the_readme_stays_a_five_minute_read():
    assert len((ROOT / "README.md").read_text().splitlines()) <= 220
