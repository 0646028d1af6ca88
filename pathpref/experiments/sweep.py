"""Sweeps: the grid of (method, Delta_T, instance, run) episodes, run in parallel, resumable.

Seeds follow common random numbers: instance ``i`` is drawn from ``seed_for(seed, i)`` and run
``r`` of it uses ``seed_for(seed, i, r)``, the same for every method and Delta_T, so methods are
compared on identical instances and human random streams. The coordinator alone writes the
store, as results arrive; a rerun with the same database runs only the missing episodes. Two
sweeps may run on one database at once: each claims an episode just before it runs
(:meth:`.store.ResultStore.claim`), so none is computed twice; the episodes the other sweep
finished or is running count as skipped (``counts["elsewhere"]``).

A sweep may be killed at any moment. Episodes are claimed a chunk at a time, and the results
that arrive together (:func:`.backends.iter_results`) are committed together, on arrival; SIGTERM
(like Ctrl-C) makes :func:`run_sweep` unwind, killing its worker processes (exit status 143
from the CLI); SIGKILL leaves nothing behind either (see :mod:`.backends`); the claims of a
killed sweep are stale, so the episodes it had not written run on resume.

A sweep too large for one coordinator is split into shards (:func:`shard_specs`), each run by
its own coordinator into its own database (one per node, say), and ``pathpref db merge``
joins the databases (:func:`.migrate.merge_databases`).
"""

from __future__ import annotations

import hashlib
import json
import os
import signal
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import closing, contextmanager
from dataclasses import replace

from tqdm import tqdm

from ..episode import EpisodeSpec, cached_world
from ..episode.body import check_runnable
from ..episode.instances import episode_instance
from ..errors import ConfigError
from ..planning.policies import resolve_methods
from ..switches import check_switches
from .backends import check_backend, failed, iter_results, max_workers, wall_limit
from .store import ResultStore, this_owner

#: a claim made on another host is stale after this many times the wall-time limits of its
#: chunk's episodes (run one after the other)
CLAIM_AGE = 4.0


def sweep_specs(map_name: str, methods: list[str], delta_ts: list[int], instances: int,
                runs: int, seed: int = 0, **common) -> list[EpisodeSpec]:
    """Every episode of a sweep, instance-major (so partial sweeps cover all methods)."""
    methods = resolve_methods(methods)
    if instances < 1 or runs < 1:
        raise ConfigError("--instances and --runs must be at least 1")
    if not delta_ts:
        raise ConfigError("--delta-t needs at least one value")
    specs = []
    for i in range(instances):
        for r in range(runs):
            for dt in delta_ts:
                for m in methods:
                    s = EpisodeSpec.single(map_name, m, dt, seed=seed, instance=i, run=r,
                                           **common)
                    s.validate()
                    specs.append(s)
    if specs:
        check_runnable(specs[0])  # the body exists and honours every option
    return specs


def parse_shard(text: str) -> tuple[int, int]:
    """``"I/N"`` (shard ``I`` of ``N``, 0 <= I < N) as ``(I, N)``; ConfigError otherwise."""
    index, sep, count = text.partition("/")
    if not (sep and index.isascii() and index.isdigit() and count.isascii()
            and count.isdigit() and len(text) <= 40 and int(index) < int(count)):
        shown = text if len(text) <= 40 else text[:37] + "..."
        raise ConfigError(f"--shard {shown!r}: write it as I/N with 0 <= I < N (e.g. 0/4)")
    return int(index), int(count)


def shard_specs(specs: list[EpisodeSpec], index: int, count: int) -> list[EpisodeSpec]:
    """The episodes of shard ``index`` of ``count``: those whose key's SHA-256, as an integer,
    is ``index`` modulo ``count``. The shards are disjoint and cover the sweep, and an
    episode's shard depends on its key alone (not on the order or the rest of the sweep)."""
    def shard(s: EpisodeSpec) -> int:
        return int.from_bytes(hashlib.sha256(s.key().encode()).digest()[:8], "big") % count

    return [s for s in specs if shard(s) == index]


def check_specs(specs: list[EpisodeSpec]) -> None:
    """Fail fast (before any work) on a bad body, map, preference or instance in the sweep,
    or a path to record (``record_path_hz``) that the body cannot."""
    seen: set[tuple] = set()
    runnable: set[tuple] = set()
    for s in specs:
        if (s.sim, s.robot, s.record_path_hz, s.physics) not in runnable:
            check_runnable(s)
            runnable.add((s.sim, s.robot, s.record_path_hz, s.physics))
        sig = (s.map, s.instance_seed, s.n_goals, s.fixed)
        if sig in seen:
            continue
        seen.add(sig)
        world = cached_world(s.map)
        world.require_preference()
        episode_instance(world, s.fixed, s.instance_seed, s.n_goals, s.human, s.t_max)


#: seconds a SIGTERM'd sweep has to unwind before it leaves with ``os._exit`` (see below)
TERM_GRACE_S = 5.0


