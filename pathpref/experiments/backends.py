"""Where episodes run: a local pool of worker processes, or a Ray cluster. Both yield results in
completion order to the coordinator, which alone writes the results store.

Both send episodes in chunks (:func:`chunk_size`: up to :data:`LOCAL_CHUNK` per local worker,
:data:`RAY_CHUNK` per Ray task, smaller near the end of a sweep so that the last chunks spread
over every worker) and yield results in batches (:func:`iter_batches`), which the coordinator
writes one transaction per batch: a worker need not wait for the coordinator between episodes,
and the coordinator's cost per episode falls with the batch.

``local`` (:func:`iter_local`), a pool whose coordinator knows which process runs which episode:

* At most ``workers`` worker processes, never more than there are episodes; each runs the
  episodes of its chunk one after the other and sends each result back through its own pipe as
  it finishes, so the coordinator knows which episode of the chunk runs. ``workers == 1`` runs
  the episodes in this process instead (no isolation: a crash or a hang there is the caller's).
* Workers die with the coordinator, whatever killed it (SIGKILL included): on Linux the kernel
  sends each one SIGKILL when the coordinator dies (``PR_SET_PDEATHSIG``); everywhere, a thread
  in each worker ends it within a second of its parent process changing. Workers ignore Ctrl-C
  (SIGINT); the coordinator kills them on its way out, whatever the reason it leaves.
* A worker that dies (SIGKILL, segfault, OOM) charges only the episode it was running: that
  episode is queued again, and recorded as failed ("worker process died N times") at its
  ``max_crashes``-th death; the rest of its chunk is queued again uncharged; the episodes of
  the other workers go on undisturbed.
* The coordinator watches each running episode's wall time and kills (SIGKILL, by PID) a worker
  past the episode's limit, :func:`wall_limit`: a frozen (SIGSTOP), deadlocked or runaway worker
  cannot hang the sweep. Without ``--episode-timeout`` the limit is generous and overrunning it
  counts as a death of the episode (queued again). With ``--episode-timeout T`` the episode
  checks ``T`` itself between decisions, and an episode whose worker is killed for overrunning
  ``T`` is recorded as failed ("timeout: ...") at once, as the episode's own check would.

``ray``: each chunk is a Ray task (``max_retries`` re-runs a task whose worker or node died;
the chunk's results return once, when the task succeeds). The maps of the episodes travel with
the tasks by content (:func:`~pathpref.episode.cache.map_payload`, put in Ray's object store
once per sweep), so a node needs neither the map files nor a shared file system.
``address=None`` starts a local Ray instance; ``address="auto"`` or ``"ray://host:10001"``
joins an existing cluster (see docs/experiments.md, "Running on a Ray cluster"); an address
whose port does not accept a connection within :data:`RAY_CONNECT_S` seconds is refused at
once (Ray itself would retry for minutes, deaf to SIGTERM).

An exception inside an episode (bad input, NaN, a timeout) is never lost: :func:`safe_run` turns
it into a failed episode with its reason, and the sweep goes on.
"""

from __future__ import annotations

import ctypes
import multiprocessing as mp
import os
import signal
import socket
import sys
import threading
import time
import traceback
from collections import Counter, deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from multiprocessing.connection import Connection, wait
from multiprocessing.process import BaseProcess

from ..episode import EpisodeResult, EpisodeSpec, Instance, run_episode
from ..episode.cache import map_payload, ship_maps
from ..errors import ConfigError, PathprefError

BACKENDS = ("local", "ray")
#: ``--workers`` above this many per CPU is refused (:func:`max_workers`)
WORKERS_PER_CPU = 4
#: seconds a Ray ``--address`` has to accept a TCP connection
RAY_CONNECT_S = 5.0
#: most episodes per chunk sent to a local worker
LOCAL_CHUNK = 8
#: most episodes per Ray task
RAY_CHUNK = 16
_PR_SET_PDEATHSIG = 1  # from <linux/prctl.h>


def failed(spec: EpisodeSpec, reason: str) -> EpisodeResult:
    """The result of an episode that could not run (``status="failed"``, with its reason)."""
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


