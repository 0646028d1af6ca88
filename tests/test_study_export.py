"""What a lab takes away from a study: MCAP and tidy CSV exports (read back with the ``mcap``
reader and ``csv``), a replay that refuses a changed row, ``db salvage`` keeping the study
tables."""

from __future__ import annotations

import csv
import json
import shutil
import sqlite3
from pathlib import Path

import numpy as np
import pytest

from pathpref.apps.cli import main

ROOT = Path(__file__).resolve().parents[1]
STUDY = ROOT / "examples" / "study_demo.json"
PUSHES = ROOT / "examples" / "pushes_demo.json"


@pytest.fixture(scope="module")
def demo_db(tmp_path_factory):
    db = tmp_path_factory.mktemp("export") / "study.sqlite"
    assert main(["study", "run", str(STUDY), "--participant", "demo", "--db", str(db),
                 "--script", str(PUSHES)]) == 0
    return db


def rows(db, q, *params):
    return sqlite3.connect(db).execute(q, params).fetchall()

def decoded(mcap, factory, topics: list[str]) -> list[tuple]:
    """Every message of ``topics`` in the MCAP file ``mcap``, decoded by the decoder factory
    ``factory`` (the format's own reader): ``(schema, channel, message, decoded)``."""
    from mcap.reader import make_reader

    with open(mcap, "rb") as f:
        reader = make_reader(f, decoder_factories=[factory()])
        return list(reader.iter_decoded_messages(topics=topics))


def export_demo(demo_db, tmp_path) -> Path:
    """``pathpref study export`` of the demo participant; the folder of its files."""
    out = tmp_path / "out"
    assert main(["study", "export", str(demo_db), "--participant", "demo", "--out",
                 str(out)]) == 0
    return out / "demo"



def test_mcap_holds_every_recorded_force_sample_and_the_events(demo_db, tmp_path, capsys):
    """Every trial_forces row is one /force/applied and one /force/sensed wrench, in order,
    with the recorded values (JSON floats round-trip exactly) 2 ms apart; every push, cue,
    belief update and decision step is a message."""
    from mcap.reader import make_reader

    out = tmp_path / "out"
    assert main(["study", "export", str(demo_db), "--participant", "demo", "--out",
                 str(out)]) == 0
    assert f"wrote {out / 'demo'}" in capsys.readouterr().out
    for k in (1, 2):
        with open(out / "demo" / f"trial-{k:02d}.mcap", "rb") as f:
            reader = make_reader(f)
            topics: dict[str, list] = {}
            for schema, channel, message in reader.iter_messages():
                if channel.topic.startswith(("/ros/", "/scene", "/tf", "/events")):
                    continue  # ROS 2 and Foxglove protobuf topics: tested below
                assert channel.message_encoding == "json" and schema.encoding == "jsonschema"
                topics.setdefault(channel.topic, []).append(
                    (message.log_time, json.loads(message.data)))
        forces = rows(demo_db, "SELECT time_s, fx, fy, sensed_fx, sensed_fy FROM trial_forces "
                      "WHERE trial = ? ORDER BY k", k)
        applied, sensed = topics["/force/applied"], topics["/force/sensed"]
        assert len(applied) == len(sensed) == len(forces) > 1000
        assert [(m["force"]["x"], m["force"]["y"]) for _, m in applied] == [
            (f[1], f[2]) for f in forces]
        assert [(m["force"]["x"], m["force"]["y"]) for _, m in sensed] == [
            (f[3], f[4]) for f in forces]
        gaps = {b[0] - a[0] for a, b in zip(applied[:-1], applied[1:])}
        assert gaps <= {1_999_999, 2_000_000, 2_000_001}  # 2 ms (rounded to the nanosecond)
        for topic, table in (("/pushes", "trial_pushes"), ("/cues", "trial_cues"),
                             ("/belief", "trial_beliefs"), ("/pose", "trial_path")):
            n = rows(demo_db, f"SELECT count(*) FROM {table} WHERE trial = ?", k)[0][0]
            assert len(topics.get(topic, [])) == n, topic
        peaks = [r[0] for r in rows(demo_db, "SELECT peak_n FROM trial_pushes WHERE trial = ? "
                                    "ORDER BY k", k)]
        assert [m["peak_n"] for _, m in topics["/pushes"]] == peaks
        path = rows(demo_db, "SELECT time_s, x, y FROM trial_path WHERE trial = ? ORDER BY k", k)
        assert [(m["pose"]["position"]["x"], m["pose"]["position"]["y"])
                for _, m in topics["/pose"]] == [(x, y) for _, x, y in path]
        poses = [t for t, _ in topics["/pose"]]
        assert len(poses) > 100 and max(b - a for a, b in zip(poses, poses[1:])) <= 20_000_000
        # the base's recorded pose at the path's rate (100 Hz; at least 50 Hz asked)



def test_mcap_ros2_messages_decode_typed(demo_db, tmp_path):
    """The /ros/ channels decode with mcap-ros2-support's decoder as geometry_msgs messages:
    one WrenchStamped per trial_forces row with the stored force, stamped at the row's time;
    one PoseStamped per decision step at the cell centre (0.5 m cells)."""
    from mcap_ros2.decoder import DecoderFactory

    got: dict[str, list] = {}
    for schema, channel, message, msg in decoded(
            export_demo(demo_db, tmp_path) / "trial-01.mcap", DecoderFactory,
            ["/ros/force/applied", "/ros/force/sensed", "/ros/pose"]):
        assert channel.message_encoding == "cdr" and schema.encoding == "ros2msg"
        got.setdefault(channel.topic, []).append((schema.name, message.log_time, msg))
    forces = rows(demo_db, "SELECT fx, fy, sensed_fx, sensed_fy FROM trial_forces "
                  "WHERE trial = 1 ORDER BY k")
    for topic, cols in (("/ros/force/applied", (0, 1)), ("/ros/force/sensed", (2, 3))):
        msgs = got[topic]
        assert {name for name, _, _ in msgs} == {"geometry_msgs/msg/WrenchStamped"}
        assert [(m.wrench.force.x, m.wrench.force.y) for _, _, m in msgs] == [
            (f[cols[0]], f[cols[1]]) for f in forces]  # float64 in CDR: exact
        assert all(m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec == t
                   for _, t, m in msgs)
        assert {m.header.frame_id for _, _, m in msgs} == {"world"}
        # the torque about the sensor of the force at the grip, 0.05 m below it on the disk
        # (navigate.xml: the handle's centre of mass under handle_site): (0.05 F_y, -0.05 F_x, 0)
        tq = np.array([(m.wrench.torque.x, m.wrench.torque.y, m.wrench.torque.z)
                       for _, _, m in msgs])
        fxy = np.array([(f[cols[0]], f[cols[1]]) for f in forces])
        assert np.allclose(tq, np.c_[0.05 * fxy[:, 1], -0.05 * fxy[:, 0], 0 * fxy[:, 0]],
                           rtol=0, atol=1e-9)
        pushed = np.hypot(*fxy.T) > 1.0
        assert pushed.any() and (np.hypot(*tq[pushed, :2].T) > 0.05 * 1.0 - 1e-9).all()
    path = rows(demo_db, "SELECT x, y FROM trial_path WHERE trial = 1 ORDER BY k")
    poses = got["/ros/pose"]
    assert {name for name, _, _ in poses} == {"geometry_msgs/msg/PoseStamped"}
    assert [(m.pose.position.x, m.pose.position.y, m.pose.orientation.w)
            for _, _, m in poses] == [(x, y, 1.0) for x, y in path]



