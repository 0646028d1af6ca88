"""The one code path of a participant's input, whatever the front end.

A front end sends small JSON messages; :meth:`Controls.handle` checks each one and turns it
into the force on the robot's handle (a :class:`~.session.PushSource`) or a request:

* ``{"type": "push", "fx": 12.5, "fy": -3.0}``: push with this force (N, world x-y) until the
  next message; its magnitude is capped at :data:`MAX_FORCE_N` (60 N, twice the simulated
  human's 30 N peak, within the 50-100 N that people exert on a handle in pHRI studies);
* ``{"type": "release"}``: stop pushing;
* ``{"type": "start"}``: the participant is ready for the next trial;
* ``{"type": "alive"}``: nothing but a sign of life (the browser page sends one every 0.25 s);
* ``{"type": "calibrate", "rest": [x, y], "reach": r, "device": "..."}``: the participant's
  gamepad calibration (:class:`StickCalibration`), recorded by the session;
* ``{"type": "stick", "ax": x, "ay": y}``: the gamepad's stick axes (the browser's Gamepad API:
  in ``[-1, 1]``, ``ay`` positive *down*), turned into a force by the calibrated rule
  (:func:`stick_force`); refused before a calibration;
* ``{"type": "tlx", "trial": k, "scores": {"mental": 55, ...}}``: the NASA-TLX answers after
  trial ``k``: the six scales of :data:`TLX_SCALES`, whole numbers 0..100 (raw, unweighted
  TLX). **Only the trial just ended, once**: an answer counts only while the front end asks
  it (:meth:`Controls.ask_tlx`, after trial ``k`` ended, until the next trial begins) and only
  for that ``k``; the first valid one closes the question. An answer before or during a
  trial, for another trial, or a second one is ignored (it can neither replace the real
  answer nor skip a questionnaire).

**The stick rule.** With the calibration's rest position ``(rx, ry)`` and reach ``r`` (the
largest deflection the participant reached from rest), the deflection is
``v = ((ax - rx) / r, -(ay - ry) / r)`` (north up), and the force is
``F = MAX_FORCE_N * g(|v|) * v / |v|`` with ``g(m) = clip((m - STICK_DEADZONE) /
(1 - STICK_DEADZONE), 0, 1)``: nothing inside the dead zone (15% of the reach: a stick at rest
never pushes), linear to 60 N at full reach. A stick message inside the dead zone is a release.

**Dead-man rule** (``deadman_s``, the browser's :data:`DEADMAN_S` = 0.5 s): a push lasts only
while its messages keep coming. A push message older than ``deadman_s`` (by ``clock``) no
longer acts: :meth:`Controls.force` is zero from then on, as if ``release`` had come, so a
page that freezes or drops mid-drag ends its push within ``deadman_s``. The page repeats its
push every 0.1 s while the pointer is down. A scripted participant (simulated time, no wall
clock) has no dead man: ``deadman_s=None``.

The browser page sends these over its WebSocket, a scripted participant
(:mod:`.script`) calls :meth:`Controls.handle` with the same text. A malformed message
(not JSON, not an object, unknown type, non-finite or missing numbers) or one longer than
:data:`MAX_MESSAGE_BYTES` is ignored and the session goes on. Logging is rate-limited: the
first :data:`LOG_FIRST` ignored messages get a line each, then at most one line per
:data:`LOG_EVERY_S` seconds (by ``clock``) saying how many were ignored since the last line.
"""

from __future__ import annotations

import json
import logging
import math
import threading
import time
from dataclasses import dataclass

import numpy as np

MAX_FORCE_N = 60.0
MAX_MESSAGE_BYTES = 256
#: the browser's dead-man time (s): a push whose messages stop for this long ends
DEADMAN_S = 0.5
#: ignored messages logged one line each; after that one line per LOG_EVERY_S seconds
LOG_FIRST = 5
LOG_EVERY_S = 10.0
#: the NASA-TLX's six scales (Hart & Staveland 1988), each answered 0..100
TLX_SCALES = ("mental", "physical", "temporal", "performance", "effort", "frustration")
#: the stick's dead zone, a share of the calibrated reach (:func:`stick_force`)
STICK_DEADZONE = 0.15
#: a calibration's reach must lie in this range (axes span [-1, 1]; a reach under 0.2 means
#: the participant did not move the stick)
REACH_RANGE = (0.2, 1.5)

