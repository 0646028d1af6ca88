"""``pathpref warmup`` (issue 62, item 3): after it no kernel is left unreached, and no
decision compiles: default-preset decisions on simple, office and classroom, a decision whose
root pool takes the observed-exits fallback, and a physical episode add no compiled signature
and fire no numba compile event; and in a new process the policy loads its kernels from the
cache when it is built (:func:`pathpref.kernels.load_cached`), so no decision, the first
included, loads or compiles one."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

from numba.core import event  # noqa: E402

import pathpref.sim  # noqa: E402,F401 - registers the MuJoCo body
from pathpref.apps import warmup  # noqa: E402
from pathpref.episode import EpisodeSpec, Physics  # noqa: E402
from pathpref.episode.runner import EpisodeRunner  # noqa: E402
from pathpref.planning import pomcp  # noqa: E402

#: a new process after the warm-up: per map, the numba events of every decision of a short
#: episode (a load from the cache and a compile both take numba's compiler lock; a compile
#: also fires ``numba:compile``), then those of a decision forced through the root pool's
#: observed-exits fallback (every tree's walk given no step), and how many overloads
#: building the first runner loaded
_FRESH = """
import json
from numba.core import event
from pathpref import kernels
from pathpref.apps.warmup import MAPS
from pathpref.episode import EpisodeSpec
from pathpref.episode.runner import EpisodeRunner
from pathpref.planning import pomcp

def counted(run):
    with event.install_recorder("numba:compiler_lock") as lock, \\
            event.install_recorder("numba:compile") as comp:
        out = run()
    seen.append(sum(e.is_start for _, e in lock.buffer) + sum(e.is_start for _, e in comp.buffer))
    return out

loaded = sum(len(k.overloads) for k in kernels.dispatchers().values())
out = {}
for m in MAPS:
    seen = []
    runner = EpisodeRunner(EpisodeSpec.single(m, "path_preference", 5, seed=7, instance=2,
                                              t_max=4))
    if not out:
        loaded = sum(len(k.overloads) for k in kernels.dispatchers().values()) - loaded
    act = runner.policy.act
    runner.policy.act = lambda *a, **k: counted(lambda: act(*a, **k))
    while not runner.done:
        runner.step()
    runner = EpisodeRunner(EpisodeSpec.single(m, "path_preference", 1, seed=1, instance=0))
    for _ in range(3):
        runner.step()
    real = pomcp.tree_pool
    pomcp.tree_pool = lambda *a: real(*a[:-1], 0)
    counted(runner.step)
    pomcp.tree_pool = real
    out[m] = seen
print(json.dumps({"decisions": out, "loaded": loaded}))
"""


def _run(spec: EpisodeSpec, steps: int) -> EpisodeRunner:
    runner = EpisodeRunner(spec)
    for _ in range(steps):
        if runner.done:
            break
        runner.step()
    return runner


def test_after_warmup_no_decision_compiles(monkeypatch):
    r = warmup.warm()
    assert r["unreached"] == []
    assert r["kernels"] >= 50 and r["signatures"] >= r["kernels"] // 2
    before = warmup.signatures()
    fallbacks = []
    real_first = pomcp.POMCP._observed_first

    def observed_first(self, belief, goals, *rest):
        fallbacks.append(len(goals))
        return real_first(self, belief, goals, *rest)

    monkeypatch.setattr(pomcp.POMCP, "_observed_first", observed_first)
    with event.install_recorder("numba:compile") as rec:
        for m in warmup.MAPS:
            _run(EpisodeSpec.single(m, "path_preference", 5, seed=7, instance=2, t_max=12), 12)
        # the rare path: every tree's walk given no step, so the whole pool falls back
        runner = _run(EpisodeSpec.single("classroom", "path_preference", 1, seed=3,
                                         instance=0), 3)
        real_pool = pomcp.tree_pool
        monkeypatch.setattr(pomcp, "tree_pool", lambda *a: real_pool(*a[:-1], 0))
        runner.step()
        monkeypatch.setattr(pomcp, "tree_pool", real_pool)
        _run(EpisodeSpec.single("office", "path_preference", 5, seed=7, instance=2, t_max=3,
                                sim="mujoco", physics=Physics.of(timing="interval").to_json()), 3)
    assert fallbacks and min(fallbacks) > 0  # the fallback was taken
    compiled = [e.data["dispatcher"].py_func.__qualname__ for _, e in rec.buffer if e.is_start]
    assert compiled == []
    assert warmup.signatures() == before
    # a new process (the cache the warm-up filled): its decisions load and compile nothing
    root = Path(__file__).resolve().parents[1]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(root), *filter(None, [os.environ.get("PYTHONPATH")])]))
    done = subprocess.run([sys.executable, "-c", _FRESH], capture_output=True, text=True,
                          env=env, cwd=root, timeout=900, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    fresh = json.loads(done.stdout.strip().splitlines()[-1])
    assert fresh["loaded"] > 0  # building the first runner loaded its kernels
    for m in warmup.MAPS:
        events = fresh["decisions"][m]
        assert len(events) >= 2 and events == [0] * len(events), (m, events)


def test_the_search_clock_is_perf_counters_and_cacheable():
    """The robust search's clock reads ``time.perf_counter``'s clock, in nopython code numba's
    cache keeps (no object-mode block lifted out of it, which its cache cannot hold)."""
    import time

    from pathpref.planning import guided

    a = time.perf_counter()
    t = guided._clock()
    b = time.perf_counter()
    assert a <= t <= b
    (cres,) = guided._clock.overloads.values()
    assert not cres.lifted and not cres.objectmode
