"""Comparisons that hold on every x86-64 machine (docs/experiments.md, "Replays exactly").

NumPy, OpenBLAS and numba choose CPU-specific kernels, so a float can differ in its last bits
between two machines (``0.1126323642245804`` against ``0.11263236422458038``). Tests that pin a
stored result compare discrete values (cells, actions, counts, flags, strings) exactly and
floats to :data:`REL` relative (:data:`ABS` absolute near 0): far below any difference a change
of method makes, far above a few ulps of accumulated rounding."""

from __future__ import annotations

import math

REL = 1e-9
ABS = 1e-12
#: physical measurements (tilt, drift, forces) pass through thousands of 2 ms MuJoCo steps and
#: an iteratively solved IK (daqp), which grow a last-bit difference to ~1e-9 relative
REL_PHYSICS = 1e-6


def same(got, want, path: str = "", rel: float = REL) -> list[str]:
    """The places where ``got`` and ``want`` differ (nested lists, tuples and dicts): exactly
    for everything but floats, floats within ``REL``/``ABS`` (NaN equals NaN)."""
    if isinstance(want, float) or isinstance(got, float):
        if isinstance(got, bool) or isinstance(want, bool):
            return [] if got == want else [f"{path}: {got!r} != {want!r}"]
        try:
            g, w = float(got), float(want)
        except (TypeError, ValueError):
            return [f"{path}: {got!r} != {want!r}"]
        if math.isnan(g) and math.isnan(w):
            return []
        return [] if math.isclose(g, w, rel_tol=rel, abs_tol=ABS) else [
            f"{path}: {got!r} != {want!r}"]
    if isinstance(want, dict):
        if not isinstance(got, dict) or set(got) != set(want):
            return [f"{path}: keys {sorted(got) if isinstance(got, dict) else got!r} != "
                    f"{sorted(want)}"]
        return [d for k in want for d in same(got[k], want[k], f"{path}.{k}", rel)]
    if isinstance(want, list | tuple):
        if not isinstance(got, list | tuple) or len(got) != len(want):
            return [f"{path}: length {len(got) if isinstance(got, list | tuple) else got!r} "
                    f"!= {len(want)}"]
        return [d for i, (g, w) in enumerate(zip(got, want))
                for d in same(g, w, f"{path}[{i}]", rel)]
    return [] if got == want else [f"{path}: {got!r} != {want!r}"]


def assert_same(got, want, what: str = "", rel: float = REL) -> None:
    """Fail with the first few differences (:func:`same`)."""
    diff = same(got, want, rel=rel)
    assert not diff, f"{what}: " + "; ".join(diff[:5])