@contextmanager
def _sigterm_exits() -> Iterator[None]:
    """While a sweep runs in the main thread, SIGTERM raises ``SystemExit(143)`` there, so the
    sweep unwinds (workers killed, store closed) instead of the process vanishing mid-step.

    Python swallows an exception raised where it cannot propagate (a fork hook, a finalizer):
    then the sweep raises it on leaving this block, or, if it has not left within
    ``TERM_GRACE_S``, the process ends with ``os._exit(143)`` (its workers die with it)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received: list[threading.Timer] = []

    def on_term(signum: int, frame) -> None:
        if not received:
            received.append(threading.Timer(TERM_GRACE_S, os._exit, (128 + signum,)))
            received[0].daemon = True
            received[0].start()
        raise SystemExit(128 + signum)

    old = signal.signal(signal.SIGTERM, on_term)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL if old is None else old)
        for timer in received:
            timer.cancel()
    if received:  # reached only if the SystemExit was swallowed
        raise SystemExit(128 + signal.SIGTERM)


def run_sweep(specs: list[EpisodeSpec], db: str, workers: int = 1, progress: bool = True,
              retry_failed: bool = False, backend: str = "local",
              address: str | None = None, steps: bool = True) -> dict[str, int]:
    """Run the episodes of ``specs`` missing from ``db`` (failed ones too when
    ``retry_failed``); results are written as they arrive, each batch in one transaction
    (without per-step rows when not ``steps``). Returns counts, with ``seconds`` and
    ``episodes_per_s`` (episodes run per second of wall time).

    ``workers`` (local processes, or a local Ray instance's CPUs) must be at most
    :func:`.backends.max_workers`; no more are started than there are episodes to run."""
    if workers < 1:
        raise ConfigError(f"--workers must be at least 1, got {workers}")
    if workers > max_workers() and (backend == "local" or address is None):
        raise ConfigError(f"--workers {workers} is too many for {os.cpu_count()} CPUs (at most "
                          f"{max_workers()}; one per CPU is fastest)")
    check_backend(backend, address)  # before the database is created or opened
    check_switches()  # the workers read them
    check_specs(specs)
    # a tampered row is refused before the file is opened for writing or any episode runs
    with _sigterm_exits(), ResultStore(db, check_rows=True, steps=steps) as store:
        done = store.done_keys(include_failed=not retry_failed)
        todo = [s for s in specs if s.key() not in done]
        counts = {"total": len(specs), "skipped": len(specs) - len(todo), "ran": 0, "failed": 0,
                  "elsewhere": 0, "busy": 0}
        bar = tqdm(total=len(todo), disable=not progress, unit="ep", dynamic_ncols=True,
                   desc="episodes", file=sys.stderr)
        owner = this_owner()

        def claim(chunk: list[EpisodeSpec]) -> list[EpisodeSpec]:
            """Claim the episodes of ``chunk`` before they are sent, in one transaction; those
            another sweep has finished since this one started, or is running, are left out
            (counted as skipped, and in ``elsewhere``; in ``busy`` too while unfinished)."""
            if not chunk:
                return []
            age = CLAIM_AGE * sum(wall_limit(s) for s in chunk)
            got = store.claim_many([failed(s, "") for s in chunk], retry_failed, age, owner)
            for answer in got:
                if answer != "claimed":
                    counts["skipped"] += 1
                    counts["elsewhere"] += 1
                    counts["busy"] += answer == "busy"
                    bar.update(1)
            return [s for s, answer in zip(chunk, got, strict=True) if answer == "claimed"]

        t0 = time.perf_counter()
        try:
            with closing(iter_results(todo, backend, workers, address, claim)) as results, \
                    bar:
                for batch in results:
                    store.add_many(batch)
                    counts["ran"] += len(batch)
                    counts["failed"] += sum(res.status != "ok" for res in batch)
                    bar.update(len(batch))
        finally:  # claims of episodes that did not finish (an error, Ctrl-C, SIGTERM)
            store.release_claims(owner)
        seconds = time.perf_counter() - t0
        counts["seconds"] = round(seconds, 1)
        counts["episodes_per_s"] = round(counts["ran"] / seconds, 2) if seconds > 0 else 0.0
    return counts


def fixed_specs(map_name: str, methods: list[str], delta_t: int, runs: int, fixed: str | dict,
                seed: int = 0, **common) -> list[EpisodeSpec]:
    """Episodes on one pinned instance (``EpisodeSpec.fixed``, as JSON or a dict; e.g. the
    paper's Fig. 4, :data:`~pathpref.episode.FIG4`), ``runs`` runs per method."""
    if isinstance(fixed, dict):
        fixed = json.dumps(fixed, sort_keys=True)
    base = sweep_specs(map_name, methods, [delta_t], 1, runs, seed, **common)
    return [replace(s, fixed=fixed) for s in base]
