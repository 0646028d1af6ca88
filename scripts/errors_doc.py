"""Write the command-line refusals of docs/errors.md (the block between its ``errors`` markers)
by running each example command of :data:`EXAMPLES` through ``pathpref``'s own ``main`` and
keeping the one line it prints on stderr, so the page shows what the commands print now (the
preset list of ``--preset`` comes from the planner's registry, not from a hand-typed copy).
Seconds; nothing is written but the page (each example is refused before any work).

    python scripts/errors_doc.py            # rewrites docs/errors.md's block
"""

from __future__ import annotations

import argparse
import contextlib
import io
from pathlib import Path

from pathpref.apps.cli import main

ROOT = Path(__file__).resolve().parents[1]
BEGIN = "<!-- errors:begin (written by scripts/errors_doc.py) -->"
END = "<!-- errors:end -->"
#: the example commands (arguments after ``pathpref``); every one is refused at its first check
EXAMPLES: tuple[tuple[str, ...], ...] = (
    ("evaluate", "--run", "3"),
    ("map", "info", "ofice"),
    ("evaluate", "--preset", "robus"),
    ("study", "run", "examples/study_demo.json", "--participant", "p1", "--db", "study.sqlite",
     "--robot-model", "tidybot"),
)


def refusal(argv: tuple[str, ...]) -> str:
    """The one line ``pathpref ARGV`` prints on stderr when it refuses them (exit status 2)."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            code = main(list(argv))
        except SystemExit as e:
            code = e.code
    lines = err.getvalue().splitlines()
    if code != 2 or len(lines) != 1:
        raise RuntimeError(f"pathpref {' '.join(argv)}: exit {code}, stderr {lines!r}")
    return lines[0]


def block() -> str:
    """The page's block: a text code fence of the refusals, in :data:`EXAMPLES`' order."""
    return "\n".join([BEGIN, "```text", *(refusal(a) for a in EXAMPLES), "```", END])


def main_() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--doc", default=str(ROOT / "docs" / "errors.md"), help="the page to update")
    args = ap.parse_args()
    doc = Path(args.doc)
    text = doc.read_text()
    head, rest = text.split(BEGIN, 1)
    _, tail = rest.split(END, 1)
    doc.write_text(head + block() + tail)
    print(f"wrote {len(EXAMPLES)} refusals into {doc}")


if __name__ == "__main__":
    main_()
