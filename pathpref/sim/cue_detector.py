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
from .kernel_parts import Slot
from .native import _ddot

#: how long a cue may stay open before it is released and counted (s; ``released``): longer
#: than the guiding person's longest hold (10 s, :mod:`.guiding_human`) and the lean rule's
#: window (``lean_s``), so only a cue no rule can end reaches it
OPEN_MAX_S = 12.0
#: the open-noise rule (:class:`FilteredCueDetector`): after ``NOISE_S`` of a cue open, a cue
#: whose mean force is below ``NOISE_COHERENCE`` of its root-mean-square is noise (a push, a
#: lean or a guiding hold points one way: their ratio is 0.9 to 1; white noise's falls as
#: ``sqrt(tau / T)``, 0.1 to 0.2 after 1 s)
NOISE_S = 1.0
NOISE_COHERENCE = 0.5


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


#: the detector's state (:attr:`CueDetector.st`): the cue under way (cleared by
#: :func:`clear_state`: ``ACTIVE`` ... ``SIMP_Y``), the resting hand in the baseline, the
#: counters and the last cue given (:func:`decide_step`'s output)
(ACTIVE, ABOVE, BELOW, IMP_X, IMP_Y, PEAK, DURATION, DIPPED, TURN, TURN_X, TURN_Y, SETTLE,
 SUM_X, SUM_Y, SIMP_X, SIMP_Y, LEAN_X, LEAN_Y, LEANED, SETTLED, SPLITS, CUE_X, CUE_Y,
 CUE_PEAK, CUE_DUR, RELEASED, DROPPED, LEFT, N_ST) = range(29)
#: :func:`decide_step`'s constants (:attr:`CueDetector.rule`): the step, ``on_s``, ``off_s``,
#: the turn's cosine, the split switch, the filtered detector's rules switch (the settle and
#: lean rules, the impulse summed above ``off`` only), ``settle_s``, ``lean_s``, ``lean_n`` and
#: the bound on a cue's time open (:data:`OPEN_MAX_S`)
(R_DT, R_ON_S, R_OFF_S, R_COS_TURN, R_SPLIT, R_FILTERED, R_SETTLE_S, R_LEAN_S, R_LEAN_N,
 R_OPEN_MAX_S, N_RULE) = range(11)


@nb.njit(cache=True)
def clear_state(st):
    """No cue under way: the slots ``ACTIVE`` ... ``SIMP_Y`` of ``st`` zeroed (the lean and
    the counters stay)."""
    for i in range(LEAN_X):
        st[i] = 0.0


@nb.njit(cache=True, inline="always")
def _dot2(buf, ax, ay, bx, by):
    """``a @ b`` of two 2-vectors as NumPy computes it (its BLAS ``ddot``), on ``buf``."""
    buf[0], buf[1], buf[2], buf[3] = ax, ay, bx, by
    return _ddot(2, buf.ctypes.data, 1, buf[2:].ctypes.data, 1)


@nb.njit(cache=True, inline="always")
def _give(st, ix, iy, peak, duration):
    """The cue that ends: impulse ``(ix, iy)``, peak and duration into the output slots."""
    st[CUE_X], st[CUE_Y], st[CUE_PEAK], st[CUE_DUR] = ix, iy, peak, duration


@nb.njit(cache=True)
def _onset(st, fx, fy, mag, on_n, rule):
    """One sample before a cue: accumulate while above ``on_n``, go active after ``on_s`` of
    it, forget a shorter excursion."""
    dt = rule[R_DT]
    if mag > on_n:
        st[ABOVE] += dt
        st[IMP_X] += fx * dt
        st[IMP_Y] += fy * dt
        if mag > st[PEAK]:
            st[PEAK] = mag
        st[DURATION] += dt
        if st[ABOVE] >= rule[R_ON_S] - 1e-12:
            st[ACTIVE] = 1.0
            st[BELOW] = 0.0
    elif st[ABOVE] != 0.0:  # idle with nothing accumulated is the cleared state
        clear_state(st)


