"""``pathpref examples DEST``: copy the examples (``examples/``: the tutorial, the PPO
training example, the example maps and demo files) into a folder, from the installed wheel
(the data package ``pathpref.examples``) or, in a source checkout, from ``examples/``."""

from __future__ import annotations

import errno
import importlib.util
import os
import shutil
import tempfile
from pathlib import Path

import pathpref

from ..errors import ConfigError
from .checks import new_file_mode

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
    anything, when one of them exists there already. The files written.

    Whole or nothing: each file is copied to a temporary name beside its target
    (``tempfile.mkstemp``) and renamed onto it; on any failure (a full disk) every file and
    folder this call made is removed and one line names the destination file that failed,
    so the same command can simply be run again."""
    root, dest = examples_root(), Path(dest)
    files = example_files(root)
    if dest.exists() and not dest.is_dir():
        raise ConfigError(f"examples destination {str(dest)!r} is a file; give a folder")
    clash = next((f for f in files if (dest / f).exists()), None)
    if clash is not None:
        raise ConfigError(f"{str(dest / clash)!r} exists already; give a new or empty folder")
    made: list[Path] = []  # folders this call created, outermost first
    out: list[Path] = []
    target = dest
    tmp: str | None = None
    try:
        for f in files:
            target = dest / f
            missing = [d for d in (target.parent, *target.parent.parents) if not d.exists()]
            for d in reversed(missing):
                d.mkdir()
                made.append(d)
            fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.")
            os.close(fd)
            shutil.copyfile(root / f, tmp)
            os.chmod(tmp, new_file_mode())
            os.replace(tmp, target)
            tmp = None
            out.append(target)
    except OSError as e:
        for path in [*out, *([Path(tmp)] if tmp else [])]:
            Path(path).unlink(missing_ok=True)
        for d in reversed(made):
            try:
                d.rmdir()
            except OSError:
                pass
        reason = ("no space left on device; free some space and run again"
                  if e.errno in (errno.ENOSPC, getattr(errno, "EDQUOT", errno.ENOSPC))
                  else (e.strerror or str(e)))
        raise ConfigError(f"cannot write {target}: {reason} (nothing was copied)") from None
    return out
