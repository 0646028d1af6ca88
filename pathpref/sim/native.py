"""The C functions a compiled physics loop calls, the very ones the Python path calls.

A numba kernel that steps MuJoCo and does the robot's arithmetic gives the same numbers as the
Python loop only if every operation is the same IEEE operation in the same order. So:

* MuJoCo's ``mj_step``, ``mj_objectAcceleration`` and ``mj_jacBodyCom`` are called by symbol
  from the ``libmujoco`` the Python bindings loaded (the same library, on the ``MjModel`` and
  ``MjData`` the bindings hold, through their ``_address``);
* matrix-vector and dot products go to the ``cblas_dgemv`` and ``cblas_ddot`` of NumPy's own
  OpenBLAS with the arguments NumPy passes for ``ndarray.dot`` (a C-ordered ``A`` row-major, a
  transposed view column-major), so they pick the same CPU kernel (FMA or not) as NumPy;
* :func:`hypot` is CPython's ``math.hypot`` of two floats (``vector_norm``: lossless scaling,
  Dekker's products and a differential correction), not the C library's ``hypot``, which
  differs in the last bit on about 1 in 200 inputs.

``MjData``'s scalar ``ncon`` is not an array in the bindings; :func:`ncon_view` finds its
byte offset in the struct once (the offset whose value follows the bindings' attribute
through changed states; everything scanned lies before the struct's ``qpos`` pointer) and
returns a one-element NumPy view of it. (The kernels track ``time`` themselves, as
``mj_step`` advances it.)

:func:`ready` is False (with :data:`WHY`) when a library, a symbol or an offset is missing:
the callers then keep their Python path.
"""

from __future__ import annotations

import ctypes
import glob
import math
import os

import mujoco
import numba as nb
import numpy as np
from numba import types

#: mjtObj's mjOBJ_BODY
OBJ_BODY = int(mujoco.mjtObj.mjOBJ_BODY)
#: CBLAS's order and transpose codes
ROW_MAJOR, COL_MAJOR, NO_TRANS = 101, 102, 111


def _libraries() -> tuple[str, str]:
    mj = glob.glob(os.path.join(os.path.dirname(mujoco.__file__), "libmujoco.so*"))
    blas = glob.glob(os.path.join(os.path.dirname(np.__file__), os.pardir, "numpy.libs",
                                  "libscipy_openblas64_*.so"))
    if len(mj) != 1 or len(blas) != 1:
        raise OSError(f"libmujoco {mj} / NumPy's OpenBLAS {blas} not found exactly once")
    return mj[0], blas[0]


#: the symbols the kernels call, by library (checked before numba is asked to link them)
SYMBOLS = (("mj_step", "mj_objectAcceleration", "mj_jacBodyCom"),
           ("scipy_cblas_dgemv64_", "scipy_cblas_ddot64_"))

try:
    from llvmlite import binding as _llvm

    for _lib, _names in zip(_libraries(), SYMBOLS, strict=True):
        _missing = [n for n in _names if not hasattr(ctypes.CDLL(_lib), n)]
        if _missing:
            raise OSError(f"{os.path.basename(_lib)} lacks {', '.join(_missing)}")
        _llvm.load_library_permanently(_lib)
    AVAILABLE, WHY = True, ""
except (OSError, RuntimeError) as exc:  # pragma: no cover - depends on the wheels installed
    AVAILABLE, WHY = False, str(exc)

_ptr, _i32, _i64, _f64 = types.voidptr, types.int32, types.int64, types.float64
mj_step = types.ExternalFunction("mj_step", types.void(_ptr, _ptr))
mj_objectAcceleration = types.ExternalFunction(
    "mj_objectAcceleration", types.void(_ptr, _ptr, _i32, _i32, _ptr, _i32))
mj_jacBodyCom = types.ExternalFunction("mj_jacBodyCom",
                                       types.void(_ptr, _ptr, _ptr, _ptr, _i32))
_dgemv = types.ExternalFunction(
    "scipy_cblas_dgemv64_",
    types.void(_i32, _i32, _i64, _i64, _f64, _ptr, _i64, _ptr, _i64, _f64, _ptr, _i64))
_ddot = types.ExternalFunction("scipy_cblas_ddot64_", _f64(_i64, _ptr, _i64, _ptr, _i64))


@nb.njit(cache=True, inline="always")
def matvec(A, x, y):
    """``y = A x`` for a C-ordered ``A`` (``A.dot(x)``: row-major ``gemv``)."""
    m, n = A.shape
    _dgemv(ROW_MAJOR, NO_TRANS, m, n, 1.0, A.ctypes.data, n, x.ctypes.data, 1, 0.0,
           y.ctypes.data, 1)


@nb.njit(cache=True, inline="always")
def matTvec(A, x, y):
    """``y = A^T x`` for a C-ordered square ``A`` (``A.T.dot(x)``: NumPy sees a Fortran-ordered
    matrix and calls a column-major ``gemv`` on ``A``'s memory)."""
    m, n = A.shape
    _dgemv(COL_MAJOR, NO_TRANS, n, m, 1.0, A.ctypes.data, n, x.ctypes.data, 1, 0.0,
           y.ctypes.data, 1)