log = logging.getLogger("pathpref.study")


def finite_number(v) -> bool:
    """A JSON number that is a finite float (a 400-digit integer is not: it overflows)."""
    if not isinstance(v, int | float) or isinstance(v, bool):
        return False
    try:
        return math.isfinite(float(v))
    except OverflowError:
        return False


@dataclass(frozen=True)
class StickCalibration:
    """A participant's gamepad calibration: the stick's rest position (axes units) and the
    largest deflection from it the participant reached (module docstring)."""

    rest: tuple[float, float]
    reach: float
    device: str = ""

    @classmethod
    def parse(cls, msg: dict) -> StickCalibration | str:
        """The calibration of a ``calibrate`` message, or why it is refused."""
        rest, reach, device = msg.get("rest"), msg.get("reach"), msg.get("device", "")
        if (not isinstance(rest, list) or len(rest) != 2
                or not all(finite_number(v) and -1.0 <= v <= 1.0 for v in rest)):
            return "calibrate needs rest [x, y] within [-1, 1]"
        if not finite_number(reach) or not REACH_RANGE[0] <= reach <= REACH_RANGE[1]:
            return f"calibrate needs reach in {REACH_RANGE[0]}..{REACH_RANGE[1]}"
        if not isinstance(device, str):
            return "calibrate's device must be a string"
        return cls((float(rest[0]), float(rest[1])), float(reach), device[:80])


def stick_force(ax: float, ay: float, cal: StickCalibration) -> np.ndarray:
    """The force (N, world x-y) of stick axes ``(ax, ay)`` under ``cal`` (module docstring)."""
    v = np.array([(ax - cal.rest[0]) / cal.reach, -(ay - cal.rest[1]) / cal.reach])
    m = float(np.hypot(*v))
    g = min(1.0, max(0.0, (m - STICK_DEADZONE) / (1.0 - STICK_DEADZONE)))
    return np.zeros(2) if g == 0.0 else MAX_FORCE_N * g * v / m


def stick_axes(f: np.ndarray, cal: StickCalibration) -> tuple[float, float]:
    """Stick axes that give the force ``f`` (|f| < MAX_FORCE_N) under ``cal``: the inverse of
    :func:`stick_force` (a simulated gamepad)."""
    n = float(np.hypot(*f))
    if n == 0.0:
        return cal.rest
    m = STICK_DEADZONE + (1.0 - STICK_DEADZONE) * min(1.0, n / MAX_FORCE_N)
    ux, uy = f[0] / n, f[1] / n
    return (cal.rest[0] + m * cal.reach * ux, cal.rest[1] - m * cal.reach * uy)


