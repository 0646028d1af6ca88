"""The browser front end: one page (plain HTML + canvas + JavaScript, no build step) and a
WebSocket, served by the ``websockets`` library on one port.

``websockets`` is already installed with pathpref (rerun-sdk depends on it), is maintained and
standards-complete (RFC 6455, limits on message size, ping/pong), and its ``process_request``
hook serves the page and refuses requests (HTTP 403) on the same port, so no web framework is
needed. The server runs in its own thread with its own asyncio loop; the physics loop (main
thread) publishes the state, and the participant's messages go to
:class:`~.controls.Controls` (the one code path of every front end).

Security: the server binds ``127.0.0.1`` by default. Any other ``--host`` serves other machines
and then every request (the page and the WebSocket) must carry the random token printed at
start in the URL (``?token=...``); a request without it gets HTTP 403 and nothing else.

Messages to the page: ``scene`` (the map, the trial: start, goal, route, candidates, whether
the belief is shown, the time limit; the status ``waiting``/``running``/``done``/``finished``)
when it changes and on connection, and ``state`` (robot position, applied force, goal
probabilities when shown, time, pushes, cues) at up to 30 Hz.
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

log = logging.getLogger("pathpref.study")


def scene_message(runner: TrialRunner, position: int, total: int, status: str,
                  outcome: dict | None = None) -> dict:
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
        "outcome": outcome,
    }


class BrowserFrontEnd:
    """Serves the page on ``host:port`` (port 0: any free port) in a background thread."""

    name = "browser"

    def __init__(self, host: str = "127.0.0.1", port: int = 8765):
        self.controls = Controls()
        self.host = host
        self.token = None if host in LOOPBACK else secrets.token_urlsafe(16)
        self.page = resources.files("pathpref.study").joinpath("page.html").read_bytes()
        self._lock = threading.Lock()
        self._scene: dict | None = None
        self._state: dict | None = None
        self._state_seq = 0
        self.latencies_ms: list[float] = []
        self.runner: TrialRunner | None = None
        self.position = self.total = self._k = 0
        self.last_outcome: dict | None = None
        self.clients: set = set()
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
        """The address to open (with the token when serving other machines)."""
        host = self.host if self.host not in ("0.0.0.0", "::") else socket.gethostname()
        return f"http://{host}:{self.port}/" + (f"?token={self.token}" if self.token else "")

    def _allowed(self, path: str) -> bool:
        if self.token is None:
            return True
        got = parse_qs(urlsplit(path).query).get("token", [""])[0]
        return hmac.compare_digest(got.encode(), self.token.encode())

    def _process_request(self, connection, request):
        path = urlsplit(request.path).path
        if not self._allowed(request.path):
            log.warning("refused a request without the token: %s", path[:60])
            return connection.respond(HTTPStatus.FORBIDDEN, "a valid ?token= is required\n")
        if path == "/ws":
            return None  # the WebSocket handshake goes on
        if path in ("/", "/index.html"):
            from websockets.datastructures import Headers
            from websockets.http11 import Response

            return Response(200, "OK", Headers([
                ("Content-Type", "text/html; charset=utf-8"),
                ("Content-Length", str(len(self.page))), ("Cache-Control", "no-store"),
                ("Connection", "close")]), self.page)
        return connection.respond(HTTPStatus.NOT_FOUND, "not found\n")

    async def _handler(self, ws) -> None:
        self.clients.add(ws)
        try:
            with self._lock:
                scene = self._scene
            if scene is not None:
                await ws.send(json.dumps(scene))
            async for message in ws:
                self.controls.handle(message)
        except Exception as e:  # noqa: BLE001 - a broken connection ends only itself
            log.info("a page disconnected: %s", e)
        finally:
            self.clients.discard(ws)
            if not self.clients:  # the last page went away mid-drag: nobody pushes now
                self.controls.handle('{"type": "release"}')

    async def _broadcast(self) -> None:
        sent_scene, sent_state = None, -1
        while True:
            await asyncio.sleep(1.0 / STATE_HZ)
            with self._lock:
                scene, state, seq = self._scene, self._state, self._state_seq
            out = []
            if scene is not None and scene is not sent_scene:
                out.append(json.dumps(scene))
                sent_scene = scene
            if state is not None and seq != sent_state:
                out.append(json.dumps(state))
                sent_state = seq
            for ws in list(self.clients):
                for m in out:
                    try:
                        await ws.send(m)
                    except Exception:  # noqa: BLE001 - a closed page is dropped
                        self.clients.discard(ws)

    def _serve(self, port: int) -> None:
        from websockets.asyncio.server import serve

        async def main() -> None:
            try:
                server = await serve(self._handler, self.host, port,
                                     process_request=self._process_request,
                                     max_size=MAX_FRAME_BYTES)
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
        """The participant's push source: the controls the page's messages write to."""
        return self.controls

    def _set_scene(self, scene: dict) -> None:
        with self._lock:
            self._scene = scene

    def publish(self, base=None, push=None) -> None:
        """The live state for the page (a physics-step hook; every 10th step: 50 Hz)."""
        r = self.runner
        self._k += 1
        if r is None or (base is not None and self._k % 10):
            return
        p = r.policy.belief.goal_marginal()
        state = {"type": "state", "t": round(r.time_s, 3),
                 "xy": [round(float(v), 4) for v in r.base.position],
                 "force": [round(float(v), 2) for v in r.body.applied],
                 "probs": [round(float(v), 4) for v in p] if r.trial.show_belief else None,
                 "cues": len(r.cues), "step": r.t}
        with self._lock:
            self._state = state
            self._state_seq += 1

    def _latency(self, cue) -> None:
        t = self.controls.released_at
        if t is not None:
            self.latencies_ms.append((time.perf_counter() - t) * 1000.0)
            self.controls.released_at = None

    def begin_trial(self, position: int, total: int, runner: TrialRunner) -> None:
        """Show the trial and wait for the participant's Start; then run in real time."""
        self.controls.reset()
        self.runner, self.position, self.total = runner, position, total
        self._set_scene(scene_message(runner, position, total, "waiting", self.last_outcome))
        self.publish()
        while not self.controls.started.wait(0.2):
            pass
        self._set_scene(scene_message(runner, position, total, "running"))
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
        self._set_scene(scene_message(runner, self.position, self.total,
                                      "finished" if last else "done", self.last_outcome))

    def close(self) -> None:
        """Let the page see the last scene, then stop the server and its thread."""
        if not self.thread.is_alive():
            return
        time.sleep(2.5 / STATE_HZ)
        self.loop.call_soon_threadsafe(self._stop.set)
        self.thread.join(5)
