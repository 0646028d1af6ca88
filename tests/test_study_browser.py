"""The study's browser front end: end to end in headless Chromium (Debian's ``chromium``,
driven by Playwright), the token rule, and bad WebSocket messages."""

from __future__ import annotations

import json
import os
import re
import shutil
import sqlite3
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from pathpref.study.server import BrowserFrontEnd

CHROMIUM = shutil.which("chromium") or ("/usr/bin/chromium" if os.path.exists(
    "/usr/bin/chromium") else None)
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
        "--disable-background-networking", "--disable-component-update", "--disable-sync"]
HEADING = {(-1, 0): 6, (1, 0): 2, (0, 1): 0, (0, -1): 4}


def wait_for(cond, timeout_s: float = 120.0) -> bool:
    """Poll ``cond`` (the server handles a message after answering a ping, not before)."""
    end = time.perf_counter() + timeout_s
    while time.perf_counter() < end:
        if cond():
            return True
        time.sleep(0.01)
    return cond()


def _get(url: str) -> tuple[int, bytes]:
    try:
        with urllib.request.urlopen(url, timeout=120) as r:
            return r.status, r.read()
    except urllib.error.HTTPError as e:
        return e.code, b""


def test_other_hosts_need_the_token():
    front = BrowserFrontEnd(host="0.0.0.0", port=0)
    try:
        assert front.token and len(front.token) >= 16 and f"token={front.token}" in front.url
        base = f"http://127.0.0.1:{front.port}/"
        assert _get(base)[0] == 403
        assert _get(base + "?token=wrong")[0] == 403
        status, body = _get(base + f"?token={front.token}")
        assert status == 200 and b"<canvas" in body
        from websockets.exceptions import InvalidStatus
        from websockets.sync.client import connect

        with pytest.raises(InvalidStatus, match="403"):
            connect(f"ws://127.0.0.1:{front.port}/ws")
        with connect(f"ws://127.0.0.1:{front.port}/ws?token={front.token}",
                     origin=f"http://127.0.0.1:{front.port}") as ws:
            ws.send('{"type": "push", "fx": 5, "fy": 0}')
            ws.send('{"type": "release"}')
    finally:
        front.close()
    loop = BrowserFrontEnd(port=0)
    try:
        # bound to loopback too: the token is required (another site's page, a stale tab)
        assert loop.token and _get(f"http://127.0.0.1:{loop.port}/")[0] == 403
        assert _get(f"http://127.0.0.1:{loop.port}/?token={loop.token}")[0] == 200
    finally:
        loop.close()


def test_favicon_is_declared_and_never_refused():
    """A desktop browser asks ``/favicon.ico`` on its own, without the token: answered
    204 with no body and not counted as refused; the served page declares its empty icon
    (``<link rel="icon" href="data:,">``), so a browser that reads it asks nothing."""
    from html.parser import HTMLParser

    front = BrowserFrontEnd(port=0)
    try:
        base = f"http://127.0.0.1:{front.port}"
        assert _get(base + "/favicon.ico") == (204, b"")
        assert _get(base + "/other.ico")[0] == 403  # only the icon is spared the token
        assert front.refused_requests == 1
        status, page = _get(base + f"/?token={front.token}")
    finally:
        front.close()
    icons = []

    class Links(HTMLParser):
        def handle_starttag(self, tag, attrs):
            a = dict(attrs)
            if tag == "link" and "icon" in (a.get("rel") or "").split():
                icons.append(a.get("href"))

    Links().feed(page.decode())
    assert status == 200 and icons == ["data:,"]


