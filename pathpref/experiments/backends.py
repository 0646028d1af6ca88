"""Where episodes run: a local process pool, or a Ray cluster. Both yield results in
completion order to the coordinator, which alone writes the results store.

* ``local``: a :class:`concurrent.futures.ProcessPoolExecutor` with at most ``workers`` episodes
  in flight. If a worker process dies (SIGKILL, segfault) the pool breaks; the episodes that were
  in flight are queued again on a fresh pool. An episode in flight during ``max_crashes`` breaks
  is recorded as failed ("worker process died"), so one that kills its worker every time cannot
  stall the sweep.
* ``ray``: each episode is a Ray task (``max_retries`` re-runs a task whose worker died).
  ``address=None`` starts a local Ray instance; ``address="auto"`` or ``"ray://host:10001"``
  joins an existing cluster (see README, "Running on a Ray cluster").

An exception inside an episode (bad input, NaN, a timeout) is never lost: :func:`safe_run` turns
it into a failed episode with its reason, and the sweep goes on.
"""

from __future__ import annotations

import multiprocessing as mp
import sys
import traceback
from collections import Counter, deque
from collections.abc import Iterator
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool

from ..episode import EpisodeResult, EpisodeSpec, Instance, run_episode
from ..errors import ConfigError, PathprefError

BACKENDS = ("local", "ray")


def failed(spec: EpisodeSpec, reason: str) -> EpisodeResult:
    """The result of an episode that could not run (``status='failed'``, with its reason)."""
    return EpisodeResult(spec=spec, instance=Instance(-1, (), -1), status="failed",
                         reason=reason[:2000])


def safe_run(spec: EpisodeSpec) -> EpisodeResult:
    """Run an episode; any exception becomes a failed episode with its reason."""
    try:
        return run_episode(spec)
    except Exception as e:  # noqa: BLE001 - recorded, the sweep goes on
        reason = f"{type(e).__name__}: {e}"
        if not isinstance(e, PathprefError):
            reason += " | " + traceback.format_exc(limit=3).replace("\n", " ")[-500:]
        return failed(spec, reason)


def _pool(workers: int) -> ProcessPoolExecutor:
    ctx = mp.get_context("fork" if sys.platform.startswith("linux") else "spawn")
    return ProcessPoolExecutor(workers, mp_context=ctx)


def iter_local(specs: list[EpisodeSpec], workers: int, max_crashes: int = 3
               ) -> Iterator[EpisodeResult]:
    """Results from a process pool (in-process when ``workers == 1``); see module docstring."""
    if workers <= 1:
        for s in specs:
            yield safe_run(s)
        return
    queue = deque(specs)
    crashes: Counter[str] = Counter()
    while queue:
        with _pool(workers) as ex:
            futs = {}
            broken = False
            while (queue or futs) and not broken:
                while queue and len(futs) < workers:
                    s = queue.popleft()
                    futs[ex.submit(safe_run, s)] = s
                done, _ = wait(futs, return_when=FIRST_COMPLETED)
                for f in done:
                    s = futs.pop(f)
                    try:
                        yield f.result()
                    except BrokenProcessPool:
                        broken = True
                        futs[f] = s  # handled with the others below
            if broken:
                for s in futs.values():
                    crashes[s.key()] += 1
                    if crashes[s.key()] >= max_crashes:
                        yield failed(s, f"worker process died {max_crashes} times")
                    else:
                        queue.appendleft(s)


def iter_ray(specs: list[EpisodeSpec], address: str | None = None, num_cpus: int | None = None,
             max_retries: int = 3) -> Iterator[EpisodeResult]:
    """Results from Ray tasks, as they finish (see module docstring)."""
    try:
        import ray
    except ImportError:
        raise ConfigError(
            "--backend ray needs Ray: pip install 'pathpref[ray]' (or pip install ray)"
        ) from None
    started = False
    if not ray.is_initialized():
        kwargs = {"address": address, "include_dashboard": False, "log_to_driver": False,
                  "configure_logging": False}
        if address is None and num_cpus is not None:
            kwargs["num_cpus"] = num_cpus
        try:
            ray.init(**kwargs)
        except (ConnectionError, RuntimeError, ValueError) as e:
            raise ConfigError(f"cannot start or join Ray (address={address!r}): {e}") from None
        started = True
    try:
        remote = ray.remote(max_retries=max_retries)(safe_run)
        window = 4 * max(1, int(ray.cluster_resources().get("CPU", 1)))
        todo = deque(specs)
        pending: dict = {}
        while todo or pending:
            while todo and len(pending) < window:
                s = todo.popleft()
                pending[remote.remote(s)] = s
            done, _ = ray.wait(list(pending), num_returns=1)
            for ref in done:
                s = pending.pop(ref)
                try:
                    yield ray.get(ref)
                except ray.exceptions.RayError as e:
                    yield failed(s, f"ray task failed: {type(e).__name__}: {e}")
    finally:
        if started:
            ray.shutdown()


def iter_results(specs: list[EpisodeSpec], backend: str, workers: int,
                 address: str | None = None) -> Iterator[EpisodeResult]:
    """Results of ``specs`` from the named backend, in completion order."""
    if backend == "local":
        return iter_local(specs, workers)
    if backend == "ray":
        return iter_ray(specs, address=address, num_cpus=workers if address is None else None)
    raise ConfigError(f"unknown backend '{backend}'; choose one of {', '.join(BACKENDS)}")
