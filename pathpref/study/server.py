"""The browser front end: one page (plain HTML + canvas + JavaScript, no build step) and a
WebSocket, served by the ``websockets`` library on one port.

``websockets`` is already installed with pathpref (rerun-sdk depends on it), is maintained and
standards-complete (RFC 6455, limits on message size, ping/pong), and its ``process_request``
hook serves the page and refuses requests (HTTP 403) on the same port, so no web framework is
needed. The server runs in its own thread with its own asyncio loop; the physics loop (main
thread) publishes the state, and the driving page's messages go to
:class:`~.controls.Controls` (the one code path of every front end).

**Locked down** (every rule is a test in ``tests/test_study_server.py``):

* *Secret*: every session draws a random token (128 bits, ``secrets.token_urlsafe(16)``); the
  URL printed for the experimenter carries it (``?token=...``) and every request, the page and
  the WebSocket, must carry it too (compared in constant time, ``hmac.compare_digest``), on
  127.0.0.1 as on any other ``--host``. A page of an earlier session (another participant)
  holds an old token and is refused with HTTP 403.
* *No icon*: ``/favicon.ico``, which a browser asks for on its own (without the token), is
  answered ``204 No Content`` (nothing served, nothing counted as refused); the page also
  declares an empty icon (``<link rel="icon" href="data:,">``), so browsers that honour it do
  not ask at all.
* *Origin and Host*: a WebSocket handshake must carry an ``Origin`` equal to the page's own
  (``http://`` + its ``Host`` header), so another site's page cannot connect even when it
  knows the token; bound to loopback, the ``Host`` must name a loopback address (no DNS
  rebinding).
* *One driver*: the first page to connect while nobody drives is the session's *driver* (its
  push, release and start messages act); every other page with the token is a read-only
  *observer* (its messages are dropped; it sees the belief and the planned path, always, and
  the trial). When the driver disconnects its push ends at once and the next page to connect
  drives.
* *Dead man*: a push ends :data:`~.controls.DEADMAN_S` (0.5 s) after its page's last push
  message (the page repeats it every 0.1 s while the pointer is down).
* *Pause*: during a trial the physics waits (the robot holds still, nothing is recorded) while
  no driver is *present*: connected and heard from (any message; the page sends ``alive``
  every 0.25 s) within :data:`PRESENT_S`. A pause longer than ``pause_limit_s`` (default
  :data:`PAUSE_LIMIT_S`) ends the session with one line; the trial stays unfinished, and
  ``--resume`` runs it again. Waiting for Start is bounded too (``start_limit_s``, default
  :data:`START_LIMIT_S`, an hour): then the session ends the same way, before the trial
  begins.
* *Questionnaire*: with the study's ``questionnaire`` the page asks it after every trial and
  the next trial (or the session's end) waits for the answer, bounded like Start.
* *Bounded connections, nobody locked out*: at most :data:`MAX_CONNECTIONS` TCP connections
  at a time, and a connection that has not finished its HTTP request or WebSocket handshake
  within :data:`OPEN_TIMEOUT_S` is closed. A connection is *unproven* until its request has
  passed the checks above (token, Host, Origin); one accepted over the cap closes the
  *oldest unproven* connection (the newest when every other one is proven), never a proven
  one. So a local process that holds every slot with idle or tokenless sockets loses them to
  the participant's page, which sends its request at once and is proven before the holder can
  open ``MAX_CONNECTIONS`` more. Malformed messages are logged within a rate limit
  (:class:`~.controls.Controls`).

Messages to the page: ``role`` (``driver`` or ``observer``) on connection; ``scene`` (the map,
the trial: start, goal, route, candidates, whether the belief is shown, the time limit; the
status ``waiting``/``running``/``paused``/``done``/``finished``) when it changes and on
connection, and ``state`` (robot position, its grid cell ``[x, y]``, applied force, goal
probabilities and the planned path (``path``: the ``[x, y]`` cells the robot intends to visit,
from its cell, :meth:`~.session.TrialRunner.planned_path`) when the trial shows the belief (to
observers always), time, pushes, cues) at up to 30 Hz.
"""