def test_malformed_and_oversized_messages_are_ignored(caplog):
    from websockets.sync.client import connect

    front = BrowserFrontEnd(port=0, clock=lambda: 0.0)  # a still clock: no dead man here
    try:
        url = f"ws://127.0.0.1:{front.port}/ws?token={front.token}"
        origin = f"http://127.0.0.1:{front.port}"
        with connect(url, origin=origin) as ws:
            for bad in ("{not json", "[]", '{"type": "push", "fx": 1e400, "fy": 0}',
                        json.dumps({"type": "push", "fx": 1, "fy": 1, "pad": "x" * 400})):
                ws.send(bad)
            ws.send('{"type": "push", "fx": 20, "fy": -10}')
            assert wait_for(lambda: front.controls.force().tolist() == [20.0, -10.0])
            assert front.controls.ignored == 4
        # a frame over 64 KiB closes that connection
        with connect(url, origin=origin, max_size=None) as ws:
            ws.send("x" * 100_000)
            with pytest.raises(Exception):  # noqa: B017 - closed with 1009, whatever the type
                for _ in range(3):
                    ws.recv(timeout=120)
        with connect(url, origin=origin) as ws:  # the session goes on: a new connection works
            ws.send('{"type": "push", "fx": 0, "fy": 30}')
            assert wait_for(lambda: front.controls.force().tolist() == [0.0, 30.0])
        # the page closed mid-drag: the push ends with it
        assert wait_for(lambda: not front.controls.force().any())
    finally:
        front.close()


def test_port_in_use_is_one_line(tmp_path, capsys):
    front = BrowserFrontEnd(port=0)
    try:
        from pathpref.apps.cli import main

        study = Path(__file__).resolve().parents[1] / "examples" / "study_demo.json"
        assert main(["study", "run", str(study), "--participant", "p", "--db",
                     str(tmp_path / "s.sqlite"), "--port", str(front.port)]) == 2
        err = capsys.readouterr().err
        assert f"cannot serve on 127.0.0.1:{front.port}" in err and err.count("\n") == 1
        assert not (tmp_path / "s.sqlite").exists()
    finally:
        front.close()


#: timeout of a wait for an event in the page (ms): far above what a loaded machine needs
EVENT_MS = 180_000


def _wait_sim(page, seconds: float) -> None:
    """Wait until the trial's simulated clock has advanced ``seconds`` (or it finished)."""
    t = page.evaluate("window.study.state.t")
    page.wait_for_function(f"window.study.state.t >= {t + seconds} || "
                           "window.study.scene.status === 'finished'", timeout=EVENT_MS,
                           polling="raf")


def _colour_pixels(img: np.ndarray, rgb: tuple[int, int, int], tol: int = 12) -> int:
    return int((np.abs(img[..., :3].astype(int) - np.array(rgb)).max(axis=-1) <= tol).sum())


@pytest.mark.skipif(CHROMIUM is None, reason="chromium not found (make install puts it there "
                    "with apt-get install chromium)")