@nb.njit(cache=True)
def _split(st, fx, fy, mag, on_n, off_n, rule, buf):
    """The split rules (module docstring): 1 when the cue under way ends here (given), -1
    when it goes on. After a re-onset the new push goes through the onset rule; after a turn
    it is active at once."""
    dt = rule[R_DT]
    if mag < off_n:
        st[DIPPED] = 1.0
        st[TURN], st[TURN_X], st[TURN_Y] = 0.0, 0.0, 0.0
        return -1
    if st[DIPPED] != 0.0 and mag > on_n:
        _give(st, st[IMP_X], st[IMP_Y], st[PEAK], st[DURATION])
        clear_state(st)
        st[SPLITS] += 1.0
        st[ABOVE], st[IMP_X], st[IMP_Y] = dt, fx * dt, fy * dt
        st[PEAK], st[DURATION] = mag, dt
        return 1
    jx, jy = st[IMP_X], st[IMP_Y]
    nj = math.hypot(jx, jy)
    if mag > on_n and nj > 0 and _dot2(buf, fx, fy, jx, jy) < rule[R_COS_TURN] * mag * nj:
        st[TURN] += dt
        st[TURN_X] = st[TURN_X] + fx * dt
        st[TURN_Y] = st[TURN_Y] + fy * dt
        if st[TURN] >= rule[R_ON_S] - 1e-12:
            _give(st, jx - st[TURN_X] + fx * dt, jy - st[TURN_Y] + fy * dt, st[PEAK],
                  st[DURATION])
            sx, sy, held = st[TURN_X], st[TURN_Y], st[TURN]
            clear_state(st)
            st[SPLITS] += 1.0
            st[ACTIVE], st[IMP_X], st[IMP_Y] = 1.0, sx, sy
            st[PEAK], st[DURATION] = mag, held
            return 1
    else:
        st[TURN], st[TURN_X], st[TURN_Y] = 0.0, 0.0, 0.0
    return -1


@nb.njit(cache=True)
def _active(st, fx, fy, mag, accumulate, on_n, off_n, rule, buf):
    """One sample of an active cue: accumulate (when ``accumulate``), release after ``off_s``
    below ``off_n`` (1: the cue given), or split (module docstring); 0: it goes on."""
    if rule[R_SPLIT] != 0.0:
        if _split(st, fx, fy, mag, on_n, off_n, rule, buf) == 1:
            return 1
    dt = rule[R_DT]
    if accumulate:
        st[IMP_X] += fx * dt
        st[IMP_Y] += fy * dt
    if mag > st[PEAK]:
        st[PEAK] = mag
    st[DURATION] += dt
    st[BELOW] = st[BELOW] + dt if mag < off_n else 0.0
    if st[BELOW] >= rule[R_OFF_S] - 1e-12:
        if st[PEAK] <= on_n:  # the onset level rose under the cue (the open-noise rule)
            st[DROPPED] += 1.0
            clear_state(st)
            return 0
        _give(st, st[IMP_X], st[IMP_Y], st[PEAK], st[DURATION])
        clear_state(st)
        return 1
    if st[DURATION] >= rule[R_OPEN_MAX_S] - 1e-12:  # no rule ended it: released, counted
        st[RELEASED] += 1.0
        clear_state(st)
    return 0


