"""The house's rule (docs/architecture.md): arrows point down. A module imports only its own
layer or those below, sim and viz do not import each other, and nothing below the simulators
imports a simulator or names an upper module, not even in a string."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: layer rank of each room; a module may import ranks <= its own (sim and viz: not each other)
RANK = {"errors": 0, "geometry": 1, "maps": 1, "mjcf": 1, "inference": 2, "planning": 3,
        "episode": 4, "experiments": 5, "sim": 6, "viz": 6, "tasks": 7, "study": 7, "apps": 8}
SIMULATORS = ("mujoco", "dm_control", "dm_env", "mink", "rerun")
UPPER_NAMES = ("pathpref.sim", "pathpref.viz", "pathpref.study", "pathpref.apps",
               "pathpref_tasks")


def _room(module: str) -> str | None:
    parts = module.split(".")
    if parts[0] == "pathpref_tasks":
        return "tasks"
    if parts[0] != "pathpref" or len(parts) < 2:
        return None
    return parts[1]


def _modules():
    for path in sorted((ROOT / "pathpref").rglob("*.py")):
        rel = path.relative_to(ROOT).with_suffix("")
        name = ".".join(rel.parts[:-1] if rel.name == "__init__" else rel.parts)
        yield name, path, path.name == "__init__.py"
    for path in sorted((ROOT / "tasks").glob("*.py")):
        yield f"pathpref_tasks.{path.stem}".removesuffix(".__init__"), path, False


def _imports(name: str, path: Path, is_pkg: bool):
    tree = ast.parse(path.read_text())
    package = name if is_pkg else name.rsplit(".", 1)[0]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                yield a.name
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
                if node.module is None:
                    for a in node.names:
                        yield f"{mod}.{a.name}"
                    continue
                yield mod
            else:
                yield node.module


def test_arrows_point_down():
    bad = []
    for name, path, is_pkg in _modules():
        room = _room(name)
        if room not in RANK:
            continue  # pathpref/__init__.py and __main__.py: the package's face
        for imp in _imports(name, path, is_pkg):
            target = _room(imp)
            if target is None or target == room or target not in RANK:
                continue
            if RANK[target] > RANK[room] or {room, target} == {"sim", "viz"}:
                bad.append(f"{path.relative_to(ROOT)} ({room}) imports {imp} ({target})")
    assert not bad, "\n".join(bad)


def test_lower_layers_name_no_simulator_or_upper_module():
    bad = []
    for name, path, is_pkg in _modules():
        room = _room(name)
        if room not in RANK or RANK[room] > RANK["experiments"]:
            continue
        for imp in _imports(name, path, is_pkg):
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