def test_browser_drag_end_to_end(tmp_path):
    """Open the page in Chromium, start the trial, drag from the robot west, west, north,
    north: the database holds cues in those directions, the trial's outcome and a rerun file;
    the screenshot shows the map (obstacle), the robot and the goal; the page draws.

    Nothing here waits a fixed wall time: a push is held for 0.4 s of *simulated* time (the
    trial is paced to the wall clock but falls behind it under load), the next drag starts
    after 1 s of simulated time, and every wait is for an event, with a timeout far above
    what a loaded machine needs (it only keeps a broken page from hanging the suite). The
    frame rate and the release-to-cue latency are printed, not asserted (benchmarks are not
    timed tests)."""
    playwright = pytest.importorskip("playwright.sync_api")
    import imageio.v2 as imageio

    study = tmp_path / "one.json"
    study.write_text(json.dumps({"trials": [{
        "name": "left", "map": "simple", "start": [5, 2], "goal": [5, 9],
        "candidates": [[2, 9], [5, 9], [9, 9]], "route": [[5, 2], [2, 2], [2, 9], [5, 9]],
        "time_limit_s": 12, "queries": 200}]}))
    db = tmp_path / "b.sqlite"
    proc = subprocess.Popen(
        [sys.executable, "-m", "pathpref", "study", "run", str(study), "--participant", "p",
         "--db", str(db), "--port", "0"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
        text=True, env={**os.environ, "MUJOCO_GL": "egl"})
    try:
        line = proc.stdout.readline()
        url = re.search(r"(http://\S+)", line).group(1)
        drags = [(-1, 0), (-1, 0), (0, 1), (0, 1)]  # west, west, north, north (map frame)
        with playwright.sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS)
            page = browser.new_page(viewport={"width": 1100, "height": 700})
            refused: list[str] = []  # no favicon or other request the page makes may fail
            page.on("requestfailed", lambda r: refused.append(r.url))
            page.on("response", lambda r: r.status >= 400 and refused.append(r.url))
            page.goto(url)
            page.wait_for_function("window.study.scene !== null", timeout=EVENT_MS)
            page.click("#start")
            page.wait_for_function("window.study.scene.status === 'running'", timeout=EVENT_MS)
            # state is null until the first state message: under load it may come late
            page.wait_for_function("window.study.state !== null", timeout=EVENT_MS)
            latency = []
            for dx, dy in drags:
                x, y = page.evaluate("window.study.robotPx()")
                cues = page.evaluate("window.study.state.cues")
                page.mouse.move(x, y)
                page.mouse.down()
                page.mouse.move(x + 110 * dx, y - 110 * dy, steps=4)  # screen y points down
                _wait_sim(page, 0.4)
                t0 = time.perf_counter()
                page.mouse.up()  # the cue is complete when the push ends
                page.wait_for_function(f"window.study.state.cues > {cues}", timeout=EVENT_MS,
                                       polling="raf")
                latency.append(time.perf_counter() - t0)
                _wait_sim(page, 1.0)
            fps = page.evaluate("window.study.fps")
            shown = page.inner_text("body")
            # headless chromium fetches no favicon (test_favicon_is_declared_and_never_refused
            # requests it as a desktop browser would); the page declares its own, empty icon
            icon = page.evaluate("document.querySelector('link[rel=icon]').href")
            shot = tmp_path / "page.png"
            page.screenshot(path=str(shot))
            page.wait_for_function("window.study.scene.status === 'finished'", timeout=EVENT_MS)
            browser.close()
        out = proc.communicate(timeout=EVENT_MS / 1000)[0]
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, out
    assert fps > 0  # the page draws (its rate is printed: a benchmark, not a timed test)
    assert "per second" not in shown and "fps" not in shown.lower()  # not the participant's
    assert refused == [] and icon == "data:,"
    print(f"page {fps:.0f} fps; drag release to cue on the page: "
          f"{[round(1000 * v) for v in latency]} ms")
    c = sqlite3.connect(db)
    status, outcome, pushes, cues, rerun = c.execute(
        "SELECT status, outcome, pushes, cues, rerun FROM trials").fetchone()
    assert status == "done" and outcome in ("success", "timeout")
    assert pushes == len(drags)
    headings = [r[0] for r in c.execute("SELECT heading FROM trial_cues ORDER BY k")]
    assert headings == [HEADING[d] for d in drags]
    peaks = [r[0] for r in c.execute("SELECT peak_n FROM trial_pushes ORDER BY k")]
    assert all(20 < p <= 60.0 + 1e-9 for p in peaks), peaks  # 110 px ~ 0.89 m x 40 N/m
    assert Path(rerun).is_file() and Path(rerun).stat().st_size > 1000
    img = imageio.imread(shot)
    assert _colour_pixels(img, (0x3C, 0x3C, 0x46)) > 5000  # the table (obstacle) and walls
    assert _colour_pixels(img, (0x1E, 0x6E, 0xDC)) > 500  # the robot
    assert _colour_pixels(img, (0xE0, 0x21, 0x8A)) > 200  # the goal ring


FAKE_PAD = """
window.fakeAxes = [0.02, -0.01];
navigator.getGamepads = () => [{ index: 0, id: "fake pad", connected: true,
                                 axes: window.fakeAxes, buttons: [] }];
"""


@pytest.mark.skipif(CHROMIUM is None, reason="chromium not found (make install puts it there "
                    "with apt-get install chromium)")
