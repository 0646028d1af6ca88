"""A wheel that works: built from the source tree, it carries the maps, the MJCF files and
``py.typed``, and installed away from the source tree it runs commands and physics."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: the stored demo sweep's episodes, as the wheel ships its cells (package data)
SWEEP_EPISODES = json.loads((ROOT / "pathpref" / "apps" / "demo_sweep.json").read_text())[
    "episodes"]


@pytest.fixture(scope="module")
def wheel_build(tmp_path_factory) -> tuple[Path, str]:
    """The wheel built from the source tree, and the build's whole log (``pip -v``)."""
    out = tmp_path_factory.mktemp("wheel")
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", str(ROOT), "--no-deps",
                        "--no-build-isolation", "-v", "-w", str(out)],
                       capture_output=True, text=True, timeout=300)
    if r.returncode != 0 and "setuptools" in r.stderr:
        pytest.skip(f"this environment's setuptools cannot build the wheel: {r.stderr[-300:]}")
    assert r.returncode == 0, r.stderr
    (whl,) = out.glob("pathpref-*.whl")
    return whl, r.stdout + r.stderr


@pytest.fixture(scope="module")
def wheel(wheel_build) -> Path:
    return wheel_build[0]


def test_the_build_warns_of_no_ignored_package(wheel_build):
    """Package data is declared as such: no setuptools "Package would be ignored" banner (a
    data folder Python could import that the ``packages`` list lacks), no other build warning
    of setuptools'."""
    _, log = wheel_build
    assert "would be ignored" not in log
    assert "BuildBackendWarning" not in log and "SetuptoolsDeprecationWarning" not in log


def _declared() -> tuple[dict[str, Path], dict[str, list[str]]]:
    """pyproject's packages, each with its folder (``package-dir`` applied), and package data."""
    import tomllib

    st = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    remap = st["package-dir"]
    folders = {}
    for pkg in st["packages"]:
        base = max((k for k in remap if pkg == k or pkg.startswith(k + ".")), key=len,
                   default=None)
        rel = (remap[base] + pkg[len(base):] if base else pkg).replace(".", "/")
        folders[pkg] = ROOT / rel
    return folders, st["package-data"]


def test_every_shipped_folder_is_a_package_and_every_file_is_declared():
    """Each folder under the shipped trees whose name Python could import is in ``packages``
    (else setuptools warns and may drop it), and every file in them that is not Python is
    matched by its own package's ``package-data`` (else the wheel lacks it)."""
    folders, data = _declared()
    assert all(f.is_dir() for f in folders.values()), folders
    by_folder = {f: pkg for pkg, f in folders.items()}
    unowned, undeclared = [], []
    for top in ("pathpref", "mjcf", "examples", "tasks"):
        for d in [ROOT / top, *sorted(p for p in (ROOT / top).rglob("*") if p.is_dir())]:
            if "__pycache__" in d.parts:
                continue
            if d.name.isidentifier() and d not in by_folder:
                unowned.append(d.relative_to(ROOT).as_posix())
    for pkg, folder in folders.items():
        for f in sorted(folder.rglob("*")):
            if not f.is_file() or f.suffix in (".py", ".pyc") or "__pycache__" in f.parts:
                continue
            owner = f.parent
            while owner not in by_folder:  # a folder that is no identifier (2f85): its parent's
                owner = owner.parent
            if by_folder[owner] != pkg:
                continue
            rel = f.relative_to(folder)
            if not any(rel.match(pat) and len(rel.parts) == len(Path(pat).parts)
                       for pat in data.get(pkg, [])):
                undeclared.append(f.relative_to(ROOT).as_posix())
    assert not unowned, unowned
    assert not undeclared, undeclared


def test_wheel_contents(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    for needed in ("pathpref/mjcf/navigate.xml", "pathpref/mjcf/carry_tool.xml",
                   "pathpref/maps/simple.json", "pathpref/maps/office.json",
                   "pathpref/maps/classroom.json", "pathpref/py.typed",
                   "pathpref_tasks/navigate.py", "pathpref/geometry/coarse.py",
                   "pathpref/episode/runner.py", "pathpref/apps/cli.py",
                   "pathpref/apps/commands.py", "pathpref_tasks/gym.py",
                   "pathpref/apps/benchmarks/physics.py",
                   "pathpref/experiments/migrate.py", "pathpref/study/page.html",
                   "pathpref/study/server.py", "pathpref/experiments/trials.py",
                   "pathpref/apps/demo_sweep.json"):
        assert needed in names, needed
    assert not any(n.startswith(("tests/", "mjcf/")) for n in names)


def _installed(wheel, tmp_path):
    """The wheel installed into ``tmp_path/site``, a folder outside the repository to run it
    from, and the environment that imports the installed copy."""
    target = tmp_path / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "--no-deps", "-q", "--target",
                    str(target), str(wheel)], check=True, timeout=300)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    return elsewhere, {**os.environ, "PYTHONPATH": str(target), "MUJOCO_GL": "disable"}


