"""A base yielding to a push: an admittance with a spring back to where the yield began.

While a cue is under way, a base with admittance damping ``b`` (N s/m) commands the planar
velocity ``v = (F_hat - k (p - p_0)) / b`` with ``F_hat`` the push estimate (N, world frame),
``p`` the base's position and ``p_0`` where the yield began; the spring ``k =
ADMITTANCE_K`` keeps a push the actuators cannot resist from carrying the base away (a 30 N
push settles 0.075 m out). A push above ``BRACE`` of the drive's force limit is not yielded to:
the base brakes back toward ``p_0`` with all its force, ``v = -k_p (p - p_0)``, since a base
that has yielded and gathered speed cannot stop while a push beyond its actuators acts on it.
"""

from __future__ import annotations

import numpy as np

#: the admittance's spring (N/m): a yielding base gives way 0.1 m to 40 N
ADMITTANCE_K = 400.0
#: share of the drive's force limit above which the base braces instead of yielding
BRACE = 0.6


def yield_velocity(f: np.ndarray, pos: np.ndarray, anchor: np.ndarray, b: float, kp: float,
                   force_limit: float) -> np.ndarray:
    """The yielding base's planar velocity command (m/s, module docstring): push estimate
    ``f``, position ``pos``, the yield's start ``anchor``, damping ``b``, the tracking gain
    ``kp`` and the drive's ``force_limit`` (N)."""
    if float(np.hypot(f[0], f[1])) > BRACE * force_limit:
        return -kp * (pos - anchor)
    return (f - ADMITTANCE_K * (pos - anchor)) / b
