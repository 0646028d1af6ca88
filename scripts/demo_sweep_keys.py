"""The text export of the demo's sweep database that the repository keeps instead of the
database (``docs/results/demo_sweep_keys.tsv``): per cell (map, method, ΔT, push rule,
preset) the number of episodes and the SHA-256 of their keys, sorted and joined by newlines.
``tests/test_demo_doc.py`` checks from it that ``pathpref demo`` re-runs the sweep's own
episodes; ``scripts/demo_sweep.sh`` writes it after every sweep.

    python scripts/demo_sweep_keys.py DB [OUT]
"""

from __future__ import annotations

import hashlib
import sqlite3
import sys
from collections.abc import Iterable
from pathlib import Path

COLUMNS = ("map", "method", "delta_t", "push_rule", "preset")


def keys_digest(keys: Iterable[str]) -> str:
    """SHA-256 (hex) of ``keys`` sorted and joined by newlines."""
    return hashlib.sha256("\n".join(sorted(keys)).encode()).hexdigest()


def export(db: Path) -> str:
    """The TSV text of ``db``'s cells: a header, then one line per cell."""
    with sqlite3.connect(f"file:{db}?mode=ro", uri=True) as con:
        rows = con.execute(f"SELECT {', '.join(COLUMNS)}, key FROM episodes").fetchall()
    cells: dict[tuple, list[str]] = {}
    for *cell, key in rows:
        cells.setdefault(tuple(str(c) for c in cell), []).append(key)
    lines = ["\t".join((*COLUMNS, "n", "keys_sha256"))]
    for cell in sorted(cells):
        lines.append("\t".join((*cell, str(len(cells[cell])), keys_digest(cells[cell]))))
    return "\n".join(lines) + "\n"


def read_export(path: Path) -> dict[tuple[str, ...], tuple[int, str]]:
    """The cells of an export: ``(map, method, ΔT, push rule, preset) -> (n, digest)``."""
    lines = path.read_text().splitlines()
    out = {}
    for line in lines[1:]:
        *cell, n, digest = line.split("\t")
        out[tuple(cell)] = (int(n), digest)
    return out


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if not 1 <= len(args) <= 2:
        print(__doc__.strip().splitlines()[-1].strip(), file=sys.stderr)
        return 2
    db = Path(args[0])
    out = Path(args[1]) if len(args) == 2 else db.with_name(f"{db.stem}_keys.tsv")
    out.write_text(export(db))
    return 0


if __name__ == "__main__":
    sys.exit(main())
