"""Detecting a human force cue from the robot's own force estimate.

A hysteresis detector on the horizontal force magnitude ``|f|``:

* idle -> active when ``|f| > on_n`` (8 N) has held for ``on_s`` (25 ms);
* active -> idle when ``|f| < off_n`` (4 N) has held for ``off_s`` (50 ms), which emits a cue.

The cue's direction is that of the impulse ``J = sum f dt`` accumulated from the first sample
above ``on_n`` to the release; its heading is binned into the 8 compass sectors (SPEC 4).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry.grid import heading_to_action


@dataclass(frozen=True)
class Cue:
    """A detected push: its impulse (N s, world x-y), peak force (N) and duration (s)."""
    impulse: np.ndarray  # N s, world frame (x, y)
    peak_n: float
    duration_s: float

    @property
    def angle(self) -> float:
        """Direction of the impulse (radians, counter-clockwise from +x)."""
        return float(np.arctan2(self.impulse[1], self.impulse[0]))

    @property
    def heading(self) -> int:
        """The impulse's compass sector (0..7: N, NE, ..., NW)."""
        return heading_to_action(self.angle)


class CueDetector:
    """Feed one force sample per physics step with :meth:`update`; it returns a :class:`Cue`
    when one ends, else None."""

    def __init__(self, dt: float, on_n: float = 8.0, on_s: float = 0.025, off_n: float = 4.0,
                 off_s: float = 0.05):
        self.dt, self.on_n, self.on_s, self.off_n, self.off_s = dt, on_n, on_s, off_n, off_s
        self.reset()

    def reset(self) -> None:
        """Forget any cue in progress."""
        self.active = False
        self._above = 0.0
        self._below = 0.0
        self._impulse = np.zeros(2)
        self._peak = 0.0
        self._duration = 0.0

    def update(self, f_xy: np.ndarray) -> Cue | None:
        """One force sample: on above ``on_n`` for ``on_s``, off below ``off_n`` for ``off_s``;
        the cue (integrated impulse) when it ends, else None."""
        mag = float(np.hypot(f_xy[0], f_xy[1]))
        if not np.isfinite(mag):
            return None
        if not self.active:
            if mag > self.on_n:
                self._above += self.dt
                self._impulse += f_xy * self.dt
                self._peak = max(self._peak, mag)
                self._duration += self.dt
                if self._above >= self.on_s - 1e-12:
                    self.active = True
                    self._below = 0.0
            else:
                self.reset()
            return None
        self._impulse += f_xy * self.dt
        self._peak = max(self._peak, mag)
        self._duration += self.dt
        self._below = self._below + self.dt if mag < self.off_n else 0.0
        if self._below >= self.off_s - 1e-12:
            cue = Cue(self._impulse.copy(), self._peak, self._duration)
            self.reset()
            return cue
        return None
