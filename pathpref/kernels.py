"""The package's numba kernels: which there are, and their code loaded from numba's cache
before a decision needs it.

numba compiles a kernel for the argument types of its first call and keeps the result in its
cache (``cache=True``: the package's ``__pycache__``, else ``NUMBA_CACHE_DIR``); a later
process loads that overload from the cache, but lazily, at the kernel's first call with those
types: after ``pathpref warmup`` (:mod:`pathpref.apps.warmup`, which fills the cache) a
process's first decision still spent about 60 ms CPU loading its kernels
(``docs/results/warmup_decisions.md``). :func:`load_cached` loads them ahead: for every kernel
of the modules imported so far, each overload the cache holds for this machine and this
source, the signatures the warm-up compiled. :func:`~pathpref.planning.policies.make_policy`
and the episode runner (once its body is built) call it, so the time is spent building the
policy and the first decision loads nothing. With an empty cache it loads nothing (and
compiles nothing: the kernels compile at their first call, as before).
"""

from __future__ import annotations

import sys

#: the packages whose kernels these are (and that the warm-up reaches)
PACKAGES = ("pathpref", "pathpref_tasks")

#: the modules whose kernels :func:`load_cached` has handled (a module's kernels are defined
#: when it is imported)
_HANDLED: set[str] = set()


def dispatchers(skip: set[str] | frozenset = frozenset()) -> dict[str, object]:
    """Every numba dispatcher defined in a module of :data:`PACKAGES` imported so far (but
    those named in ``skip``) that is compiled on its own (``module.name`` -> dispatcher): the
    inlined helpers (``inline="always"``) are left out, numba compiles them into each
    caller."""
    from numba.core.dispatcher import Dispatcher

    out = {}
    for mod_name, mod in list(sys.modules.items()):
        if mod is None or mod_name in skip or not mod_name.startswith(PACKAGES):
            continue
        for attr, obj in list(vars(mod).items()):
            if (isinstance(obj, Dispatcher) and obj.py_func.__module__ == mod_name
                    and obj.targetoptions.get("inline", "never") != "always"):
                out[f"{mod_name}.{attr}"] = obj
    return out


def cached_signatures(kernel) -> list[tuple]:
    """The argument types of each overload of ``kernel`` (a numba dispatcher) that numba's
    cache holds and this process can load: the index's entries whose key is the one numba
    computes here for that signature (this machine's code generator, this source's bytecode).
    numba's private cache internals (``_cache``, ``_cache_file._load_index``,
    ``_index_key``) are read here only; a dispatcher without a cache (``cache=False``) has
    none."""
    cache = getattr(kernel, "_cache", None)
    index = getattr(cache, "_cache_file", None)
    if index is None:
        return []
    codegen = kernel.targetctx.codegen()
    try:
        return [key[0] for key in index._load_index()
                if cache._index_key(key[0], codegen) == key]
    except (AttributeError, TypeError, ValueError, IndexError, OSError):
        # numba's cache internals changed: nothing is loaded ahead (each kernel still loads
        # at its first call); ``pathpref doctor`` names the cause (check_cache_index)
        return []


def load_cached() -> int:
    """Load every cached overload (:func:`cached_signatures`) of every kernel of the modules
    imported since the last call (module docstring); returns how many overloads it loaded.
    A signature already compiled or loaded is left alone."""
    found = dispatchers(_HANDLED)
    _HANDLED.update(m for m in list(sys.modules) if m.startswith(PACKAGES))
    n = 0
    for kernel in found.values():
        for sig in cached_signatures(kernel):
            if tuple(sig) not in kernel.overloads:
                kernel.compile(sig)
                n += 1
    return n
