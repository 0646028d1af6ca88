"""Draw the house (docs/architecture.png) from the package's own imports.

    python scripts/draw_architecture.py [docs/architecture.png]

Every module of ``pathpref/`` and ``tasks/`` (installed as ``pathpref_tasks``) is read with
``ast``; an ``import`` or ``from ... import`` of another room is an arrow from the importing
room to the imported one. The rooms stand in rows by their layer (:data:`RANK`, the rule of
docs/architecture.md: a room imports only its own layer or lower ones), each box showing the
room's module count; an arrow's width grows with the number of importing modules, and an
arrow that points up (or joins ``sim`` and ``viz``) is drawn red. ``tests/test_architecture.py``
checks the same graph with :func:`modules` and :func:`imports`.
"""

from __future__ import annotations

import argparse
import ast
import math
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: layer rank of each room; a module may import ranks <= its own (sim and viz: not each other)
RANK = {"errors": 0, "switches": 0, "geometry": 1, "maps": 1, "mjcf": 1, "inference": 2,
        "planning": 3, "episode": 4, "experiments": 5, "sim": 6, "viz": 6, "tasks": 7,
        "study": 7, "apps": 8, "ros": 8}


def room_of(module: str) -> str | None:
    """The room of a dotted module name (None: not the package's)."""
    parts = module.split(".")
    if parts[0] == "pathpref_tasks":
        return "tasks"
    if parts[0] != "pathpref" or len(parts) < 2:
        return None
    return parts[1]


def modules(root: Path = ROOT):
    """``(dotted name, path, is a package's __init__)`` of every module under ``root``."""
    for path in sorted((root / "pathpref").rglob("*.py")):
        rel = path.relative_to(root).with_suffix("")
        name = ".".join(rel.parts[:-1] if rel.name == "__init__" else rel.parts)
        yield name, path, path.name == "__init__.py"
    for path in sorted((root / "tasks").glob("*.py")):
        yield f"pathpref_tasks.{path.stem}".removesuffix(".__init__"), path, False


def imports(name: str, path: Path, is_pkg: bool):
    """The dotted names module ``name`` (at ``path``) imports, relative imports resolved."""
    tree = ast.parse(path.read_text())
    package = name if is_pkg else name.rsplit(".", 1)[0]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                yield a.name
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
                if node.module is None:
                    for a in node.names:
                        yield f"{mod}.{a.name}"
                    continue
                yield mod
            else:
                yield node.module


def room_graph(root: Path = ROOT) -> tuple[Counter, Counter]:
    """``(modules per room, importing modules per (room, imported room))`` of the rooms in
    :data:`RANK` (imports within a room are not arrows)."""
    sizes, edges = Counter(), Counter()
    for name, path, is_pkg in modules(root):
        room = room_of(name)
        if room not in RANK:
            continue
        sizes[room] += 1
        for target in {room_of(i) for i in imports(name, path, is_pkg)}:
            if target in RANK and target != room:
                edges[room, target] += 1
    return sizes, edges


def wrong_way(room: str, target: str) -> bool:
    """Whether an arrow breaks the rule: up a layer, or between ``sim`` and ``viz``."""
    return RANK[target] > RANK[room] or {room, target} == {"sim", "viz"}


def draw(out: Path, root: Path = ROOT) -> tuple[Counter, Counter]:
    """Draw the room graph of ``root`` to ``out`` (PNG); the graph drawn."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import FancyBboxPatch

    sizes, edges = room_graph(root)
    rows: dict[int, list[str]] = {}
    for room in sorted(sizes, key=lambda r: (RANK[r], r)):
        rows.setdefault(RANK[room], []).append(room)
    ranks = sorted(rows)
    w, h = 1.6, 0.55
    pos = {}
    for y, rank in enumerate(ranks):
        row = rows[rank]
        for i, room in enumerate(row):
            pos[room] = ((i - (len(row) - 1) / 2) * 2.4, 1.6 * y)
    fig, ax = plt.subplots(figsize=(10, 1.1 * len(ranks) + 1))
    for (room, target), n in sorted(edges.items()):
        (x0, y0), (x1, y1) = pos[room], pos[target]
        bad = wrong_way(room, target)
        ax.annotate("", xy=(x1, y1 + (h / 2 if y1 < y0 else -h / 2)),
                    xytext=(x0, y0 - (h / 2 if y1 < y0 else -h / 2)),
                    arrowprops={"arrowstyle": "-|>", "color": "#c0392b" if bad else "#7f8c8d",
                                "lw": 0.6 + 0.8 * math.log1p(n), "alpha": 0.9 if bad else 0.45,
                                "shrinkA": 2, "shrinkB": 2,
                                "connectionstyle": "arc3,rad=0.08"})
    for room, (x, y) in pos.items():
        ax.add_patch(FancyBboxPatch((x - w / 2, y - h / 2), w, h,
                                    boxstyle="round,pad=0.04", fc="#eaf2f8", ec="#2e4053"))
        ax.text(x, y + 0.07, f"{room}/", ha="center", va="center", fontsize=11,
                fontweight="bold")
        n = sizes[room]
        ax.text(x, y - 0.14, f"{n} module{'s' if n > 1 else ''}", ha="center", va="center",
                fontsize=8)
    for y, rank in enumerate(ranks):
        ax.text(-6.3, 1.6 * y, f"layer {rank}", ha="left", va="center", fontsize=9,
                color="#566573")
    n_bad = sum(n for (r, t), n in edges.items() if wrong_way(r, t))
    ax.set_title(f"pathpref's rooms by layer, arrows = imports ({len(edges)} room pairs, "
                 f"{n_bad} pointing the wrong way)", fontsize=11)
    ax.set_xlim(-6.5, 6.5)
    ax.set_ylim(-0.8, 1.6 * (len(ranks) - 1) + 0.8)
    ax.axis("off")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return sizes, edges


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("out", nargs="?", default=str(ROOT / "docs" / "architecture.png"),
                   help="the PNG to write (default: docs/architecture.png)")
    a = p.parse_args(argv)
    sizes, edges = draw(Path(a.out))
    print(f"wrote {a.out}: {len(sizes)} rooms, {sum(sizes.values())} modules, "
          f"{len(edges)} room-to-room arrows")


if __name__ == "__main__":
    main()
