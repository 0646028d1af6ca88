"""Where episodes run: a local process pool, or a Ray cluster. Both yield results in
completion order to the coordinator, which alone writes the results store.

* ``local``: ``workers`` processes (at most one per episode), each running one episode at a
  time. A worker that dies (SIGKILL, segfault) or makes no progress past a timeout derived from
  the episode's size is replaced; only its own episode is charged and run again, and recorded as
  failed ("worker process died") after ``max_crashes`` deaths, so one that kills its worker every
  time cannot stall the sweep. Workers die with the coordinator, however it dies.
* ``ray``: each episode is a Ray task (``max_retries`` re-runs a task whose worker died).
  ``address=None`` starts a local Ray instance; ``address="auto"`` or ``"ray://host:10001"``
  joins an existing cluster (see README, "Running on a Ray cluster").

An exception inside an episode (bad input, NaN, a timeout) is never lost: :func:`safe_run` turns
it into a failed episode with its reason, and the sweep goes on.
"""

from __future__ import annotations

import ctypes
import multiprocessing as mp
import os
import signal
import sys
import threading
import time
import traceback
from collections import Counter, deque
from collections.abc import Iterator
from multiprocessing.connection import wait as mp_wait

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


def _die_with_parent(parent: int) -> None:
    """Make this worker die with the coordinator, whatever kills it: on Linux the kernel sends
    SIGKILL when the parent exits (``PR_SET_PDEATHSIG``); everywhere a watchdog thread exits
    once the parent pid changes (the fallback, and the race between fork and prctl)."""
    if sys.platform.startswith("linux"):
        try:
            ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
        except OSError:
            pass
    if os.getppid() != parent:
        os._exit(1)

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(1.0)
        os._exit(1)

    threading.Thread(target=watch, daemon=True).start()


def _worker(conn, parent: int) -> None:
    """A pool process: run the episodes the coordinator sends, one at a time, until None."""
    _die_with_parent(parent)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the coordinator handles Ctrl-C
    while True:
        spec = conn.recv()
        if spec is None:
            return
        conn.send(safe_run(spec))


def default_timeout(spec: EpisodeSpec) -> float:
    """Wall time after which a worker running ``spec`` counts as stuck (killed, episode re-run):
    ``--episode-timeout`` when given, else ``60 s + T_max x (0.5 s + queries x 20 us)`` for the
    grid (x 10 with physics), tens of times what an episode takes on a slow core."""
    if spec.timeout_s:
        return 5.0 + 1.2 * spec.timeout_s
    per_step = 0.5 + spec.queries * 20e-6
    return 60.0 + spec.t_max * per_step * (1.0 if spec.sim == "grid" else 10.0)


class _Slot:
    """One worker process of the local pool and the episode it runs."""

    def __init__(self, ctx) -> None:
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_worker, args=(child, os.getpid()), daemon=True)
        self.proc.start()
        child.close()
        self.spec: EpisodeSpec | None = None
        self.t0 = 0.0

    def give(self, spec: EpisodeSpec) -> None:
        self.spec, self.t0 = spec, time.monotonic()
        self.conn.send(spec)

    def kill(self) -> None:
        if self.proc.is_alive():
            os.kill(self.proc.pid, signal.SIGKILL)
        self.proc.join(5)
        self.conn.close()


def iter_local(specs: list[EpisodeSpec], workers: int, max_crashes: int = 3
               ) -> Iterator[EpisodeResult]:
    """Results from a pool of worker processes (in-process when ``workers == 1``).

    Each worker runs one episode at a time, so a death is charged to the episode it ran: the
    episode is queued again, and recorded as failed after ``max_crashes`` deaths; the others
    are not touched. A worker past :func:`default_timeout` on one episode (frozen, or a search
    that never returns) is killed by pid and counts as a death of that episode. Workers die
    with the coordinator (:func:`_die_with_parent`)."""
    if workers <= 1:
        for s in specs:
            yield safe_run(s)
        return
    ctx = mp.get_context("fork" if sys.platform.startswith("linux") else "spawn")
    queue = deque(specs)
    crashes: Counter[str] = Counter()
    slots = [_Slot(ctx) for _ in range(min(workers, len(specs)))]
    try:
        while queue or any(sl.spec is not None for sl in slots):
            for sl in slots:
                if sl.spec is None and queue:
                    sl.give(queue.popleft())
            busy = [sl for sl in slots if sl.spec is not None]
            ready = mp_wait([sl.conn for sl in busy], timeout=1.0)
            for k, sl in enumerate(slots):
                if sl.spec is None:
                    continue
                reason = None
                if sl.conn in ready:
                    try:
                        res = sl.conn.recv()
                    except (EOFError, OSError):
                        reason = "worker process died"
                    else:
                        sl.spec = None
                        yield res
                        continue
                elif time.monotonic() - sl.t0 > default_timeout(sl.spec):
                    reason = f"worker made no progress for {default_timeout(sl.spec):g} s"
                if reason is None:
                    continue
                spec, sl.spec = sl.spec, None
                sl.kill()
                slots[k] = _Slot(ctx)
                crashes[spec.key()] += 1
                if crashes[spec.key()] >= max_crashes:
                    yield failed(spec, f"{reason} ({max_crashes} times)")
                else:
                    queue.appendleft(spec)
    finally:
        for sl in slots:
            sl.kill()


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
