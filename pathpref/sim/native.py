"""The C functions a compiled physics loop calls, the very ones the Python path calls.

A numba kernel that steps MuJoCo and does the robot's arithmetic gives the same numbers as the
Python loop only if every operation is the same IEEE operation in the same order. So:

* MuJoCo's ``mj_step``, ``mj_objectAcceleration``, ``mj_jacBodyCom`` and ``mj_jacBody`` are
  called by symbol from the ``libmujoco`` the Python bindings loaded (the same library, on the
  ``MjModel`` and ``MjData`` the bindings hold, through their ``_address``);
* matrix-vector and dot products go to the ``cblas_dgemv`` and ``cblas_ddot`` of NumPy's own
  OpenBLAS with the arguments NumPy passes for ``ndarray.dot`` (a C-ordered ``A`` row-major, a
  transposed view column-major), so they pick the same CPU kernel (FMA or not) as NumPy;
* :func:`hypot` is CPython's ``math.hypot`` of two floats (``vector_norm``: lossless scaling,
  Dekker's products and a differential correction), not the C library's ``hypot``, which
  differs in the last bit on about 1 in 200 inputs.

Scalars of ``MjData`` are not arrays in the bindings, so the kernels read none: the number
of contacts comes from the scene's ``contact`` sensor (``sensordata``, see
``mjcf/navigate.xml``) and the kernels track ``time`` themselves, as ``mj_step`` advances it.

There is no path without them: the Python step calls the same compiled functions (the cue
detector's ``decide_step``, the estimator's, the sensor's), so importing this module checks,
with ``ctypes`` and before numba is asked to link anything, that NumPy is at least
:data:`NUMPY_MIN` (pyproject's floor, the version tested) and that both libraries have every
symbol of :data:`SYMBOLS`; if not it raises :class:`~pathpref.errors.ConfigError`, one line
naming the requirement (numba would otherwise abort the interpreter, "LLVM ERROR: Symbol not
found", at the first physical step). Conda's and distributions' NumPy ship no OpenBLAS of
their own, and older PyPI wheels (1.26's) a differently named one. ``pathpref doctor``
(:mod:`pathpref.apps.doctor`) checks the same, and the private internals this module relies on.
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
from numba.core import cgutils
from numba.extending import intrinsic

from ..errors import ConfigError

#: mjtObj's mjOBJ_BODY
OBJ_BODY = int(mujoco.mjtObj.mjOBJ_BODY)
#: CBLAS's order and transpose codes
ROW_MAJOR, COL_MAJOR, NO_TRANS = 101, 102, 111


#: the oldest NumPy tested (pyproject's ``numpy>=`` floor; tests/test_doctor.py checks both say
#: the same): its PyPI wheels bundle ``scipy-openblas64``, whose symbols :data:`SYMBOLS` names
NUMPY_MIN = (2, 4)
#: how to get a NumPy with its own OpenBLAS (the end of every line of :func:`problem`)
NUMPY_FIX = ("install NumPy's PyPI wheel: pip install --force-reinstall "
             f"'numpy>={NUMPY_MIN[0]}.{NUMPY_MIN[1]}'")

#: how to get MuJoCo's library back
MUJOCO_FIX = ("reinstall MuJoCo at the version pathpref pins (pyproject; pathpref doctor "
              "names it) with pip install --force-reinstall")


def _libraries() -> tuple[str, str]:
    mj = glob.glob(os.path.join(os.path.dirname(mujoco.__file__), "libmujoco.so*"))
    blas = glob.glob(os.path.join(os.path.dirname(np.__file__), os.pardir, "numpy.libs",
                                  "libscipy_openblas64_*.so"))
    if len(mj) != 1:
        raise OSError(f"pathpref's MuJoCo physics needs the libmujoco of the mujoco package, "
                      f"found {len(mj)} in {os.path.dirname(mujoco.__file__)}: {MUJOCO_FIX}")
    if len(blas) != 1:
        raise OSError(f"pathpref's MuJoCo physics needs NumPy's own OpenBLAS "
                      f"(numpy.libs/libscipy_openblas64_*.so), found {len(blas)} beside "
                      f"numpy {np.__version__} at {os.path.dirname(np.__file__)} (conda's and "
                      f"distributions' NumPy ship none): {NUMPY_FIX}")
    return mj[0], blas[0]


#: the symbols the kernels call, by library (checked before numba is asked to link them)
SYMBOLS = (("mj_step", "mj_objectAcceleration", "mj_jacBodyCom", "mj_jacBody"),
           ("scipy_cblas_dgemv64_", "scipy_cblas_ddot64_"))


def numpy_version() -> tuple[int, int]:
    """NumPy's ``(major, minor)`` (its version string's leading numbers)."""
    major, minor = (np.__version__.split(".") + ["0"])[:2]
    return int(major), int("".join(ch for ch in minor if ch.isdigit()) or 0)


def problem() -> str:
    """Why the compiled functions cannot link here, as one line ("" when they can): NumPy
    older than :data:`NUMPY_MIN`, a library not found, or a symbol of :data:`SYMBOLS` it
    lacks (looked up with ``ctypes``, which fails softly where numba's linker aborts)."""
    if numpy_version() < NUMPY_MIN:
        return (f"pathpref's MuJoCo physics needs NumPy >= {NUMPY_MIN[0]}.{NUMPY_MIN[1]} "
                f"(found {np.__version__}): {NUMPY_FIX}")
    try:
        libs = _libraries()
    except OSError as exc:
        return str(exc)
    for lib, names in zip(libs, SYMBOLS, strict=True):
        missing = [n for n in names if not hasattr(ctypes.CDLL(lib), n)]
        if missing:
            fix = NUMPY_FIX if lib == libs[1] else MUJOCO_FIX
            return (f"pathpref's MuJoCo physics needs {', '.join(missing)} in "
                    f"{os.path.basename(lib)}, which lacks it (numpy {np.__version__}, mujoco "
                    f"{mujoco.__version__}): {fix}")
    return ""


WHY = problem()
if WHY:
    raise ConfigError(WHY)
from llvmlite import binding as _llvm  # noqa: E402

for _lib in _libraries():
    _llvm.load_library_permanently(_lib)
#: the libraries and symbols were found (importing this module fails otherwise; kept for the
#: callers that ask :func:`ready`)
AVAILABLE = True

_ptr, _i32, _i64, _f64 = types.voidptr, types.int32, types.int64, types.float64
mj_step = types.ExternalFunction("mj_step", types.void(_ptr, _ptr))
mj_objectAcceleration = types.ExternalFunction(
    "mj_objectAcceleration", types.void(_ptr, _ptr, _i32, _i32, _ptr, _i32))
mj_jacBodyCom = types.ExternalFunction("mj_jacBodyCom",
                                       types.void(_ptr, _ptr, _ptr, _ptr, _i32))
mj_jacBody = types.ExternalFunction("mj_jacBody", types.void(_ptr, _ptr, _ptr, _ptr, _i32))
_dgemv = types.ExternalFunction(
    "scipy_cblas_dgemv64_",
    types.void(_i32, _i32, _i64, _i64, _f64, _ptr, _i64, _ptr, _i64, _f64, _ptr, _i64))
_ddot = types.ExternalFunction("scipy_cblas_ddot64_", _f64(_i64, _ptr, _i64, _ptr, _i64))


def bit_generator_pointers(rng: np.random.Generator) -> np.ndarray:
    """What numba's unboxing of ``rng`` reads of its bit generator, read once: the state's
    address, the state pointer and the ``next_uint64``, ``next_uint32`` and ``next_double``
    functions' addresses (``BitGenerator.ctypes``; int64[5], for :func:`bit_generator`). A
    kernel called often takes these instead of the ``Generator``, whose unboxing asks
    ``ctypes`` for all of them at every call."""
    c = rng.bit_generator.ctypes

    def address(fn) -> int:
        return ctypes.cast(fn, ctypes.c_void_p).value

    return np.array([c.state_address, c.state.value, address(c.next_uint64),
                     address(c.next_uint32), address(c.next_double)], dtype=np.int64)


#: the members of numba's ``BitGenerator`` data model :func:`bit_generator` fills, in the order
#: of :func:`bit_generator_pointers` (numba's private struct: ``pathpref doctor`` checks it)
BIT_GENERATOR_FIELDS = ("state_address", "state", "fnptr_next_uint64", "fnptr_next_uint32",
                        "fnptr_next_double")


@intrinsic
def bit_generator(typingctx, pointers):
    """numba's ``BitGenerator`` value (what ``Generator.bit_generator`` is in compiled code)
    from :func:`bit_generator_pointers`: ``numba.np.random.distributions``' functions draw
    from it exactly as from the unboxed ``Generator`` (the same state, the same C functions
    of NumPy's bit generator)."""
    bitgen = types.NumPyRandomBitGeneratorType("bit_generator")
    fields = BIT_GENERATOR_FIELDS

    def codegen(context, builder, sig, args):
        arr = context.make_array(sig.args[0])(context, builder, args[0])
        out = cgutils.create_struct_proxy(bitgen)(context, builder)
        for i, name in enumerate(fields):
            setattr(out, name, builder.load(cgutils.gep(builder, arr.data, i)))
        out.parent = cgutils.get_null_value(out.parent.type)
        return out._getvalue()

    return bitgen(pointers), codegen


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


def addresses(model: mujoco.MjModel, data: mujoco.MjData) -> tuple[int, int]:
    """The C addresses of ``model``'s ``mjModel`` and ``data``'s ``mjData``, which the
    kernels pass to MuJoCo's C functions: the bindings' private ``_address``, read here only
    (``pathpref doctor`` checks it, :func:`~pathpref.apps.doctor.check_mujoco_by_address`)."""
    return model._address, data._address


def entry_point(kernel, args: tuple):
    """The compiled overload of the numba function ``kernel`` for ``args``' types (compiled,
    or loaded from numba's cache, if it is not yet), to call directly: numba's dispatcher
    resolves the overload from the types of every argument on each call, which for a kernel
    of many arrays costs more than the call; a caller resolves it once per setup. A
    ``kernel`` that is not a numba dispatcher (a test's wrapper) is returned as it is."""
    from numba.core.dispatcher import Dispatcher

    if not isinstance(kernel, Dispatcher):
        return kernel
    sig = tuple(kernel.typeof_pyval(a) for a in args)
    if sig not in kernel.overloads:
        kernel.compile(sig)
    return kernel.overloads[sig].entry_point


def ready() -> bool:
    """Whether the compiled path can run here: always, once this module is imported (its
    import raises, naming the requirement, where the libraries or symbols are missing)."""
    return AVAILABLE
