"""The study server locked down: every attack of issue 30 as a test (raw HTTP and WebSocket
clients; the page itself is driven by Chromium in ``test_study_browser.py``).

Nothing here asserts a wall-clock duration: waits are for events (``wait_for``, with a timeout
far above what a loaded machine needs), and the dead man and the log limit are checked with an
injected clock."""

from __future__ import annotations

import json
import logging
import socket
import sqlite3
import threading
import time
import urllib.error
import urllib.request
from pathlib import Path

import pytest
from websockets.exceptions import InvalidStatus
from websockets.sync.client import connect

from pathpref.apps.cli import main
from pathpref.study.controls import DEADMAN_S, LOG_EVERY_S, LOG_FIRST, Controls
from pathpref.study.plan import parse_study
from pathpref.study.server import BrowserFrontEnd, PageGone

ROOT = Path(__file__).resolve().parents[1]
STUDY = ROOT / "examples" / "study_demo.json"
PUSHES = ROOT / "examples" / "pushes_demo.json"
WAIT_S = 120.0



def keep_alive(ws, stop: threading.Event) -> None:
    """The driver's page saying "alive" every 0.1 s until ``stop`` (or the server closes)."""

    def alive():
        while not stop.is_set():
            try:
                ws.send('{"type": "alive"}')
            except Exception:  # noqa: BLE001 - the server closed at the end
                return
            time.sleep(0.1)

    threading.Thread(target=alive, daemon=True).start()

def wait_for(cond, timeout_s: float = WAIT_S) -> bool:
    end = time.perf_counter() + timeout_s
    while time.perf_counter() < end:
        if cond():
            return True
        time.sleep(0.01)
    return cond()


def get(url: str, headers: dict | None = None) -> int:
    try:
        with urllib.request.urlopen(urllib.request.Request(url, headers=headers or {}),
                                    timeout=WAIT_S) as r:
            return r.status
    except urllib.error.HTTPError as e:
        return e.code


def ws_url(front, token=None) -> str:
    return f"ws://127.0.0.1:{front.port}/ws?token={token or front.token}"


def origin(front) -> str:
    return f"http://127.0.0.1:{front.port}"


def page(front):
    """A WebSocket as the page opens it: the token, its own origin; the role message read."""
    ws = connect(ws_url(front), origin=origin(front), open_timeout=WAIT_S)
    role = json.loads(ws.recv(timeout=WAIT_S))
    assert role["type"] == "role"
    return ws, role["role"]


class Clock:
    def __init__(self):
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t


@pytest.fixture
def front():
    f = BrowserFrontEnd(port=0)
    yield f
    f.close()


def test_every_request_needs_this_sessions_token(front):
    """On 127.0.0.1 too: the page, the WebSocket; a page of an earlier session (P01's tab,
    another token) is refused by the next session (P02's) on the same port."""
    base = f"http://127.0.0.1:{front.port}/"
    assert len(front.token) >= 16 and front.url.endswith(f"?token={front.token}")
    assert get(base) == 403
    assert get(base + "?token=wrong") == 403
    assert get(base + f"?token={front.token}") == 200
    with pytest.raises(InvalidStatus, match="403"):
        connect(f"ws://127.0.0.1:{front.port}/ws", origin=origin(front))
    other = BrowserFrontEnd(port=0)  # P01's session: its token is worth nothing here
    try:
        assert other.token != front.token
        with pytest.raises(InvalidStatus, match="403"):
            connect(ws_url(front, other.token), origin=origin(front))
    finally:
        other.close()
    ws, role = page(front)
    ws.close()
    assert role == "driver"


@pytest.mark.parametrize("headers", [
    {"Origin": "http://evil.example"},  # another site's page that learnt the token
    {},  # no Origin: not a page of ours
    {"Origin": "http://evil.example:1", "Host": "evil.example:1"},  # DNS rebinding
])
def test_foreign_origin_or_host_is_refused(front, headers):
    with pytest.raises(InvalidStatus, match="403"):
        connect(ws_url(front), origin=headers.get("Origin"),
                additional_headers={"Host": headers["Host"]} if "Host" in headers else None)
    assert not front.controls.started.is_set()
    if "Host" in headers:
        assert get(f"http://127.0.0.1:{front.port}/?token={front.token}", headers) == 403