def test_installed_wheel_runs_from_another_directory(wheel, tmp_path):
    elsewhere, env = _installed(wheel, tmp_path)
    code = (
        "import pathpref, pathpref.sim.scene as s\n"
        "from pathpref.geometry.world import load_world\n"
        f"assert pathpref.__file__.startswith({str(tmp_path / 'site')!r}), pathpref.__file__\n"
        "sc = s.build_scene(load_world('office'))\n"
        "import mujoco\n"
        "d = mujoco.MjData(sc.model)\n"
        "mujoco.mj_step(sc.model, d)\n"
        "print('ok', s.mjcf_path('navigate.xml').parent.name)\n"
    )
    r = subprocess.run([sys.executable, "-c", code], cwd=elsewhere, env=env,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["ok", "mjcf"]
    r = subprocess.run([sys.executable, "-m", "pathpref", "map", "info", "classroom",
                        "--json"], cwd=elsewhere, env=env, capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0 and '"polytopes": 73' in r.stdout, r.stderr


def test_wheel_ships_the_examples(wheel, tmp_path):
    """The examples and example maps are in the wheel (``pathpref.examples``), and the
    installed ``pathpref examples DEST`` copies exactly the source tree's example files."""
    names = set(zipfile.ZipFile(wheel).namelist())
    src = sorted(p.relative_to(ROOT / "examples").as_posix()
                 for p in [*(ROOT / "examples").glob("*"), *(ROOT / "examples").glob("maps/*")]
                 if p.suffix in (".py", ".json") and p.name != "__init__.py")
    assert "tutorial.py" in src and "maps/hall.json" in src and "train_ppo.py" in src
    for rel in src:
        assert f"pathpref/examples/{rel}" in names, rel
    _, env = _installed(wheel, tmp_path)
    dest = tmp_path / "copied"
    r = subprocess.run([sys.executable, "-m", "pathpref", "examples", str(dest)],
                       capture_output=True, text=True, env=env, timeout=300, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    got = sorted(p.relative_to(dest).as_posix() for p in dest.rglob("*") if p.is_file())
    assert got == src
    for rel in src:
        assert (dest / rel).read_bytes() == (ROOT / "examples" / rel).read_bytes(), rel


def test_installed_wheel_runs_the_whole_demo(wheel, tmp_path):
    """``pathpref demo`` from the wheel installed away from the source tree prints every
    section (the stored sweep shipped as package data, with its command and preset; the
    re-run with its n; the filmed setting's rate; the filmed episodes) and writes every file.
    Grid body and ``--runs 6`` (n = 6 grid runs per method) to stay within seconds."""
    from pathpref.planning.pomdp import DEFAULT_PRESET

    elsewhere, env = _installed(wheel, tmp_path)
    r = subprocess.run([sys.executable, "-m", "pathpref", "demo", "--sim", "grid", "--runs",
                        "6", "--out", "out"], cwd=elsewhere, env=env, capture_output=True,
                       text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    out = r.stdout
    p = DEFAULT_PRESET
    for section in (f"pathpref demo (preset {p}): where inferring the path preference matters",
                    "stored sweep demo_sweep.json (shipped with pathpref): "
                    f"{SWEEP_EPISODES} grid episodes, "
                    f"30 per cell, preset {p}, made by `sh scripts/demo_sweep.sh "
                    f"docs/results/demo_sweep.sqlite {p}`",
                    "-> inferring the preference MATTERS",
                    f"Re-running the setting with preset {p}: simple, human 'corrective "
                    "delay=1 miss=0.2' (ΔT = 1), n = 6 grid runs per method (drawn as the "
                    "sweep draws them: runs 0..1 of its 5 instances, the first 6; --runs 30 "
                    "is exactly the sweep's cell)",
                    "Over n = 6 grid runs per method, corrective human, preset",
                    "The filmed setting (simple, path_preference, the map's human, push rule "
                    f"'corrective delay=1 miss=0.2' (ΔT = 1), preset {p}) succeeds in ",
                    "Path preference and goal only differ in ",
                    f"Rendered episodes (grid; preset {p}; instance ", "| path_preference | ",
                    "| goal_only | "):
        assert section in out, section
    assert "missing" not in out and "NOTE" not in out  # the sweep is here, made by this preset
    assert len([ln for ln in out.splitlines() if ln.startswith("- ") and " -> " in ln]) == 6
    assert re.search(r"succeeds in \d/6 grid episodes, [01]\.\d\d \[95% Wilson", out)
    for name in ("map_simple.png", "trajectories.png", "belief.png", "success_vs_pushes.png",
                 "rates.csv", "summary.csv"):
        assert (elsewhere / "out" / name).stat().st_size > 0, name


def test_wheel_ships_the_tidybot_and_every_mesh_it_names(wheel):
    import xml.etree.ElementTree as ET

    names = set(zipfile.ZipFile(wheel).namelist())
    src = ROOT / "mjcf" / "stanford_tidybot"
    root = ET.parse(src / "tidybot.xml").getroot()
    meshdir = root.find("compiler").get("meshdir")
    files = [m.get("file") for a in root.iter("asset") for m in a.iter("mesh")]
    assert len(files) == 20  # the base's 5, the Gen3's 8, the 2F-85's 7
    for f in ["tidybot.xml", "LICENSE", "README.md", *(f"{meshdir}/{f}" for f in files)]:
        assert f"pathpref/mjcf/stanford_tidybot/{f}" in names, f
