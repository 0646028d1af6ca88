"""``pathpref examples DEST``: copy the examples (``examples/``: the tutorial, the PPO
training example, the example maps and demo files) into a folder, from the installed wheel
(the data package ``pathpref.examples``) or, in a source checkout, from ``examples/``."""

from __future__ import annotations

import importlib.util
import shutil
from pathlib import Path

import pathpref

from ..errors import ConfigError

#: what is copied: the example files by suffix, in the top folder and ``maps/``
SUFFIXES = (".py", ".json")


def examples_root() -> Path:
    """The folder of the examples: the installed ``pathpref.examples``, else the source
    tree's ``examples/``."""
    spec = importlib.util.find_spec("pathpref.examples")
    if spec is not None and spec.submodule_search_locations:
        return Path(next(iter(spec.submodule_search_locations)))
    src = Path(pathpref.__file__).resolve().parents[1] / "examples"
    if not src.is_dir():
        raise ConfigError("no examples here: this pathpref is neither a wheel with "
                          "pathpref.examples nor a source checkout with examples/")
    return src


def example_files(root: Path) -> list[Path]:
    """The example files under ``root``, relative (``__init__.py`` and caches left out)."""
    return sorted(p.relative_to(root) for p in [*root.glob("*"), *root.glob("maps/*")]
                  if p.is_file() and p.suffix in SUFFIXES and p.name != "__init__.py")


def copy_examples(dest: str | Path) -> list[Path]:
    """Copy every example file into ``dest`` (made when missing); refuses, before copying
    anything, when one of them exists there already. The files written."""
    root, dest = examples_root(), Path(dest)
    files = example_files(root)
    if dest.exists() and not dest.is_dir():
        raise ConfigError(f"examples destination {str(dest)!r} is a file; give a folder")
    clash = next((f for f in files if (dest / f).exists()), None)
    if clash is not None:
        raise ConfigError(f"{str(dest / clash)!r} exists already; give a new or empty folder")
    out = []
    for f in files:
        (dest / f).parent.mkdir(parents=True, exist_ok=True)
        out.append(Path(shutil.copyfile(root / f, dest / f)))
    return out
