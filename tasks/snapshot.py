"""Snapshots of a task environment's episode: :meth:`~.environment.Environment.snapshot` and
:meth:`~.environment.Environment.restore` (and the Gymnasium env's, :mod:`.gym`).

A snapshot holds the whole episode, so that restoring it and replaying the same actions gives
the same observations, rewards and metrics bit for bit:

* the physics: a copy of the whole ``MjData`` (``mj_copyData``: the integration state that
  ``mj_getState(mjSTATE_INTEGRATION)`` holds, and also what the last ``mj_step`` computed
  from the state before it, ``sensordata``, ``site_xmat``, the contacts and the warning
  counts, which the parts read after a step and before the next one recomputes them);
* every part's state and the task's own (:func:`clone` of the task's attributes): the sensor
  (its window, bias, held sample and its NumPy ``Generator``), the estimator, the detector,
  the controller's ramp, the guidance admittance, the arm, the task's force filter, the
  decision step and the push under way, the runner, the belief and the planner with their
  random generators, and dm_control's step count.

Why the parts' state is beside MuJoCo's state and not in ``userdata``: it is not a fixed
vector. The cues felt, the runner's log, the belief over routes and the planner's search tree
grow during an episode, the generators' states are NumPy objects, and the task's parts are
Python objects a new episode replaces; ``nuserdata`` is fixed when the model compiles. So
``physics.set_state(physics.get_state())`` (``qpos``, ``qvel``, ``act``) restores the
physics only; ``env.snapshot()`` is the snapshot of an episode.

The task's objects are copied as one graph (``copy.deepcopy``, so objects shared stay shared
and bound methods follow their objects), except what belongs to the environment rather than
the episode: the environment's physics, ``MjModel`` and ``MjData``, the task itself, its scene
and its world (read only) stand for the environment's own (:class:`Bound`); an array that is a
view into MuJoCo's buffers (the parts read ``qpos``, ``sensordata``, a site's rotation in
place) is kept as a view (:class:`ViewOf`: which buffer, where, its shape and strides) and
made again on the restoring environment's buffer; an array that is a view into another array
stays a view of that array's copy. A part that caches raw addresses says what to drop in its
``__getstate__`` (:class:`~pathpref.sim.sensing.FaultySensor`,
:class:`~pathpref.sim.coasting.Coaster`). A snapshot can be restored any number of times, into
the environment it came from or into another one loaded with the same arguments.
"""

from __future__ import annotations

import copy
import gc
import types
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from pathpref.errors import ConfigError

#: the model's sizes a snapshot must find again in the environment it is restored into
MODEL_SIZES = ("nq", "nv", "nu", "na", "nbody", "ngeom", "nsite", "nsensor", "nsensordata",
               "nuserdata", "nmocap", "neq")
#: the task's attributes that are the environment's, not the episode's (read only)
BOUND_ATTRS = ("scene", "world")
#: the Physics attributes the task sets at each episode (:meth:`.navigate.Navigate.
#: initialize_episode`): its physics steps and its drawing
PHYSICS_ATTRS = ("substep", "substeps", "drawing")
#: types the graph walk neither follows nor copies specially (deepcopy copies them whole)
_LEAVES = (type, types.ModuleType, types.FunctionType, types.BuiltinFunctionType,
           types.BuiltinMethodType, str, bytes, int, float, complex, bool, type(None),
           np.generic, np.random.Generator, np.random.RandomState, np.random.BitGenerator)
#: modules whose objects the walk does not enter (deepcopy copies them whole)
_OPAQUE = ("numpy", "numba", "mujoco", "llvmlite", "dm_control", "scipy")


@dataclass(frozen=True, eq=False)
class Bound:
    """An object of the environment (``name``: ``task``, ``physics``, ``model``, ``data``, the
    dm_control wrappers ``physics.model`` and ``physics.data``, ``scene``, ``world``) in a
    snapshot: the restoring environment's own stands for it."""

    name: str


@dataclass(frozen=True, eq=False)
class ViewOf:
    """An array that is a view into a MuJoCo buffer: ``field`` of ``owner`` (``"qpos"``,
    ``"warning.number"``), ``offset`` bytes into it, with its ``shape``, ``strides`` and
    ``dtype``."""

    owner: Any
    field: str
    offset: int
    shape: tuple
    strides: tuple
    dtype: np.dtype

    def on(self, owner) -> np.ndarray:
        """The view on ``owner``'s buffer."""
        return _view(_field(owner, self.field), self.offset, self.shape, self.strides,
                     self.dtype)