@nb.njit(cache=True)
def _settling(st, ex, ey, mag, baseline, on_n, off_n, rule):
    """The settle rule (the filtered detector's docstring): -1 while the cue goes on, else
    the cue ends at a new baseline (1: given, 0: dropped). The window restarts at a sample
    farther than ``off`` from the window's mean so far; a full window whose mean is not
    below ``on`` (a steady push, not a resting hand) starts a new window."""
    dt = rule[R_DT]
    if st[SETTLE] > 0.0:
        mx, my = st[SUM_X] / st[SETTLE], st[SUM_Y] / st[SETTLE]
        if math.hypot(ex - mx, ey - my) > off_n:
            for i in range(SETTLE, SIMP_Y + 1):
                st[i] = 0.0
    st[SETTLE] += dt
    st[SUM_X] = st[SUM_X] + ex * dt
    st[SUM_Y] = st[SUM_Y] + ey * dt
    if mag > off_n:
        st[SIMP_X] = st[SIMP_X] + ex * dt
        st[SIMP_Y] = st[SIMP_Y] + ey * dt
    if st[SETTLE] < rule[R_SETTLE_S] - 1e-12:
        return -1
    lx, ly = st[SUM_X] / st[SETTLE], st[SUM_Y] / st[SETTLE]
    lift = math.hypot(lx, ly)
    qx, qy = st[LEAN_X], st[LEAN_Y]
    size = math.hypot(qx, qy)
    if size > 0.0 and math.hypot(lx + qx, ly + qy) <= max(off_n, 0.25 * size):
        st[LEAN_X], st[LEAN_Y] = 0.0, 0.0  # the leaning hand left: the baseline gives it back
        st[LEFT] += 1.0
    elif lift >= on_n:
        if lift < rule[R_LEAN_N] and st[SETTLE] < rule[R_LEAN_S] - 1e-12:
            return -1  # perhaps a lean: keep the window
        if lift >= rule[R_LEAN_N]:
            for i in range(SETTLE, SIMP_Y + 1):
                st[i] = 0.0
            return -1
        st[LEAN_X], st[LEAN_Y] = st[LEAN_X] + lx, st[LEAN_Y] + ly  # a resting hand above on
        st[LEANED] += 1.0
    given = 0
    if st[PEAK] - lift > on_n:
        _give(st, st[IMP_X] - st[SIMP_X], st[IMP_Y] - st[SIMP_Y], st[PEAK],
              st[DURATION] - st[SETTLE])
        given = 1
    baseline[0], baseline[1] = baseline[0] + lx, baseline[1] + ly
    clear_state(st)
    st[SETTLED] += 1.0
    return given


@nb.njit(cache=True)
def decide_step(fx, fy, st, baseline, queue, on_n, off_n, rule, buf):
    """The hysteresis of one sample ``(fx, y)`` (N) on the detector's state ``st``: the onset
    rule while idle, else the release (and, with ``rule[R_SPLIT]``, the split rules); with
    ``rule[R_FILTERED]`` the sample is ``e = f - b`` of :class:`FilteredCueDetector` (past its
    low-pass and idle test), the lean's leaving is checked before an onset, an onset drops
    the calibration ``queue``, the settle and lean rules run first on an active cue and the
    impulse sums ``e`` only above ``off_n``. ``|f|`` is the C library's ``hypot`` (NumPy's),
    the dot products NumPy's BLAS ``ddot`` (on ``buf``, 4 floats). Returns 1 when a cue ends
    with this sample (impulse, peak and duration in ``st[CUE_X:]``), else 0 (a sample whose
    magnitude is not finite changes nothing). The one arithmetic of both detectors' Python
    steps and the compiled move (:mod:`.coasting`)."""
    mag = math.hypot(fx, fy)
    if not math.isfinite(mag):
        return 0
    if rule[R_FILTERED] == 0.0:
        if st[ACTIVE] == 0.0:
            _onset(st, fx, fy, mag, on_n, rule)
            return 0
        return _active(st, fx, fy, mag, True, on_n, off_n, rule, buf)
    if st[ACTIVE] == 0.0:
        _onset(st, fx, fy, mag, on_n, rule)
        if st[ACTIVE] != 0.0:
            queue[0], queue[1] = 0, 0  # the push's rising edge never calibrates
        return 0
    settled = _settling(st, fx, fy, mag, baseline, on_n, off_n, rule)
    if settled >= 0:
        return settled
    return _active(st, fx, fy, mag, mag > off_n, on_n, off_n, rule, buf)


