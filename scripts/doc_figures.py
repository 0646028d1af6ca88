"""Write docs/results/doc_figures.json: the figures of the README and docs/ that take a command
too long for a test to run, each measured by running that command here, with the command and
the commit. ``tests/test_doc_figures.py`` compares the pages' text with this file (and the
quick figures with their commands' live output), so a change of default or speed that moves a
figure fails a test until this script is run again and the page says the new number.

    MUJOCO_GL=egl PYTHONPATH=. python scripts/doc_figures.py      # minutes: runs the commands

Add a figure: one function in :data:`FIGURES` (name -> (command, how to read its output)),
then one line in tests/test_doc_figures.py's ``CHECKS``.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "results" / "doc_figures.json"


def _study_demo_simulated_s(out: str) -> float:
    """The scripted 2-trial demo's simulated time: the sum of its trials' ``in X s``."""
    times = [float(t) for t in re.findall(r"trial \d+/\d+ \(\w+\): \w+ in ([\d.]+) s", out)]
    if len(times) != 2:
        raise RuntimeError(f"expected 2 trials in the study demo's output, got {out!r}")
    return round(sum(times), 1)


#: name -> (the ``pathpref`` arguments, ``{db}`` a fresh database; how to read the figure from
#: the command's stdout)
FIGURES: dict[str, tuple[list[str], Callable[[str], float]]] = {
    "study_demo_simulated_s": (
        ["study", "run", "examples/study_demo.json", "--participant", "demo", "--db", "{db}",
         "--script", "examples/pushes_demo.json"], _study_demo_simulated_s),
}


def measure(name: str) -> dict:
    """Run figure ``name``'s command from the repository's root and read its figure."""
    argv, read = FIGURES[name]
    with tempfile.TemporaryDirectory() as tmp:
        args = [a.format(db=Path(tmp) / "figure.sqlite") for a in argv]
        env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl"),
               "PYTHONPATH": str(ROOT)}
        r = subprocess.run([sys.executable, "-m", "pathpref", *args], cwd=ROOT, env=env,
                           capture_output=True, text=True, timeout=3600, check=True)
    return {"value": read(r.stdout), "command": "pathpref " + " ".join(argv)}


def main() -> None:
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args()
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT,
                            capture_output=True, text=True).stdout.strip()
    figures = {name: {**measure(name), "commit": commit} for name in FIGURES}
    OUT.write_text(json.dumps(figures, indent=1, sort_keys=True) + "\n")
    for name, f in figures.items():
        print(f"{name} = {f['value']}  ({f['command']})")


if __name__ == "__main__":
    main()
