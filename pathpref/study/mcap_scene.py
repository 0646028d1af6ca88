"""The trial's scene as Foxglove messages (protobuf, the ``foxglove-sdk`` schemas) for the
MCAP export, in metres on the ``world`` frame (a map unit is one cell of
:data:`pathpref.sim.scene.CELL_SIZE_M`; the centre of cell ``(x, y)`` is
``((x - 0.5) c, (y - 0.5) c)``):

* :func:`scene_update`: the outer walls (a closed line around ``width x height`` cells), each
  obstacle (a closed line through its vertices), the preferred route (a line through the
  centres of its cells) and the start (grey) and goal (green) cells as spheres;
* :func:`belief_update`: the goal candidates as spheres, coloured by the robot's probability
  ``p`` of each (red, opacity ``0.15 + 0.85 p``, diameter ``(0.2 + 0.6 p) c``);
* :func:`base_transform`: the ``world -> base`` frame transform of a pose;
* :func:`event`: a push or cue as a ``foxglove.Event`` (its start and end time, and every
  field of its row as metadata: ``key`` the column, ``value`` the stored value as text,
  ``repr`` of a float so ``float(value)`` gives it back exactly; ``kind`` ``push``/``cue``);
* :func:`arrow_update`: a push or cue drawn as an arrow from the base's position along its
  direction ``(dx, dy)``, shaft ``length`` m, shown for ``lifetime_s``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

from ..sim.scene import CELL_SIZE_M


def _fx():
    try:
        import foxglove.messages as fx
    except ImportError:
        from ..errors import ConfigError

        raise ConfigError("MCAP export needs the foxglove-sdk package: pip install "
                          "'pathpref[export]' (or pass --no-mcap)") from None
    return fx


def fx_type(name: str):
    """The Foxglove message type ``name`` (``foxglove.messages``)."""
    return getattr(_fx(), name)


def schema(message_type):
    """(name, encoding, data) of a Foxglove message type's schema (protobuf descriptors)."""
    s = message_type.get_schema()
    return s.name, s.encoding, bytes(s.data)


def quaternion_z(yaw: float) -> tuple[float, float]:
    """``(qz, qw)`` of the rotation by ``yaw`` about z."""
    return math.sin(0.5 * yaw), math.cos(0.5 * yaw)


def _stamp(fx, ns: int):
    return fx.Timestamp(sec=ns // 1_000_000_000, nsec=ns % 1_000_000_000)


def _centre(fx, cell: Sequence[float]):
    return fx.Point3(x=(cell[0] - 0.5) * CELL_SIZE_M, y=(cell[1] - 0.5) * CELL_SIZE_M, z=0.0)


def _sphere(fx, cell, diameter: float, colour):
    return fx.SpherePrimitive(
        pose=fx.Pose(position=fx.Vector3(x=(cell[0] - 0.5) * CELL_SIZE_M,
                                         y=(cell[1] - 0.5) * CELL_SIZE_M, z=0.0),
                     orientation=fx.Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)),
        size=fx.Vector3(x=diameter, y=diameter, z=diameter), color=colour)