def run_chunk(specs: list[EpisodeSpec], maps: dict | None = None) -> list[EpisodeResult]:
    """The results of a chunk of episodes, in order (:func:`safe_run` each), after taking the
    shipped ``maps`` (:func:`~pathpref.episode.cache.ship_maps`); maps that cannot be taken
    fail every episode of the chunk with the reason."""
    if maps:
        try:
            ship_maps(maps)
        except PathprefError as e:
            return [failed(s, f"{type(e).__name__}: {e}") for s in specs]
    return [safe_run(s) for s in specs]


def chunk_size(left: int, workers: int, most: int) -> int:
    """Episodes in the next chunk: ``left // (2 workers)`` (every worker gets at least two more
    chunks' share near the end), between 1 and ``most``."""
    return max(1, min(most, left // (2 * max(1, workers))))


def max_workers() -> int:
    """The most worker processes a sweep may ask for: ``WORKERS_PER_CPU`` x ``os.cpu_count()``
    (the CLI's default ``--workers`` is one per CPU)."""
    return WORKERS_PER_CPU * (os.cpu_count() or 1)


def wall_limit(spec: EpisodeSpec) -> float:
    """Seconds of wall time after which the coordinator kills the worker running ``spec``.

    * ``spec.timeout_s`` (``--episode-timeout T``) given: ``1.1 T + 1`` (the episode's own check
      between decisions normally fires first; this catches a decision that never returns).
    * Otherwise ``120 + t_max x (2 + queries / 1000 + time_budget_ms / 1000)``: 120 s for a
      worker's first episode (imports, numba cache, map and model), then per decision 2 s of
      simulation plus 1 ms per POMCP query and the robust search's time budget. That is 330 s
      for the paper's simple map (t_max 30, 5000 queries) whose episodes take about a second:
      only a worker that is frozen or runaway reaches it. Give ``--episode-timeout`` to replace it.
    """
    if spec.timeout_s:
        return 1.1 * spec.timeout_s + 1.0
    return 120.0 + spec.t_max * (2.0 + spec.queries / 1000 + spec.time_budget_ms / 1000)


def _die_with(parent: int) -> None:
    """Make this worker process die when ``parent`` (the coordinator) does (module docstring)."""
    if sys.platform.startswith("linux"):
        try:
            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
        except (OSError, AttributeError):
            pass  # the watchdog below still applies
    if os.getppid() != parent:  # the coordinator died before prctl took effect
        os._exit(1)
    threading.Thread(target=_watch_parent, args=(parent,), name="pathpref-parent-watch",
                     daemon=True).start()


def _watch_parent(parent: int) -> None:
    while os.getppid() == parent:
        time.sleep(1.0)
    os._exit(1)


def _work(conn: Connection, parent: int, inherited: list[Connection]) -> None:
    """A worker process: run each chunk of episodes received on ``conn``, sending back each
    result as it finishes; leave at end of file (the coordinator closed its end). ``inherited``
    are the coordinator's ends of pipes that a fork copied here: closed, so that only the
    coordinator holds them."""
    for c in inherited:
        c.close()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    _die_with(parent)
    while True:
        try:
            chunk = conn.recv()
        except EOFError:
            return
        for spec in chunk:
            conn.send(safe_run(spec))


@dataclass
class _Worker:
    proc: BaseProcess
    conn: Connection
    chunk: deque = field(default_factory=deque)  # its episodes; the first one runs
    started: float = 0.0  # when the running episode started
    deadline: float = 0.0

    @property
    def spec(self) -> EpisodeSpec | None:
        """The episode it runs, None when idle."""
        return self.chunk[0] if self.chunk else None


@dataclass
class _Ended:
    """An episode that left its worker: with its result, or without (the worker died or was
    killed past the episode's wall-time limit; ``why`` says which)."""

    spec: EpisodeSpec
    result: EpisodeResult | None = None
    why: str = ""
    timed_out: bool = False  # killed past an explicit ``--episode-timeout``


def _signal_name(exitcode: int | None) -> str:
    if exitcode is not None and exitcode < 0:
        try:
            return f"killed by {signal.Signals(-exitcode).name}"
        except ValueError:
            return f"killed by signal {-exitcode}"
    return f"exit code {exitcode}"


class _Pool:
    """Worker processes each running one chunk of episodes at a time (module docstring);
    ``returned`` holds the episodes of chunks whose worker died before running them."""

    def __init__(self, size: int, limit: Callable[[EpisodeSpec], float]):
        self.fork = sys.platform.startswith("linux")
        self.ctx = mp.get_context("fork" if self.fork else "spawn")
        self.size, self.limit = size, limit
        self.workers: list[_Worker] = []
        self.returned: list[EpisodeSpec] = []

    def _spawn(self) -> _Worker:
        here, there = self.ctx.Pipe()
        inherited = [w.conn for w in self.workers] + [here] if self.fork else []
        proc = self.ctx.Process(target=_work, args=(there, os.getpid(), inherited),
                                name="pathpref-worker", daemon=True)
        proc.start()
        there.close()
        w = _Worker(proc, here)
        self.workers.append(w)
        return w

    def _remove(self, w: _Worker) -> None:
        if w.proc.exitcode is None:
            try:
                os.kill(w.proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        w.proc.join()
        w.conn.close()
        self.workers.remove(w)

    def idle(self) -> _Worker | None:
        """A live worker without an episode (started if the pool is not full), or None."""
        for w in list(self.workers):
            if w.spec is None and not w.proc.is_alive():  # died between episodes
                self._remove(w)
        free = [w for w in self.workers if w.spec is None]
        if free:
            return free[0]
        return self._spawn() if len(self.workers) < self.size else None

    def busy(self) -> bool:
        return any(w.spec is not None for w in self.workers)

    def start(self, w: _Worker, chunk: list[EpisodeSpec]) -> bool:
        """Give ``chunk`` to the idle worker ``w``; False if ``w`` turned out dead (removed)."""
        try:
            w.conn.send(chunk)
        except OSError:  # it died since idle() looked
            self._remove(w)
            return False
        w.chunk = deque(chunk)
        self._next(w)
        return True

    def _next(self, w: _Worker) -> None:
        """The clock of ``w``'s running episode starts now."""
        w.started = time.monotonic()
        if w.chunk:
            w.deadline = w.started + self.limit(w.chunk[0])

    def collect(self) -> list[_Ended]:
        """Wait for the first result, death or overrun among the running episodes; all that
        have ended by then (a dead or killed worker is removed, the rest of its chunk put in
        ``returned``)."""
        busy = [w for w in self.workers if w.spec is not None]
        if not busy:
            return []
        timeout = max(0.0, min(w.deadline for w in busy) - time.monotonic())
        ready = set(wait([w.conn for w in busy] + [w.proc.sentinel for w in busy], timeout))
        ended = []
        for w in busy:
            if w.conn in ready:
                try:
                    while w.chunk and w.conn.poll():
                        result = w.conn.recv()
                        ended.append(_Ended(w.chunk.popleft(), result))
                        self._next(w)
                except (EOFError, OSError):  # died: end of file, or in the middle of a result
                    pass
                else:
                    if not w.chunk or w.proc.sentinel not in ready:
                        continue
            if not w.chunk:  # died with its chunk done: seen as idle and dead by idle()
                continue
            spec = w.spec
            now = time.monotonic()
            if w.conn in ready or w.proc.sentinel in ready:
                w.proc.join()
                ended.append(_Ended(spec, why=_signal_name(w.proc.exitcode)))
            elif now >= w.deadline:
                ran = now - w.started
                if spec.timeout_s:
                    why = (f"timeout: episode exceeded {spec.timeout_s:g} s (its worker was "
                           f"killed after {ran:.1f} s)")
                else:
                    why = (f"killed after {ran:.0f} s without a result, this episode's limit "
                           f"(set --episode-timeout to change it)")
                ended.append(_Ended(spec, why=why, timed_out=bool(spec.timeout_s)))
            else:
                continue
            w.chunk.popleft()
            self.returned.extend(w.chunk)
            self._remove(w)
        return ended

    def close(self) -> None:
        """Kill every worker (they hold no state) and reap it."""
        for w in list(self.workers):
            self._remove(w)


#: ``claim(chunk)``: the episodes of ``chunk`` this sweep may run (claimed for it, in order);
#: the others are dropped (another sweep has them)
Claim = Callable[[list[EpisodeSpec]], list[EpisodeSpec]]


def _claimed(chunk: list[EpisodeSpec], claim: Claim | None) -> list[EpisodeSpec]:
    return chunk if claim is None else claim(chunk)


def local_batches(specs: list[EpisodeSpec], workers: int, max_crashes: int = 3,
                  limit: Callable[[EpisodeSpec], float] = wall_limit,
                  claim: Claim | None = None) -> Iterator[list[EpisodeResult]]:
    """Results from a pool of worker processes (in-process when ``workers == 1``), in
    completion order, each batch the results that arrived together; ``limit`` gives an
    episode's wall-time limit in seconds; ``claim`` is asked for each chunk just before it is
    sent (for each episode just before it runs when in-process). Rules: module docstring."""
    if workers <= 1:
        for s in specs:
            if _claimed([s], claim):
                yield [safe_run(s)]
        return
    queue = deque(specs)
    mine: set[str] = set()  # keys claimed already (a chunk's rest, returned by a dead worker)
    deaths: Counter[str] = Counter()
    pool = _Pool(min(workers, len(queue)), limit)
    try:
        while queue or pool.busy():
            while queue and (w := pool.idle()) is not None:
                n = chunk_size(len(queue), pool.size, LOCAL_CHUNK)
                chunk = [queue.popleft() for _ in range(min(n, len(queue)))]
                new = [s for s in chunk if s.key() not in mine]
                mine |= {s.key() for s in (_claimed(new, claim) if new else ())}
                chunk = [s for s in chunk if s.key() in mine]
                if chunk and not pool.start(w, chunk):
                    queue.extendleft(reversed(chunk))
            batch = []
            for end in pool.collect():
                if end.result is not None:
                    batch.append(end.result)
                elif end.timed_out:
                    batch.append(failed(end.spec, end.why))
                else:
                    key = end.spec.key()
                    deaths[key] += 1
                    if deaths[key] >= max_crashes:
                        batch.append(failed(end.spec, f"worker process died {deaths[key]} "
                                                      f"times (last: {end.why})"))
                    else:
                        queue.appendleft(end.spec)
            queue.extendleft(reversed(pool.returned))
            pool.returned.clear()
            if batch:
                yield batch
    finally:
        pool.close()


def iter_local(specs: list[EpisodeSpec], workers: int, max_crashes: int = 3,
               limit: Callable[[EpisodeSpec], float] = wall_limit,
               claim: Claim | None = None) -> Iterator[EpisodeResult]:
    """:func:`local_batches`, one result at a time."""
    for batch in local_batches(specs, workers, max_crashes, limit, claim):
        yield from batch


def _require_reachable(address: str) -> None:
    """Refuse (ConfigError) a Ray address whose port does not accept a TCP connection within
    ``RAY_CONNECT_S`` seconds. ``auto`` is resolved as Ray does; when there is nothing to
    resolve, Ray's own error (immediate) is the one given."""
    target = address.removeprefix("ray://")
    if target == "local":  # Ray starts a new local instance
        return
    if target == "auto":
        try:
            from ray._private.services import canonicalize_bootstrap_address

            target = canonicalize_bootstrap_address("auto") or ""
        except Exception:  # noqa: BLE001 - no cluster found, or another Ray version: Ray says
            return
    host, _, port = target.rpartition(":")
    if not host or not port.isdigit():
        raise ConfigError(f"Ray address {address!r} is not host:port, ray://host:port or auto")
    try:
        socket.create_connection((host.strip("[]"), int(port)), timeout=RAY_CONNECT_S).close()
    except OSError as e:
        raise ConfigError(f"cannot reach Ray at {address!r} within {RAY_CONNECT_S:g} s ({e}); "
                          f"is `ray start --head` running there?") from None


def check_backend(backend: str, address: str | None = None) -> None:
    """Refuse (ConfigError) a backend that cannot run, before a sweep creates or opens its
    database: an unknown name, a Ray ``address`` that does not accept a connection
    (:func:`_require_reachable`), or Ray not installed."""
    if backend not in BACKENDS:
        raise ConfigError(f"unknown backend '{backend}'; choose one of {', '.join(BACKENDS)}")
    if backend != "ray":
        return
    if address is not None:
        _require_reachable(address)
    try:
        import ray  # noqa: F401
    except ImportError:
        raise ConfigError(
            "--backend ray needs Ray: pip install 'pathpref[ray]' (or pip install ray)"
        ) from None


def ray_batches(specs: list[EpisodeSpec], address: str | None = None,
                num_cpus: int | None = None, max_retries: int = 3,
                claim: Claim | None = None) -> Iterator[list[EpisodeResult]]:
    """Results from Ray tasks of chunks, each batch the chunks that finished together (see
    module docstring); ``claim`` as for :func:`local_batches`, asked for each chunk just
    before its task is submitted."""
    try:
        import ray
    except ImportError:
        raise ConfigError(
            "--backend ray needs Ray: pip install 'pathpref[ray]' (or pip install ray)"
        ) from None
    started = False
    if not ray.is_initialized():
        if address is not None:
            _require_reachable(address)
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
        remote = ray.remote(max_retries=max_retries)(run_chunk)
        maps = ray.put(map_payload({s.map for s in specs}))
        cpus = max(1, int(ray.cluster_resources().get("CPU", 1)))
        window = 2 * cpus  # chunks in flight: each CPU has its next one queued
        todo = deque(specs)
        pending: dict = {}
        while todo or pending:
            while todo and len(pending) < window:
                n = chunk_size(len(todo), cpus, RAY_CHUNK)
                chunk = _claimed([todo.popleft() for _ in range(min(n, len(todo)))], claim)
                if chunk:
                    pending[remote.remote(chunk, maps)] = chunk
            # a bounded wait, so that a signal's Python handler (SIGTERM: exit) gets to run
            done, _ = ray.wait(list(pending), num_returns=1, timeout=1.0)
            if done:  # and every other chunk finished by now
                done, _ = ray.wait(list(pending), num_returns=len(pending), timeout=0)
            batch = []
            for ref in done:
                chunk = pending.pop(ref)
                try:
                    batch.extend(ray.get(ref))
                except ray.exceptions.RayError as e:
                    batch.extend(failed(s, f"ray task failed: {type(e).__name__}: {e}")
                                 for s in chunk)
            if batch:
                yield batch
    finally:
        if started:
            ray.shutdown()


def iter_ray(specs: list[EpisodeSpec], address: str | None = None, num_cpus: int | None = None,
             max_retries: int = 3, claim: Claim | None = None) -> Iterator[EpisodeResult]:
    """:func:`ray_batches`, one result at a time."""
    for batch in ray_batches(specs, address, num_cpus, max_retries, claim):
        yield from batch


def iter_results(specs: list[EpisodeSpec], backend: str, workers: int,
                 address: str | None = None, claim: Claim | None = None
                 ) -> Iterator[list[EpisodeResult]]:
    """Batches of results of ``specs`` from ``backend``, with at most ``workers`` worker
    processes (local) or CPUs (a local Ray instance), and never more than there are episodes;
    ``claim(chunk)`` is asked just before each chunk is sent (:func:`local_batches`)."""
    workers = max(1, min(workers, len(specs)))
    if backend == "local":
        return local_batches(specs, workers, claim=claim)
    if backend == "ray":
        return ray_batches(specs, address=address,
                           num_cpus=workers if address is None else None, claim=claim)
    raise ConfigError(f"unknown backend '{backend}'; choose one of {', '.join(BACKENDS)}")
