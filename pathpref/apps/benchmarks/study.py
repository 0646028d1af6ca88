"""``study`` section: from a push message on the browser front end's WebSocket to the cue in
the robot's belief, end to end in real time (server, physics, sensor, detector, belief)."""

from __future__ import annotations

import json
import tempfile
import threading
import time
from pathlib import Path
from statistics import median
from typing import Any

# a push of 35 N for 0.4 s, then release; the cue ends 50 ms after the force falls below 4 N
PUSH_N, PUSH_S, GAP_S = 35.0, 0.4, 1.2
DIRECTIONS = [(-1, 0), (0, 1), (1, 0), (0, -1)]
#: the longest the client waits for a push's cue to show (s): the trial runs in real time, and
#: on a loaded machine its physics falls behind the clock, so a cue may show seconds late (it
#: is still counted, with its latency, rather than taken for the next push's)
CUE_WAIT_S = 10.0


def _client(url: str, origin: str, n: int, out: dict) -> None:
    """Start the trial, then push ``n`` times as the page does (the push repeated every
    0.1 s while held, ``alive`` every 0.25 s); per push, the seconds from sending the release
    to receiving the first state whose cue count includes it."""
    from websockets.sync.client import connect

    lat: list[float] = []
    with connect(url, origin=origin) as ws:
        stop = threading.Event()

        def alive() -> None:
            while not stop.wait(0.25):
                try:
                    ws.send('{"type": "alive"}')
                except Exception:  # noqa: BLE001 - the server closed at the study's end
                    return

        threading.Thread(target=alive, daemon=True).start()
        cues = 0
        for status in ("waiting", "running"):  # press Start when the page would show it
            while True:
                m = json.loads(ws.recv(timeout=30))
                if m["type"] == "scene" and m["status"] == status:
                    break
            if status == "waiting":
                ws.send('{"type": "start"}')
        time.sleep(GAP_S)  # as a person would: look before the first push
        for k in range(n):
            dx, dy = DIRECTIONS[k % len(DIRECTIONS)]
            push = json.dumps({"type": "push", "fx": PUSH_N * dx, "fy": PUSH_N * dy})
            end = time.perf_counter() + PUSH_S
            while time.perf_counter() < end:
                ws.send(push)
                time.sleep(min(0.1, max(0.0, end - time.perf_counter())))
            ws.send('{"type": "release"}')
            t0 = time.perf_counter()
            while time.perf_counter() - t0 < CUE_WAIT_S:
                m = json.loads(ws.recv(timeout=5))
                if m["type"] == "state" and m["cues"] > cues:
                    lat.append((time.perf_counter() - t0) * 1000.0)
                    cues = m["cues"]
                    break
            time.sleep(GAP_S)
        out["latencies_ms"] = lat
        # stay until the trial ends: without its page the trial would pause
        end = time.perf_counter() + 120
        while time.perf_counter() < end:
            m = json.loads(ws.recv(timeout=120))
            if m["type"] == "scene" and m["status"] == "finished":
                break
        stop.set()


def bench_study(quick: bool = False) -> dict[str, Any]:
    """Median latency (ms) from the WebSocket's release message to the state showing the cue
    in the belief (``study_latency_ms``), and from the release's arrival at the server to the
    belief update (``study_latency_server_ms``), over pushes on ``simple``."""
    from ...study.conduct import run_study
    from ...study.plan import parse_study
    from ...study.server import BrowserFrontEnd

    n = 3 if quick else 8
    study = parse_study({"trials": [{
        "name": "bench", "map": "simple", "start": [5, 2], "goal": [5, 9],
        "candidates": [[2, 9], [5, 9], [9, 9]], "route": [[5, 2], [2, 2], [2, 9], [5, 9]],
        "time_limit_s": 4 + n * (PUSH_S + GAP_S + 1.0), "queries": 300}]})
    front = BrowserFrontEnd(port=0)
    out: dict = {}
    client = threading.Thread(target=_client, args=(
        f"ws://127.0.0.1:{front.port}/ws?token={front.token}", f"http://127.0.0.1:{front.port}",
        n, out), daemon=True)
    client.start()
    with tempfile.TemporaryDirectory() as tmp:
        run_study(study, "bench", Path(tmp) / "bench.sqlite", front, log=lambda m: None)
    client.join(10)
    lat = out.get("latencies_ms", [])
    return {"study_latency_ms": round(median(lat), 1) if lat else None,
            "study_latency_server_ms": round(median(front.latencies_ms), 1)
            if front.latencies_ms else None,
            "study_pushes": n, "study_cues_seen": len(lat)}