class Controls:
    """The participant's current push and requests (thread-safe: the web server's thread
    writes, the physics loop reads)."""

    def __init__(self, deadman_s: float | None = None, clock=time.monotonic):
        self._lock = threading.Lock()
        self._force = np.zeros(2)
        self.started = threading.Event()
        self.ignored = 0
        self.deadman_s, self.clock = deadman_s, clock
        self._pushed_at = 0.0
        #: pushes ended by the dead-man rule (their page stopped sending)
        self.deadman_releases = 0
        self._logged = 0
        self._log_at: float | None = None
        self._unlogged = 0
        #: wall time (perf_counter) of the last message that ended a push (release)
        self.released_at: float | None = None
        self.calibration: StickCalibration | None = None
        #: questionnaire answers by trial position; hooks told of each (the session records)
        self.tlx: dict[int, dict[str, int]] = {}
        #: the trial whose questionnaire is asked now (None: no answer is accepted)
        self.asking: int | None = None
        self.on_tlx: list = []
        #: told of every accepted calibration (the session records it)
        self.on_calibration: list = []

    def force(self) -> np.ndarray:
        """The force (N, world x-y) the participant applies now (zero once the push's
        messages are older than ``deadman_s``: module docstring)."""
        with self._lock:
            if (self.deadman_s is not None and self._force.any()
                    and self.clock() - self._pushed_at > self.deadman_s):
                self._force = np.zeros(2)
                self.deadman_releases += 1
                self.released_at = time.perf_counter()
            return self._force.copy()

    def release(self) -> None:
        """End the push now (the page that pushed went away)."""
        with self._lock:
            if self._force.any():
                self.released_at = time.perf_counter()
            self._force = np.zeros(2)

    def _ignore(self, why: str) -> None:
        """Count an ignored message; log it within the rate limit (module docstring)."""
        self.ignored += 1
        now = self.clock()
        if self._logged < LOG_FIRST:
            self._logged += 1
            self._log_at = now
            log.warning("ignored a front-end message: %s", why)
        elif now - self._log_at >= LOG_EVERY_S:
            log.warning("ignored %d more front-end messages, the last: %s",
                        self._unlogged + 1, why)
            self._unlogged, self._log_at = 0, now
        else:
            self._unlogged += 1

    def handle(self, text: str | bytes) -> bool:
        """Apply one message (module docstring); False when it was ignored."""
        if len(text) > MAX_MESSAGE_BYTES:
            self._ignore(f"{len(text)} bytes, more than {MAX_MESSAGE_BYTES}")
            return False
        try:
            msg = json.loads(text)
        except (ValueError, UnicodeDecodeError, RecursionError):
            self._ignore("not JSON")
            return False
        if not isinstance(msg, dict):
            self._ignore("not a JSON object")
            return False
        kind = msg.get("type")
        if kind == "push":
            fx, fy = msg.get("fx"), msg.get("fy")
            if not all(finite_number(v) for v in (fx, fy)):
                self._ignore("push needs finite numbers fx and fy (N)")
                return False
            f = np.array([float(fx), float(fy)], float)
            n = float(np.hypot(*f))
            if n > MAX_FORCE_N:
                f *= MAX_FORCE_N / n
            with self._lock:
                self._force = f
                self._pushed_at = self.clock()
        elif kind == "release":
            with self._lock:
                self._force = np.zeros(2)
                self.released_at = time.perf_counter()
        elif kind == "start":
            self.started.set()
        elif kind == "calibrate":
            cal = StickCalibration.parse(msg)
            if isinstance(cal, str):
                self._ignore(cal)
                return False
            self.calibration = cal
            for hook in self.on_calibration:
                hook(cal)
        elif kind == "tlx":
            k, scores = msg.get("trial"), msg.get("scores")
            if (not isinstance(k, int) or isinstance(k, bool) or not 1 <= k <= 100_000
                    or not isinstance(scores, dict) or set(scores) != set(TLX_SCALES)
                    or not all(isinstance(v, int) and not isinstance(v, bool) and 0 <= v <= 100
                               for v in scores.values())):
                self._ignore("tlx needs trial k and scores " + ", ".join(TLX_SCALES)
                             + " (whole numbers 0..100)")
                return False
            with self._lock:
                asked = self.asking == k and k not in self.tlx
                if asked:
                    self.asking = None
                    self.tlx[k] = {n: scores[n] for n in TLX_SCALES}
            if not asked:
                self._ignore(f"tlx for trial {k}, but " + (
                    "no questionnaire is asked now" if self.asking is None
                    else f"the questionnaire asks about trial {self.asking}"))
                return False
            for hook in self.on_tlx:
                hook(k, self.tlx[k])
        elif kind == "stick":
            ax, ay = msg.get("ax"), msg.get("ay")
            if self.calibration is None:
                self._ignore("stick before a calibration")
                return False
            if not all(finite_number(v) and -1.5 <= v <= 1.5 for v in (ax, ay)):
                self._ignore("stick needs numbers ax and ay in [-1, 1]")
                return False
            f = stick_force(float(ax), float(ay), self.calibration)
            with self._lock:
                if not f.any() and self._force.any():
                    self.released_at = time.perf_counter()
                self._force = f
                self._pushed_at = self.clock()
        elif kind != "alive":
            self._ignore(f"unknown type {str(kind)[:20]!r} (push, release, start, alive, "
                         "calibrate, stick, tlx)")
            return False
        return True

    def ask_tlx(self, k: int) -> None:
        """Accept the questionnaire's answer about trial ``k`` (it just ended), once."""
        with self._lock:
            self.asking = int(k)

    def reset(self) -> None:
        """Between trials: no push, not started, no questionnaire asked."""
        with self._lock:
            self._force = np.zeros(2)
            self.asking = None
        self.started.clear()