@nb.njit(cache=True, inline="always")
def norm(v):
    """``sqrt(v . v)`` as :func:`pathpref.sim.controller.norm` computes it (``ddot``)."""
    return math.sqrt(_ddot(v.shape[0], v.ctypes.data, 1, v.ctypes.data, 1))


@nb.njit(cache=True, inline="always")
def _split(x):
    t = x * 134217729.0  # Veltkamp's constant, 2^27 + 1 (Dekker 5.5, 5.6)
    hi = t - (t - x)
    return hi, x - hi


@nb.njit(cache=True, inline="always")
def _mul(x, y):
    """``x y`` as an unevaluated sum ``hi + lo`` (Dekker 5.12)."""
    xh, xl = _split(x)
    yh, yl = _split(y)
    p = xh * yh
    q = xh * yl + xl * yh
    z = p + q
    return z, p - z + q + xl * yl


@nb.njit(cache=True)
def hypot(x, y):
    """CPython's ``math.hypot(x, y)`` (``vector_norm`` of 3.11), bit for bit: with ``m`` the
    larger magnitude scaled to ``[0.5, 1)`` by a power of two, the sum of squares is kept as
    ``1 + csum`` with two error terms, ``h = sqrt(sum)`` corrected once by
    ``(sum - h^2) / (2 h)``, then scaled back."""
    ax, ay = abs(x), abs(y)
    if math.isinf(ax) or math.isinf(ay):
        return math.inf
    if math.isnan(ax) or math.isnan(ay):
        return math.nan
    mx = max(ax, ay)
    if mx == 0.0:
        return mx
    e = math.frexp(mx)[1]
    if e < -1023:  # subnormal: CPython scales by DBL_MIN first
        dmin = 2.2250738585072014e-308
        return dmin * hypot(x / dmin, y / dmin)
    scale = math.ldexp(1.0, -e)
    csum, frac1, frac2 = 1.0, 0.0, 0.0
    for v in (ax, ay):
        ph, pl = _mul(v * scale, v * scale)
        s = csum + ph
        frac2 += (csum - s) + ph
        csum = s
        frac1 += pl
    h = math.sqrt(csum - 1.0 + (frac1 + frac2))
    ph, pl = _mul(-h, h)
    s = csum + ph
    frac2 += (csum - s) + ph
    csum = s
    frac1 += pl
    h += (csum - 1.0 + (frac1 + frac2)) / (2.0 * h)
    return h / scale


def _struct_head(data: mujoco.MjData) -> bytes:
    """The bytes of ``data``'s struct before its ``qpos`` pointer (all inside the struct)."""
    target, base, chunks = data.qpos.ctypes.data, data._address, []
    for k in range(1 << 16):  # 256 bytes at a time (the struct's pointers that follow qpos's
        # take more): at most 16 MB, far beyond the scalars
        chunk = ctypes.string_at(base + 256 * k, 256)
        hit = np.flatnonzero(np.frombuffer(chunk, dtype=np.uint64) == target)
        if len(hit):
            return b"".join(chunks) + chunk[: int(hit[0]) * 8]
        chunks.append(chunk)
    raise RuntimeError("MjData's qpos pointer not found in its struct")


def _find_offset() -> int:
    """The byte offset of ``ncon`` (int32) in ``mjData``: the only offset whose value equals
    the bindings' attribute in every one of several states (four spheres apart, overlapping,
    apart, far apart)."""
    bodies = "".join(f'<body pos="{0.05 * i} 0 0"><freejoint/><geom size=".1"/></body>'
                     for i in range(4))
    xml = f"<mujoco><worldbody>{bodies}</worldbody></mujoco>"
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    c_off = None
    for spread in (1.0, 0.0, 1.0, 5.0):
        data.qpos[0::7] = spread * np.arange(4) * 0.05
        mujoco.mj_forward(model, data)
        head = _struct_head(data)
        n = np.frombuffer(head[: len(head) // 4 * 4], np.int32)
        c = set((np.flatnonzero(n == data.ncon) * 4).tolist())
        c_off = c if c_off is None else c_off & c
    if c_off is None or len(c_off) != 1:
        raise RuntimeError(f"MjData's ncon offset not unique: {c_off}")
    return c_off.pop()


_OFFSET: int | None = None


def ready() -> bool:
    """Whether the compiled path can run here: the libraries and symbols found
    (:data:`AVAILABLE`) and ``MjData``'s ``ncon`` offset found (once per process; else
    :data:`WHY` says why and the callers keep their Python path)."""
    global _OFFSET, AVAILABLE, WHY
    if AVAILABLE and _OFFSET is None:
        try:
            _OFFSET = _find_offset()
        except RuntimeError as exc:  # pragma: no cover - another MuJoCo's struct
            AVAILABLE, WHY = False, str(exc)
    return AVAILABLE


def ncon_view(data: mujoco.MjData) -> np.ndarray:
    """A one-element view of ``data.ncon`` (int32) in the struct (valid while ``data`` lives;
    checked against the bindings' attribute; call after :func:`ready`)."""
    if not ready():
        raise RuntimeError(f"no compiled path here: {WHY}")
    ncon = np.ctypeslib.as_array((ctypes.c_int32 * 1).from_address(data._address + _OFFSET))
    if ncon[0] != data.ncon:
        raise RuntimeError("MjData's ncon view disagrees with the bindings")
    return ncon