def _address(a: np.ndarray) -> int:
    return a.__array_interface__["data"][0]


def _view(buf: np.ndarray, offset: int, shape: tuple, strides: tuple, dtype) -> np.ndarray:
    return np.ndarray(shape, dtype, buffer=buf, offset=offset, strides=strides)


def _field(owner, name: str) -> np.ndarray:
    for part in name.split("."):
        owner = getattr(owner, part)
    return owner


def _fields(owner) -> Iterator[tuple[str, np.ndarray]]:
    """The arrays of an ``MjModel`` or ``MjData`` (its own and one level down: ``opt.gravity``,
    ``warning.number``)."""
    for name in dir(owner):
        if name.startswith("_"):
            continue
        try:
            v = getattr(owner, name)
        except Exception:  # noqa: BLE001 - a property the bindings refuse here
            continue
        if isinstance(v, np.ndarray):
            yield name, v
        elif type(v).__module__.startswith("mujoco") and not callable(v):
            for sub in dir(v):
                if sub.startswith("_"):
                    continue
                try:
                    w = getattr(v, sub)
                except Exception:  # noqa: BLE001
                    continue
                if isinstance(w, np.ndarray):
                    yield f"{name}.{sub}", w


def _extent(a: np.ndarray) -> tuple[int, int]:
    """The bytes ``a`` spans, ``[lo, hi)``."""
    lo = hi = _address(a)
    for n, s in zip(a.shape, a.strides, strict=True):
        if s < 0:
            lo += (n - 1) * s
        else:
            hi += (n - 1) * s
    return lo, hi + a.itemsize


def _walk(root, stop: dict) -> tuple[list, list, list]:
    """The arrays, MuJoCo objects and :class:`ViewOf` records reachable from ``root``
    (through containers, instances and bound methods; not into ``stop``'s objects, nor into
    NumPy's, numba's, MuJoCo's or dm_control's). A function closing over state would be
    copied as it is (deepcopy does not copy functions): refused."""
    seen, arrays, owners, views = set(), [], [], []
    todo = [root]
    while todo:
        o = todo.pop()
        if id(o) in seen or id(o) in stop:
            continue
        seen.add(id(o))
        if isinstance(o, np.ndarray):
            arrays.append(o)
        elif isinstance(o, mujoco.MjModel | mujoco.MjData):
            owners.append(o)
        elif isinstance(o, ViewOf):
            views.append(o)
            todo.append(o.owner)
        elif isinstance(o, types.FunctionType):
            if o.__closure__:
                raise TypeError(f"cannot snapshot the closure {o.__qualname__}: its state "
                                "would not be copied")
        elif isinstance(o, _LEAVES) or type(o).__module__.split(".")[0] in _OPAQUE:
            continue
        elif isinstance(o, types.MethodType):
            todo.append(o.__self__)
        else:
            todo.extend(gc.get_referents(o))
    return arrays, owners, views


def _root(a: np.ndarray):
    while isinstance(a.base, np.ndarray):
        a = a.base
    return a


def clone(root, replace: dict[int, Any], buffers: tuple = ()):
    """A deep copy of ``root`` in which the object of id ``k`` is ``replace[k]`` (module
    docstring); ``buffers`` are the replaced MuJoCo objects (views into their buffers become
    :class:`ViewOf` records of the :class:`Bound` replacing them). A :class:`ViewOf` whose
    owner is replaced by a real one becomes a view on it; views into arrays stay views of the
    arrays' copies."""
    arrays, owners, views = _walk(root, replace)
    memo: dict[int, Any] = dict(replace)
    keep: list = [root]
    for o in owners:  # the MuJoCo objects the graph owns are copied whole
        memo[id(o)] = copy.deepcopy(o)
        keep.append(o)
    spans = [(*_extent(f), o, name, _address(f)) for o in (*owners, *buffers)
             for name, f in _fields(o) if f.size]
    copies: dict[int, np.ndarray] = {}  # id(an array owning its memory) -> its copy
    for a in arrays:
        r = _root(a)
        if r.dtype.hasobject:
            continue  # deepcopy's own copy (views of object arrays are not kept)
        if r.base is None:
            if a is not r:
                if id(r) not in copies:
                    copies[id(r)] = memo[id(r)] = r.copy()
                    keep.append(r)
                memo[id(a)] = _view(copies[id(r)], _address(a) - _address(r), a.shape,
                                    a.strides, a.dtype)
                keep.append(a)
            continue
        lo, hi = _extent(a)
        for s_lo, s_hi, owner, name, start in spans:
            if s_lo <= lo and hi <= s_hi:
                target, off = memo[id(owner)], _address(a) - start
                memo[id(a)] = ViewOf(target, name, off, a.shape, a.strides, a.dtype) \
                    if isinstance(target, Bound) else \
                    _view(_field(target, name), off, a.shape, a.strides, a.dtype)
                keep.append(a)
                break
        # else: memory NumPy does not own and no MuJoCo buffer holds: deepcopy's copy
    for v in views:
        target = memo.get(id(v.owner), v.owner)
        memo[id(v)] = ViewOf(target, v.field, v.offset, v.shape, v.strides, v.dtype) \
            if isinstance(target, Bound) else v.on(target)
    memo[id(memo)] = keep  # deepcopy's keep-alive list: no id is reused while it copies
    return copy.deepcopy(root, memo)