class CueDetector:
    """Feed one force sample per physics step with :meth:`update`; it returns a :class:`Cue`
    when one ends, else None. Its state is the array :attr:`st` (slots ``ACTIVE`` ...) that
    :func:`decide_step` advances."""

    #: the settle and lean rules of :class:`FilteredCueDetector` (``rule[R_FILTERED]``)
    filtered = False

    def __init__(self, dt: float, on_n: float = DETECTOR["on_n"],
                 on_s: float = DETECTOR["on_s"], off_n: float = DETECTOR["off_n"],
                 off_s: float = DETECTOR["off_s"], split: bool = False,
                 turn_deg: float = 45.0, open_max_s: float = OPEN_MAX_S):
        self.dt, self.on_n, self.on_s, self.off_n, self.off_s = dt, on_n, on_s, off_n, off_s
        self.cos_turn = float(np.cos(np.deg2rad(turn_deg)))
        if not (math.isfinite(open_max_s) and open_max_s > 0):
            raise ConfigError(f"detector open_max_s must be a finite number > 0, got "
                              f"{open_max_s}")
        #: :func:`decide_step`'s constants
        self.rule = np.zeros(N_RULE)
        self.rule[[R_DT, R_ON_S, R_OFF_S, R_COS_TURN, R_FILTERED, R_OPEN_MAX_S]] = (
            dt, on_s, off_s, self.cos_turn, float(self.filtered), open_max_s)
        self.split = split
        self._buf = np.zeros(4)
        #: the state (cue under way, lean, counters, last cue: slots ``ACTIVE`` ...)
        self.st = np.zeros(N_ST)
        # decide_step's baseline and calibration queue, which only the filtered rules use
        self._baseline, self._queue = np.zeros(2), np.zeros(2, dtype=np.int64)
        self.reset()

    @property
    def split(self) -> bool:
        """Two pushes make two cues (module docstring)."""
        return self.rule[R_SPLIT] != 0.0

    @split.setter
    def split(self, on: bool) -> None:
        self.rule[R_SPLIT] = float(bool(on))

    @property
    def active(self) -> bool:
        """A cue is under way (past its onset)."""
        return self.st[ACTIVE] != 0.0

    @property
    def _above(self) -> float:
        """Seconds above ``on_n`` since the onset rule began counting (0: nothing under way)."""
        return float(self.st[ABOVE])

    @property
    def splits(self) -> int:
        """Cues that ended by a split (re-onset or turn) since :meth:`reset`."""
        return int(self.st[SPLITS])

    @property
    def settled(self) -> int:
        """Cues that ended at a new baseline (:class:`FilteredCueDetector`'s settle rule)."""
        return int(self.st[SETTLED])

    @property
    def released(self) -> int:
        """Cues released, not given, after ``open_max_s`` open (:data:`OPEN_MAX_S`): no rule
        could end them (a condition to report)."""
        return int(self.st[RELEASED])

    @property
    def left(self) -> int:
        """Leans whose hand left (read at the settle: :class:`FilteredCueDetector`)."""
        return int(self.st[LEFT])

    @property
    def dropped(self) -> int:
        """Cues dropped at their release because their peak stayed under the onset level the
        noise floor rose to while they were open (:class:`FilteredCueDetector`)."""
        return int(self.st[DROPPED])

    def reset(self) -> None:
        """Forget any cue in progress (the counters stay)."""
        clear_state(self.st)

    def given_cue(self) -> Cue:
        """The cue :func:`decide_step` gave last (its record in :attr:`st`; the compiled move
        reads it when its detector's step gave one, :mod:`.coasting`)."""
        st = self.st
        return Cue(np.array([st[CUE_X], st[CUE_Y]]), float(st[CUE_PEAK]), float(st[CUE_DUR]))

    def update(self, f_xy: np.ndarray) -> Cue | None:
        """One force sample: on above ``on_n`` for ``on_s``, off below ``off_n`` for ``off_s``;
        the cue (integrated impulse) when it ends, else None."""
        if decide_step(float(f_xy[0]), float(f_xy[1]), self.st, self._baseline, self._queue,
                       self.on_n, self.off_n, self.rule, self._buf):
            return self.given_cue()
        return None