def test_one_driver_the_others_only_watch(front):
    """The first page drives; a second page's push and start do nothing; when the driver
    leaves mid-push the push ends, and the next page to connect drives."""
    a, role_a = page(front)
    b, role_b = page(front)
    assert (role_a, role_b) == ("driver", "observer")
    b.send('{"type": "push", "fx": 40, "fy": 0}')
    b.send('{"type": "start"}')
    a.send('{"type": "push", "fx": 0, "fy": 25}')
    assert wait_for(lambda: front.controls.force().tolist() == [0.0, 25.0])
    b.send('{"type": "alive"}')
    a.send('{"type": "alive"}')  # handled after b's messages were (one loop, in order)
    assert wait_for(lambda: front.driver_present())
    assert not front.controls.started.is_set() and front.controls.ignored == 0
    a.close()
    assert wait_for(lambda: front.driver is None and not front.controls.force().any())
    c, role_c = page(front)
    assert role_c == "driver"
    b.close()
    c.close()


def test_dead_man_ends_a_push_whose_messages_stop():
    """A push message acts for DEADMAN_S; then the force is zero as if released."""
    clock = Clock()
    c = Controls(deadman_s=DEADMAN_S, clock=clock)
    assert c.handle('{"type": "push", "fx": 40, "fy": 0}')
    clock.t += 0.9 * DEADMAN_S
    assert c.force().tolist() == [40.0, 0.0]
    assert c.handle('{"type": "push", "fx": 40, "fy": 0}')  # the page repeats it
    clock.t += 0.9 * DEADMAN_S
    assert c.force().tolist() == [40.0, 0.0]
    clock.t += 0.2 * DEADMAN_S  # 1.1 DEADMAN_S since the last message
    assert not c.force().any() and c.deadman_releases == 1
    clock.t += 100
    assert not c.force().any() and c.deadman_releases == 1
    script = Controls(clock=clock)  # a scripted participant: no dead man
    script.handle('{"type": "push", "fx": 0, "fy": 30}')
    clock.t += 1e6
    assert script.force().tolist() == [0.0, 30.0]


def test_a_silent_driver_page_loses_its_push_over_the_socket(front):
    """A drag whose page froze (connected, nothing sent): the push ends by the dead man."""
    ws, _ = page(front)
    ws.send('{"type": "push", "fx": 40, "fy": 0}')
    assert wait_for(lambda: front.controls.force().any())
    assert wait_for(lambda: not front.controls.force().any())
    assert front.controls.deadman_releases == 1 and front.driver is not None
    ws.close()


def test_malformed_messages_are_logged_within_the_rate_limit(caplog):
    """2000 malformed messages: LOG_FIRST lines, then one line per LOG_EVERY_S with the
    count since the last line."""
    clock = Clock()
    c = Controls(clock=clock)
    with caplog.at_level(logging.WARNING, "pathpref.study"):
        for _ in range(2000):
            assert not c.handle("{not json")
        assert c.ignored == 2000 and len(caplog.records) == LOG_FIRST
        clock.t += LOG_EVERY_S
        c.handle("[]")
        assert len(caplog.records) == LOG_FIRST + 1
        assert f"ignored {2000 - LOG_FIRST + 1} more" in caplog.records[-1].getMessage()
        c.handle("[]")
        assert len(caplog.records) == LOG_FIRST + 1


