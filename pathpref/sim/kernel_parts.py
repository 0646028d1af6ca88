"""Which parts the compiled move runs (:mod:`.coasting`), each part's own declaration, safe
by default.

A part (the base, its sensor, estimator, detector, controller, measurements, guidance) whose
step the kernel mirrors says so in its class's own body: ``KERNEL_RUNS = True`` and a
``kernel_ready()`` that says whether the mode it is in now is one the kernel runs (the
faulty sensor: no thermal drift and a held sample; the estimator: started; the base: its
float control path, its measurements up to the estimate), and, for a setup fixed when the
part is built, a ``kernel_setup()`` (the carry arm: its physical mode, not the legacy one).
None of them is inherited: a subclass changes the step, so it keeps the Python path until it
declares them itself (once the kernel mirrors what it changed), and a part without a
declaration (a new detector, a controller with its own law, the differential drive) never
runs compiled. So a new part or mode runs in Python until someone makes the kernel run it,
instead of running compiled without its behaviour until someone forbids it.
"""

from __future__ import annotations

#: per class: whether its own body declares (module docstring) and its own ``kernel_setup``
#: (None: none); a class's body is read once (the checks run before every kernel call)
_DECLARATIONS: dict[type, tuple[bool, object]] = {}


def _declaration(cls: type) -> tuple[bool, object]:
    own = cls.__dict__
    found = (own.get("KERNEL_RUNS") is True and "kernel_ready" in own,
             own.get("kernel_setup"))
    _DECLARATIONS[cls] = found
    return found


def declared(part) -> bool:
    """Whether ``part``'s own class declares that the kernel runs it (module docstring):
    ``KERNEL_RUNS = True`` and ``kernel_ready`` both in its class's body, and, when that
    body also has a ``kernel_setup()``, the part's setup (fixed when it was built: the carry
    arm's legacy mode is not run) is one the kernel runs."""
    cls = type(part)
    ok, setup = _DECLARATIONS.get(cls) or _declaration(cls)
    return ok and (setup is None or setup(part))


def runs(part) -> bool:
    """Whether the kernel runs ``part``'s next step: declared (:func:`declared`) and in a
    mode the kernel runs (its ``kernel_ready()``)."""
    return declared(part) and part.kernel_ready()


class Slot:
    """An attribute of a part held in slot ``index`` of the part's state record ``rec`` (a
    float64 array the part owns and the compiled move reads and writes in place, so nothing
    is copied between the two drivers): read as a Python float (``boolean``: as
    ``value != 0``), written as a float (a bool as 1.0 or 0.0). The float64 slot holds a
    Python float exactly, so both drivers see the same numbers."""

    __slots__ = ("index", "boolean")

    def __init__(self, index: int, boolean: bool = False):
        self.index, self.boolean = index, boolean

    def __get__(self, part, owner=None):
        if part is None:
            return self
        v = part.rec.item(self.index)
        return v != 0.0 if self.boolean else v

    def __set__(self, part, value) -> None:
        part.rec[self.index] = value