from __future__ import annotations

import asyncio
import hmac
import json
import logging
import secrets
import socket
import threading
import time
from http import HTTPStatus
from importlib import resources
from urllib.parse import parse_qs, urlsplit

import numpy as np

from ..errors import ConfigError
from .controls import Controls
from .session import Pacer, TrialRunner

LOOPBACK = ("127.0.0.1", "localhost", "::1")
STATE_HZ = 30.0
MAX_FRAME_BYTES = 64 * 1024  # larger WebSocket frames close the connection (the page reconnects)
#: a driver heard from within this many wall seconds is present (else the trial pauses)
PRESENT_S = 2.0
#: a trial paused longer than this (s) ends the session, the trial left to run again
PAUSE_LIMIT_S = 600.0
#: a wait for Start longer than this (s) ends the session (the trial not yet begun)
START_LIMIT_S = 3600.0
#: TCP connections served at a time; the page and a few observers need far fewer
MAX_CONNECTIONS = 16
#: seconds a connection may take to send its HTTP request and finish the handshake
OPEN_TIMEOUT_S = 5.0

log = logging.getLogger("pathpref.study")


class PageGone(ConfigError):
    """The participant's page was gone longer than the pause limit."""


def scene_message(runner: TrialRunner, position: int, total: int, status: str,
                  outcome: dict | None = None, questionnaire: str | None = None) -> dict:
    """What the page draws that does not move: the map and the trial (``runner``'s)."""
    world, trial = runner.world, runner.trial
    spec = world.spec
    return {
        "type": "scene", "status": status,
        "map": {"name": world.name, "width": spec.width, "height": spec.height,
                "cell": runner.base.scene.cell_size,
                "obstacles": [np.asarray(o.vertices, float).tolist() for o in spec.obstacles]},
        "trial": {"position": position, "total": total, "name": trial.name,
                  "start": trial.start, "goal": trial.goal, "route": trial.route,
                  "candidates": trial.candidates, "show_belief": trial.show_belief,
                  "time_limit_s": trial.time_limit_s},
        "outcome": outcome, "questionnaire": questionnaire,
    }