def test_browser_gamepad_calibration_pushes_and_questionnaire(tmp_path):
    """A gamepad in the page (the Gamepad API, faked in the page: Chromium headless has no
    device): the calibration step (rest, then full reach) is sent and recorded for the
    participant, and stick pushes west and north reach the database as cues in those
    directions with the force of the stated rule: 0.8 of the reach gives
    60 * (0.8 - 0.15) / 0.85 = 45.882 N. The study asks the NASA-TLX after the trial: the
    answers given in the page are recorded with the trial's position and name."""
    playwright = pytest.importorskip("playwright.sync_api")
    study = tmp_path / "one.json"
    study.write_text(json.dumps({"questionnaire": "nasa-tlx", "trials": [{
        "name": "left", "map": "simple", "start": [5, 2], "goal": [5, 9],
        "candidates": [[2, 9], [5, 9], [9, 9]], "route": [[5, 2], [2, 2], [2, 9], [5, 9]],
        "time_limit_s": 8, "queries": 100}]}))
    answers = {"mental": 40, "physical": 65, "temporal": 20, "performance": 15, "effort": 55,
               "frustration": 5}
    db = tmp_path / "g.sqlite"
    proc = subprocess.Popen(
        [sys.executable, "-m", "pathpref", "study", "run", str(study), "--participant", "p",
         "--db", str(db), "--port", "0"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
        text=True, env={**os.environ, "MUJOCO_GL": "egl"})
    rest, reach = (0.02, -0.01), 0.9
    try:
        url = re.search(r"(http://\S+)", proc.stdout.readline()).group(1)
        with playwright.sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS)
            page = browser.new_page(viewport={"width": 1100, "height": 700})
            page.add_init_script(FAKE_PAD)
            page.goto(url)
            page.wait_for_function("window.study.scene !== null && window.study.role === "
                                   "'driver'", timeout=EVENT_MS)
            page.wait_for_selector("#calibrate", state="visible", timeout=EVENT_MS)
            page.click("#calibrate")
            page.wait_for_function("window.study.pad.step === 'reach'", timeout=EVENT_MS)
            page.evaluate(f"window.fakeAxes[0] = {rest[0] + reach}")  # full reach, east
            page.wait_for_function("window.study.pad.cal !== null", timeout=EVENT_MS)
            page.evaluate(f"window.fakeAxes[0] = {rest[0]}")
            page.click("#start")
            page.wait_for_function("window.study.scene.status === 'running' && "
                                   "window.study.state !== null", timeout=EVENT_MS)
            for dx, dy in [(-1, 0), (0, 1)]:
                cues = page.evaluate("window.study.state.cues")
                # 0.8 of the reach; the browser's axis 1 points down (north is negative)
                page.evaluate(f"window.fakeAxes[0] = {rest[0] + 0.8 * reach * dx}; "
                              f"window.fakeAxes[1] = {rest[1] - 0.8 * reach * dy}")
                _wait_sim(page, 0.4)
                page.evaluate(f"window.fakeAxes[0] = {rest[0]}; window.fakeAxes[1] = {rest[1]}")
                page.wait_for_function(f"window.study.state.cues > {cues}", timeout=EVENT_MS,
                                       polling="raf")
                _wait_sim(page, 1.0)
            page.wait_for_function("window.study.scene.status === 'finished'", timeout=EVENT_MS)
            # the questionnaire after the trial: the session ends only once it is answered
            page.wait_for_selector("#tlx", state="visible", timeout=EVENT_MS)
            assert proc.poll() is None
            for k, v in answers.items():
                page.evaluate(f"document.getElementById('tlx-{k}').value = {v}")
            page.click("#tlxsubmit")
            out = proc.communicate(timeout=EVENT_MS / 1000)[0]
            browser.close()
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, out
    c = sqlite3.connect(db)
    tlx = c.execute("SELECT participant, trial, name, mental, physical, temporal, performance, "
                    "effort, frustration, raw_tlx FROM study_tlx").fetchall()
    assert [t[:9] for t in tlx] == [("p", 1, "left", *answers.values())]
    assert tlx[0][9] == pytest.approx(200 / 6, abs=1e-12)  # (40+65+20+15+55+5) / 6
    assert [r[0] for r in c.execute("SELECT heading FROM trial_cues ORDER BY k")] == [
        HEADING[(-1, 0)], HEADING[(0, 1)]]
    peaks = [r[0] for r in c.execute("SELECT peak_n FROM trial_pushes ORDER BY k")]
    assert peaks == pytest.approx([60 * 0.65 / 0.85] * 2, rel=1e-6)
    cal = c.execute("SELECT k, trial, device, rest_x, rest_y, reach FROM study_calibrations "
                    "WHERE participant = 'p'").fetchall()
    assert len(cal) == 1 and cal[0][:3] == (0, 1, "fake pad")
    assert cal[0][3:5] == pytest.approx(rest, abs=1e-12)
    assert cal[0][5] == pytest.approx(reach, abs=1e-12)


