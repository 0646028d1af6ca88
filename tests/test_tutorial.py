"""The tutorial script (examples/tutorial.py) runs end to end at its tiny size: a new map, its
figure, a belief, a sweep and its table, a video and a rerun file."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_tutorial_runs_from_map_to_table_and_video(tmp_path):
    env = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
    p = subprocess.run([sys.executable, str(ROOT / "examples" / "tutorial.py"), "--out",
                        str(tmp_path), "--tiny"], capture_output=True, text=True, env=env,
                       timeout=300, cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    table = (tmp_path / "table.md").read_text()
    for row in ("| compliant |", "| goal only |", "| path preference |",
                "| path preference + blend |"):
        assert row in table
    from pathpref.planning.pomdp import DEFAULT_PRESET

    # one preset, named: the first line, the sweep and the video
    assert p.stdout.splitlines()[0] == (f"pathpref tutorial: preset {DEFAULT_PRESET} for every "
                                        "episode (sweep and video)")
    assert f"16 episodes run (preset {DEFAULT_PRESET})" in p.stdout
    assert f"episode (preset {DEFAULT_PRESET}): goal reached" in p.stdout
    import sqlite3

    with sqlite3.connect(tmp_path / "results.sqlite") as con:
        assert con.execute("SELECT DISTINCT preset FROM episodes").fetchall() == [
            (DEFAULT_PRESET,)]
    assert "P(goal (2, 9)) = 1.00" in p.stdout  # three NW nudges: the north-west goal
    for name, least in (("map.png", 10_000), ("episode.mp4", 1_000), ("episode.rrd", 10_000)):
        assert (tmp_path / name).stat().st_size > least, name
