"""Checks the command line runs before any work: numbers in range at parse time, outputs that
can be written, maps small enough to build, tables small enough to allocate.

Every refusal is a :class:`~pathpref.errors.ConfigError` or
:class:`~pathpref.errors.MapError` (or, at parse time, an argparse error): one line, exit
status 2, and no file or folder created or touched. Outputs are written whole or not at all
(:func:`atomic_output`, :func:`staged_outputs`): a temporary file made exclusively with
:func:`tempfile.mkstemp` in the target folder, moved onto the target with :func:`os.replace`,
removed on any failure (a full disk included).
"""

from __future__ import annotations

import argparse
import os
import stat
import sys
import tempfile
import threading
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

from ..episode.spec import LIMITS, MAX_EPISODES, ZERO_OK, check_number, range_error
from ..errors import DISK_FULL, ConfigError, did_you_mean, is_disk_full  # noqa: F401
from ..experiments.store import new_file_mode

FIGURE_SUFFIXES = (".png", ".pdf", ".svg")


# --- numbers --------------------------------------------------------------------------------
class RangeAction(argparse.Action):
    """An option whose value(s) must be a number in ``limits`` (see
    :data:`pathpref.episode.spec.LIMITS`); refused at parse time with one line, e.g.
    ``--queries must be an integer in 1..10000000, got 18446744073709551616``."""

    def __init__(self, option_strings, dest, limits: str, **kwargs):
        """``limits``: the key of :data:`~pathpref.episode.spec.LIMITS` (lo, hi, integer)."""
        self.limits = limits
        super().__init__(option_strings, dest, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        """Convert and range-check each value, or fail the parse with one line."""
        lo, hi, integer = LIMITS[self.limits]
        zero_ok = self.limits in ZERO_OK
        items = values if isinstance(values, list) else [values]
        out = []
        for text in items:
            try:
                value = _parse(text, integer)
            except ValueError:
                shown = text if len(text) <= 40 else text[:37] + "..."
                parser.error(str(range_error(option_string, lo, hi, integer, repr(shown),
                                             zero_ok)))
            try:
                out.append(check_number(option_string, value, lo, hi, integer, zero_ok))
            except ConfigError as e:
                parser.error(str(e))
        setattr(namespace, self.dest, out if isinstance(values, list) else out[0])


def _parse(text: str, integer: bool) -> int | float:
    """``text`` as an int (no more than 40 characters: no int-string limit) or a float."""
    text = text.strip()
    if len(text) > 40:
        raise ValueError("too long")
    return int(text) if integer else float(text)


def check_episode_count(counts: Sequence[int], what: str) -> int:
    """The product of the sweep's sizes, or a ConfigError past :data:`MAX_EPISODES` (checked
    before any episode spec is built)."""
    total = 1
    for c in counts:
        total *= max(int(c), 0)
    if total > MAX_EPISODES:
        raise ConfigError(f"{what} = {total:,} episodes, above the limit of {MAX_EPISODES:,}; "
                          "run fewer instances, runs, methods or ΔT values")
    return total


# --- outputs --------------------------------------------------------------------------------
def _kind(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISFIFO(mode):
        return "a pipe"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def check_folder(parent: Path, out: Path) -> None:
    """``parent`` (the folder of ``out``) exists and is writable."""
    if not parent.is_dir():
        raise ConfigError(f"cannot write {out}: folder {parent} does not exist")
    if not os.access(parent, os.W_OK):
        raise ConfigError(f"cannot write {out}: folder {parent} is not writable")


def check_writable(out: str | Path, option: str = "output",
                   suffixes: Sequence[str] | None = None) -> Path:
    """Fail before any work unless ``out`` is a regular file or a new name, with an allowed
    suffix, in an existing writable folder."""
    text = os.fspath(out)
    if not text or text.endswith(os.sep):
        raise ConfigError(f"{option} {text!r}: give a file name, not a folder")
    out = Path(text)
    try:
        st = os.stat(out)  # follows a symlink: its target must be a regular file too
    except FileNotFoundError:
        st = None
    except OSError as e:
        raise ConfigError(f"cannot write {option} {out}: {e.strerror or e}") from None
    if st is not None and not stat.S_ISREG(st.st_mode):
        raise ConfigError(f"{option} {out} is {_kind(st.st_mode)}; give a file name (a "
                          "regular file is replaced, a new one created)")
    if suffixes is not None and out.suffix.lower() not in suffixes:
        allowed = ", ".join(suffixes)
        raise ConfigError(f"{option} {out}: unsupported file type {out.suffix or '(none)'!r}; "
                          f"use a file name ending in {allowed}")
    check_folder(out.parent if str(out.parent) else Path("."), out)
    return out


#: the command that makes a database, by what it holds (``check_database``'s ``made_by``)
SWEEP_MAKER = "run 'pathpref evaluate --db {db}' first"
STUDY_MAKER = ("record trials first with 'pathpref study run STUDY --participant ID --db {db}' "
               "(docs/study.md)")


def check_database(db: str | Path, option: str = "--db", must_exist: bool = False,
                   made_by: str = SWEEP_MAKER) -> Path:
    """A results database path: a regular file (or a new name when not ``must_exist``) in an
    existing writable folder (SQLite writes a journal beside it). A missing one names the
    command that makes it (``made_by``: :data:`SWEEP_MAKER` for sweeps,
    :data:`STUDY_MAKER` for study trials)."""
    db = Path(db)
    if must_exist and not db.exists():
        raise ConfigError(f"no results database at {db}; {made_by.format(db=db)}")
    return check_writable(db, option)


def check_methods(names: Sequence[str]) -> list[str]:
    """The methods of ``names`` (``all``, ``reference`` and ``baselines`` expanded,
    :func:`~pathpref.planning.policies.resolve_methods`); an unknown one is refused naming
    the closest known name."""
    from ..planning.policies import METHODS, resolve_methods

    try:
        return resolve_methods(list(names))
    except ConfigError as e:
        known = [*METHODS, "all", "reference", "baselines"]
        bad = next((n for n in names if n not in known), None)
        hint = did_you_mean(bad, known)
        if not hint:
            raise
        raise ConfigError(str(e).replace(f"'{bad}'", f"'{bad}'{hint}", 1)) from None


def check_output_folder(out: str | Path, option: str = "--out") -> Path:
    """An output folder: an existing writable folder, or a new name in one (created later)."""
    out = Path(out)
    if out.exists() or out.is_symlink():
        if not out.is_dir():
            raise ConfigError(f"{option} {out} exists and is not a folder; give a folder "
                              "(existing or new)")
        if not os.access(out, os.W_OK | os.X_OK):
            raise ConfigError(f"cannot write into {option} {out}: the folder is not writable")
        return out
    parent = out.parent if str(out.parent) else Path(".")
    check_folder(parent, out)
    return out


def write_error(out: Path | str, e: BaseException) -> ConfigError:
    """A one-line ConfigError for a failed write of ``out`` (nothing was left behind)."""
    if is_disk_full(e):
        return ConfigError(f"cannot write {out}: no space left on device; free some space and "
                           "run again (no partial file was kept)")
    reason = e.strerror if isinstance(e, OSError) and e.strerror else str(e)
    return ConfigError(f"cannot write {out}: {reason} (no partial file was kept)")


def _temp_beside(out: Path) -> Path:
    """An exclusive temporary file beside ``out``; ``mkstemp`` makes it 0600, so it gets the
    mode a file written directly would have (the user's umask) before it is moved on ``out``."""
    parent = out.parent if str(out.parent) else Path(".")
    fd, tmp = tempfile.mkstemp(dir=parent, prefix=f".{out.stem}.", suffix=out.suffix)
    os.fchmod(fd, new_file_mode())
    os.close(fd)
    return Path(tmp)


@contextmanager
def staged_outputs(outs: Sequence[str | Path | None]) -> Iterator[list[Path | None]]:
    """Temporary paths for ``outs`` (None stays None), made exclusively with ``mkstemp`` in each
    target's folder (never a predictable name); moved onto the targets when the block ends
    without error, removed otherwise. An OSError while writing becomes one ConfigError."""
    temps: list[Path | None] = []
    try:
        for out in outs:
            temps.append(_temp_beside(Path(out)) if out is not None else None)
        try:
            yield temps
        except OSError as e:
            raise write_error(next(o for o in outs if o is not None), e) from None
        mode = new_file_mode()
        for out, tmp in zip(outs, temps, strict=True):
            if tmp is not None:
                os.chmod(tmp, mode)  # a writer may have replaced the file
                os.replace(tmp, out)
    finally:
        for tmp in temps:
            if tmp is not None and os.path.lexists(tmp):
                os.unlink(tmp)


def atomic_output(out: str | Path, write: Callable[[Path], object]) -> Path:
    """Call ``write(tmp_path)`` and move the result onto ``out``; nothing is left on failure."""
    out = check_writable(out)
    with staged_outputs([out]) as (tmp,):
        write(tmp)
    return out


# --- maps and tables ------------------------------------------------------------------------
#: maps whose arrangement may have this many polytopes get a note when their build is slow
NOTE_POLYTOPES = 200
#: seconds a build runs before its note
NOTE_AFTER_S = 1.0


def load_world_checked(source: str, force: bool = False, progress: bool = True):
    """The cached world of ``source``, refused before building when its arrangement may be too
    large (:func:`~pathpref.geometry.arrangement.check_arrangement_size`, unless ``force``).

    A build that takes more than :data:`NOTE_AFTER_S` on a map that may have
    :data:`NOTE_POLYTOPES` polytopes or more says so on a terminal (stderr a TTY), on a line
    that is erased when the build ends: never a line of its own before an error that follows
    (a refusal is one line), nor in a log."""
    from ..episode import cached_map, cached_world
    from ..geometry.arrangement import check_arrangement_size

    spec = cached_map(source)
    lines, cells, bound = check_arrangement_size(spec, force)
    shown: list[bool] = []
    lock = threading.Lock()

    def note() -> None:
        with lock:
            if shown:
                return
            shown.append(True)
            print(f"pathpref: building map '{spec.name}' ({lines} lines, {cells:,} free cells, "
                  f"up to {bound:,} polytopes) ...", end="\r", file=sys.stderr, flush=True)

    tty = getattr(sys.stderr, "isatty", lambda: False)()
    timer = threading.Timer(NOTE_AFTER_S, note) if progress and tty and \
        bound >= NOTE_POLYTOPES else None
    if timer is not None:
        timer.daemon = True
        timer.start()
    try:
        return cached_world(source)
    finally:
        if timer is not None:
            timer.cancel()
            with lock:
                if shown:
                    print("\r\033[K", end="", file=sys.stderr, flush=True)
                shown.append(False)  # a late timer prints nothing


def check_goal_count(source: str, n_goals: int) -> None:
    """``--goals`` against the map's free cells (every candidate is a free cell other than the
    start), before the map is built: one error line, no progress note first."""
    from ..episode import cached_map
    from ..episode.instances import too_few_candidates
    from ..geometry.maps import free_cell_mask

    spec = cached_map(source)
    free = int(free_cell_mask(spec).sum())
    if int(n_goals) > free - 1:
        raise too_few_candidates(spec.name, int(n_goals), free)


def check_model_size_early(source: str, n_goals: int) -> None:
    """:func:`check_model_size` before the map is built, with its free cells and the fewest
    neighbour slots (1): a map too large for the tables is one line and no build."""
    from ..episode import cached_map
    from ..geometry.maps import free_cell_mask

    spec = cached_map(source)

    class _World:
        name = spec.name
        n_cells = int(free_cell_mask(spec).sum())

        class graph:  # noqa: N801 - the attribute World has
            max_degree = 1

    check_model_size(_World(), n_goals)


def check_model_size(world, n_goals: int) -> int:
    """Bytes the human model's likelihood tables need for ``n_goals`` candidates on ``world``
    (the formula of :meth:`pathpref.inference.human.ObservationModel.build`); a ConfigError
    before any work when above its ``MAX_TABLE_BYTES``."""
    from ..inference import human

    n, K = world.n_cells, max(world.graph.max_degree, 1)
    G = min(int(n_goals), n)
    need = 3 * n * 8 * G * (K + 1) * 8
    if need > human.MAX_TABLE_BYTES:
        raise ConfigError(
            f"map '{world.name}': likelihood tables for {n:,} cells x {G} goals x {K} neighbour "
            f"slots would need {need / 2**30:.1f} GiB, above the limit "
            f"{human.MAX_TABLE_BYTES / 2**30:.0f} GiB; use fewer goal candidates (--goals) or "
            "a smaller map")
    return need
