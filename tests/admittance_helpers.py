"""The closed form of a guided push (``M dv/dt + b v = F`` from rest, the deformation
``dp/dt = v``), worked out independently of the simulation."""

from __future__ import annotations

import math


def admittance_travel(force_n: float, seconds: float, after_s: float, mass: float,
                      damping: float, v_max: float = math.inf) -> float:
    """The deformation after a steady push of ``force_n`` for ``seconds`` and ``after_s`` of
    decay: ``F/b (T - tau (1 - e^{-T/tau}))`` during the push plus ``v(T) tau (1 -
    e^{-after/tau})`` after it, ``tau = M / b`` (``v`` below ``v_max`` throughout)."""
    tau = mass / damping
    v_end = force_n / damping * (1.0 - math.exp(-seconds / tau))
    assert v_end <= v_max, "the closed form holds below the speed cap"
    return force_n / damping * (seconds - tau * (1.0 - math.exp(-seconds / tau))) \
        + v_end * tau * (1.0 - math.exp(-after_s / tau))