def test_mcap_scene_belief_and_transforms_decode_as_foxglove(demo_db, tmp_path):
    """/scene, /scene/belief and /tf decode with the protobuf decoder as Foxglove messages:
    the walls of the 10x10 map (0..5 m) and its table (cells 5-6: 2..3 m), the route through
    the stored cells, one coloured sphere per goal candidate per belief update with opacity
    0.15 + 0.85 p, and one world -> base transform per decision step."""
    from mcap_protobuf.decoder import DecoderFactory

    got: dict[str, list] = {}
    for schema, _, message, msg in decoded(export_demo(demo_db, tmp_path) / "trial-01.mcap",
                                           DecoderFactory, ["/scene", "/scene/belief", "/tf"]):
        got.setdefault(message.channel_id, []).append((schema.name, msg))
    by_name: dict[str, list] = {}
    for msgs in got.values():
        by_name.setdefault(msgs[0][0], []).append([m for _, m in msgs])
    (scene, beliefs), (tfs,) = sorted(by_name["foxglove.SceneUpdate"], key=len), \
        by_name["foxglove.FrameTransform"]
    (entity,) = scene[0].entities
    walls, table, route = entity.lines
    assert [(p.x, p.y) for p in walls.points] == [(0, 0), (5, 0), (5, 5), (0, 5)]
    assert sorted((p.x, p.y) for p in table.points) == [(2, 2), (2, 3), (3, 2), (3, 3)]
    trial = rows(demo_db, "SELECT route, candidates FROM trials WHERE trial = 1")[0]
    assert [(p.x, p.y) for p in route.points] == [
        ((x - 0.5) * 0.5, (y - 0.5) * 0.5) for x, y in json.loads(trial[0])]
    stored = [json.loads(g) for (g,) in rows(
        demo_db, "SELECT goals FROM trial_beliefs WHERE trial = 1 ORDER BY k")]
    assert len(beliefs) == len(stored)
    cands = json.loads(trial[1])
    for msg, p in zip(beliefs, stored, strict=True):
        spheres = msg.entities[0].spheres
        assert [(s.pose.position.x, s.pose.position.y) for s in spheres] == [
            ((x - 0.5) * 0.5, (y - 0.5) * 0.5) for x, y in cands]
        assert [s.color.a for s in spheres] == pytest.approx([0.15 + 0.85 * q for q in p],
                                                              abs=1e-12)
    path = rows(demo_db, "SELECT x, y FROM trial_path WHERE trial = 1 ORDER BY k")
    assert [(m.parent_frame_id, m.child_frame_id, m.translation.x, m.translation.y)
            for m in tfs] == [("world", "base", x, y) for x, y in path]


def test_a_trial_without_a_recorded_path_has_its_poses_at_the_decision_steps(demo_db,
                                                                             tmp_path):
    """A file written before ``trial_path`` existed: /pose, /ros/pose and /tf fall back to one
    per decision step, at the centre of the stored cell (0.5 m cells)."""
    import shutil

    from mcap.reader import make_reader

    old = tmp_path / "old.sqlite"
    shutil.copy(demo_db, old)
    c = sqlite3.connect(old)
    c.execute("DELETE FROM trial_path")
    c.commit()
    c.close()
    out = tmp_path / "out"
    assert main(["study", "export", str(old), "--participant", "demo", "--out", str(out)]) == 0
    with open(out / "demo" / "trial-01.mcap", "rb") as f:
        msgs = [(ch.topic, m) for _, ch, m in make_reader(f).iter_messages(
            topics=["/pose", "/ros/pose", "/tf"])]
    steps = rows(old, "SELECT x, y FROM trial_steps WHERE trial = 1 ORDER BY t")
    for topic in ("/pose", "/ros/pose", "/tf"):
        assert sum(t == topic for t, _ in msgs) == len(steps) > 1, topic
    first = json.loads(next(m.data for t, m in msgs if t == "/pose"))
    x, y = steps[0]
    assert (first["pose"]["position"]["x"], first["pose"]["position"]["y"]) == (
        (x - 0.5) * 0.5, (y - 0.5) * 0.5)



