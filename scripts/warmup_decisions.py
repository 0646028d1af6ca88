"""CPU time of every decision on simple, office and classroom in a fresh process, after
``pathpref warmup`` or not (issue 62's target: after a warm-up with an empty numba cache, no
decision over 50 ms CPU). Run it as

    NUMBA_CACHE_DIR=$(mktemp -d) sh -c 'pathpref warmup --quiet; python scripts/warmup_decisions.py'

Each map runs one default-preset episode (every decision timed with time.process_time around
the policy's ``act``), then one decision whose root pool is forced through the observed-exits
fallback (the tree sampler's walk budget 0, so every tree goes to ``POMCP._observed_first``).
Prints one line per map: the CPU ms of building the episode's runner (its policy loads the
kernels it needs from numba's cache then: :func:`pathpref.kernels.load_cached`), decisions, the
first's and the largest CPU ms, and the fallback's.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from pathpref.episode import EpisodeSpec
from pathpref.episode.runner import EpisodeRunner
from pathpref.planning import pomcp


def timed_episode(map_name: str, seed: int = 0) -> tuple[list[float], float, EpisodeRunner]:
    """Every decision's CPU ms of one episode, and the CPU ms of building its runner."""
    t0 = time.process_time()
    runner = EpisodeRunner(EpisodeSpec.single(map_name, "path_preference", 5, seed=seed,
                                              instance=0))
    built = 1000 * (time.process_time() - t0)
    times: list[float] = []
    act = runner.policy.act

    def timed(*a, **k):
        t0 = time.process_time()
        out = act(*a, **k)
        times.append(1000 * (time.process_time() - t0))
        return out

    runner.policy.act = timed
    while not runner.done:
        runner.step()
    return times, built, runner


def forced_fallback(map_name: str) -> float:
    """CPU ms of one decision whose every tree is drawn observed exits first."""
    runner = EpisodeRunner(EpisodeSpec.single(map_name, "path_preference", 1, seed=1,
                                              instance=0))
    for _ in range(3):
        runner.step()
    real = pomcp.tree_pool
    pomcp.tree_pool = lambda *a: real(*a[:-1], 0)  # walk budget 0: every tree falls back
    try:
        t0 = time.process_time()
        runner.step()
        return 1000 * (time.process_time() - t0)
    finally:
        pomcp.tree_pool = real


def main() -> int:
    worst = 0.0
    for m in ("simple", "office", "classroom"):
        times, built, _ = timed_episode(m)
        fb = forced_fallback(m)
        worst = max(worst, max(times), fb)
        print(f"{m}: runner built in {built:.1f} ms, {len(times)} decisions, first "
              f"{times[0]:.1f} ms, largest {max(times):.1f} ms (at decision "
              f"{int(np.argmax(times)) + 1}), forced fallback step {fb:.1f} ms CPU", flush=True)
    print(f"largest: {worst:.1f} ms CPU")
    return 0


if __name__ == "__main__":
    sys.exit(main())