#: :func:`filter_step`'s constants, in this order in :attr:`FilteredCueDetector.params`
#: (the open-noise rule's: its window in samples and :data:`NOISE_COHERENCE`,
#: and the low-pass's gain once it has fired, for ``noisy_tau_s``)
ALPHA, BETA, GAMMA, ON_K, OFF_K, BASE_ON, BASE_OFF, NOISE_K, COHERENCE, NOISY_ALPHA = range(10)
#: slots of :attr:`FilteredCueDetector.f`: the low-pass's output, then the open-noise rule's
#: sums over the cue open (``e``, ``|e|^2``, samples)
F_X, F_Y, O_SX, O_SY, O_SQ, O_N, N_F = range(7)
#: slots of :attr:`FilteredCueDetector.rec`, its calibration's scalars (the variance at rest
#: in N^2 and the thresholds it sets, N), which both drivers read and write in place
D_VAR, D_ON, D_OFF, N_DREC = range(4)


@nb.njit(cache=True)
def filter_step(x, y, idle, at_rest, f, baseline, ring, queue, var, on, off, params, hold_n):
    """One sample ``(x, y)`` (finite) of :class:`FilteredCueDetector` up to its onset rule,
    on plain arrays: the low-pass ``f += alpha (x - f)`` (``f`` in place); when ``idle`` (no
    cue under way), the calibration: the sample queued in ``ring`` (``queue`` = head, length)
    at rest, else the queue dropped; samples older than ``hold_n`` committed to ``baseline``
    (``b += gamma (f - b)``) and, with ``|e| < off``, to the noise level
    (``var += beta (|e|^2 / 2 - var)``), then ``on = max(base_on, on_k sqrt(var))`` and
    ``off = max(base_off, off_k sqrt(var))`` if it changed; when not idle, the open-noise
    rule: over each ``noise_k`` samples of a cue open, with mean ``m`` and mean square ``s``
    of ``e``, ``|m|^2 < c^2 s`` (``c`` the coherence, :data:`NOISE_COHERENCE`) raises ``var``
    to ``(s - |m|^2) / 2`` when larger (and the thresholds with it) and slows the low-pass
    to ``params[NOISY_ALPHA]`` (in place). Returns ``(var, on, off, ex, ey, quiet)``:
    ``e = f - b`` and whether the onset rule has nothing to do (idle and ``|e|^2 < 0.98
    on^2``; ``np.hypot`` is within an ulp of the true norm, the sum of squares within a
    few). The one arithmetic of the Python step and the compiled move (:mod:`.coasting`)."""
    fx, fy = f[F_X], f[F_Y]
    a = params[ALPHA]
    fx, fy = fx + a * (x - fx), fy + a * (y - fy)
    f[F_X], f[F_Y] = fx, fy
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
    if idle:
        f[O_SX], f[O_SY], f[O_SQ], f[O_N] = 0.0, 0.0, 0.0, 0.0
    else:  # the open-noise rule (FilteredCueDetector's docstring)
        f[O_SX] += ex
        f[O_SY] += ey
        f[O_SQ] += ex * ex + ey * ey
        f[O_N] += 1.0
        if f[O_N] >= params[NOISE_K]:
            n = f[O_N]
            mx, my, ms = f[O_SX] / n, f[O_SY] / n, f[O_SQ] / n
            c = params[COHERENCE]
            if mx * mx + my * my < c * c * ms:
                v = 0.5 * (ms - mx * mx - my * my)
                if v > var:
                    var = v
                    params[ALPHA] = params[NOISY_ALPHA]
                    sigma = math.sqrt(var)
                    on = params[ON_K] * sigma
                    on = on if on > params[BASE_ON] else params[BASE_ON]
                    off = params[OFF_K] * sigma
                    off = off if off > params[BASE_OFF] else params[BASE_OFF]
            f[O_SX], f[O_SY], f[O_SQ], f[O_N] = 0.0, 0.0, 0.0, 0.0
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
    * **leaning** (a hand resting above ``on``: a person leaning on the handle at 10-40 N for
      20 s, which no ``settle_s`` window below ``on`` absorbs, would hold one cue active and
      blind the detector to the next push): an active cue whose ``e`` has stayed within ``off``
      of its mean for ``lean_s`` (3 s, longer than a deliberate correction is held steady),
      that mean's magnitude below ``lean_n`` (45 N: leans up to 40 N with noise to spare),
      ends there the same way, the mean added to the baseline and remembered as the lean ``L``
      (:attr:`leaned` counts them: a condition to report); a push on top of the lean, across
      it or against it is then felt as any push, in its own direction. **The hand leaving**
      is read at the settle, not at the onset: ``e`` falls to ``-L`` and stays there, so a cue
      whose settle window's mean ``m`` lies within ``max(off, |L| / 4)`` of ``-L`` is the lean
      ending: the baseline gives ``L`` back, the lean is forgotten (:attr:`left` counts it)
      and no cue is given unless the peak stood out of ``|m|`` by more than ``on``. A push
      against the lean returns to the lean and ends by the release rule, read its own way.
      (Judged at the onset, a push against the lean pointed where the hand leaving does and
      was read as the lean ending, then as a cue along the lean: 180 degrees wrong.) A
      guiding push held within ``off`` of its mean for ``lean_s`` on a base that does not
      follow (into a wall) is taken for a lean the same way;
    * **noise larger than the thresholds** (the open-noise rule): the noise level is learnt
      at rest with no cue under way, so a noise whose peaks cross ``on`` opens a cue that no
      release (below ``off`` for ``off_s``) ends and the detector never rests again. Over
      each :data:`NOISE_S` (1 s) of a cue open, the mean ``m`` and mean square ``s`` of ``e``
      tell noise from a hand: a push, a lean or a guiding hold points one way (``|m|^2 /
      s`` 0.8 to 1), white noise does not (``|m|^2 / s`` about ``tau / T``, a few hundredths);
      below :data:`NOISE_COHERENCE` squared (0.25) the per-axis variance ``(s - |m|^2) / 2``
      becomes the noise level when larger (thresholds ``on_k sigma``, ``off_k sigma``) and
      the low-pass slows to ``noisy_tau_s`` (50 ms: the filtered noise falls by half, at
      some latency, and stays so: the same device). The cue then ends below the new ``off``
      and is dropped, not given, its peak being under the new ``on`` (:attr:`dropped`).
      Pushes under 1 s never reach the rule and the realistic sensor's noise never fires it;
    * **a bound on a cue's time open** (:data:`OPEN_MAX_S`, 12 s, both detectors): a cue no
      rule has ended by then (a steady force above ``lean_n``) is released, not given, and
      counted (:attr:`released`);
    * the impulse sums ``e`` only while ``|e| > off``, so the release tail (pure noise) does
      not turn the cue's direction.

    :meth:`update` takes ``at_rest`` (from the estimator) besides the force sample.
    """

    filtered = True

    def __init__(self, dt: float, *, tau_s: float = 0.015, on_n: float = DETECTOR["on_n"],
                 on_s: float = DETECTOR["on_s"], off_n: float = DETECTOR["off_n"],
                 off_s: float = DETECTOR["off_s"], on_k: float = 6.0, off_k: float = 3.0,
                 floor_tau_s: float = 2.0, split: bool = False, turn_deg: float = 45.0,
                 baseline_tau_s: float = 1.0, hold_s: float = 0.15, settle_s: float = 0.5,
                 lean_s: float = 3.0, lean_n: float = 45.0, open_max_s: float = OPEN_MAX_S,
                 noisy_tau_s: float = 0.05):
        #: the calibration's scalars (slots ``D_*``: :attr:`var`, :attr:`on_n`, :attr:`off_n`)
        self.rec = np.zeros(N_DREC)
        for name, v in (("tau_s", tau_s), ("floor_tau_s", floor_tau_s),
                        ("baseline_tau_s", baseline_tau_s), ("hold_s", hold_s),
                        ("settle_s", settle_s), ("lean_s", lean_s), ("lean_n", lean_n),
                        ("noisy_tau_s", noisy_tau_s)):
            if not (math.isfinite(v) and v >= 0) or (name == "settle_s" and v <= on_s):
                raise ConfigError(f"detector {name} must be a finite number >= 0"
                                  f"{' and > on_s' if name == 'settle_s' else ''}, got {v}")
        self.tau_s, self.on_k, self.off_k, self.floor_tau_s = tau_s, on_k, off_k, floor_tau_s
        self.base_on_n, self.base_off_n = on_n, off_n
        self.baseline_tau_s, self.hold_s, self.settle_s = baseline_tau_s, hold_s, settle_s
        self.lean_s, self.lean_n = max(lean_s, settle_s), lean_n
        self._alpha = dt / (tau_s + dt)
        self._beta = dt / (floor_tau_s + dt)
        self._gamma = dt / (baseline_tau_s + dt)
        #: ``hold_s`` in samples (:func:`filter_step`'s ``hold_n``)
        self.hold_n = int(round(hold_s / dt))
        #: :func:`filter_step`'s constants (its ``params``)
        self.params = np.array([self._alpha, self._beta, self._gamma, on_k, off_k, on_n, off_n,
                                max(1.0, round(NOISE_S / dt)), NOISE_COHERENCE,
                                dt / (max(noisy_tau_s, tau_s) + dt)])
        self.var = 0.0
        self.baseline = np.zeros(2)  # N, world x-y
        super().__init__(dt, on_n, on_s, off_n, off_s, split, turn_deg, open_max_s)

    #: the per-axis variance of the filtered force at rest (N^2) and the thresholds it sets
    #: (N), in :attr:`rec`
    var = Slot(D_VAR)
    on_n = Slot(D_ON)
    off_n = Slot(D_OFF)

    #: the compiled move runs this detector's step (the low-pass and calibration,
    #: :func:`filter_step`, and :func:`decide_step`; :mod:`.kernel_parts`)
    KERNEL_RUNS = True

    def kernel_ready(self) -> bool:
        """Every step (a cue under way runs in the kernel only through a push phase:
        :meth:`.coasting.Coaster.ready`)."""
        return True

    def reset(self) -> None:
        """Forget any cue in progress, the filter's state, the baseline and the lean (the
        noise level and the counters stay)."""
        self.rule[[R_SETTLE_S, R_LEAN_S, R_LEAN_N]] = self.settle_s, self.lean_s, self.lean_n
        clear_state(self.st)
        self.st[LEAN_X], self.st[LEAN_Y] = 0.0, 0.0
        self.f = np.zeros(N_F)
        self.baseline = np.zeros(2)
        # the calibration queue: a ring of (fx, fy) rows and its (head, length)
        self._ring = np.zeros((self.hold_n + 4, 2))
        self._queue = np.zeros(2, dtype=np.int64)

    def step_arrays(self) -> tuple:
        """The detector's arrays as the compiled move (:mod:`.coasting`) takes them:
        :func:`filter_step`'s (the low-pass, baseline, calibration ring and queue, constants),
        then :func:`decide_step`'s (state, rule, scratch) and the record :attr:`rec`; the
        same arrays :meth:`update` passes."""
        return (self.f, self.baseline, self._ring, self._queue, self.params, self.st,
                self.rule, self._buf, self.rec)

    @property
    def leaned(self) -> int:
        """Resting hands above ``on`` taken into the baseline (class docstring)."""
        return int(self.st[LEANED])

    @property
    def lean(self) -> np.ndarray:
        """The resting hand in the baseline (N; zero: none; a new array)."""
        return self.st[LEAN_X:LEAN_Y + 1].copy()

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
            self.on_n, self.off_n, self.params, self.hold_n)
        if quiet:
            return None
        return self._decide(ex, ey)

    def _decide(self, ex: float, ey: float) -> Cue | None:
        """The rest of :meth:`update` for ``e = (ex, ey)`` once the idle test did not
        answer (:func:`decide_step`): the onset rule, or the settle rule and the hysteresis
        of an active cue."""
        if decide_step(ex, ey, self.st, self.baseline, self._queue, self.on_n, self.off_n,
                       self.rule, self._buf):
            return self.given_cue()
        return None
