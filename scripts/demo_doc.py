"""Write the numbers of docs/demo.md (the block between its ``demo-numbers`` markers): the stored
sweep's verdicts, the demo's grid rates under the planner's default preset, the filmed
setting's success rate with its 95% Wilson interval, how often the filmed pair differs and
the filmed MuJoCo pair (run without video). About 1 minute on 2 cores.

    MUJOCO_GL=egl python scripts/demo_doc.py                 # rewrites docs/demo.md's block
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

from pathpref.apps.demo import DOC_BEGIN, DOC_END, doc_block, grid_rates  # noqa: E402
from pathpref.planning.pomdp import DEFAULT_PRESET  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    """Compute the block and put it in place of the old one."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--doc", default=str(ROOT / "docs" / "demo.md"), help="the page to update")
    args = ap.parse_args()
    import pathpref.sim  # noqa: F401  (registers the MuJoCo body)

    rates = grid_rates(preset=DEFAULT_PRESET)
    k, film, tried = rates.film("mujoco")
    doc = Path(args.doc)
    text = doc.read_text()
    head, rest = text.split(DOC_BEGIN, 1)
    _, tail = rest.split(DOC_END, 1)
    doc.write_text(head + "\n".join(doc_block(rates, k, film, tried)) + tail)
    print(f"wrote the numbers of {doc} (preset {DEFAULT_PRESET})")


if __name__ == "__main__":
    main()
