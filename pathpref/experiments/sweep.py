"""Sweeps: the grid of (method, Delta_T, instance, run) episodes, run in parallel, resumable.

Seeds follow common random numbers: instance ``i`` is drawn from ``seed_for(seed, i)`` and run
``r`` of it uses ``seed_for(seed, i, r)``, the same for every method and Delta_T, so methods are
compared on identical instances and human random streams. The coordinator alone writes the
store, as results arrive; a rerun with the same database runs only the missing episodes.
"""

from __future__ import annotations

import json
import multiprocessing as mp
import sys
import time
import traceback
from collections.abc import Iterator
from dataclasses import replace

from tqdm import tqdm

from ..errors import ConfigError, PathprefError
from ..planning.policies import resolve_methods
from .episode import EpisodeResult, EpisodeSpec, cached_world, episode_instance, run_episode
from .instances import Instance, seed_for
from .store import ResultStore


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
                    s = EpisodeSpec(map=map_name, method=m, delta_t=int(dt), instance=i, run=r,
                                    instance_seed=seed_for(seed, i), run_seed=seed_for(seed, i, r),
                                    **common)
                    s.validate()
                    specs.append(s)
    return specs


def check_specs(specs: list[EpisodeSpec]) -> None:
    """Fail fast (before any work) on a bad map, preference or instance in the sweep."""
    seen: set[tuple] = set()
    for s in specs:
        sig = (s.map, s.instance_seed, s.n_goals, s.fixed)
        if sig in seen:
            continue
        seen.add(sig)
        world = cached_world(s.map)
        world.require_preference()
        episode_instance(world, s)


def safe_run(spec: EpisodeSpec) -> EpisodeResult:
    """Run an episode; an error becomes a failed episode with its reason."""
    try:
        return run_episode(spec)
    except Exception as e:  # noqa: BLE001 - recorded, the sweep goes on
        res = EpisodeResult(spec=spec, instance=Instance(-1, (), -1), status="failed",
                            reason=f"{type(e).__name__}: {e}")
        if not isinstance(e, PathprefError):
            res.reason += " | " + traceback.format_exc(limit=3).replace("\n", " ")[-500:]
        return res


def iter_local(specs: list[EpisodeSpec], workers: int) -> Iterator[EpisodeResult]:
    """Results in completion order from a process pool (in-process when ``workers == 1``)."""
    if workers <= 1:
        for s in specs:
            yield safe_run(s)
        return
    ctx = mp.get_context("fork" if sys.platform.startswith("linux") else "spawn")
    with ctx.Pool(workers) as pool:
        yield from pool.imap_unordered(safe_run, specs, chunksize=1)


def run_sweep(specs: list[EpisodeSpec], db: str, workers: int = 1, progress: bool = True,
              retry_failed: bool = False, backend: str = "local") -> dict[str, int]:
    """Run the episodes of ``specs`` missing from ``db``; returns counts."""
    if workers < 1:
        raise ConfigError(f"--workers must be at least 1, got {workers}")
    if backend != "local":
        raise ConfigError(f"unknown backend '{backend}'; this version supports 'local'")
    check_specs(specs)
    with ResultStore(db) as store:
        done = store.done_keys(include_failed=not retry_failed)
        todo = [s for s in specs if s.key() not in done]
        counts = {"total": len(specs), "skipped": len(specs) - len(todo), "ran": 0, "failed": 0}
        bar = tqdm(total=len(todo), disable=not progress, unit="ep", dynamic_ncols=True,
                   desc="episodes", file=sys.stderr)
        t0 = time.perf_counter()
        for res in iter_local(todo, workers):
            store.add(res)
            counts["ran"] += 1
            counts["failed"] += res.status != "ok"
            bar.update(1)
        bar.close()
        counts["seconds"] = round(time.perf_counter() - t0, 1)
    return counts


def fixed_specs(map_name: str, methods: list[str], delta_t: int, runs: int, fixed: dict,
                seed: int = 0, **common) -> list[EpisodeSpec]:
    """Episodes on one pinned instance (e.g. the paper's Fig. 4), ``runs`` runs per method."""
    base = sweep_specs(map_name, methods, [delta_t], 1, runs, seed, **common)
    return [replace(s, fixed=json.dumps(fixed, sort_keys=True)) for s in base]
