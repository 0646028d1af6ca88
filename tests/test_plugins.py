"""Another package adds a body and a method through entry points (``pathpref.plugins``),
installed the venv-less way: a module and a dist-info whose ``entry_points.txt`` declares them."""

from __future__ import annotations

import sys

import pytest

from pathpref.episode import EpisodeSpec, run_episode
from pathpref.episode.body import BODIES
from pathpref.errors import ConfigError
from pathpref.planning.policies import METHODS, resolve_methods

from .plugin_helpers import install_package

PACKAGE = '''
from pathpref.episode.body import GridBody
from pathpref.geometry.grid import STAY
from pathpref.planning.policies import CompliantPolicy


class StubbornBody(GridBody):
    """The grid body whose moves all fail: the robot never leaves its start."""

    def move(self, action):
        return self.cell


class Still(CompliantPolicy):
    """Never moves."""

    def act(self, t, cell, heading):
        return STAY


NOT_A_BODY = 3
'''


@pytest.fixture
def example_package(tmp_path, monkeypatch):
    install_package(tmp_path, monkeypatch, "pathpref_example_plugins", PACKAGE, """\
        [pathpref.bodies]
        stubborn = pathpref_example_plugins:StubbornBody
        notabody = pathpref_example_plugins:NOT_A_BODY
        missing = pathpref_example_plugins_gone:Body

        [pathpref.methods]
        still = pathpref_example_plugins:Still
        """)
    yield
    sys.modules.pop("pathpref_example_plugins", None)
    for name in ("stubborn", "notabody", "missing"):
        BODIES.pop(name, None)
    METHODS.pop("still", None)


def test_a_package_adds_a_body_and_a_method(example_package):
    """The package's method and body run an episode by name: a robot that never moves (its
    body refuses every move, its method stays) spends all T_max steps at its start."""
    assert resolve_methods(["still"]) == ["still"]
    for sim, method in (("stubborn", "path_preference"), ("grid", "still")):
        spec = EpisodeSpec.single("simple", method, 5, seed=2, sim=sim, t_max=6, queries=20)
        res = run_episode(spec)
        start = res.log[0]
        assert res.steps == 6 and not res.goal_reached
        assert all((s.x, s.y) == (start.x, start.y) for s in res.log)


def test_bad_plugins_are_one_line_errors(example_package):
    with pytest.raises(ConfigError, match="must name a Body subclass") as e:
        run_episode(EpisodeSpec.single("simple", "compliant", 5, sim="notabody", t_max=3))
    assert "\n" not in str(e.value)
    with pytest.raises(ConfigError, match=r"entry point 'missing' of group pathpref.bodies"):
        run_episode(EpisodeSpec.single("simple", "compliant", 5, sim="missing", t_max=3))
    with pytest.raises(ConfigError, match="unknown simulator 'nowhere'"):
        run_episode(EpisodeSpec.single("simple", "compliant", 5, sim="nowhere", t_max=3))
    with pytest.raises(ConfigError, match="unknown method 'nothing'"):
        resolve_methods(["nothing"])


@pytest.mark.parametrize("source, named", [
    ("raise SystemExit('bye from the plug-in')\n", "SystemExit: bye from the plug-in"),
    ("import sys\nsys.exit(1)\n", "SystemExit: 1"),
    ("raise RuntimeError('broken\\non two lines')\n", "RuntimeError: broken on two lines"),
])
def test_a_plugin_that_exits_or_raises_on_import_is_one_line(tmp_path, monkeypatch, capsys,
                                                            source, named):
    """Issue 47: a plug-in whose import calls ``exit()`` (or raises) no longer ends pathpref
    with its own status and text: exit 2, one line naming the entry point, nothing made."""
    from pathpref.apps.cli import main

    install_package(tmp_path, monkeypatch, "pathpref_quitting_plugin", source,
                    "[pathpref.methods]\nquitter = pathpref_quitting_plugin:Q\n")
    db = tmp_path / "r.sqlite"
    try:
        assert main(["evaluate", "--methods", "quitter", "--delta-t", "5", "--instances",
                     "1", "--runs", "1", "--workers", "1", "--db", str(db),
                     "--no-progress"]) == 2
    finally:
        sys.modules.pop("pathpref_quitting_plugin", None)
        METHODS.pop("quitter", None)
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("pathpref: error: entry point 'quitter'")
    assert named in err and not db.exists()


def test_evaluate_takes_a_plugin_body(example_package, tmp_path, capsys):
    """``pathpref evaluate --sim stubborn`` runs the package's body: every stored episode is
    under that simulator and, its robot never leaving the start, none reaches the goal; a
    task the body does not offer is refused in one line."""
    import sqlite3

    from pathpref.apps.cli import main

    db = tmp_path / "r.sqlite"
    argv = ["evaluate", "--map", "simple", "--db", str(db), "--runs", "1", "--instances", "1",
            "--methods", "compliant", "--delta-t", "5", "--sim", "stubborn", "--no-progress"]
    assert main(argv) == 0
    with sqlite3.connect(db) as conn:
        rows = conn.execute("SELECT sim, task, goal_reached FROM episodes").fetchall()
    assert rows == [("stubborn", "navigate", 0)]
    capsys.readouterr()
    assert main([*argv, "--robot", "carry", "--db", str(tmp_path / "c.sqlite")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "carry" in err[0]


RING = '''
def ring():
    """A 9 x 9 room around a 3 x 3 block."""
    return {"name": "ring", "width": 9, "height": 9,
            "obstacles": [{"cells": {"lower_left": [3, 3], "size": [3, 3]}}],
            "preference": {"route": [[1, 1], [7, 1], [7, 7], [1, 7]], "closed": True}}
'''


@pytest.fixture
def ring_package(tmp_path, monkeypatch):
    install_package(tmp_path, monkeypatch, "pathpref_example_ring", RING, """\
        [pathpref.maps]
        ring = pathpref_example_ring:ring
        """)
    yield
    sys.modules.pop("pathpref_example_ring", None)


def test_a_plugin_map_works_in_every_command(ring_package, tmp_path, capsys, monkeypatch):
    """A map another package declares is a map name everywhere: ``pathpref map info ring``
    describes it (72 free cells, 8 polytopes), an episode runs on it, ``evaluate`` stores
    its episodes under its name."""
    import sqlite3

    from pathpref.apps.cli import main

    assert main(["map", "info", "ring"]) == 0
    out = capsys.readouterr().out
    info = dict(line.strip().split(": ", 1) for line in out.splitlines() if ": " in line)
    # 81 cells less the 3 x 3 block; the block's four lines cut the room into 3 x 3 - 1
    assert (info["name"], info["free_cells"], info["polytopes"]) == ("ring", "72", "8")
    res = run_episode(EpisodeSpec.single("ring", "compliant", 5, seed=1, t_max=4, n_goals=3))
    assert res.steps >= 1
    monkeypatch.chdir(tmp_path)
    assert main(["evaluate", "--map", "ring", "--db", "r.sqlite", "--runs", "1",
                 "--instances", "1", "--methods", "compliant", "--delta-t", "5", "--goals",
                 "3", "--no-progress"]) == 0
    with sqlite3.connect(tmp_path / "r.sqlite") as conn:
        assert conn.execute("SELECT DISTINCT map FROM episodes").fetchall() == [("ring",)]
