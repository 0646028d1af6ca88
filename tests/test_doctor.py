"""``pathpref doctor`` and the native module's import check (issue 62, item 4): the checks pass
on this installation; a missing symbol, too old a NumPy, a NumPy without its OpenBLAS, a
package outside its pin or a changed numba internal each give one line naming the cause and a
non-zero exit, never an abort."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

import pytest  # noqa: E402

from pathpref.apps import doctor  # noqa: E402
from pathpref.apps.cli import main  # noqa: E402
from pathpref.sim import native  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def test_doctor_passes_here(capsys):
    assert main(["doctor"]) == 0
    out, err = capsys.readouterr()
    assert err == ""
    assert re.fullmatch(r"pathpref doctor: all 7 checks passed \(numpy [\d.]+, numba [\d.]+, "
                        r"llvmlite [\d.]+, mujoco 3\.17\.0, dm-control 1\.0\.50\)\n", out)


def test_pyproject_floor_is_the_one_checked():
    """pyproject's NumPy floor is the one native.py checks at import (one home each, kept
    equal), and the NumPy running the tests meets it."""
    deps = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]
    (numpy,) = [d for d in deps if re.match(r"numpy\b", d)]
    assert numpy == "numpy>={}.{}".format(*native.NUMPY_MIN)
    assert native.numpy_version() >= native.NUMPY_MIN


def test_a_missing_symbol_is_one_line(monkeypatch, capsys):
    """A symbol the kernels link that NumPy's OpenBLAS lacks: one line naming it, its
    library and the fix, exit 1 (checked by ctypes: numba never asked to link it)."""
    mj, blas = native.SYMBOLS
    monkeypatch.setattr(native, "SYMBOLS", (mj, (*blas, "scipy_cblas_nosuch64_")))
    assert main(["doctor"]) == 1
    out, err = capsys.readouterr()
    assert out == ""
    (line,) = err.splitlines()
    assert line.startswith("pathpref doctor: pathpref's MuJoCo physics needs "
                           "scipy_cblas_nosuch64_ in libscipy_openblas64_")
    assert line.endswith("pip install --force-reinstall 'numpy>={}.{}'".format(
        *native.NUMPY_MIN))


def test_a_package_outside_its_pin_is_one_line(monkeypatch):
    real = doctor.metadata.version
    monkeypatch.setattr(doctor.metadata, "version",
                        lambda name: "4.0.0" if name == "mujoco" else real(name))
    assert doctor.check_versions() == [
        "mujoco 4.0.0 is installed; pathpref needs mujoco==3.17.0 (pyproject): "
        "pip install 'mujoco==3.17.0'"]


@pytest.mark.parametrize("version, spec, ok", [
    ("3.17.0", "==3.17.0", True), ("3.17", "==3.17.0", True), ("4.0.0", "==3.17.0", False),
    ("2.4.6", ">=2.4", True), ("2.3.9", ">=2.4", False), ("2.10.0", ">=2.4", True),
    ("0.68.1", ">=0.59,<0.69", True), ("0.69.0", ">=0.59,<0.69", False),
    ("2.4.0rc1", ">=2.4", True), ("1.0.50", "!=1.0.50", False), ("1.0", "", True)])
def test_specifiers(version, spec, ok):
    assert doctor.satisfies(version, spec) is ok


def test_a_changed_bit_generator_struct_is_one_line(monkeypatch):
    monkeypatch.setattr(native, "BIT_GENERATOR_FIELDS",
                        (*native.BIT_GENERATOR_FIELDS[:-1], "fnptr_next_float64"))
    (line,) = doctor.check_bit_generator()
    assert "BitGenerator struct" in line and "lacks the 64-bit members fnptr_next_float64" in line


def test_a_changed_dispatcher_is_one_line(monkeypatch):
    def gone(kernel, args):
        raise KeyError("overloads")

    monkeypatch.setattr(native, "entry_point", gone)
    (line,) = doctor.check_entry_point()
    assert "Dispatcher.overloads[sig].entry_point" in line and "KeyError" in line


def test_a_changed_cache_index_is_one_line_and_loads_nothing(monkeypatch):
    """numba's private cache index renamed: the kernels are not loaded ahead (no error: each
    loads at its first call) and the doctor says why in one line."""
    from numba.core.caching import IndexDataCacheFile

    from pathpref import kernels
    from pathpref.apps.doctor_probes import add_one

    assert doctor.check_cache_index() == []
    assert kernels.cached_signatures(add_one)  # the probe's overload, as the check found
    monkeypatch.delattr(IndexDataCacheFile, "_load_index")
    assert kernels.cached_signatures(add_one) == []
    (line,) = doctor.check_cache_index()
    assert "cache index" in line and "does not list" in line


def test_a_changed_mujoco_signature_is_one_line(monkeypatch):
    """A hand-typed signature that no longer matches the C function (here ``mj_jacBody``
    declared with the body id where the Jacobian's rotational part goes) is found by
    comparing with the bindings' call, not by a crash later."""
    from numba import types

    ptr, i32 = types.voidptr, types.int32
    monkeypatch.setattr(native, "mj_jacBody", types.ExternalFunction(
        "mj_jacBodyCom", types.void(ptr, ptr, ptr, ptr, i32)))
    (line,) = doctor.check_mujoco_by_address()
    assert line.startswith("mujoco 3.17.0: mj_jacBodyCom called by address")


def _fresh(setup: str) -> subprocess.CompletedProcess:
    """``pathpref doctor`` in a fresh interpreter after ``setup``."""
    code = f"{setup}\nimport sys\nfrom pathpref.apps.cli import main\nsys.exit(main(['doctor']))"
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          cwd=ROOT, timeout=300, env={**os.environ, "MUJOCO_GL": "egl"})


def test_too_old_a_numpy_is_one_line_not_an_abort():
    """NumPy below the floor (set after numba's import: numba reads the version itself): the
    physics refuses at import with one line naming the floor, the doctor prints it, exit 1."""
    r = _fresh("import numba, numpy\nnumpy.__version__ = '2.3.5'")
    assert r.returncode == 1, r.stderr
    assert r.stderr.splitlines()[-1] == (
        "pathpref doctor: pathpref's MuJoCo physics needs NumPy >= 2.4 (found 2.3.5): "
        "install NumPy's PyPI wheel: pip install --force-reinstall 'numpy>=2.4'")
    assert all(x.startswith("pathpref doctor: ") for x in r.stderr.splitlines())


def test_a_numpy_without_its_openblas_is_one_line_not_an_abort(tmp_path):
    """NumPy as conda or a distribution ships it (no ``numpy.libs`` beside it): the physics
    refuses at import with one line, and the CLI turns it into that line, exit 1."""
    r = _fresh(f"import numpy; numpy.__file__ = {str(tmp_path / 'numpy' / '__init__.py')!r}")
    assert r.returncode == 1, r.stderr
    (line,) = r.stderr.splitlines()
    assert line.startswith("pathpref doctor: pathpref's MuJoCo physics needs NumPy's own "
                           "OpenBLAS (numpy.libs/libscipy_openblas64_*.so), found 0 beside")
    assert "conda's and distributions' NumPy ship none" in line
