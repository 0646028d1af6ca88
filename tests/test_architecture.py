"""The house's rule (docs/architecture.md): arrows point down. A module imports only its own
layer or those below, sim and viz do not import each other, and nothing below the simulators
imports a simulator or names an upper module, not even in a string."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))

from draw_architecture import RANK, draw, imports, modules, room_of  # noqa: E402

SIMULATORS = ("mujoco", "dm_control", "dm_env", "mink", "rerun")
UPPER_NAMES = ("pathpref.sim", "pathpref.viz", "pathpref.study", "pathpref.apps",
               "pathpref_tasks")


def test_arrows_point_down():
    bad = []
    for name, path, is_pkg in modules(ROOT):
        room = room_of(name)
        if room not in RANK:
            continue  # pathpref/__init__.py and __main__.py: the package's face
        for imp in imports(name, path, is_pkg):
            target = room_of(imp)
            if target is None or target == room or target not in RANK:
                continue
            if RANK[target] > RANK[room] or {room, target} == {"sim", "viz"}:
                bad.append(f"{path.relative_to(ROOT)} ({room}) imports {imp} ({target})")
    assert not bad, "\n".join(bad)


def test_lower_layers_name_no_simulator_or_upper_module():
    bad = []
    for name, path, is_pkg in modules(ROOT):
        room = room_of(name)
        if room not in RANK or RANK[room] > RANK["experiments"]:
            continue
        for imp in imports(name, path, is_pkg):
            if imp.split(".")[0] in SIMULATORS:
                bad.append(f"{path.relative_to(ROOT)} imports {imp}")
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Constant) and isinstance(node.value, str):
                bad += [f"{path.relative_to(ROOT)} names {u!r}" for u in UPPER_NAMES
                        if u in node.value]
    assert not bad, "\n".join(bad)


def test_the_rule_catches_an_upward_import(tmp_path, monkeypatch):
    """The checker itself: a geometry module importing the simulator is reported."""
    fake = tmp_path / "pathpref" / "geometry"
    fake.mkdir(parents=True)
    (fake / "bad.py").write_text("from ..sim.body import MujocoBody\nX = 'pathpref.apps.cli'\n")
    (tmp_path / "tasks").mkdir()
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)
    for test in (test_arrows_point_down, test_lower_layers_name_no_simulator_or_upper_module):
        try:
            test()
        except AssertionError as e:
            assert "bad.py" in str(e)
        else:
            raise AssertionError(f"{test.__name__} missed an upward import")


def test_the_house_is_drawn_from_theimports(tmp_path):
    """scripts/draw_architecture.py draws the room graph: every room of the rule, an arrow
    for an import between rooms (``sim`` imports ``geometry``; nothing imports ``apps``),
    none pointing up, a PNG written."""
    out = tmp_path / "house.png"
    sizes, edges = draw(out)
    assert set(sizes) >= {"geometry", "inference", "planning", "episode", "experiments", "sim",
                          "viz", "tasks", "study", "apps"}
    assert edges["sim", "geometry"] > 0 and edges["apps", "sim"] > 0
    assert not any(t == "apps" for _, t in edges)
    assert not any(RANK[t] > RANK[r] for r, t in edges)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 20_000