PATH_RGB = (0x7A, 0x3C, 0xC8)  # the planned path's colour on the page (page.html PATH_RGB)


@pytest.mark.skipif(CHROMIUM is None, reason="chromium not found (make install puts it there "
                    "with apt-get install chromium)")
def test_browser_observer_draws_the_planned_path(tmp_path):
    """A trial with the belief hidden, a driver page and an observer page (two windows): the
    observer's canvas draws the robot's planned path (the page's count of the vertices it
    drew, and the path's colour in a screenshot of the canvas); the driver's draws none."""
    playwright = pytest.importorskip("playwright.sync_api")
    import imageio.v2 as imageio

    study = tmp_path / "one.json"
    study.write_text(json.dumps({"trials": [{
        "name": "hidden", "map": "simple", "start": [5, 2], "goal": [5, 9],
        "candidates": [[2, 9], [5, 9], [9, 9]], "route": [[5, 2], [2, 2], [2, 9], [5, 9]],
        "time_limit_s": 6, "queries": 100, "condition": {"belief": "hidden"}}]}))
    proc = subprocess.Popen(
        [sys.executable, "-m", "pathpref", "study", "run", str(study), "--participant", "p",
         "--db", str(tmp_path / "o.sqlite"), "--port", "0"], stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT, text=True, env={**os.environ, "MUJOCO_GL": "egl"})
    try:
        url = re.search(r"(http://\S+)", proc.stdout.readline()).group(1)
        with playwright.sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS)
            pages = []
            for role in ("driver", "observer"):
                page = browser.new_context(viewport={"width": 1100, "height": 700}).new_page()
                page.goto(url)
                page.wait_for_function(f"window.study.scene !== null && window.study.role "
                                       f"=== '{role}'", timeout=EVENT_MS)
                pages.append(page)
            driver, observer = pages
            driver.click("#start")
            observer.wait_for_function(
                "window.study.state !== null && window.study.state.path !== null && "
                "window.study.state.path.length >= 3 && window.study.pathDrawn >= 3",
                timeout=EVENT_MS, polling="raf")
            shots = {}
            for name, page in (("observer", observer), ("driver", driver)):
                shots[name] = tmp_path / f"{name}.png"
                page.locator("#map").screenshot(path=str(shots[name]))
            drawn = driver.evaluate("[window.study.pathDrawn, window.study.state.path]")
            driver.wait_for_function("window.study.scene.status === 'finished'",
                                     timeout=EVENT_MS)
            browser.close()
        out = proc.communicate(timeout=EVENT_MS / 1000)[0]
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, out
    assert drawn == [0, None]  # the driver is not shown the belief: no path either
    purple = {k: _colour_pixels(imageio.imread(v), PATH_RGB) for k, v in shots.items()}
    assert purple["driver"] == 0
    print(f"planned path pixels: {purple}")
    assert purple["observer"] > 150, purple  # a dashed line 3 px wide over >= 2 cells