def scene_update(ns: int, size: tuple[int, int] | None, obstacles: Sequence,
                 route: Sequence, start: Sequence[int], goal: Sequence[int]):
    """The static scene (module docstring) at ``ns`` nanoseconds since the epoch; ``size``
    (width, height) in cells, or None (the map cannot be read: no walls); obstacles are
    vertex arrays in map units (``[[x, y], ...]``), ``route`` a list of cells."""
    fx = _fx()
    c = CELL_SIZE_M

    def loop(points, colour, thickness=0.04):
        return fx.LinePrimitive(type=fx.LinePrimitiveLineType.LineLoop, thickness=thickness,
                                points=[fx.Point3(x=float(x) * c, y=float(y) * c, z=0.0)
                                        for x, y in points], color=colour)

    black = fx.Color(r=0.1, g=0.1, b=0.1, a=1.0)
    lines = [loop(list(v), black) for v in obstacles]
    if size is not None:
        w, h = size
        lines.insert(0, loop([(0, 0), (w, 0), (w, h), (0, h)], black, 0.06))
    lines.append(fx.LinePrimitive(type=fx.LinePrimitiveLineType.LineStrip, thickness=0.05,
                                  points=[_centre(fx, cell) for cell in route],
                                  color=fx.Color(r=0.2, g=0.4, b=1.0, a=0.9)))
    ends = [_sphere(fx, start, 0.3 * c, fx.Color(r=0.5, g=0.5, b=0.5, a=1.0)),
            _sphere(fx, goal, 0.3 * c, fx.Color(r=0.1, g=0.7, b=0.2, a=1.0))]
    return fx.SceneUpdate(entities=[fx.SceneEntity(
        timestamp=_stamp(fx, ns), frame_id="world", id="scene", lines=lines, spheres=ends)])


def belief_update(ns: int, candidates: Sequence[Sequence[int]], p: Sequence[float]):
    """The goal candidates coloured by their probabilities ``p`` (module docstring)."""
    fx = _fx()
    return fx.SceneUpdate(entities=[fx.SceneEntity(
        timestamp=_stamp(fx, ns), frame_id="world", id="belief", spheres=[
            _sphere(fx, cell, (0.2 + 0.6 * pi) * CELL_SIZE_M,
                    fx.Color(r=0.9, g=0.1, b=0.1, a=0.15 + 0.85 * pi))
            for cell, pi in zip(candidates, p, strict=True)])])


def base_transform(ns: int, x: float, y: float, qz: float = 0.0, qw: float = 1.0,
                   child: str = "base"):
    """The ``world -> child`` transform: translation ``(x, y, 0)`` m, rotation about z."""
    fx = _fx()
    return fx.FrameTransform(timestamp=_stamp(fx, ns), parent_frame_id="world",
                             child_frame_id=child, translation=fx.Vector3(x=x, y=y, z=0.0),
                             rotation=fx.Quaternion(x=0.0, y=0.0, z=qz, w=qw))


def _metadata_value(v) -> str:
    return "" if v is None else repr(v) if isinstance(v, float) else str(v)


def event(start_ns: int, end_ns: int, kind: str, row: Mapping):
    """A ``foxglove.Event`` from ``start_ns`` to ``end_ns`` (module docstring)."""
    fx = _fx()
    return fx.Event(start_time=_stamp(fx, start_ns), end_time=_stamp(fx, end_ns), metadata=[
        fx.KeyValuePair(key="kind", value=kind)] + [
        fx.KeyValuePair(key=k, value=_metadata_value(v)) for k, v in row.items()])


def arrow_update(ns: int, entity: str, x: float, y: float, dx: float, dy: float,
                 length: float, lifetime_s: float, colour: tuple[float, float, float]):
    """One arrow (module docstring): tail at ``(x, y)`` m, pointing along ``(dx, dy)`` (a
    rotation of ``atan2(dy, dx)`` about z), head 0.15 m long, red-green-blue ``colour``."""
    fx = _fx()
    half = 0.5 * math.atan2(dy, dx)
    life = max(0.0, lifetime_s)
    return fx.SceneUpdate(entities=[fx.SceneEntity(
        timestamp=_stamp(fx, ns), frame_id="world", id=entity,
        lifetime=fx.Duration(sec=int(life), nsec=int(round((life % 1.0) * 1e9)) % 1_000_000_000),
        arrows=[fx.ArrowPrimitive(
            pose=fx.Pose(position=fx.Vector3(x=x, y=y, z=0.3),
                         orientation=fx.Quaternion(x=0.0, y=0.0, z=math.sin(half),
                                                   w=math.cos(half))),
            shaft_length=length, shaft_diameter=0.04, head_length=0.15, head_diameter=0.1,
            color=fx.Color(r=colour[0], g=colour[1], b=colour[2], a=1.0))])])