def test_2000_malformed_messages_over_the_socket(caplog):
    clock = Clock()  # the log limit's clock stands still: at most LOG_FIRST lines
    f = BrowserFrontEnd(port=0, clock=clock)
    try:
        with caplog.at_level(logging.WARNING, "pathpref.study"):
            ws, _ = page(f)
            for k in range(2000):
                ws.send(["{", "[]", '{"type": "push", "fx": 1e400, "fy": 0}',
                         '{"type": "push", "fx": ' + "9" * 200 + ', "fy": 0}'][k % 4])
            ws.send('{"type": "push", "fx": 3, "fy": 4}')
            assert wait_for(lambda: f.controls.force().tolist() == [3.0, 4.0])
            ws.close()
        # 200-digit fx is a finite number (1e200), capped at 60 N: not ignored
        assert f.controls.ignored == 1500
        ignored = [r for r in caplog.records if "ignored" in r.getMessage()]
        assert len(ignored) == LOG_FIRST
    finally:
        f.close()


def test_idle_connections_are_capped_and_time_out():
    """Idle TCP connections cannot exhaust the server: the ones over the cap are closed as
    they are accepted, the rest when the handshake time runs out; then a page is served."""
    f = BrowserFrontEnd(port=0, max_connections=4, open_timeout_s=1.0)
    socks = []
    try:
        for _ in range(30):
            socks.append(socket.create_connection(("127.0.0.1", f.port), timeout=WAIT_S))
        assert wait_for(lambda: f.refused_connections == 26)

        def closed(s) -> bool:
            try:
                return s.recv(1) == b""
            except OSError:
                return True

        for s in socks:  # every one is closed by the server (EOF or reset)
            assert closed(s)
        assert wait_for(lambda: f.open_connections == 0)
        assert get(f"http://127.0.0.1:{f.port}/?token={f.token}") == 200
    finally:
        for s in socks:
            s.close()
        f.close()


TRIAL = {"name": "a", "map": "simple", "start": [5, 2], "goal": [5, 9],
         "candidates": [[2, 9], [5, 9], [9, 9]], "route": [[5, 2], [2, 2], [2, 9], [5, 9]],
         "time_limit_s": 10, "queries": 30}


def _run_in_thread(study, participant, db, front, resume=False):
    from pathpref.study.conduct import run_study

    box: dict = {}

    def target():
        try:
            box["rows"] = run_study(study, participant, db, front, resume=resume,
                                    log=lambda m: None)
        except BaseException as e:  # noqa: BLE001 - handed to the test
            box["error"] = e

    th = threading.Thread(target=target, daemon=True)
    th.start()
    return th, box


def test_trial_pauses_while_the_page_is_gone_and_goes_on_when_it_returns(tmp_path):
    """The driver presses Start and disappears: the trial pauses (simulated time stands
    still, nothing runs unattended); a page that comes back drives it to its end."""
    study = parse_study({"trials": [{**TRIAL, "time_limit_s": 3}]})
    f = BrowserFrontEnd(port=0)
    db = tmp_path / "p.sqlite"
    th, box = _run_in_thread(study, "p1", db, f)
    ws, _ = page(f)
    assert wait_for(lambda: f._scene is not None)
    ws.send('{"type": "start"}')
    ws.close()
    assert wait_for(lambda: f._status == "paused")
    t = f.runner.time_s
    time.sleep(0.3)
    assert f.runner.time_s == t < 3  # paused: the physics does not step
    ws, role = page(f)
    assert role == "driver"
    stop = threading.Event()

    keep_alive(ws, stop)
    th.join(WAIT_S)
    stop.set()
    assert "error" not in box, box.get("error")
    assert [r["status"] for r in box["rows"]] == ["done"]
    assert f.pauses and f.pauses[0][0] == 1


def test_page_gone_past_the_pause_limit_leaves_the_trial_to_run_again(tmp_path):
    from pathpref.study.conduct import run_study
    from pathpref.study.script import PushScript, ScriptedFrontEnd

    study = parse_study({"trials": [TRIAL]})
    f = BrowserFrontEnd(port=0, pause_limit_s=0.5)
    db = tmp_path / "p.sqlite"
    th, box = _run_in_thread(study, "p1", db, f)
    ws, _ = page(f)
    assert wait_for(lambda: f._scene is not None)
    ws.send('{"type": "start"}')
    ws.close()
    th.join(WAIT_S)
    err = box.get("error")
    assert isinstance(err, PageGone) and "\n" not in str(err) and "--resume" in str(err)
    c = sqlite3.connect(db)
    assert c.execute("SELECT status FROM trials").fetchall() == [("running",)]
    # the simulated time stopped when the page went (the Pacer keeps it behind the wall
    # clock): far from the 10 s limit the old server ran out unattended
    assert f.runner.time_s < 10 and not f.runner.done
    rows = run_study(study, "p1", db, ScriptedFrontEnd(PushScript({"pushes": []})),
                     resume=True, log=lambda m: None)
    assert [r["status"] for r in rows] == ["done"]