@dataclass(frozen=True, eq=False)
class Snapshot:
    """An episode of a task environment (module docstring): its task's class and model sizes
    (the environments it fits), the ``MjData`` copy and the copied state."""

    task: str
    sizes: tuple
    data: mujoco.MjData
    state: dict


def _bound(env) -> dict[str, Any]:
    """The environment's own objects, by their :class:`Bound` names."""
    task, physics = env.task, env.physics
    out = {"task": task, "physics": physics, "physics.model": physics.model,
           "physics.data": physics.data, "model": physics.model.ptr, "data": physics.data.ptr}
    for name in BOUND_ATTRS:
        if name in vars(task):
            out[name] = vars(task)[name]
    return out


def _sizes(model) -> tuple:
    return tuple(int(getattr(model, n)) for n in MODEL_SIZES)


def take(env) -> Snapshot:
    """The snapshot of ``env``'s episode now (a :class:`~.environment.Environment`)."""
    task, physics = env.task, env.physics
    bound = _bound(env)
    replace: dict[int, Any] = {id(o): Bound(name) for name, o in bound.items()}
    state = {"task": {k: v for k, v in vars(task).items()},
             "physics": {k: vars(physics)[k] for k in PHYSICS_ATTRS if k in vars(physics)},
             "env": {"_step_count": env._step_count,
                     "_reset_next_step": env._reset_next_step}}
    state = clone(state, replace, (bound["model"], bound["data"]))
    return Snapshot(type(task).__qualname__, _sizes(physics.model.ptr),
                    copy.copy(physics.data.ptr), state)


def put(env, snap: Snapshot) -> None:
    """Restore ``snap`` into ``env`` (the environment it came from or one loaded with the
    same arguments); a one-line ConfigError when it does not fit."""
    if not isinstance(snap, Snapshot):
        raise ConfigError(f"restore takes a snapshot from env.snapshot(), got "
                          f"{type(snap).__name__}")
    task, physics = env.task, env.physics
    if type(task).__qualname__ != snap.task or _sizes(physics.model.ptr) != snap.sizes:
        raise ConfigError(f"this snapshot is of a {snap.task} environment with another model; "
                          "restore it into one loaded with the same task and arguments")
    bound = _bound(env)
    tokens = _tokens(snap.state)
    replace: dict[int, Any] = {}
    for tok in tokens:
        if tok.name not in bound:
            raise ConfigError(f"this snapshot needs the environment's {tok.name}, which "
                              "this one has not; restore it into one loaded with the same "
                              "arguments")
        replace[id(tok)] = bound[tok.name]
    state = clone(snap.state, replace)
    vars(task).clear()
    vars(task).update(state["task"])
    for k in PHYSICS_ATTRS:
        vars(physics).pop(k, None)
    vars(physics).update(state["physics"])
    env._step_count = state["env"]["_step_count"]
    env._reset_next_step = state["env"]["_reset_next_step"]
    mujoco.mj_copyData(physics.data.ptr, physics.model.ptr, snap.data)


def _tokens(state) -> list[Bound]:
    """The :class:`Bound` records in a snapshot's state."""
    found, seen, todo = [], set(), [state]
    while todo:
        o = todo.pop()
        if id(o) in seen:
            continue
        seen.add(id(o))
        if isinstance(o, Bound):
            found.append(o)
        elif isinstance(o, ViewOf):
            todo.append(o.owner)
        elif isinstance(o, np.ndarray | mujoco.MjModel | mujoco.MjData) or \
                isinstance(o, _LEAVES) or type(o).__module__.split(".")[0] in _OPAQUE:
            continue
        elif isinstance(o, types.MethodType):
            todo.append(o.__self__)
        else:
            todo.extend(gc.get_referents(o))
    return found
