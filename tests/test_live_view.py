"""``study run --live-port``: a Foxglove live view of the trials, read by a WebSocket client
speaking Foxglove's protocol (``foxglove.sdk.v1``, formerly ``foxglove.websocket.v1``) on
loopback: the server advertises ``/scene``, ``/scene/belief``, ``/tf`` and ``/pose``, and the
base's poses arrive while the trial runs, as protobuf ``foxglove.PoseInFrame`` messages inside
the map."""

from __future__ import annotations

import base64
import json
import socket
import struct
import threading
import time
from pathlib import Path

import pytest

from pathpref.apps.cli import main

pytest.importorskip("foxglove")
ws_client = pytest.importorskip("websockets.sync.client")

ROOT = Path(__file__).resolve().parents[1]
STUDY = ROOT / "examples" / "study_demo.json"
PUSHES = ROOT / "examples" / "pushes_demo.json"
TOPICS = {"/scene", "/scene/belief", "/tf", "/pose"}


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _connect(port: int, deadline: float):
    """The client's connection once the server listens (retried until ``deadline``)."""
    while True:
        try:
            return ws_client.connect(f"ws://127.0.0.1:{port}", open_timeout=2,
                                     subprotocols=["foxglove.sdk.v1", "foxglove.websocket.v1"])
        except OSError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.05)


def _pose_decoder(channel: dict):
    """A decoder of the channel's protobuf messages, built from the schema it advertises."""
    from mcap.records import Schema
    from mcap_protobuf.decoder import DecoderFactory

    schema = Schema(id=1, name=channel["schemaName"], encoding="protobuf",
                    data=base64.b64decode(channel["schema"]))
    return DecoderFactory().decoder_for("protobuf", schema)


def test_study_run_serves_a_live_view_a_foxglove_client_reads(tmp_path, capsys, monkeypatch):
    """The scripted run is faster than real time: its first trial waits (at most 60 s) until
    the client has subscribed, so the poses cannot all pass before it listens."""
    from pathpref.study.live import LiveView

    subscribed = threading.Event()
    show = LiveView.show
    monkeypatch.setattr(LiveView, "show", lambda self, *a, **k: (
        subscribed.wait(60), show(self, *a, **k)))
    port = _free_port()
    out: dict = {}
    run = threading.Thread(target=lambda: out.setdefault("rc", main([
        "study", "run", str(STUDY), "--participant", "live", "--db", str(tmp_path / "s.sqlite"),
        "--script", str(PUSHES), "--live-port", str(port)])))
    run.start()
    poses = []
    try:
        with _connect(port, time.monotonic() + 60) as ws:
            channels: dict[str, dict] = {}
            deadline = time.monotonic() + 60
            while not TOPICS <= set(channels) and time.monotonic() < deadline:
                msg = ws.recv(timeout=10)
                if isinstance(msg, str) and json.loads(msg)["op"] == "advertise":
                    channels.update({c["topic"]: c for c in json.loads(msg)["channels"]})
            assert TOPICS <= set(channels), sorted(channels)
            pose = channels["/pose"]
            assert pose["encoding"] == "protobuf"
            assert pose["schemaName"] == "foxglove.PoseInFrame"
            ws.send(json.dumps({"op": "subscribe",
                                "subscriptions": [{"id": 7, "channelId": pose["id"]}]}))
            time.sleep(0.2)  # the server takes the subscription before the trial starts
            subscribed.set()
            decode = _pose_decoder(pose)
            while len(poses) < 20 and time.monotonic() < deadline:
                try:
                    msg = ws.recv(timeout=5)
                except TimeoutError:
                    break
                if isinstance(msg, bytes) and msg[0] == 0x01:  # messageData
                    sub, _stamp = struct.unpack_from("<IQ", msg, 1)
                    assert sub == 7
                    poses.append(decode(msg[13:]))
    finally:
        subscribed.set()
        run.join(timeout=600)
    assert not run.is_alive() and out["rc"] == 0
    assert "live view: connect Foxglove to ws://127.0.0.1:" in capsys.readouterr().out
    assert len(poses) >= 20  # the trial streams at the path's rate (100 Hz)
    for p in poses:
        assert p.frame_id == "world"
        assert 0.0 <= p.pose.position.x <= 5.0 and 0.0 <= p.pose.position.y <= 5.0  # 10 x 10
        # cells of 0.5 m
    closed = time.monotonic() + 10  # the server was stopped with the run (it closes its
    while True:                      # listener asynchronously)
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) != 0:
                break
        assert time.monotonic() < closed, "the live view still listens after the run"
        time.sleep(0.1)


def test_live_port_refusals_are_one_line(tmp_path, capsys):
    for argv, words in (
            (["--live-port", "8765"], "is the study server's --port"),
            (["--live-port", "80"], "use a free port 1024..65535"),
            (["--live-port", "9100", "--port", "9100"], "is the study server's --port")):
        rc = main(["study", "run", str(STUDY), "--participant", "p", "--db",
                   str(tmp_path / "r.sqlite"), "--script", str(PUSHES), *argv])
        err = [ln for ln in capsys.readouterr().err.splitlines() if ln]
        assert rc == 2 and len(err) == 1 and words in err[0], err
    assert not (tmp_path / "r.sqlite").exists()
