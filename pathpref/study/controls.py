"""The one code path of a participant's input, whatever the front end.

A front end sends small JSON messages; :meth:`Controls.handle` checks each one and turns it
into the force on the robot's handle (a :class:`~.session.PushSource`) or a request:

* ``{"type": "push", "fx": 12.5, "fy": -3.0}``: push with this force (N, world x-y) until the
  next message; its magnitude is capped at :data:`MAX_FORCE_N` (60 N, twice the simulated
  human's 30 N peak, within the 50-100 N that people exert on a handle in pHRI studies);
* ``{"type": "release"}``: stop pushing;
* ``{"type": "start"}``: the participant is ready for the next trial.

The browser page sends these over its WebSocket, a scripted participant
(:mod:`.script`) calls :meth:`Controls.handle` with the same text. A malformed message
(not JSON, not an object, unknown type, non-finite or missing numbers) or one longer than
:data:`MAX_MESSAGE_BYTES` is logged in one line and ignored; the session goes on.
"""

from __future__ import annotations

import json
import logging
import math
import threading
import time

import numpy as np

MAX_FORCE_N = 60.0
MAX_MESSAGE_BYTES = 256

log = logging.getLogger("pathpref.study")


class Controls:
    """The participant's current push and requests (thread-safe: the web server's thread
    writes, the physics loop reads)."""

    def __init__(self):
        self._lock = threading.Lock()
        self._force = np.zeros(2)
        self.started = threading.Event()
        self.ignored = 0
        #: wall time (perf_counter) of the last message that ended a push (release)
        self.released_at: float | None = None

    def force(self) -> np.ndarray:
        """The force (N, world x-y) the participant applies now."""
        with self._lock:
            return self._force.copy()

    def _ignore(self, why: str) -> None:
        self.ignored += 1
        log.warning("ignored a front-end message: %s", why)

    def handle(self, text: str | bytes) -> bool:
        """Apply one message (module docstring); False when it was ignored."""
        if len(text) > MAX_MESSAGE_BYTES:
            self._ignore(f"{len(text)} bytes, more than {MAX_MESSAGE_BYTES}")
            return False
        try:
            msg = json.loads(text)
        except (ValueError, UnicodeDecodeError):
            self._ignore("not JSON")
            return False
        if not isinstance(msg, dict):
            self._ignore("not a JSON object")
            return False
        kind = msg.get("type")
        if kind == "push":
            fx, fy = msg.get("fx"), msg.get("fy")
            if not all(isinstance(v, int | float) and not isinstance(v, bool)
                       and math.isfinite(v) for v in (fx, fy)):
                self._ignore("push needs finite numbers fx and fy (N)")
                return False
            f = np.array([fx, fy], float)
            n = float(np.hypot(*f))
            if n > MAX_FORCE_N:
                f *= MAX_FORCE_N / n
            with self._lock:
                self._force = f
        elif kind == "release":
            with self._lock:
                self._force = np.zeros(2)
                self.released_at = time.perf_counter()
        elif kind == "start":
            self.started.set()
        else:
            self._ignore(f"unknown type {str(kind)[:20]!r} (push, release, start)")
            return False
        return True

    def reset(self) -> None:
        """Between trials: no push, not started."""
        with self._lock:
            self._force = np.zeros(2)
        self.started.clear()
