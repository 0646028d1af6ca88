"""Each part declares whether the compiled move runs it (:mod:`pathpref.sim.kernel_parts`),
safe by default: a subclass or a part that does not declare keeps the Python path."""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

import pathpref.sim  # noqa: E402,F401 - registers the MuJoCo body
from pathpref.episode import Physics  # noqa: E402
from pathpref.geometry.world import load_world  # noqa: E402
from pathpref.sim import native  # noqa: E402
from pathpref.sim.body import base_params, build_base, scene_for  # noqa: E402
from pathpref.sim.controller import HeldVelocity, ProfiledController  # noqa: E402
from pathpref.sim.cue_detector import FilteredCueDetector  # noqa: E402
from pathpref.sim.kernel_parts import declared, runs  # noqa: E402


class QuietDetector(FilteredCueDetector):
    """A detector with a behaviour of its own the kernel does not mirror (no declaration)."""


class DeclaredDetector(FilteredCueDetector):
    """The same, declared (its author says the kernel mirrors it)."""

    KERNEL_RUNS = True

    def kernel_ready(self) -> bool:
        return True


class HalfDeclared(FilteredCueDetector):
    """``KERNEL_RUNS`` without saying which modes: not run."""

    KERNEL_RUNS = True


def test_declarations_are_not_inherited():
    dt = 0.002
    assert declared(FilteredCueDetector(dt))
    assert not declared(QuietDetector(dt))
    assert not declared(HalfDeclared(dt))
    assert declared(DeclaredDetector(dt))
    assert declared(ProfiledController()) and declared(HeldVelocity())
    assert not declared(object())


@pytest.mark.skipif(not native.ready(), reason=f"no compiled path: {native.WHY}")
def test_an_undeclared_part_keeps_the_python_path():
    """The realistic base coasts; the same base with a detector subclass that does not
    declare, or with a controller subclass, does not (its coaster is None); a sensor in a
    mode the kernel does not run (before its first sample) is not ready."""
    physics = Physics()
    world = load_world("simple")
    scene = scene_for(world, base=base_params(physics))
    base = build_base(scene, "navigate", physics, np.random.default_rng(0))
    base.reset(world.cell((3, 3)))
    assert base.coaster is not None
    s = base.sensing
    assert runs(s.faulty) is (s.faulty.samples > 0)
    detector = s.detector
    s.detector = QuietDetector(base.dt)
    assert base.coaster is None
    s.detector = detector

    class OwnLaw(ProfiledController):
        pass

    controller = base.controller
    base.controller = OwnLaw()
    assert base.coaster is None
    base.controller = controller
    assert base.coaster is not None


def _reach_ins(source: str) -> list[str]:
    """The private names of other objects a module's source reads: ``x._name`` with ``x``
    anything but ``self`` (dunders aside)."""
    import ast

    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Attribute) and node.attr.startswith("_") \
                and not node.attr.startswith("__") \
                and not (isinstance(node.value, ast.Name) and node.value.id == "self"):
            out.append(f"{ast.unparse(node.value)}.{node.attr}")
    return out


def test_the_coaster_reads_no_private_name_of_another_object():
    """The compiled move's glue (:mod:`pathpref.sim.coasting`) reaches each part through the
    part's own public interface (its record, ``kernel_*`` methods, properties), never a
    private name of another object (MuJoCo's ``_address`` is read by
    :func:`pathpref.sim.native.addresses` alone)."""
    import inspect

    from pathpref.sim import coasting

    assert _reach_ins("a._b\nself._c\nx.y._z\nq.__len__\n") == ["a._b", "x.y._z"]
    assert _reach_ins(inspect.getsource(coasting)) == []