class Holding:
    """A scripted front end that waits in trial 2 until released (a live session)."""

    def __init__(self, script):
        from pathpref.study.script import ScriptedFrontEnd

        self.inner = ScriptedFrontEnd(script)
        self.name = "script"
        self.in_trial2 = threading.Event()
        self.go = threading.Event()

    def source(self):
        return self.inner.source()

    def begin_trial(self, position, total, runner):
        self.inner.begin_trial(position, total, runner)
        self.position = position

    def after_decision(self, runner):
        if self.position == 2 and not self.in_trial2.is_set():
            self.in_trial2.set()
            assert self.go.wait(WAIT_S)

    def end_trial(self, runner, outcome):
        pass

    def close(self):
        pass


def test_resume_while_the_session_runs_is_refused_and_deletes_nothing(tmp_path, capsys):
    from pathpref.study.plan import load_study
    from pathpref.study.script import PushScript

    study = load_study(STUDY)
    db = tmp_path / "s.sqlite"
    front = Holding(PushScript.load(PUSHES))
    th, box = _run_in_thread(study, "p1", db, front)
    assert front.in_trial2.wait(WAIT_S)
    c = sqlite3.connect(db)
    before = c.execute("SELECT status FROM trials ORDER BY trial").fetchall()
    assert before == [("done",), ("running",)]
    for extra in (["--resume"], []):
        assert main(["study", "run", str(STUDY), "--participant", "p1", "--db", str(db),
                     "--script", str(PUSHES), *extra]) == 2
        cap = capsys.readouterr()
        assert cap.err.count("\n") == 1 and "has a live session" in cap.err
        assert "scripted participant" not in cap.out
    assert c.execute("SELECT status FROM trials ORDER BY trial").fetchall() == before
    front.go.set()
    th.join(WAIT_S)
    assert "error" not in box, box.get("error")
    assert [r["status"] for r in box["rows"]] == ["done", "done"]
    assert not Path(f"{db}.p1.lock").exists()  # released at the end
    # a killed session's lock goes with its process: --resume is then accepted
    assert main(["study", "run", str(STUDY), "--participant", "p1", "--db", str(db),
                 "--script", str(PUSHES), "--resume"]) == 0


def test_refused_participant_serves_no_page(tmp_path, capsys):
    """`study run` for a participant who has trials refuses before serving (no URL)."""
    db = tmp_path / "s.sqlite"
    assert main(["study", "run", str(STUDY), "--participant", "x", "--db", str(db),
                 "--script", str(PUSHES)]) == 0
    capsys.readouterr()
    assert main(["study", "run", str(STUDY), "--participant", "x", "--db", str(db),
                 "--port", "0"]) == 2
    cap = capsys.readouterr()
    assert "open http" not in cap.out and "already has 2 trial(s)" in cap.err


@pytest.mark.parametrize("kind", ["study_json", "study_toml", "push_deep", "push_digits",
                                  "push_unknown_trial"])