def test_pushes_and_cues_are_typed_foxglove_events_and_arrows(demo_db, tmp_path):
    """/events/pushes and /events/cues decode (protobuf decoder) as foxglove.Event: one per
    stored row, in order, spanning the push (t_start..t_end) or the cue's push (time_s -
    duration_s..time_s) on the trial's clock, with every column back exactly from its
    metadata; /scene/pushes and /scene/cues draw one arrow each along the impulse, from the
    base's recorded position at the push's start or from the cue's cell centre."""
    import math
    from datetime import datetime

    from mcap_protobuf.decoder import DecoderFactory

    out = export_demo(demo_db, tmp_path)
    seen = 0
    for k in (1, 2):
        got: dict[str, list] = {}
        for schema, channel, _, msg in decoded(
                out / f"trial-{k:02d}.mcap", DecoderFactory,
                ["/events/pushes", "/events/cues", "/scene/pushes", "/scene/cues"]):
            got.setdefault(channel.topic, []).append((schema.name, msg))
        started = rows(demo_db, "SELECT started_utc FROM trials WHERE trial = ?", k)[0][0]
        t0 = int(datetime.fromisoformat(started).timestamp())
        for kind, table, cols in (
                ("pushes", "trial_pushes", ("k", "t_start", "t_end", "peak_n", "impulse_x",
                                            "impulse_y")),
                ("cues", "trial_cues", ("k", "time_s", "x", "y", "heading", "magnitude_n",
                                        "impulse_x", "impulse_y", "duration_s"))):
            stored = rows(demo_db, f"SELECT {', '.join(cols)} FROM {table} WHERE trial = ? "
                          "ORDER BY k", k)
            events = got.get(f"/events/{kind}", [])
            assert len(events) == len(stored) > 0, (k, kind)
            for (name, ev), r in zip(events, stored, strict=True):
                meta = {m.key: m.value for m in ev.metadata}
                assert name == "foxglove.Event"
                assert meta["kind"] == {"pushes": "push", "cues": "cue"}[kind]
                assert meta["participant"] == "demo" and int(meta["trial"]) == k
                back = tuple(int(meta[c]) if c in ("k", "x", "y", "heading") else
                             float(meta[c]) for c in cols)
                assert back == r  # exact: repr of a float round-trips
                row = dict(zip(cols, r, strict=True))
                start, end = ((row["t_start"], row["t_end"]) if kind == "pushes" else
                              (max(0.0, row["time_s"] - row["duration_s"]), row["time_s"]))
                for stamp, want in ((ev.start_time, start), (ev.end_time, end)):
                    got_s = stamp.seconds - t0 + stamp.nanos * 1e-9
                    assert got_s == pytest.approx(want, abs=1e-6)
            arrows = got.get(f"/scene/{kind}", [])
            assert len(arrows) == len(stored)
            for (_, upd), r in zip(arrows, stored, strict=True):
                row = dict(zip(cols, r, strict=True))
                (a,) = upd.entities[0].arrows
                q = a.pose.orientation
                angle = 2 * math.atan2(q.z, q.w)
                want = math.atan2(row["impulse_y"], row["impulse_x"])
                assert math.remainder(angle - want, 2 * math.pi) == pytest.approx(0, abs=1e-9)
                if kind == "cues":
                    at = ((row["x"] - 0.5) * 0.5, (row["y"] - 0.5) * 0.5)
                else:
                    at = rows(demo_db, "SELECT x, y FROM trial_path WHERE trial = ? AND "
                              "time_s <= ? ORDER BY k DESC LIMIT 1", k, row["t_start"])[0]
                assert (a.pose.position.x, a.pose.position.y) == pytest.approx(at, abs=1e-12)
                assert 0 < a.shaft_length <= 1.5
            seen += len(stored)
    assert seen >= 4


def test_continuous_path_is_recorded_at_100_hz_and_exported(demo_db, tmp_path):
    """trial_path holds the base every 5th 2 ms physics step (10 ms apart), starting at the
    start cell's centre; path.csv and /ros/path (PoseStamped) carry every row unchanged."""
    from mcap_ros2.decoder import DecoderFactory

    path = rows(demo_db, "SELECT time_s, x, y, ee_x FROM trial_path WHERE trial = 1 "
                "ORDER BY k")
    n_forces = rows(demo_db, "SELECT count(*) FROM trial_forces WHERE trial = 1")[0][0]
    assert len(path) == (n_forces + 4) // 5 > 500
    gaps = [b[0] - a[0] for a, b in zip(path[:-1], path[1:])]
    assert max(gaps) == pytest.approx(0.010, abs=1e-9) == min(gaps)
    x, y = rows(demo_db, "SELECT x, y FROM trial_steps WHERE trial = 1 AND t = 0")[0]
    assert path[0][1:3] == pytest.approx(((x - 0.5) * 0.5, (y - 0.5) * 0.5), abs=1e-3)
    assert {p[3] for p in path} == {None}  # the plain base carries nothing
    out = export_demo(demo_db, tmp_path)
    with open(out / "path.csv", newline="") as f:
        table = [r for r in csv.DictReader(f) if r["trial"] == "1"]
    assert [(float(r["time_s"]), float(r["x"]), float(r["y"])) for r in table] == [
        p[:3] for p in path]
    poses = [(m.pose.position.x, m.pose.position.y) for _, _, _, m in decoded(
        out / "trial-01.mcap", DecoderFactory, ["/ros/path", "/ros/end_effector"])]
    assert poses == [p[1:3] for p in path]



def test_export_of_a_file_without_the_path_table(demo_db, tmp_path):
    """A study file written before trial_path existed exports whole: path.csv is its header,
    the MCAP has no /ros/path messages, every other table as before."""
    from mcap.reader import make_reader

    db = tmp_path / "old.sqlite"
    shutil.copy(demo_db, db)
    with sqlite3.connect(db) as c:
        c.execute("DROP TABLE trial_path")
    out = tmp_path / "out"
    assert main(["study", "export", str(db), "--participant", "demo", "--out", str(out)]) == 0
    assert (out / "demo" / "path.csv").read_text().splitlines() == [
        "participant,trial,k,time_s,x,y,ee_x,ee_y,ee_z"]
    with open(out / "demo" / "trial-01.mcap", "rb") as f:
        summary = make_reader(f).get_summary()
    topics = {ch.id: ch.topic for ch in summary.channels.values()}
    counts = {topics[i]: n for i, n in summary.statistics.channel_message_counts.items()}
    assert counts.get("/ros/path", 0) == 0 and counts["/ros/force/applied"] > 1000


