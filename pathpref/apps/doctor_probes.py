"""The small compiled functions :mod:`.doctor` runs to check numba's private internals by use
(compiled on first call, cached like every kernel)."""

from __future__ import annotations

import numba as nb
from numba.np.random.distributions import random_standard_normal

from ..sim.native import bit_generator


@nb.njit(cache=True)
def normals(pointers, out):
    """``out[i]`` = the ``i``-th standard normal of the generator whose
    :func:`~pathpref.sim.native.bit_generator_pointers` are ``pointers`` (as the faulty
    sensor's :func:`~pathpref.sim.sensing.emit_step` draws them)."""
    bitgen = bit_generator(pointers)
    for i in range(out.shape[0]):
        out[i] = random_standard_normal(bitgen)


@nb.njit(cache=True, _nrt=False)
def add_one(x):
    """``x += 1`` in place, compiled without numba's reference counting (``_nrt=False``)."""
    for i in range(x.shape[0]):
        x[i] += 1.0