def test_hostile_files_are_one_line(tmp_path, capsys, kind):
    study, pushes = STUDY, PUSHES
    if kind == "study_json":
        study = tmp_path / "deep.json"
        study.write_text("[" * 100_000 + "]" * 100_000)
    elif kind == "study_toml":
        study = tmp_path / "deep.toml"
        study.write_text("a = " + "[" * 100_000 + "]" * 100_000 + "\n")
    elif kind == "push_deep":
        pushes = tmp_path / "deep.json"
        pushes.write_text('{"pushes": ' + "[" * 100_000 + "]" * 100_000 + "}")
    elif kind == "push_digits":
        pushes = tmp_path / "digits.json"
        pushes.write_text('{"pushes": [{"t": 0.5, "fx": ' + "9" * 400
                          + ', "fy": 0, "duration": 0.4}]}')
    else:
        pushes = tmp_path / "named.json"
        pushes.write_text(json.dumps({"trials": {"lfet": []}}))
    db = tmp_path / "s.sqlite"
    assert main(["study", "run", str(study), "--participant", "p", "--db", str(db),
                 "--script", str(pushes)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    want = {"study_json": "nested too deeply", "study_toml": "nested too deeply",
            "push_deep": "nested too deeply", "push_digits": "finite numbers",
            "push_unknown_trial": "trials.lfet: the study has no trial"}[kind]
    assert want in err
    assert not db.exists()



def test_waiting_for_start_is_bounded(tmp_path):
    """Nobody presses Start: past the limit the session ends in one line, nothing recorded,
    and a later session of the participant runs the trial."""
    from pathpref.study.conduct import run_study
    from pathpref.study.script import PushScript, ScriptedFrontEnd

    study = parse_study({"trials": [TRIAL]})
    db = tmp_path / "p.sqlite"
    th, box = _run_in_thread(study, "p1", db, BrowserFrontEnd(port=0, start_limit_s=0.3))
    th.join(WAIT_S)
    err = box.get("error")
    assert isinstance(err, PageGone) and "\n" not in str(err) and "Start" in str(err)
    assert sqlite3.connect(db).execute("SELECT count(*) FROM trials").fetchone()[0] == 0
    rows = run_study(study, "p1", db, ScriptedFrontEnd(PushScript({"pushes": []})),
                     log=lambda m: None)
    assert [r["status"] for r in rows] == ["done"]


def test_observers_see_the_planned_path_the_driver_only_when_the_belief_is_shown(tmp_path):
    """A trial with the belief hidden: every state message an observer gets carries the
    robot's planned path (free cells of the map, grid neighbours one after the other, from
    the robot's cell, ending at the candidate the belief favours); the driver's carries
    neither the belief nor the path."""
    study = parse_study({"trials": [{**TRIAL, "time_limit_s": 2,
                                     "condition": {"belief": "hidden"}}]})
    world = study.trials[0].world
    cands = [tuple(c) for c in TRIAL["candidates"]]
    f = BrowserFrontEnd(port=0)
    th, box = _run_in_thread(study, "p1", tmp_path / "p.sqlite", f)
    drv, role = page(f)
    obs, role_o = page(f)
    assert (role, role_o) == ("driver", "observer")
    stop = threading.Event()
    got: dict[str, list] = {"driver": [], "observer": []}

    def read(ws, who):
        try:
            while True:
                m = json.loads(ws.recv(timeout=WAIT_S))
                if m["type"] == "state":
                    got[who].append(m)
        except Exception:  # noqa: BLE001 - closed at the end of the session
            return

    readers = [threading.Thread(target=read, args=(ws, who), daemon=True)
               for ws, who in ((drv, "driver"), (obs, "observer"))]
    for t in readers:
        t.start()
    keep_alive(drv, stop)
    assert wait_for(lambda: f._scene is not None)
    drv.send('{"type": "start"}')
    th.join(WAIT_S)
    stop.set()
    f.close()
    for t in readers:
        t.join(WAIT_S)
    assert "error" not in box, box.get("error")
    assert got["observer"] and got["driver"]
    assert all(m["path"] is None and m["probs"] is None for m in got["driver"])
    steps = set()
    for m in got["observer"]:
        path = [tuple(c) for c in m["path"]]
        assert path[0] == tuple(m["cell"])
        for xy in path:
            world.cell(xy)  # a free cell of the map (a MapError otherwise)
        assert all(max(abs(a[0] - b[0]), abs(a[1] - b[1])) == 1
                   for a, b in zip(path, path[1:]))
        best = max(m["probs"])
        assert path[-1] in cands and m["probs"][cands.index(path[-1])] >= best - 1e-4
        steps.add(m["step"])
    assert len(steps) >= 2  # states from more than one decision step


def test_a_process_holding_every_slot_never_locks_the_page_out():
    """Issue 47: a local process that keeps every connection slot full (idle sockets, opened
    again as they are closed) cannot keep the session's page out: the page and its WebSocket
    get in on every one of 6 tries, and a page that got in is never the one closed."""
    f = BrowserFrontEnd(port=0, max_connections=4, open_timeout_s=30.0)
    stop = threading.Event()
    held: list[socket.socket] = []

    def hold() -> None:  # a new idle socket every 20 ms, 400 at most (bounded)
        for _ in range(400):
            if stop.is_set():
                return
            try:
                held.append(socket.create_connection(("127.0.0.1", f.port), timeout=WAIT_S))
            except OSError:
                pass
            time.sleep(0.02)

    th = threading.Thread(target=hold, daemon=True)
    try:
        for _ in range(8):  # every slot taken before the page comes
            held.append(socket.create_connection(("127.0.0.1", f.port), timeout=WAIT_S))
        assert wait_for(lambda: f.refused_connections >= 4)
        th.start()
        driver, role = page(f)
        assert role == "driver"
        for _ in range(6):  # the page reloaded 6 times (an observer each time)
            assert get(f"http://127.0.0.1:{f.port}/?token={f.token}") == 200
            ws, role = page(f)
            assert role == "observer"
            time.sleep(0.2)  # the holder opens about 10 more sockets meanwhile
            ws.close()
        assert f.refused_connections > 20
        assert driver.ping().wait(WAIT_S)  # the page that got in is still served
        driver.close()
    finally:
        stop.set()
        th.join(WAIT_S)
        for s in held:
            s.close()
        f.close()


def test_answers_only_for_the_trial_just_ended_once_and_one_calibration_per_step(tmp_path):
    """Issue 47: from the driving page, NASA-TLX answers for trials that do not exist, sent
    before or during a trial, or a second answer, are not stored: each trial keeps the answer
    given after it ended; 3000 calibrate messages make at most one row per write (one per
    decision step, and one before and after each trial)."""
    import sqlite3

    from pathpref.study.controls import TLX_SCALES

    study = parse_study({"questionnaire": "nasa-tlx",
                         "trials": [{**TRIAL, "name": "a", "time_limit_s": 2},
                                    {**TRIAL, "name": "b", "time_limit_s": 2}]})
    f = BrowserFrontEnd(port=0)
    db = tmp_path / "p.sqlite"
    th, box = _run_in_thread(study, "p1", db, f)
    ws, role = page(f)
    assert role == "driver"
    stop = threading.Event()
    keep_alive(ws, stop)

    def tlx(k: int, v: int) -> str:
        return json.dumps({"type": "tlx", "trial": k, "scores": dict.fromkeys(TLX_SCALES, v)})

    cal = json.dumps({"type": "calibrate", "rest": [0.0, 0.0], "reach": 1.0, "device": "x"})
    try:
        assert wait_for(lambda: f._scene is not None and f._status == "waiting")
        for k in range(1, 501):  # 500 answers for trials that exist or not, before any
            ws.send(tlx(k, 1))
        for _ in range(1500):
            ws.send(cal)
        ws.send('{"type": "start"}')
        assert wait_for(lambda: f._status == "running")
        ws.send(tlx(1, 2))  # during the trial
        for _ in range(1500):
            ws.send(cal)
        assert wait_for(lambda: f._status == "done")
        ws.send(tlx(2, 3))  # a pre-answer of the next trial
        ws.send(tlx(1, 40))  # the real answer
        ws.send(tlx(1, 4))  # a second one
        assert wait_for(lambda: f._status == "waiting")
        ws.send('{"type": "start"}')
        assert wait_for(lambda: f._status == "finished")
        ws.send(tlx(2, 60))
        th.join(WAIT_S)
    finally:
        stop.set()
        f.close()
    assert "error" not in box, box.get("error")
    c = sqlite3.connect(db)
    got = c.execute("SELECT trial, name, mental, raw_tlx FROM study_tlx ORDER BY trial")
    assert got.fetchall() == [(1, "a", 40, 40.0), (2, "b", 60, 60.0)]
    steps = sum(r["steps"] for r in box["rows"])
    n_cal = c.execute("SELECT count(*) FROM study_calibrations").fetchone()[0]
    assert 1 <= n_cal <= steps + 4


# --- issue 47: side files never followed through a link; a full disk is one line ---------
def _demo_rerun(db: Path, participant: str, position: int) -> Path:
    from pathpref.study.conduct import rerun_path
    from pathpref.study.plan import load_study

    study = load_study(STUDY)
    return rerun_path(db, participant, position, study.order_for(participant)[position - 1])


@pytest.mark.parametrize("side", ["lock", "rerun"])
def test_a_symlinked_side_file_is_refused_and_its_target_untouched(tmp_path, capsys, side):
    """A symbolic link planted at ``DB.P.lock`` or at a trial's rerun file: one line, exit 2,
    the link's target unchanged, nothing recorded."""
    db = tmp_path / "s.sqlite"
    target = tmp_path / "precious.txt"
    target.write_text("keep me\n")
    link = db.with_name(f"{db.name}.p.lock") if side == "lock" else _demo_rerun(db, "p", 2)
    link.parent.mkdir(exist_ok=True)
    link.symlink_to(target)
    assert main(["study", "run", str(STUDY), "--participant", "p", "--db", str(db),
                 "--script", str(PUSHES)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "symbolic link" in err and str(link) in err, err
    assert target.read_text() == "keep me\n" and link.is_symlink()
    assert not db.exists()
    assert not db.with_name(f"{db.name}.p.lock").exists() or side == "lock"


@pytest.mark.parametrize("where", ["database", "rerun"])
def test_a_full_disk_in_a_trial_is_one_line_and_resume_runs_it_again(tmp_path, capsys,
                                                                     monkeypatch, where):
    """SQLite's 'database or disk is full' at the third write of trial 1, or the rerun SDK's
    error of a full disk (its text as rerun 0.41 gives it) when the trial's file is opened:
    one line naming the file, exit 2, no rerun file of that trial, no lock left; --resume
    then runs both trials."""
    from pathpref.experiments.trials import TrialWriter
    from pathpref.study import record

    real, real_logger = TrialWriter.write, record.RerunLogger
    calls = {"n": 0}

    def write(self, *a, **k):
        calls["n"] += 1
        if calls["n"] == 3:
            raise sqlite3.OperationalError("database or disk is full")
        return real(self, *a, **k)

    class FullLogger:
        def __init__(self, world, goals, true_goal, out, **kwargs):
            Path(out).write_bytes(b"RRF2 half")
            raise RuntimeError("Failed to encode LogMsg: Failed to write: No space left on "
                               "device (os error 28)")

    if where == "database":
        monkeypatch.setattr(TrialWriter, "write", write)
    else:
        monkeypatch.setattr(record, "RerunLogger", FullLogger)
    db = tmp_path / "s.sqlite"
    argv = ["study", "run", str(STUDY), "--participant", "p", "--db", str(db), "--script",
            str(PUSHES)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no space left on device in trial 1" in err, err
    named = db if where == "database" else _demo_rerun(db, "p", 1)
    assert f"cannot write {named}:" in err and "--resume" in err
    assert not _demo_rerun(db, "p", 1).exists()
    assert not db.with_name(f"{db.name}.p.lock").exists()
    monkeypatch.setattr(TrialWriter, "write", real)
    monkeypatch.setattr(record, "RerunLogger", real_logger)
    assert main([*argv, "--resume"]) == 0
    rows = sqlite3.connect(db).execute("SELECT trial, status FROM trials").fetchall()
    assert sorted(rows) == [(1, "done"), (2, "done")]