def test_tidy_csv_folder(demo_db, tmp_path):
    assert main(["study", "export", str(demo_db), "--participant", "demo", "--out",
                 str(tmp_path), "--no-mcap"]) == 0
    folder = tmp_path / "demo"
    assert sorted(p.name for p in folder.iterdir()) == [
        "beliefs.csv", "calibration.csv", "cues.csv", "forces.csv", "path.csv", "pushes.csv",
        "steps.csv", "tlx.csv", "trials.csv"]

    def read(name):
        with open(folder / name, newline="") as f:
            return list(csv.DictReader(f))

    forces = read("forces.csv")
    assert len(forces) == rows(demo_db, "SELECT count(*) FROM trial_forces")[0][0]
    assert {r["participant"] for r in forces} == {"demo"}
    trials = read("trials.csv")
    assert [(r["trial"], r["outcome"]) for r in trials] == [
        (str(a), b) for a, b in rows(demo_db, "SELECT trial, outcome FROM trials ORDER BY "
                                     "trial")]
    beliefs = read("beliefs.csv")
    stored = rows(demo_db, "SELECT trial, k, goals FROM trial_beliefs ORDER BY trial, k")
    assert len(beliefs) == sum(len(json.loads(g)) for _, _, g in stored)  # 3 goals each
    first = [r for r in beliefs if r["trial"] == "1" and r["k"] == "0"]
    assert [(r["goal_x"], r["goal_y"]) for r in first] == [("2", "9"), ("5", "9"), ("9", "9")]
    assert [float(r["p"]) for r in first] == json.loads(stored[0][2])


