"""Install a package the venv-less way for a test: its module and a dist-info whose
``entry_points.txt`` declares what it provides, on ``sys.path`` (``importlib.metadata`` finds
it as it finds an installed one)."""

from __future__ import annotations

import textwrap
from pathlib import Path


def install_package(root: Path, monkeypatch, module: str, source: str,
                    entry_points: str) -> Path:
    """Write ``module`` (its ``source``) and ``<module>-0.1.dist-info`` with
    ``entry_points`` (the text of ``entry_points.txt``) under ``root`` and put ``root`` on
    ``sys.path``; the dist-info folder."""
    (root / f"{module}.py").write_text(source)
    info = root / f"{module}-0.1.dist-info"
    info.mkdir()
    name = module.replace("_", "-")
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(textwrap.dedent(entry_points))
    monkeypatch.syspath_prepend(str(root))
    return info
