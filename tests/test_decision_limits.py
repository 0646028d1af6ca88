"""The default preset's decision steps stay under stated CPU-time limits on the built-in maps.

The issue's targets (CPU time, warm kernels) are a median of 5 ms, a 95th percentile of 15 ms
and a worst step of 50 ms. The limits here are three times those, so that the test holds on a
loaded machine of 2 shared cores (CPU time still grows there: the caches are shared); a step
that compiles a kernel (seconds) or a decision several times slower than the targets fails it.
The measurement is ``pathpref bench``'s own (:func:`~pathpref.apps.benchmarks.maps.
bench_default_decisions`: every step of grid episodes, the consistent human, a push every 5
steps, one warm-up episode first).
"""

import pytest

from pathpref.apps.benchmarks.maps import bench_default_decisions
from pathpref.planning.pomdp import DEFAULT_PRESET

#: CPU ms: the issue's targets x 3
LIMITS_MS = {"default_decision_ms": 15.0, "default_decision_p95_ms": 45.0,
             "default_decision_max_ms": 150.0}


@pytest.mark.parametrize("name", ["simple", "office", "classroom"])
def test_default_preset_decisions_under_limits(name):
    r = bench_default_decisions(name, episodes=2)
    assert r["default_preset"] == DEFAULT_PRESET
    assert r["default_decisions"] >= 10  # two whole episodes were timed
    over = {k: round(r[k], 1) for k, limit in LIMITS_MS.items() if r[k] > limit}
    assert not over, f"{name}: {over} over the limits {LIMITS_MS} (CPU ms)"