def test_export_of_an_unknown_participant_is_one_line(demo_db, tmp_path, capsys):
    assert main(["study", "export", str(demo_db), "--participant", "nobody", "--out",
                 str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no trials of participant 'nobody'" in err


@pytest.mark.parametrize("change, column", [
    ("UPDATE trials SET outcome = 'success', success = 1 WHERE trial = 1", None),
    ("UPDATE trials SET pushes = pushes + 1 WHERE trial = 1", "pushes"),
    ("UPDATE trials SET effort_ns = effort_ns * 1.01 WHERE trial = 1", "effort_ns"),
    ("DELETE FROM trial_cues WHERE trial = 1 AND k = 0", "cues"),
    ("UPDATE trials SET time_s = time_s + 0.5 WHERE trial = 1", "time_s"),
])
def test_replay_refuses_a_changed_row(demo_db, tmp_path, capsys, change, column):
    """A timed-out trial relabelled a success (or a success relabelled a timeout), a push
    added, effort inflated, a cue row removed, the time changed: one line naming the column,
    exit 2, no video."""
    db = tmp_path / "t.sqlite"
    shutil.copy(demo_db, db)
    outcome = rows(db, "SELECT outcome FROM trials WHERE trial = 1")[0][0]
    if column is None:  # relabel to the other outcome
        change = ("UPDATE trials SET outcome = 'timeout', success = 0 WHERE trial = 1"
                  if outcome == "success" else change)
        column = "outcome"
    with sqlite3.connect(db) as c:
        c.execute(change)
    out = tmp_path / "t.mp4"
    assert main(["replay", str(db), "--participant", "demo", "--trial", "1", "--out",
                 str(out), "--width", "32", "--height", "24"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"trials.{column} is" in err, err
    assert not out.exists()


def test_replay_streams_frames_and_holds_no_list(demo_db, tmp_path, monkeypatch):
    """Frames go to the encoder one at a time: the encoder never holds more than the frame it
    is given (the replay keeps no frame list; counted, not timed)."""
    from pathpref.sim import render
    from pathpref.study import replay

    seen = {"n": 0, "ids": set()}
    real = render.VideoWriter.append

    def append(self, frame):
        seen["n"] += 1
        seen["ids"].add(id(frame))
        real(self, frame)

    monkeypatch.setattr(render.VideoWriter, "append", append)
    n = replay.replay_trial(demo_db, "demo", 1, tmp_path / "v.mp4", 32, 24)
    time_s = rows(demo_db, "SELECT time_s FROM trials WHERE trial = 1")[0][0]
    assert n == seen["n"] and abs(n - (time_s * 25 + 1 + 25)) <= 2  # + last frame, 1 s card
    # a frame list would keep every frame alive: distinct ids for all; streamed frames are
    # freed and their memory reused, so ids repeat
    assert len(seen["ids"]) < n


def test_replay_video_shows_the_trail_and_ends_with_the_outcome_card(demo_db, tmp_path,
                                                                     monkeypatch):
    """The top view draws the base's trail: every trail point lies on the recorded path
    (trial_path, within 1 cm: the replay runs the same physics), consecutive points >= 5 cm
    apart, and by the end it spans the trip; the video ends with the final frame and the
    outcome card held for 1 s (25 identical frames, the frame faded, the card's box white)."""
    from pathpref.sim import render
    from pathpref.study import replay

    frames, trails = [], []
    real_append, real_views = render.VideoWriter.append, render.RolloutRenderer.views

    def append(self, frame):
        frames.append(np.array(frame))
        real_append(self, frame)

    def views(self, data, overlay):
        trails.append(None if overlay.trail is None else np.array(overlay.trail))
        return real_views(self, data, overlay)

    monkeypatch.setattr(render.VideoWriter, "append", append)
    monkeypatch.setattr(render.RolloutRenderer, "views", views)
    replay.replay_trial(demo_db, "demo", 1, tmp_path / "c.mp4", 160, 90)
    path = np.array(rows(demo_db, "SELECT x, y FROM trial_path WHERE trial = 1 ORDER BY k"))
    last = trails[-1]
    assert len(last) > 20
    gap = np.hypot(*np.diff(last[:-1], axis=0).T)
    assert gap.min() >= replay.TRAIL_STEP_M - 1e-12
    near = np.min(np.hypot(*(last[:, None, :] - path[None, :, :]).transpose(2, 0, 1)), axis=1)
    assert near.max() < 0.01
    assert np.hypot(*(last[0] - path[0])) < 0.01 and np.hypot(*(last[-1] - path[-1])) < 0.01
    card, final = frames[-1], frames[-26]
    assert all(np.array_equal(f, card) for f in frames[-25:])
    assert not np.array_equal(final, card)
    h, w = card.shape[:2]
    assert (card[h // 2 - 2:h // 2 + 2, w // 2 - 2:w // 2 + 2] >= 250).all()  # the box
    assert card.mean() > final.mean() + 20  # faded towards white
    lines = [t for t, _ in replay.study_outcome_lines(
        {"outcome": "success", "time_s": 16.04, "violations": 0, "pushes": 7, "cues": 7,
         "effort_ns": 98.14, "steps": 9})]
    assert lines == ["SUCCESS: goal reached in 16.0 s", "preferred route followed",
                     "pushes: 7   cues: 7   effort: 98.1 N s", "decision steps: 9"]
    assert replay.study_outcome_lines(
        {"outcome": "timeout", "time_s": 30.0, "violations": 2, "pushes": 1, "cues": 0,
         "effort_ns": 3.0, "steps": 30})[:2] == [
        ("TIMEOUT: goal not reached in 30.0 s", (190, 30, 30)),
        ("preferred route: 2 violation(s)", (190, 30, 30))]


def test_salvage_keeps_the_study_tables(demo_db, tmp_path, capsys):
    """An intact study database salvages whole (every row of every study table); a trial that
    lost a row is left out whole and counted."""
    from pathpref.experiments.trials import STUDY_TABLE_NAMES

    out = tmp_path / "saved.sqlite"
    assert main(["db", "salvage", str(demo_db), str(out)]) == 0
    assert "saved 2 study trials" in capsys.readouterr().out
    for t in STUDY_TABLE_NAMES:
        q = f"SELECT * FROM {t} ORDER BY participant, trial"
        assert rows(out, q) == rows(demo_db, q), t
    broken = tmp_path / "broken.sqlite"
    shutil.copy(demo_db, broken)
    with sqlite3.connect(broken) as c:
        c.execute("DELETE FROM trial_pushes WHERE trial = 2 AND k = 1")
    out2 = tmp_path / "saved2.sqlite"
    assert main(["db", "salvage", str(broken), str(out2)]) == 0
    said = capsys.readouterr().out
    assert "saved 1 study trials" in said and "lost 1 trials" in said
    assert rows(out2, "SELECT trial FROM trials") == [(1,)]
    assert rows(out2, "SELECT count(*) FROM trial_forces WHERE trial = 2") == [(0,)]
    q = "SELECT * FROM trial_forces ORDER BY k"
    assert rows(out2, q) == rows(demo_db, "SELECT * FROM trial_forces WHERE trial = 1 "
                                 "ORDER BY k")


def test_replay_video_has_its_info_panel(demo_db, tmp_path, monkeypatch):
    """The replay's frames carry the info panel (it was blank): the trial, the step, the
    belief and the recorded outcome, on every frame but the outcome card's (held 1 s)."""
    from pathpref.study import replay

    infos = []
    real = replay.info_panel

    def spy(w, h, info):
        infos.append(info)
        return real(w, h, info)

    monkeypatch.setattr(replay, "info_panel", spy)
    n = replay.replay_trial(demo_db, "demo", 1, tmp_path / "p.mp4", 320, 180)
    assert len(infos) == n - 25 > 0
    outcome, time_s, cues = rows(demo_db, "SELECT outcome, time_s, cues FROM trials WHERE "
                                 "trial = 1")[0]
    assert infos[0].title.startswith("demo trial 1: ")
    assert f"recorded: {outcome} in {time_s:.1f} s" in infos[-1].extra
    assert infos[-1].pushes == cues and abs(float(infos[-1].belief.sum()) - 1.0) < 1e-9


def test_parquet_beside_csv_reads_back_with_arrow(demo_db, tmp_path, capsys):
    """``--format both``: every table as CSV and as Parquet with the same columns and rows
    (pyarrow's own reader; every value printed as the CSV prints it), typed as the study
    tables (int64, float64, string); the force samples are every stored row, 2 ms apart.
    ``--format parquet`` alone writes no CSV; the default writes no Parquet."""
    pq = pytest.importorskip("pyarrow.parquet", reason="pyarrow is installed by make install "
                             "(the 'parquet' extra); without it Parquet export is refused")
    out = tmp_path / "both"
    assert main(["study", "export", str(demo_db), "--participant", "demo", "--out", str(out),
                 "--no-mcap", "--format", "both"]) == 0
    folder = out / "demo"
    stems = ["beliefs", "calibration", "cues", "forces", "path", "pushes", "steps", "tlx",
             "trials"]
    assert sorted(p.name for p in folder.iterdir()) == sorted(
        [f"{s}.csv" for s in stems] + [f"{s}.parquet" for s in stems])
    for stem in stems:
        with open(folder / f"{stem}.csv", newline="") as f:
            header, *body = list(csv.reader(f))
        table = pq.read_table(folder / f"{stem}.parquet")
        assert table.column_names == header and table.num_rows == len(body)
        cols = [table.column(n).to_pylist() for n in header]
        assert [["" if v is None else str(v) for v in r] for r in zip(*cols)] == body, stem
    forces = pq.read_table(folder / "forces.parquet")
    assert str(forces.schema.field("fx").type) == "double"
    assert str(forces.schema.field("k").type) == "int64"
    assert str(forces.schema.field("participant").type) == "string"
    stored = rows(demo_db, "SELECT trial, k, time_s, fx, fy, sensed_fx, sensed_fy FROM "
                  "trial_forces ORDER BY trial, k")
    got = list(zip(*(forces.column(n).to_pylist() for n in (
        "trial", "k", "time_s", "fx", "fy", "sensed_fx", "sensed_fy")), strict=True))
    assert got == stored and len(got) > 1000
    for (t0, k0, s0, *_), (t1, k1, s1, *_) in zip(got, got[1:]):
        if t0 == t1:
            assert k1 == k0 + 1 and abs((s1 - s0) - 0.002) < 1e-9  # the 2 ms physics step
    only = tmp_path / "pq"
    assert main(["study", "export", str(demo_db), "--participant", "demo", "--out", str(only),
                 "--no-mcap", "--format", "parquet"]) == 0
    assert sorted(p.suffix for p in (only / "demo").iterdir()) == [".parquet"] * len(stems)
    csv_only = tmp_path / "csv"
    assert main(["study", "export", str(demo_db), "--participant", "demo", "--out",
                 str(csv_only), "--no-mcap"]) == 0
    assert sorted(p.suffix for p in (csv_only / "demo").iterdir()) == [".csv"] * len(stems)


def test_parquet_row_groups_bound_the_buffer(tmp_path, monkeypatch):
    """Worst case of the Parquet buffer: more rows than a row group holds are written as
    several groups (the buffer never holds more than PARQUET_GROUP_ROWS rows), and an empty
    table is a file with its columns and no rows."""
    pq = pytest.importorskip("pyarrow.parquet", reason="pyarrow is installed by make install")
    from pathpref.study import export

    monkeypatch.setattr(export, "PARQUET_GROUP_ROWS", 4)
    cols = [("participant", "TEXT"), ("k", "INTEGER"), ("x", "REAL")]
    seen = []
    w = export.TableWriter(tmp_path, "t", cols, ("parquet",))
    for k in range(10):
        w.write(["p", k, None if k == 3 else k / 8])
        seen.append(len(w._buffer))
    assert max(seen) < 4 and w.close() == {"t.parquet": 10}
    f = pq.ParquetFile(tmp_path / "t.parquet")
    assert f.metadata.num_row_groups == 3  # 4 + 4 + 2
    assert f.read().to_pylist() == [{"participant": "p", "k": k,
                                     "x": None if k == 3 else k / 8} for k in range(10)]
    assert export._write_table(tmp_path, "e", cols, [], ("csv", "parquet")) == {
        "e.csv": 0, "e.parquet": 0}
    assert pq.read_table(tmp_path / "e.parquet").column_names == ["participant", "k", "x"]


# --- issue 47: an export is written whole or not at all ----------------------------------
def _export(db, out, *extra) -> int:
    return main(["study", "export", str(db), "--participant", "demo", "--out", str(out),
                 *extra])


def _tree(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file()}


def test_full_disk_during_an_export_leaves_nothing(demo_db, tmp_path, capsys, monkeypatch):
    """ENOSPC while the MCAP files are written (after every table): one line, exit 2; a new
    --out folder is gone, and an earlier export in an existing one is unchanged."""
    import errno

    from pathpref.study import export

    assert _export(demo_db, tmp_path / "old", "--no-mcap") == 0
    before = _tree(tmp_path / "old")
    capsys.readouterr()

    def full(*a, **k):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(export, "write_mcap", full)
    for out in (tmp_path / "new", tmp_path / "old"):
        assert _export(demo_db, out) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("pathpref: error: cannot write ")
        assert "no space left on device" in err and "nothing was written" in err
    assert not (tmp_path / "new").exists()
    assert _tree(tmp_path / "old") == before  # no temporary folder, nothing replaced


def test_export_out_that_is_a_file_is_one_line(demo_db, tmp_path, capsys):
    f = tmp_path / "file.txt"
    f.write_text("keep")
    assert _export(demo_db, f) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is not a folder" in err
    assert f.read_text() == "keep" and sorted(tmp_path.iterdir()) == [f]


@pytest.mark.parametrize("change, named", [
    ("UPDATE trials SET candidates = '[[2, 9], [5' WHERE trial = 1", "has candidates ="),
    ("UPDATE trial_beliefs SET goals = '[0.1, 0.2, 0.3, 0.4]' WHERE trial = 1 AND k = 0",
     "has goals ="),
    ("UPDATE trials SET started_utc = 'yesterday' WHERE trial = 2", "has started_utc ="),
    ("UPDATE trial_forces SET fx = 'strong' WHERE trial = 1 AND k = 5", "has fx = 'strong'"),
    ("UPDATE trial_forces SET time_s = 1e308 WHERE trial = 2 AND k = 3", "has time_s = 1e+308"),
    ("UPDATE trial_steps SET time_s = 1e308 WHERE trial = 2 AND t = 1", "has time_s = 1e+308"),
    ("UPDATE trials SET trial = 1e30 WHERE trial = 2", "has trial = 1e+30"),
])
@pytest.mark.parametrize("fmt", ["csv", "both"])
def test_export_of_a_tampered_row_is_one_line_and_leaves_nothing(demo_db, tmp_path, capsys,
                                                                 change, named, fmt):
    db = tmp_path / "t.sqlite"
    shutil.copy(demo_db, db)
    with sqlite3.connect(db) as c:
        c.execute(change)
    assert _export(db, tmp_path / "x", "--format", fmt) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and named in err and "changed outside pathpref" in err, err
    assert not (tmp_path / "x").exists()


# --- issue 47: report and replay on tampered study rows ------------------------------------
TAMPERED_TRIALS = [
    ("candidates = '[[2, 9'", "has candidates = '[[2, 9'"),
    ("seed = -1", "has seed = -1, not an integer >= 0"),
    ("goal = '[1, 1]'", "has goal = '[1, 1]', not one of the trial's candidates"),
    ("trial = 1e30", "has trial = 1e+30, not an integer"),
    ("condition = '{not json'", "has condition = '{not json'"),
    ("success = NULL", "has success = NULL"),
    ("success = 5", "has success = 5, not 0 or 1"),
    ("success = 'x'", "has success = 'x', not an integer"),
]


def _tampered(demo_db, tmp_path, change: str) -> Path:
    db = tmp_path / "t.sqlite"
    shutil.copy(demo_db, db)
    with sqlite3.connect(db) as c:
        c.execute(f"UPDATE trials SET {change} WHERE trial = 1")
    return db


@pytest.mark.parametrize("change, named", TAMPERED_TRIALS)
def test_report_on_a_tampered_trial_row_is_one_line(demo_db, tmp_path, capsys, change,
                                                    named):
    db = _tampered(demo_db, tmp_path, change)
    csv_out = tmp_path / "r.csv"
    assert main(["report", str(db), "--csv", str(csv_out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and named in err and "changed outside pathpref" in err, err
    assert "trials row (participant 'demo'" in err
    assert not csv_out.exists() and not (tmp_path / "r-study.csv").exists()


@pytest.mark.parametrize("change, named", [
    t if not t[0].startswith("trial =") else (t[0], "has no trial 1 of participant 'demo'")
    for t in TAMPERED_TRIALS])
def test_replay_of_a_tampered_trial_row_is_one_line(demo_db, tmp_path, capsys, change, named):
    db = _tampered(demo_db, tmp_path, change)
    out = tmp_path / "t.mp4"
    assert main(["replay", str(db), "--participant", "demo", "--trial", "1", "--out",
                 str(out), "--width", "32", "--height", "24"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and named in err, err
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["t.sqlite"]


def _rerun_cli() -> str | None:
    import shutil as sh
    import sys

    here = Path(sys.executable).parent / "rerun"
    return str(here) if here.exists() else sh.which("rerun")


def _rerun_catalog() -> bool:
    try:
        import datafusion  # noqa: F401  (rerun-sdk[catalog])
        import pandas  # noqa: F401
        import rerun.server  # noqa: F401
    except ImportError:
        return False
    return True


@pytest.mark.skipif(_rerun_cli() is None or not _rerun_catalog(),
                    reason="rerun-sdk[catalog] (the rerun CLI and rr.server) not installed")
def test_rerun_mcap_import_yields_typed_entities(demo_db, tmp_path):
    """rerun's MCAP importer (``rerun mcap convert``) makes /ros/pose an InstancePoses3D and
    each /ros/force/* message a decoded geometry_msgs WrenchStamped and each push and cue a
    decoded foxglove.Event (one per row, its k in the metadata), read back from the .rrd
    through rerun's own Python reader (``rr.server``): one per trial_forces row with the stored
    force, in order (the JSON twins stay raw bytes)."""
    import subprocess

    import rerun as rr

    out = tmp_path / "out"
    assert main(["study", "export", str(demo_db), "--participant", "demo", "--out",
                 str(out)]) == 0
    rrd = tmp_path / "t1.rrd"
    subprocess.run([_rerun_cli(), "mcap", "convert", str(out / "demo" / "trial-01.mcap"),
                    "-o", str(rrd)], check=True, capture_output=True, timeout=120)
    forces = rows(demo_db, "SELECT fx, fy, sensed_fx, sensed_fy FROM trial_forces "
                  "WHERE trial = 1 ORDER BY k")
    with rr.server.Server(datasets={"t": [str(rrd)]}) as server:
        ds = server.client().get_dataset("t")
        names = {str(c.name) for c in ds.schema()}
        assert "/ros/pose:InstancePoses3D:translations" in names
        assert "/force/applied:McapMessage:data" in names
        for topic, table in (("/events/pushes", "trial_pushes"), ("/events/cues", "trial_cues")):
            col = f"{topic}:foxglove.Event:message"  # decoded: a typed event, not bytes
            ks = [int(next(kv["value"] for kv in m["metadata"] if kv["key"] == "k"))
                  for cell in ds.filter_contents([topic]).reader(
                      index="message_log_time").to_arrow_table().column(col).to_pylist()
                  if cell for m in cell]
            assert sorted(ks) == [k for (k,) in rows(
                demo_db, f"SELECT k FROM {table} WHERE trial = 1 ORDER BY k")], topic
        for topic, cols in (("/ros/force/applied", (0, 1)), ("/ros/force/sensed", (2, 3))):
            table = ds.filter_contents([topic]).reader(
                index="message_log_time").to_arrow_table()
            col = f"{topic}:geometry_msgs.msg.WrenchStamped:message"
            got = [(m["wrench"]["force"]["x"], m["wrench"]["force"]["y"])
                   for cell in table.sort_by("message_log_time").column(col).to_pylist()
                   if cell for m in cell]
            assert got == [(f[cols[0]], f[cols[1]]) for f in forces], topic


def _lerobot_layout(root: Path) -> tuple[dict, object, object]:
    """The dataset at ``root`` checked against LeRobot v3's documented layout (meta/info.json,
    meta/tasks.parquet, meta/episodes/chunk-XXX/file-XXX.parquet, data/chunk-XXX/file-XXX
    .parquet; every feature a column of its dtype and shape; LeRobot's five own columns;
    episodes contiguous in ``index``); (info, frames, episodes) as pyarrow tables."""
    pa = pytest.importorskip("pyarrow")
    pq = pytest.importorskip("pyarrow.parquet")
    pd = pytest.importorskip("pandas")
    info = json.loads((root / "meta" / "info.json").read_text())
    assert info["codebase_version"] == "v3.0" and info["video_path"] is None
    assert info["data_path"] == "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
    for k in ("timestamp", "frame_index", "episode_index", "index", "task_index"):
        assert info["features"][k]["shape"] == [1]
    episodes = pq.read_table(root / "meta" / "episodes" / "chunk-000" / "file-000.parquet")
    eps = episodes.to_pylist()
    files = sorted({(e["data/chunk_index"], e["data/file_index"]) for e in eps})
    frames = pa.concat_tables(pq.read_table(root / info["data_path"].format(
        chunk_index=c, file_index=f)) for c, f in files)
    types = {"float32": pa.float32(), "int64": pa.int64(), "bool": pa.bool_()}
    for k, ft in info["features"].items():
        want = types[ft["dtype"]] if ft["shape"] == [1] else pa.list_(types[ft["dtype"]],
                                                                      ft["shape"][0])
        assert frames.schema.field(k).type == want, k
    assert frames.num_rows == info["total_frames"] and len(eps) == info["total_episodes"]
    assert frames.column("index").to_pylist() == list(range(frames.num_rows))
    tasks = pd.read_parquet(root / "meta" / "tasks.parquet")
    assert len(tasks) == info["total_tasks"] and list(tasks.columns) == ["task_index"]
    task_of = {int(v): k for k, v in tasks["task_index"].items()}
    fi, ei, ts, ti = (frames.column(c).to_pylist() for c in (
        "frame_index", "episode_index", "timestamp", "task_index"))
    at = 0
    for e in eps:
        assert (e["dataset_from_index"], e["dataset_to_index"]) == (at, at + e["length"])
        seg = range(at, at + e["length"])
        assert [fi[i] for i in seg] == list(range(e["length"]))
        assert {ei[i] for i in seg} == {e["episode_index"]}
        assert {task_of[ti[i]] for i in seg} == set(e["tasks"])
        assert max(abs(ts[i] - fi[i] / info["fps"]) for i in seg) < 1e-4  # float32 seconds
        at += e["length"]
    return info, frames, episodes


def _lerobot_loader_check(root: Path, frames) -> None:
    """LeRobot's own loader on the dataset, when installed (the optional 'lerobot' extra):
    every frame's state as written."""
    try:
        from lerobot.datasets.lerobot_dataset import LeRobotDataset
    except ImportError:
        return
    ds = LeRobotDataset("local/pathpref", root=root)
    assert len(ds) == frames.num_rows
    for i in (0, frames.num_rows // 2, frames.num_rows - 1):
        got = ds[i]["observation.state"].tolist()
        assert got == pytest.approx(frames.column("observation.state")[i].as_py(), abs=0)


def test_lerobot_dataset_of_study_trials(demo_db, tmp_path, capsys):
    """``pathpref dataset`` (study): a LeRobot v3 dataset, an episode per finished trial, a
    frame per trial_path row (100 fps): the state is the recorded position, the intervention
    the force applied at that physics step (trial_forces at the same time), is_intervention
    |F| > 0.5 N, the action the velocity to the next frame, the robot's action the decision in
    force; stats.json's means those of the frames."""
    root = tmp_path / "ds"
    assert main(["dataset", str(demo_db), "--out", str(root)]) == 0
    assert "LeRobot v3.0 dataset, 2 episodes" in capsys.readouterr().out
    info, frames, episodes = _lerobot_layout(root)
    assert info["fps"] == 100
    eps = episodes.to_pylist()
    assert [e["source_key"] for e in eps] == ["demo/1", "demo/2"]
    assert eps[0]["tasks"] == [
        "reach goal (5, 9) of map simple along the route " + " ".join(
            f"({x}, {y})" for x, y in json.loads(rows(demo_db, "SELECT route FROM trials "
                                                      "WHERE trial = 1")[0][0]))]
    col = {c: frames.column(c).to_pylist() for c in frames.column_names}
    pushed = 0
    for e in eps:
        trial = int(e["source_key"].split("/")[1])
        path = rows(demo_db, "SELECT time_s, x, y FROM trial_path WHERE trial = ? ORDER BY k",
                    trial)
        force = dict(((round(t, 6), (fx, fy)) for t, fx, fy in rows(
            demo_db, "SELECT time_s, fx, fy FROM trial_forces WHERE trial = ?", trial)))
        steps = rows(demo_db, "SELECT time_s, action FROM trial_steps WHERE trial = ? "
                     "ORDER BY t", trial)
        assert e["length"] == len(path)
        seg = range(e["dataset_from_index"], e["dataset_to_index"])
        xy = np.array([p[1:] for p in path])
        assert np.array([col["observation.state"][i] for i in seg]) == pytest.approx(
            xy.astype(np.float32), abs=0)
        f = np.array([force.get(round(p[0], 6), (0.0, 0.0)) for p in path])
        assert np.array([col["intervention"][i] for i in seg]) == pytest.approx(
            f.astype(np.float32), abs=0)
        on = list(np.hypot(f[:, 0], f[:, 1]) > 0.5)
        assert [col["is_intervention"][i] for i in seg] == on
        pushed += sum(on)
        v = np.vstack([np.diff(xy, axis=0) * 100, [0.0, 0.0]])
        assert np.array([col["action"][i] for i in seg]) == pytest.approx(v, abs=1e-3)
        acts = [[a for s, a in steps if s <= p[0] + 1e-9][-1] for p in path]
        assert [col["observation.robot_action"][i] for i in seg] == acts
    assert pushed > 100  # the demo's pushes are a second or so each
    stats = json.loads((root / "meta" / "stats.json").read_text())
    assert stats["observation.state"]["mean"] == pytest.approx(
        np.mean(col["observation.state"], axis=0), abs=1e-5)
    assert stats["is_intervention"]["mean"] == [pytest.approx(pushed / frames.num_rows)]
    assert stats["observation.state"]["count"] == [frames.num_rows]
    _lerobot_loader_check(root, frames)
    before = _tree(root)
    capsys.readouterr()
    for args, said in (([str(demo_db), "--out", str(root)], "exists; give a new folder"),
                       ([str(demo_db), "--out", str(tmp_path / "e"), "--source", "episodes"],
                        "holds no --sim mujoco episodes"),
                       ([str(tmp_path / "none.sqlite"), "--out", str(tmp_path / "n")],
                        "no results database")):
        assert main(["dataset", *args]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and said in err, err
    assert _tree(root) == before and sorted(p.name for p in tmp_path.iterdir()) == ["ds"]


def test_lerobot_dataset_of_physical_episodes(tmp_path, capsys):
    """``pathpref dataset --source episodes`` on a one-episode ``--sim mujoco`` sweep: a frame
    per decision step (fps 1), the state the cell after step t, the intervention the heading
    observed from the push after it (row t + 1), is_intervention row t's, the action the next
    one (row t + 1's); the frames that are interventions are the episode's inputs."""
    db = tmp_path / "sweep.sqlite"
    assert main(["evaluate", "--sim", "mujoco", "--methods", "path_preference", "--delta-t",
                 "5", "--instances", "1", "--runs", "1", "--goals", "3", "--queries", "100",
                 "--db", str(db), "--no-progress", "--workers", "1"]) == 0
    root = tmp_path / "eps"
    assert main(["dataset", str(db), "--out", str(root), "--source", "episodes"]) == 0
    info, frames, episodes = _lerobot_layout(root)
    assert info["fps"] == 1 and info["total_episodes"] == 1
    (key, inputs), = rows(db, "SELECT key, inputs FROM episodes")
    assert episodes.column("source_key").to_pylist() == [key]
    steps = rows(db, "SELECT x, y, action, heading, is_intervention FROM steps WHERE key = ? "
                 "ORDER BY t", key)
    col = {c: frames.column(c).to_pylist() for c in frames.column_names}
    assert col["observation.state"] == [[float(s[0]), float(s[1])] for s in steps]
    assert col["intervention"] == [s[3] for s in steps[1:]] + [-1]
    assert col["action"] == [s[2] for s in steps[1:]] + [-1]
    assert col["is_intervention"] == [bool(s[4]) for s in steps]
    assert sum(col["is_intervention"]) == inputs > 0
    _lerobot_loader_check(root, frames)
    assert main(["dataset", str(db), "--out", str(tmp_path / "s")]) == 2  # no study trials
    assert "holds no finished study trials" in capsys.readouterr().err
    assert not (tmp_path / "s").exists()