class BrowserFrontEnd:
    """Serves the page on ``host:port`` (port 0: any free port) in a background thread, under
    the rules of the module docstring. ``clock`` (wall seconds) times the dead man and the
    driver's presence."""

    name = "browser"

    def __init__(self, host: str = "127.0.0.1", port: int = 8765,
                 pause_limit_s: float = PAUSE_LIMIT_S, start_limit_s: float = START_LIMIT_S,
                 max_connections: int = MAX_CONNECTIONS,
                 open_timeout_s: float = OPEN_TIMEOUT_S, clock=time.monotonic):
        from .controls import DEADMAN_S

        self.clock = clock
        self.controls = Controls(deadman_s=DEADMAN_S, clock=clock)
        self.host = host
        self.token = secrets.token_urlsafe(16)
        self.page = resources.files("pathpref.study").joinpath("page.html").read_bytes()
        self.pause_limit_s, self.start_limit_s = float(pause_limit_s), float(start_limit_s)
        self.max_connections, self.open_timeout_s = int(max_connections), float(open_timeout_s)
        self._lock = threading.Lock()
        self._scene: dict | None = None
        self._state: tuple[str, str] | None = None  # (driver's JSON, observers' JSON)
        self._state_seq = 0
        self.latencies_ms: list[float] = []
        self.runner: TrialRunner | None = None
        self.position = self.total = self._k = 0
        self.last_outcome: dict | None = None
        self.clients: set = set()
        self.driver = None
        self._driver_seen = 0.0
        self.open_connections = self.refused_connections = self.refused_requests = 0
        #: connections whose request has not passed the checks yet, oldest first
        self._unproven: dict = {}
        #: (trial position, wall seconds) of every pause of a trial
        self.pauses: list[tuple[int, float]] = []
        self._status = "waiting"
        #: the questionnaire asked after every trial (the session sets it from the study)
        self.questionnaire: str | None = None
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self.loop = asyncio.new_event_loop()
        self.thread = threading.Thread(target=self._serve, args=(port,), daemon=True,
                                       name="pathpref-study-server")
        self.thread.start()
        self._ready.wait(10)
        if self._error is not None:
            raise ConfigError(f"cannot serve on {host}:{port}: {self._error}")

    # --- server thread ---------------------------------------------------------------------
    @property
    def url(self) -> str:
        """The address to open, with the session's token."""
        host = self.host if self.host not in ("0.0.0.0", "::") else socket.gethostname()
        if ":" in host:
            host = f"[{host}]"
        return f"http://{host}:{self.port}/?token={self.token}"

    def _allowed(self, path: str) -> bool:
        """The request carries the session's token (constant-time comparison)."""
        got = parse_qs(urlsplit(path).query).get("token", [""])[0]
        return hmac.compare_digest(got.encode(), self.token.encode())

    def _host_ok(self, host: str | None) -> bool:
        """Bound to loopback, the ``Host`` header names a loopback address (DNS rebinding)."""
        if self.host not in LOOPBACK:
            return True
        if not host:
            return False
        name = host.rsplit(":", 1)[0] if not host.startswith("[") else host[1:].split("]")[0]
        return name in LOOPBACK

    def _refused(self, why: str) -> None:
        """Count a refused request; log the 1st, 10th, 100th, ... (a stale page retries)."""
        self.refused_requests += 1
        if str(self.refused_requests).strip("0") == "1":
            log.warning("refused request %d: %s", self.refused_requests, why)

    def _process_request(self, connection, request):
        path = urlsplit(request.path).path
        if path == "/favicon.ico":  # a browser's own request, never with the token: no icon,
            return connection.respond(HTTPStatus.NO_CONTENT, "")  # nothing refused or logged
        if not self._allowed(request.path):
            self._refused("without the session's token")
            return connection.respond(HTTPStatus.FORBIDDEN, "a valid ?token= is required\n")
        hosts = request.headers.get_all("Host")
        host = hosts[0] if len(hosts) == 1 else None
        if not self._host_ok(host):
            self._refused(f"for host {str(host)[:60]}")
            return connection.respond(HTTPStatus.FORBIDDEN, "wrong Host\n")
        if path == "/ws":
            origins = request.headers.get_all("Origin")
            origin = origins[0] if len(origins) == 1 else None
            if host is None or origin != f"http://{host}":
                self._refused(f"from origin {str(origin)[:60]}")
                return connection.respond(HTTPStatus.FORBIDDEN, "wrong Origin\n")
            self._unproven.pop(connection, None)  # the session's page: never evicted
            return None  # the WebSocket handshake goes on
        if path in ("/", "/index.html"):
            self._unproven.pop(connection, None)
            from websockets.datastructures import Headers
            from websockets.http11 import Response

            return Response(200, "OK", Headers([
                ("Content-Type", "text/html; charset=utf-8"),
                ("Content-Length", str(len(self.page))), ("Cache-Control", "no-store"),
                ("Referrer-Policy", "no-referrer"), ("X-Frame-Options", "DENY"),
                ("Connection", "close")]), self.page)
        return connection.respond(HTTPStatus.NOT_FOUND, "not found\n")

    def driver_present(self) -> bool:
        """A driving page is connected and was heard from within :data:`PRESENT_S`."""
        with self._lock:
            return self.driver is not None and self.clock() - self._driver_seen < PRESENT_S

    async def _handler(self, ws) -> None:
        with self._lock:
            driving = self.driver is None
            if driving:
                self.driver, self._driver_seen = ws, self.clock()
            scene = self._scene
        self.clients.add(ws)
        try:
            await ws.send(json.dumps({"type": "role",
                                      "role": "driver" if driving else "observer"}))
            if scene is not None:
                await ws.send(json.dumps(scene))
            async for message in ws:
                if ws is not self.driver:
                    continue  # an observer only watches
                with self._lock:
                    self._driver_seen = self.clock()
                self.controls.handle(message)
        except Exception as e:  # noqa: BLE001 - a broken connection ends only itself
            log.info("a page disconnected: %s", e)
        finally:
            self.clients.discard(ws)
            with self._lock:
                was_driver = self.driver is ws
                if was_driver:
                    self.driver = None
            if was_driver:  # the driving page went away mid-drag: its push ends now
                self.controls.release()

    async def _broadcast(self) -> None:
        sent_scene, sent_state = None, -1
        while True:
            await asyncio.sleep(1.0 / STATE_HZ)
            with self._lock:
                scene, state, seq, driver = self._scene, self._state, self._state_seq, self.driver
            common = []
            if scene is not None and scene is not sent_scene:
                common.append(json.dumps(scene))
                sent_scene = scene
            new_state = state is not None and seq != sent_state
            sent_state = seq
            for ws in list(self.clients):
                out = common + ([state[0] if ws is driver else state[1]] if new_state else [])
                for m in out:
                    try:
                        await ws.send(m)
                    except Exception:  # noqa: BLE001 - a closed page is dropped
                        self.clients.discard(ws)

    def _connection_class(self):
        """The server's connections, capped at ``max_connections`` open at a time; over the
        cap the oldest unproven connection is closed (module docstring). Runs on the server's
        loop only (``_unproven`` is an insertion-ordered dict used as a queue)."""
        from websockets.asyncio.server import ServerConnection

        front = self

        class Capped(ServerConnection):
            def connection_made(self, transport) -> None:
                super().connection_made(transport)
                self._evicted = False
                front.open_connections += 1
                front._unproven[self] = None
                if front.open_connections > front.max_connections:
                    victim = next(iter(front._unproven))  # the oldest unproven (maybe self)
                    del front._unproven[victim]
                    victim._evicted = True
                    front.open_connections -= 1
                    front.refused_connections += 1
                    if str(front.refused_connections).strip("0") == "1":
                        log.warning("closed %d unproven connection(s) over the cap of %d",
                                    front.refused_connections, front.max_connections)
                    victim.transport.abort()

            def connection_lost(self, exc) -> None:
                front._unproven.pop(self, None)
                if not self._evicted:
                    front.open_connections -= 1
                super().connection_lost(exc)

        return Capped

    def _serve(self, port: int) -> None:
        from websockets.asyncio.server import serve

        async def main() -> None:
            try:
                server = await serve(self._handler, self.host, port,
                                     process_request=self._process_request,
                                     max_size=MAX_FRAME_BYTES,
                                     open_timeout=self.open_timeout_s,
                                     create_connection=self._connection_class())
            except OSError as e:
                self._error = e
                self._ready.set()
                return
            self.port = server.sockets[0].getsockname()[1]
            self._stop = asyncio.Event()
            self._ready.set()
            task = asyncio.create_task(self._broadcast())
            await self._stop.wait()
            task.cancel()
            server.close()
            await server.wait_closed()

        asyncio.set_event_loop(self.loop)
        self.loop.run_until_complete(main())
        self.loop.close()

    # --- physics thread --------------------------------------------------------------------
    def source(self) -> Controls:
        """The participant's push source: the controls the driving page's messages write to."""
        return self.controls

    def _set_scene(self, status: str, outcome: dict | None = None) -> None:
        scene = scene_message(self.runner, self.position, self.total, status, outcome,
                              self.questionnaire if status in ("done", "finished") else None)
        with self._lock:
            self._scene, self._status = scene, status

    def publish(self, base=None, push=None) -> None:
        """The live state for the pages (a physics-step hook; every 10th step: 50 Hz)."""
        r = self.runner
        self._k += 1
        if r is None or (base is not None and self._k % 10):
            return
        p = [round(float(v), 4) for v in r.policy.belief.goal_marginal()]
        state = {"type": "state", "t": round(r.time_s, 3),
                 "xy": [round(float(v), 4) for v in r.base.position],
                 "force": [round(float(v), 2) for v in r.body.applied],
                 "cell": r.world.cells[r.cell].tolist(),
                 "probs": p, "path": r.world.cells[r.planned_path()].tolist(),
                 "cues": len(r.cues), "step": r.t}
        observer = json.dumps(state)
        driver = observer if r.trial.show_belief else json.dumps(
            state | {"probs": None, "path": None})
        with self._lock:
            self._state = (driver, observer)
            self._state_seq += 1

    def _hold(self, base=None, push=None) -> None:
        """A physics-step hook: while no driver is present the trial pauses (module
        docstring); a pause over ``pause_limit_s`` raises :class:`PageGone`."""
        if self.driver_present():
            return
        self.controls.release()
        self._set_scene("paused")
        log.warning("trial %d paused: the participant's page is gone", self.position)
        waited = self._await(
            self.driver_present, self.pause_limit_s,
            f"the participant's page was gone for over {self.pause_limit_s:g} s in trial "
            f"{self.position}; it is left unfinished: run the same command with --resume to "
            "run it again")
        self.pauses.append((self.position, waited))
        self._set_scene("running")

    def _await(self, ready, limit_s: float, message: str, poll_s: float = 0.05) -> float:
        """Wait until ``ready()`` is true (``ready`` may block up to its own timeout; else a
        sleep of ``poll_s`` between calls) and return the seconds waited; past ``limit_s``
        raise :class:`PageGone` with ``message``: every wait of a session is bounded."""
        t0 = self.clock()
        while not ready():
            if self.clock() - t0 > limit_s:
                raise PageGone(message)
            if poll_s:
                time.sleep(poll_s)
        return self.clock() - t0

    def _latency(self, cue) -> None:
        t = self.controls.released_at
        if t is not None:
            self.latencies_ms.append((time.perf_counter() - t) * 1000.0)
            self.controls.released_at = None

    def begin_trial(self, position: int, total: int, runner: TrialRunner) -> None:
        """Show the trial and wait for the driver's Start; then run in real time, paused
        while the driver is gone."""
        self.controls.reset()
        self.runner, self.position, self.total = runner, position, total
        self._set_scene("waiting", self.last_outcome)
        self.publish()
        self._await(lambda: self.controls.started.wait(0.2), self.start_limit_s,
                    f"nobody pressed Start for {self.start_limit_s:g} s before trial "
                    f"{position}; run the same command with --resume to go on from it",
                    poll_s=0.0)
        self._set_scene("running")
        runner.base.on_substep.append(self._hold)
        runner.base.on_substep.append(Pacer())
        runner.base.on_substep.append(self.publish)
        runner.on_cue.append(self._latency)

    def after_decision(self, runner: TrialRunner) -> None:
        """Publish the state after the decision step (and its belief update)."""
        self.publish()

    def end_trial(self, runner: TrialRunner, outcome: dict) -> None:
        """Show the outcome until the participant starts the next trial."""
        self.publish()
        last = self.position == self.total
        self.last_outcome = {k: outcome[k] for k in ("outcome", "time_s", "pushes")}
        if self.questionnaire:  # asked before the page can see the trial ended
            self.controls.ask_tlx(self.position)
        self._set_scene("finished" if last else "done", self.last_outcome)
        if self.questionnaire:  # the answers come before the next trial (or the end)
            self._await(lambda: self.position in self.controls.tlx, self.start_limit_s,
                        f"no questionnaire answer after trial {self.position} for "
                        f"{self.start_limit_s:g} s (the trial is recorded); run the same "
                        "command with --resume to go on")

    def close(self) -> None:
        """Let the page see the last scene, then stop the server and its thread."""
        if not self.thread.is_alive():
            return
        time.sleep(2.5 / STATE_HZ)
        self.loop.call_soon_threadsafe(self._stop.set)
        self.thread.join(5)
