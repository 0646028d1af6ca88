"""Detecting a human force cue from the robot's own force estimate.

A hysteresis detector on the horizontal force magnitude ``|f|``:

* idle -> active when ``|f| > on_n`` (8 N) has held for ``on_s`` (25 ms);
* active -> idle when ``|f| < off_n`` (4 N) has held for ``off_s`` (50 ms), which emits a cue.

The cue's direction is that of the impulse ``J = sum f dt`` accumulated from the first sample
above ``on_n`` to the release; its heading is binned into the 8 compass sectors (SPEC 4).

**Two pushes are two cues** (``split=True``, the detector of pushes at any time): an active cue
also ends, and the next one begins, when

* *re-onset*: the force fell below ``off_n`` (for less than ``off_s``, else the cue had ended)
  and rises above ``on_n`` again: a person's push does not dip to nothing and come back, so a
  dip followed by a new rise is a second push (two half-sine pushes 20 ms apart dip to zero);
* *turn*: the force, above ``on_n``, points more than ``turn_deg`` (45 degrees, one sector
  away) from the cue's impulse so far for ``on_s`` (25 ms): a second push that overlaps the
  first. The samples of the turn start the new cue.

Without the split, two pushes less than ``off_s`` apart merge into one impulse whose direction
nobody gave (east then north: 45 degrees). ``split=False`` is the original detector, bit for bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb
import numpy as np

from ..episode.physics import DETECTOR
from ..errors import ConfigError
from ..geometry.grid import heading_to_action

#: how far from the lean's opposite a would-be onset may point and still be the resting hand
#: leaving (degrees; :class:`FilteredCueDetector`)
LEAVE_DEG = 25.0


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

    def __init__(self, dt: float, on_n: float = DETECTOR["on_n"],
                 on_s: float = DETECTOR["on_s"], off_n: float = DETECTOR["off_n"],
                 off_s: float = DETECTOR["off_s"], split: bool = False,
                 turn_deg: float = 45.0):
        self.dt, self.on_n, self.on_s, self.off_n, self.off_s = dt, on_n, on_s, off_n, off_s
        self.split, self.cos_turn = split, float(np.cos(np.deg2rad(turn_deg)))
        #: cues that ended by a split (re-onset or turn) since :meth:`reset`
        self.splits = 0
        #: cues that ended at a new baseline (:class:`FilteredCueDetector`'s settle rule)
        self.settled = 0
        self.reset()

    def reset(self) -> None:
        """Forget any cue in progress."""
        self._clear()

    def _clear(self) -> None:
        self.active = False
        self._above = 0.0
        self._below = 0.0
        self._impulse = np.zeros(2)
        self._peak = 0.0
        self._duration = 0.0
        self._dipped = False
        self._turn = 0.0
        self._turn_impulse = np.zeros(2)

    def update(self, f_xy: np.ndarray) -> Cue | None:
        """One force sample: on above ``on_n`` for ``on_s``, off below ``off_n`` for ``off_s``;
        the cue (integrated impulse) when it ends, else None."""
        mag = float(np.hypot(f_xy[0], f_xy[1]))
        if not np.isfinite(mag):
            return None
        if not self.active:
            self._onset(f_xy, mag)
            return None
        return self._active(f_xy, mag, True)

    def _onset(self, f: np.ndarray, mag: float) -> None:
        """One sample before a cue: accumulate while above ``on_n``, go active after ``on_s``
        of it, forget a shorter excursion."""
        if mag > self.on_n:
            self._above += self.dt
            self._impulse += f * self.dt
            self._peak = max(self._peak, mag)
            self._duration += self.dt
            if self._above >= self.on_s - 1e-12:
                self.active = True
                self._below = 0.0
        elif self._above != 0.0:  # idle with nothing accumulated is the cleared state
            self._clear()

    def _active(self, f: np.ndarray, mag: float, accumulate: bool) -> Cue | None:
        """One sample of an active cue: accumulate (when ``accumulate``), release after
        ``off_s`` below ``off_n``, or split (module docstring)."""
        if self.split:
            new = self._split(f, mag)
            if new is not None:
                return new
        if accumulate:
            self._impulse += f * self.dt
        self._peak = max(self._peak, mag)
        self._duration += self.dt
        self._below = self._below + self.dt if mag < self.off_n else 0.0
        if self._below >= self.off_s - 1e-12:
            cue = Cue(self._impulse.copy(), self._peak, self._duration)
            self._clear()
            return cue
        return None

    def _split(self, f: np.ndarray, mag: float) -> Cue | None:
        """The split rules (module docstring): the cue that ends, or None. After a re-onset
        the new push goes through the onset rule; after a turn it is active at once."""
        if mag < self.off_n:
            self._dipped = True
            self._turn, self._turn_impulse = 0.0, np.zeros(2)
            return None
        if self._dipped and mag > self.on_n:
            cue = Cue(self._impulse.copy(), self._peak, self._duration)
            self._clear()
            self.splits += 1
            self._above, self._impulse = self.dt, f * self.dt
            self._peak, self._duration = mag, self.dt
            return cue
        j = self._impulse
        nj = float(np.hypot(j[0], j[1]))
        if mag > self.on_n and nj > 0 and float(f @ j) < self.cos_turn * mag * nj:
            self._turn += self.dt
            self._turn_impulse = self._turn_impulse + f * self.dt
            if self._turn >= self.on_s - 1e-12:
                cue = Cue(self._impulse - self._turn_impulse + f * self.dt, self._peak,
                          self._duration)
                started, held = self._turn_impulse.copy(), self._turn
                self._clear()
                self.splits += 1
                self.active, self._impulse = True, started
                self._peak, self._duration = mag, held
                return cue
        else:
            self._turn, self._turn_impulse = 0.0, np.zeros(2)
        return None


#: :func:`filter_step`'s constants, in this order in :attr:`FilteredCueDetector.params`
ALPHA, BETA, GAMMA, ON_K, OFF_K, BASE_ON, BASE_OFF = range(7)


@nb.njit(cache=True)
def filter_step(x, y, idle, at_rest, f, baseline, ring, queue, var, on, off, params, hold_n):
    """One sample ``(x, y)`` (finite) of :class:`FilteredCueDetector` up to its onset rule,
    on plain arrays: the low-pass ``f += alpha (x - f)`` (``f`` in place); when ``idle`` (no
    cue under way), the calibration: the sample queued in ``ring`` (``queue`` = head, length)
    at rest, else the queue dropped; samples older than ``hold_n`` committed to ``baseline``
    (``b += gamma (f - b)``) and, with ``|e| < off``, to the noise level
    (``var += beta (|e|^2 / 2 - var)``), then ``on = max(base_on, on_k sqrt(var))`` and
    ``off = max(base_off, off_k sqrt(var))`` if it changed. Returns ``(var, on, off, ex, ey,
    quiet)``: ``e = f - b`` and whether the onset rule has nothing to do (idle and ``|e|^2 <
    0.98 on^2``; ``np.hypot`` is within an ulp of the true norm, the sum of squares within a
    few). The one arithmetic of the Python step and the compiled move (:mod:`.coasting`)."""
    fx, fy = f[0], f[1]
    a = params[ALPHA]
    fx, fy = fx + a * (x - fx), fy + a * (y - fy)
    f[0], f[1] = fx, fy
    if idle:
        cap = ring.shape[0]
        if not at_rest:
            queue[0], queue[1] = 0, 0
        else:
            j = (queue[0] + queue[1]) % cap
            ring[j, 0], ring[j, 1] = fx, fy
            queue[1] += 1
            learnt = False
            while queue[1] > hold_n:
                j = queue[0]
                qx, qy = ring[j, 0], ring[j, 1]
                queue[0] = (j + 1) % cap
                queue[1] -= 1
                bx, by = baseline[0], baseline[1]
                ex, ey = qx - bx, qy - by
                if ex * ex + ey * ey < off * off:
                    var += params[BETA] * (0.5 * (ex * ex + ey * ey) - var)
                    learnt = True
                baseline[0], baseline[1] = bx + params[GAMMA] * ex, by + params[GAMMA] * ey
            if learnt:
                sigma = math.sqrt(var)  # what noise_n gives: sqrt is correctly rounded
                on = params[ON_K] * sigma  # max(base, k sigma), base on a tie
                on = on if on > params[BASE_ON] else params[BASE_ON]
                off = params[OFF_K] * sigma
                off = off if off > params[BASE_OFF] else params[BASE_OFF]
    ex, ey = fx - baseline[0], fy - baseline[1]
    return var, on, off, ex, ey, idle and ex * ex + ey * ey < 0.98 * on * on


class FilteredCueDetector(CueDetector):
    """The hysteresis detector for a noisy force estimate, calibrated while idle.

    * a first-order low-pass (time constant ``tau_s``, 15 ms) before the thresholds:
      ``f_k = f_{k-1} + a (x_k - f_{k-1})``, ``a = dt / (tau_s + dt)``;
    * a **baseline** ``b`` (what the handle feels with nobody pushing: a hand resting on it, a
      bias the estimator has not yet removed): the thresholds apply to ``e = f - b``, and the
      cue's impulse is ``sum e dt``. ``b`` follows the filtered force with time constant
      ``baseline_tau_s`` (1 s) from idle samples only (below);
    * thresholds relative to the noise: ``on = max(on_n, on_k sigma)``,
      ``off = max(off_n, off_k sigma)``, ``sigma^2`` the per-axis variance of ``e`` at rest,
      an exponential average over ``floor_tau_s`` of ``|e|^2 / 2``;
    * **what may calibrate** ``b`` and ``sigma``: a sample at rest (the caller's ``at_rest``)
      with no cue under way, committed ``hold_s`` (0.15 s, the estimator's ``quiet_s``) after
      it was taken if no cue went active meanwhile (the rising edge of a push, taken before
      the push crossed ``on``, is dropped); ``sigma`` further takes only samples with
      ``|e| < off`` (a push's edge, a resting hand's arrival is never noise). Pushes therefore
      cannot raise the thresholds. Gating at ``off = 3 sigma`` keeps 98.9 % of a 2-D
      Gaussian's samples and lowers ``sigma^2`` by 5 % (``4.5 e^-4.5 / (1 - e^-4.5)``); a
      noise larger than the current ``off`` is still learnt, the gate widening by
      ``off_k / 2`` per time constant;
    * **settling** (a resting hand that set a cue off): an active cue whose ``e`` has stayed
      within ``off`` of its mean for ``settle_s`` (0.5 s), that mean below ``on``, ends there;
      the mean becomes the new baseline, and the cue is emitted (impulse up to the window)
      only if its peak stood out of that level by more than ``on`` (a push followed by a
      resting hand), else dropped (a hand arriving at 6 N plus noise). A cue thus ends either
      back at the baseline (below ``off`` for ``off_s``) or at a new one;
    * **leaning** (a hand resting above ``on``: a person leaning on the handle at 10-15 N for
      20 s, which no ``settle_s`` window below ``on`` absorbs, would hold one cue active and
      blind the detector to the next push): an active cue whose ``e`` has stayed within ``off``
      of its mean for ``lean_s`` (3 s, longer than a deliberate correction is held steady),
      that mean's magnitude below ``lean_n`` (20 N), ends there the same way, the mean added to
      the baseline and remembered as the lean ``L`` (:attr:`leaned` counts them: a condition
      to report); a push on top of the lean is then felt as any push. When the hand leaves,
      ``e`` jumps toward ``-L``: a would-be onset within ``LEAVE_DEG`` (25 degrees: the
      realistic sensor's 2 N noise turns an 8 N onset by 14 degrees) of ``-L`` and no
      stronger than ``|L| + off`` is the lean ending, the baseline gives ``L`` back and no cue
      is given (a push straight against the lean reads the same way at its onset and is
      missed: ``cue_recall_after_leaning_hand`` 0.875, the misses are those pushes);
    * the impulse sums ``e`` only while ``|e| > off``, so the release tail (pure noise) does
      not turn the cue's direction.

    :meth:`update` takes ``at_rest`` (from the estimator) besides the force sample.
    """

    def __init__(self, dt: float, *, tau_s: float = 0.015, on_n: float = DETECTOR["on_n"],
                 on_s: float = DETECTOR["on_s"], off_n: float = DETECTOR["off_n"],
                 off_s: float = DETECTOR["off_s"], on_k: float = 6.0, off_k: float = 3.0,
                 floor_tau_s: float = 2.0, split: bool = False, turn_deg: float = 45.0,
                 baseline_tau_s: float = 1.0, hold_s: float = 0.15, settle_s: float = 0.5,
                 lean_s: float = 3.0, lean_n: float = 20.0):
        for name, v in (("tau_s", tau_s), ("floor_tau_s", floor_tau_s),
                        ("baseline_tau_s", baseline_tau_s), ("hold_s", hold_s),
                        ("settle_s", settle_s), ("lean_s", lean_s), ("lean_n", lean_n)):
            if not (math.isfinite(v) and v >= 0) or (name == "settle_s" and v <= on_s):
                raise ConfigError(f"detector {name} must be a finite number >= 0"
                                  f"{' and > on_s' if name == 'settle_s' else ''}, got {v}")
        self.tau_s, self.on_k, self.off_k, self.floor_tau_s = tau_s, on_k, off_k, floor_tau_s
        self.base_on_n, self.base_off_n = on_n, off_n
        self.baseline_tau_s, self.hold_s, self.settle_s = baseline_tau_s, hold_s, settle_s
        self.lean_s, self.lean_n = max(lean_s, settle_s), lean_n
        #: resting hands above ``on`` taken into the baseline (class docstring)
        self.leaned = 0
        self._alpha = dt / (tau_s + dt)
        self._beta = dt / (floor_tau_s + dt)
        self._gamma = dt / (baseline_tau_s + dt)
        self._hold_n = int(round(hold_s / dt))
        #: :func:`filter_step`'s constants (its ``params``)
        self.params = np.array([self._alpha, self._beta, self._gamma, on_k, off_k, on_n, off_n])
        self.var = 0.0  # per-axis variance of the filtered force at rest (N^2)
        self.baseline = np.zeros(2)  # N, world x-y
        super().__init__(dt, on_n, on_s, off_n, off_s, split, turn_deg)

    def reset(self) -> None:
        """Forget any cue in progress, the filter's state and the baseline (the noise level
        stays)."""
        self._clear()
        self.f = np.zeros(2)
        self.baseline = np.zeros(2)
        self.lean = np.zeros(2)  # the resting hand in the baseline (N; zero: none)
        # the calibration queue: a ring of (fx, fy) rows and its (head, length)
        self._ring = np.zeros((self._hold_n + 4, 2))
        self._queue = np.zeros(2, dtype=np.int64)

    def _clear(self) -> None:
        super()._clear()
        self._settle = 0.0
        self._settle_sum = np.zeros(2)
        self._settle_impulse = np.zeros(2)

    @property
    def noise_n(self) -> float:
        """The learnt per-axis spread of the filtered force at rest (N, 1 sigma)."""
        return math.sqrt(self.var)

    @property
    def queued(self) -> int:
        """Idle samples waiting ``hold_s`` to calibrate the baseline and noise level."""
        return int(self._queue[1])

    def pending(self) -> np.ndarray:
        """The queued samples ``(fx, fy)``, oldest first (a new array)."""
        head, n = self._queue.tolist()
        return self._ring[(head + np.arange(n)) % len(self._ring)]

    def update(self, f_xy: np.ndarray, at_rest: bool = False) -> Cue | None:
        """One force sample (and whether the robot is at rest with no push): low-pass, minus
        the baseline, then the hysteresis of :class:`CueDetector`; the cue or None."""
        x, y = float(f_xy[0]), float(f_xy[1])
        if not (math.isfinite(x) and math.isfinite(y)):
            return None
        idle = not self.active and self._above == 0.0
        self.var, self.on_n, self.off_n, ex, ey, quiet = filter_step(
            x, y, idle, at_rest, self.f, self.baseline, self._ring, self._queue, self.var,
            self.on_n, self.off_n, self.params, self._hold_n)
        if quiet:
            return None
        return self._decide(ex, ey)

    def _decide(self, ex: float, ey: float) -> Cue | None:
        """The rest of :meth:`update` for ``e = (ex, ey)`` once the idle test did not
        answer: the onset rule, or the settle rule and the hysteresis of an active cue."""
        e = np.array([ex, ey])
        mag = float(np.hypot(ex, ey))
        if not self.active:
            if self._lean_ends(e, mag):
                return None
            self._onset(e, mag)
            if self.active:
                self._queue[:] = 0  # the push's rising edge never calibrates
            return None
        settled = self._settling(e, mag)
        if settled is not False:
            return settled
        return self._active(e, mag, mag > self.off_n)

    def _lean_ends(self, e: np.ndarray, mag: float) -> bool:
        """Whether a would-be onset ``e`` is the remembered lean leaving (class docstring):
        then the baseline gives the lean back."""
        L = self.lean
        size = float(np.hypot(L[0], L[1]))
        if size == 0.0 or mag > size + self.off_n or \
                -float(e @ L) < math.cos(math.radians(LEAVE_DEG)) * mag * size:
            return False
        self.baseline = self.baseline - L
        self.lean = np.zeros(2)
        self._clear()
        return True

    def _settling(self, e: np.ndarray, mag: float) -> Cue | None | bool:
        """The settle rule (class docstring): False while the cue goes on, else the cue that
        ends at a new baseline (None when it is dropped). The window restarts at a sample
        farther than ``off`` from the window's mean so far; a full window whose mean is not
        below ``on`` (a steady push, not a resting hand) starts a new window."""
        if self._settle > 0.0:
            m = self._settle_sum / self._settle
            if float(np.hypot(e[0] - m[0], e[1] - m[1])) > self.off_n:
                self._settle, self._settle_sum = 0.0, np.zeros(2)
                self._settle_impulse = np.zeros(2)
        self._settle += self.dt
        self._settle_sum = self._settle_sum + e * self.dt
        if mag > self.off_n:
            self._settle_impulse = self._settle_impulse + e * self.dt
        if self._settle < self.settle_s - 1e-12:
            return False
        level = self._settle_sum / self._settle
        lift = float(np.hypot(level[0], level[1]))
        if lift >= self.on_n:
            if lift < self.lean_n and self._settle < self.lean_s - 1e-12:
                return False  # perhaps a lean: keep the window
            if lift >= self.lean_n:
                self._settle, self._settle_sum = 0.0, np.zeros(2)
                self._settle_impulse = np.zeros(2)
                return False
            self.lean = self.lean + level  # a resting hand above on
            self.leaned += 1
        cue = None
        if self._peak - lift > self.on_n:
            cue = Cue(self._impulse - self._settle_impulse, self._peak,
                      self._duration - self._settle)
        self.baseline = self.baseline + level
        self._clear()
        self.settled += 1
        return cue
