"""``pathpref doctor``: whether this installation can run what pathpref compiles, one line per
failure naming its cause.

pathpref's compiled physics relies on things no version number promises (docs/physics.md,
"What the compiled steps rely on"), so each is checked by using it, not by its version:

* **versions**: every package pathpref requires (its installed metadata: pyproject's
  dependencies, the ``mujoco`` and ``dm-control`` pins of docs/STACK included) is installed
  and within its specifier;
* **native symbols**: :mod:`pathpref.sim.native` imports, so NumPy is at least
  :data:`~pathpref.sim.native.NUMPY_MIN` and ``libmujoco`` and NumPy's OpenBLAS have every
  symbol the kernels link (:data:`~pathpref.sim.native.SYMBOLS`, looked up with ``ctypes``);
* **MuJoCo by address**: each C function the kernels declare (``mj_step``,
  ``mj_objectAcceleration``, ``mj_jacBodyCom``, ``mj_jacBody``), called through ``ctypes``
  with the kernels' own hand-typed signature on the bindings' private ``_address`` of an
  ``MjModel`` and ``MjData``, gives exactly what the bindings' function gives;
* **numba's BitGenerator**: the private data model has the members
  :func:`~pathpref.sim.native.bit_generator` fills, and normals drawn through it equal NumPy's
  ``Generator.standard_normal`` from the same seed;
* **entry points**: ``Dispatcher.overloads[sig].entry_point``
  (:func:`~pathpref.sim.native.entry_point`) is a compiled function that answers;
* **no NRT**: ``njit(_nrt=False)`` (the search and coasting kernels') is accepted and compiles
  without numba's reference counting;
* **cache index**: numba's private cache index (``_cache._cache_file._load_index``,
  ``_cache._index_key``), through which :func:`pathpref.kernels.load_cached` loads the
  kernels before the first decision, lists the overload a cached probe kernel just compiled
  (without it every kernel still loads at its first call: the first decision is slower).

A check that needs an earlier one (the native module) is not run when that one failed: its
line already names the cause.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from importlib import metadata

#: the comparison operators of a requirement's specifier
_OPS: dict[str, Callable[[tuple, tuple], bool]] = {
    "==": lambda a, b: a == b, "!=": lambda a, b: a != b, ">=": lambda a, b: a >= b,
    "<=": lambda a, b: a <= b, ">": lambda a, b: a > b, "<": lambda a, b: a < b}


def release(version: str) -> tuple[int, ...]:
    """The numeric release of a version string (``"3.17.0"`` -> ``(3, 17, 0)``; a pre- or
    post-release suffix is dropped, ``"2.4.0rc1"`` -> ``(2, 4, 0)``)."""
    parts = []
    for p in version.split("."):
        m = re.match(r"\d+", p)
        if m is None:
            break
        parts.append(int(m.group()))
        if m.end() < len(p):
            break
    return tuple(parts)


def satisfies(version: str, specifier: str) -> bool:
    """Whether ``version`` meets every clause of ``specifier`` (``">=1.3,<2"``, ``"==3.17.0"``;
    releases compared as padded number tuples, so ``3.17`` == ``3.17.0``)."""
    have = release(version)
    for clause in filter(None, (c.strip() for c in specifier.split(","))):
        op = next(o for o in ("==", "!=", ">=", "<=", ">", "<") if clause.startswith(o))
        want = release(clause[len(op):].strip())
        n = max(len(have), len(want))
        if not _OPS[op](have + (0,) * (n - len(have)), want + (0,) * (n - len(want))):
            return False
    return True


def requirements() -> list[tuple[str, str]]:
    """``(name, specifier)`` of every package pathpref requires outside its extras, as the
    installed ``pathpref`` says (pyproject's ``dependencies``)."""
    out = []
    for line in metadata.requires("pathpref") or []:
        if ";" in line:  # an extra's (or a platform's) requirement
            continue
        m = re.match(r"\s*([A-Za-z0-9_.-]+)(\[[^\]]*\])?\s*(.*)", line)
        if m:
            out.append((m.group(1), m.group(3).strip()))
    return out


def check_versions() -> list[str]:
    """One line per required package missing or outside its specifier."""
    out = []
    try:
        reqs = requirements()
    except metadata.PackageNotFoundError:
        return ["pathpref is not installed (no package metadata to read its requirements "
                "from): pip install . (or make install) in its source tree"]
    for name, spec in reqs:
        try:
            have = metadata.version(name)
        except metadata.PackageNotFoundError:
            out.append(f"{name} is not installed; pathpref needs {name}{spec}: "
                       f"pip install '{name}{spec}'")
            continue
        if spec and not satisfies(have, spec):
            out.append(f"{name} {have} is installed; pathpref needs {name}{spec} (pyproject): "
                       f"pip install '{name}{spec}'")
    return out


def check_native() -> list[str]:
    """NumPy's floor, the libraries and their symbols (:func:`pathpref.sim.native.problem`,
    which the module's import raises): its one line, if any."""
    from ..errors import PathprefError

    try:
        from ..sim import native
    except PathprefError as e:
        return [str(e)]
    why = native.problem()
    return [why] if why else []


#: a body on a free joint above a floor: every function below has something to compute
_PROBE_XML = """<mujoco><worldbody><geom type="plane" size="2 2 0.1"/>
<body name="b" pos="0 0 0.3"><freejoint/><geom type="box" size="0.1 0.2 0.05" mass="2"/>
<body name="c" pos="0.2 0 0"><joint type="hinge" axis="0 1 0"/>
<geom type="capsule" size="0.03" fromto="0 0 0 0.2 0 0" mass="0.5"/></body></body>
</worldbody></mujoco>"""


def _ctypes_function(lib, ext):
    """``ext`` (a numba ``ExternalFunction`` of :mod:`pathpref.sim.native`) as a ``ctypes``
    function of ``lib`` with the same hand-typed signature."""
    import ctypes

    from numba import types

    kinds = {types.voidptr: ctypes.c_void_p, types.int32: ctypes.c_int32,
             types.int64: ctypes.c_int64, types.float64: ctypes.c_double}
    fn = getattr(lib, ext.symbol)
    fn.argtypes = [kinds[a] for a in ext.sig.args]
    fn.restype = None if ext.sig.return_type == types.none else kinds[ext.sig.return_type]
    return fn


def check_mujoco_by_address() -> list[str]:
    """Each MuJoCo C function the kernels call by address, through ``ctypes`` with the
    kernels' signature on the bindings' ``_address`` (read by
    :func:`~pathpref.sim.native.addresses`), equals the bindings' own call (exactly)."""
    import ctypes

    import mujoco
    import numpy as np

    from ..sim import native

    model = mujoco.MjModel.from_xml_string(_PROBE_XML)
    ours, theirs = mujoco.MjData(model), mujoco.MjData(model)
    for d in (ours, theirs):
        d.qvel[:] = np.linspace(-0.5, 0.7, model.nv)
    try:
        addr = native.addresses(model, ours)
    except AttributeError as e:
        return [f"mujoco {mujoco.__version__}: the bindings have no _address ({e}), which the "
                f"compiled kernels pass to MuJoCo's C functions: use mujoco==3.17.0"]
    lib = ctypes.CDLL(native._libraries()[0])
    out = []

    def differs(name: str, a, b) -> None:
        if not all(np.array_equal(x, y) for x, y in zip(a, b, strict=True)):
            out.append(f"mujoco {mujoco.__version__}: {name} called by address with the "
                       "signature pathpref.sim.native declares differs from the bindings' "
                       f"mujoco.{name}: its C signature changed; use the mujoco pyproject pins")

    step = _ctypes_function(lib, native.mj_step)
    for _ in range(20):
        step(*addr)
        mujoco.mj_step(model, theirs)
    differs("mj_step", (ours.qpos, ours.qvel), (theirs.qpos, theirs.qvel))
    body = model.body("c").id
    acc = [np.zeros(6), np.zeros(6)]
    _ctypes_function(lib, native.mj_objectAcceleration)(
        *addr, native.OBJ_BODY, body, acc[0].ctypes.data, 0)
    mujoco.mj_objectAcceleration(model, theirs, native.OBJ_BODY, body, acc[1], 0)
    differs("mj_objectAcceleration", acc[:1], acc[1:])
    for ext, theirs_fn in ((native.mj_jacBodyCom, mujoco.mj_jacBodyCom),
                           (native.mj_jacBody, mujoco.mj_jacBody)):
        jac = [np.zeros((3, model.nv)) for _ in range(4)]
        _ctypes_function(lib, ext)(*addr, jac[0].ctypes.data, jac[1].ctypes.data, body)
        theirs_fn(model, theirs, jac[2], jac[3], body)
        differs(ext.symbol, jac[:2], jac[2:])
    return out


def check_bit_generator() -> list[str]:
    """numba's private ``BitGenerator`` model has the members
    :func:`~pathpref.sim.native.bit_generator` fills (64-bit each), and normals drawn through
    it equal ``Generator.standard_normal`` from the same seed."""
    import numba
    import numpy as np
    from numba import types
    from numba.core.datamodel import default_manager

    from ..sim import native

    where = (f"numba {numba.__version__}: its private BitGenerator struct, which "
             "pathpref.sim.native.bit_generator fills for the sensor's compiled draws,")
    try:
        import numba.np.random.generator_core  # noqa: F401 - registers the model

        model = default_manager.lookup(types.NumPyRandomBitGeneratorType("bit_generator"))
        members = dict(zip(model._fields, model._members, strict=True))
    except Exception as e:  # noqa: BLE001 - any change of numba's internals is the finding
        return [f"{where} cannot be read ({type(e).__name__}: {e}): use numba 0.68"]
    lacking = [f for f in native.BIT_GENERATOR_FIELDS
               if f not in members or members[f].bitwidth != 64]
    if lacking:
        return [f"{where} lacks the 64-bit members {', '.join(lacking)}: use numba 0.68"]
    from .doctor_probes import normals

    got = np.zeros(16)
    rng = np.random.default_rng(62)  # alive while the pointers to its state are used
    normals(native.bit_generator_pointers(rng), got)
    if not np.array_equal(got, np.random.default_rng(62).standard_normal(16)):
        return [f"{where} draws other normals than NumPy's Generator from the same seed: "
                "use numba 0.68"]
    return []


def _numba_probe(probe: Callable[[], bool], wrong: str, what: str) -> list[str]:
    """One line when ``probe()`` (a use of one of numba's internals) is False (``wrong`` says
    how) or raises (its exception says how); ``what`` names the internal and what relies on
    it. Any exception counts: a change of numba's internals is the finding."""
    import numba

    try:
        ok, why = bool(probe()), wrong
    except Exception as e:  # noqa: BLE001 - any change of numba's internals is the finding
        ok, why = False, f"fails ({type(e).__name__}: {e})"
    return [] if ok else [f"numba {numba.__version__}: {what} {why}: use numba 0.68"]


def check_entry_point() -> list[str]:
    """:func:`~pathpref.sim.native.entry_point` (``Dispatcher.overloads[sig].entry_point``)
    gives a compiled function that answers (``hypot(3, 4) = 5``)."""
    from ..sim import native

    def probe() -> bool:
        fn = native.entry_point(native.hypot, (3.0, 4.0))
        return fn is not native.hypot and fn(3.0, 4.0) == math.hypot(3.0, 4.0)

    return _numba_probe(probe, "answers wrongly", "Dispatcher.overloads[sig].entry_point, "
                        "which the compiled steps call directly "
                        "(pathpref.sim.native.entry_point),")


def check_no_nrt() -> list[str]:
    """``njit(_nrt=False)`` is still an option numba takes, and honours."""
    import numpy as np

    def probe() -> bool:
        from .doctor_probes import add_one

        x = np.zeros(3)
        add_one(x)
        return bool(x.sum() == 3.0) and add_one.targetoptions.get("_nrt") is False

    return _numba_probe(probe, "is dropped", "the private option njit(_nrt=False) of the "
                        "search and coasting kernels")


def check_cache_index() -> list[str]:
    """:func:`pathpref.kernels.cached_signatures` finds, in numba's cache index, the overload
    of the probe kernel ``add_one`` (``cache=True``) that its call just compiled or loaded."""
    import numpy as np

    from ..kernels import cached_signatures

    def probe() -> bool:
        from .doctor_probes import add_one

        add_one(np.zeros(3))
        return any(tuple(sig) in add_one.overloads for sig in cached_signatures(add_one))

    return _numba_probe(probe, "does not list the overload just compiled, so each kernel "
                        "loads at its first call", "its private cache index, which pathpref "
                        "reads to load the kernels before the first decision "
                        "(pathpref.kernels.load_cached),")


#: the checks in order (name, function, whether it needs the native module)
CHECKS: tuple[tuple[str, Callable[[], list[str]], bool], ...] = (
    ("versions", check_versions, False),
    ("native symbols", check_native, False),
    ("MuJoCo by address", check_mujoco_by_address, True),
    ("numba BitGenerator", check_bit_generator, True),
    ("numba entry points", check_entry_point, True),
    ("numba _nrt=False", check_no_nrt, True),
    ("numba cache index", check_cache_index, True),
)


def diagnose() -> list[str]:
    """Every check's failures, one line each (empty: all passed)."""
    out: list[str] = []
    native_ok = True
    for name, check, needs_native in CHECKS:
        if needs_native and not native_ok:
            continue
        lines = check()
        if name == "native symbols":
            native_ok = not lines
        out += lines
    return out


def versions() -> str:
    """``numpy X, numba Y, llvmlite Z, mujoco W, dm-control V`` as installed."""
    have = []
    for name in ("numpy", "numba", "llvmlite", "mujoco", "dm-control"):
        try:
            have.append(f"{name} {metadata.version(name)}")
        except metadata.PackageNotFoundError:
            have.append(f"{name} missing")
    return ", ".join(have)
