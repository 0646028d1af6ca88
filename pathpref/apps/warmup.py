"""``pathpref warmup``: every numba kernel compiled, or loaded from numba's cache, before the
first decision needs it.

numba compiles a kernel for the argument types of its first call and keeps the result in its
cache (``cache=True``: the package's ``__pycache__``, else ``NUMBA_CACHE_DIR`` or the user's
cache folder). Without a warm-up an installation compiles the first time each kernel is
reached: 99 functions (17 s CPU) during the first physical episode, and a 3.5 s stall at the
first decision whose root pool takes the observed-exits fallback (``POMCP._observed_first``,
reached only when a tree's Wilson walk passes its budget). The warm-up reaches every kernel
through the code that calls it in use, so each is compiled for the argument types it is
called with:

* **planning**: on ``simple``, ``office`` and ``classroom``, a short grid episode of every
  preset (the paper's POMCP and the robust family's guided search), of every everyday method
  and of every belief prior, then the root pool's observed-exits fallback on a belief with
  pushes observed (the draws :meth:`~pathpref.planning.pomcp.POMCP._trees` hands to it), and
  the route prior's sparse factorisation of maps larger than the bundled ones;
* **physics**: short MuJoCo episodes under each push timing and sensor, the differential
  drive, the carrying arm on the disk and on the TidyBot, and the dm_control tasks at decision
  and control rate (the compiled move of :mod:`pathpref.sim.coasting` with and without an arm).

:func:`unreached` names the kernels still without a compiled signature afterwards (helpers
numba inlines into their callers, ``inline="always"``, have none of their own and are not
counted); the command prints them, and the tests require there be none. A later process loads
what the warm-up compiled when it builds a policy or an episode
(:func:`pathpref.kernels.load_cached`), not at its first decision.
"""

from __future__ import annotations

import importlib
import pkgutil
import time
from collections.abc import Callable, Iterable

import numpy as np

from ..kernels import PACKAGES, dispatchers

#: the maps whose decisions are warmed (the bundled ones)
MAPS = ("simple", "office", "classroom")
#: decision steps of each warm-up episode (enough for pushes, crossings and waits to occur)
T_MAX = 8
#: search queries per decision of a warm-up episode (the kernels' types do not depend on it)
QUERIES = 100


def _import_all() -> None:
    """Import every module of :data:`PACKAGES` (so that every kernel is seen), the
    simulator's included; a module that cannot be imported here (an optional extra) is
    skipped."""
    for name in PACKAGES:
        pkg = importlib.import_module(name)
        for info in pkgutil.walk_packages(pkg.__path__, name + "."):
            if info.name.endswith("__main__"):
                continue
            try:
                importlib.import_module(info.name)
            except Exception:  # noqa: BLE001,S112 - an optional extra's module, not a kernel's
                continue


def kernels() -> dict[str, object]:
    """Every numba dispatcher defined in :data:`PACKAGES` that is compiled on its own
    (``module.name`` -> dispatcher; :func:`pathpref.kernels.dispatchers` once every module is
    imported): the inlined helpers (``inline="always"``) are left out, numba compiles them
    into each caller."""
    _import_all()
    return dispatchers()


def signatures() -> int:
    """The number of compiled signatures of every kernel in this process."""
    return sum(len(k.overloads) for k in kernels().values())


def _callees(kernel, known: dict[int, str]) -> set[str]:
    """The kernels ``kernel``'s Python source names (its globals, nested functions included)."""
    out, codes = set(), [kernel.py_func.__code__]
    while codes:
        code = codes.pop()
        for name in code.co_names:
            obj = kernel.py_func.__globals__.get(name)
            if id(obj) in known:
                out.add(known[id(obj)])
        codes += [c for c in code.co_consts if hasattr(c, "co_names")]
    return out


def unreached() -> list[str]:
    """The kernels neither compiled in this process nor called by one that is (none after
    :func:`warm`). A kernel another kernel calls is compiled into its caller, and a caller
    loaded from numba's cache brings it along, so it has no signature of its own then."""
    ks = kernels()
    known = {id(k): name for name, k in ks.items()}
    reached = [name for name, k in ks.items() if k.overloads]
    seen = set(reached)
    while reached:
        for callee in _callees(ks[reached.pop()], known):
            if callee not in seen:
                seen.add(callee)
                reached.append(callee)
    return sorted(set(ks) - seen)


def _episode(map_name: str, t_max: int = T_MAX, method: str = "path_preference",
             **fields) -> None:
    from ..episode import EpisodeSpec
    from ..episode.runner import run_episode

    fields.setdefault("queries", QUERIES)
    run_episode(EpisodeSpec.single(map_name, method, fields.pop("delta_t", 5), seed=62,
                                   instance=1, t_max=t_max, **fields))


def _fallback(map_name: str) -> None:
    """The root pool's rare path: trees drawn observed exits first
    (:meth:`~pathpref.planning.pomcp.POMCP._observed_first`, with the budget and the array
    types :meth:`~pathpref.planning.pomcp.POMCP._trees` hands it) on the route belief of a
    robust episode after its first pushes, for every goal."""
    from ..episode import EpisodeSpec
    from ..episode.runner import EpisodeRunner
    from ..planning.pomcp import WALK_STEPS_MIN, WALK_STEPS_PER_POLYTOPE

    runner = EpisodeRunner(EpisodeSpec.single(map_name, "path_preference", 1, seed=62,
                                              instance=1, t_max=T_MAX, preset="robust",
                                              queries=QUERIES))
    for _ in range(3):
        if not runner.done:
            runner.step()
    planner, belief = runner.policy.planner, runner.policy.belief
    budget = WALK_STEPS_PER_POLYTOPE * len(planner.nbr) + WALK_STEPS_MIN
    planner._observed_first(belief, np.arange(len(planner.goal_cells), dtype=np.int64),
                            planner.preference_cdf(belief), 62, budget)


def _sparse_factor() -> None:
    """The route prior's factorisation above :data:`~pathpref.inference.routes.DENSE_MAX`
    rows (maps larger than the bundled ones): SuperLU kept as ``L D L^T`` and its compiled
    solve, on a path graph's M-matrix ``2 I - adjacency / 2`` one row too large to be dense."""
    from ..inference.routes import DENSE_MAX, _factor

    n = DENSE_MAX + 1
    i = np.arange(n - 1)
    rows = np.concatenate([np.arange(n), i, i + 1])
    cols = np.concatenate([np.arange(n), i + 1, i])
    data = np.concatenate([np.full(n, 2.0), np.full(2 * (n - 1), -0.5)])
    _, lu = _factor(n, rows, cols, data)
    lu.solve(np.ones(n))


def planning_steps(maps: Iterable[str] = MAPS) -> list[tuple[str, Callable[[], None]]]:
    """The planning warm-up as ``(what, run)`` steps (module docstring)."""
    from ..inference.priors import PRIORS
    from ..planning.policies import METHODS, REFERENCE_METHODS
    from ..planning.pomdp import PRESETS

    steps: list[tuple[str, Callable[[], None]]] = []
    for m in maps:
        steps += [(f"{m}: preset {p}", lambda m=m, p=p: _episode(m, preset=p))
                  for p in PRESETS]
        steps.append((f"{m}: observed-exits fallback", lambda m=m: _fallback(m)))
    first = next(iter(maps))
    steps += [(f"{first}: method {x}", lambda x=x: _episode(first, method=x))
              for x in METHODS if x not in REFERENCE_METHODS and x != "path_preference"]
    steps += [(f"{first}: prior {p}", lambda p=p: _episode(first, prior=p)) for p in PRIORS]
    steps.append(("routes: sparse factor (maps above the bundled ones' size)", _sparse_factor))
    return steps


def physics_steps() -> list[tuple[str, Callable[[], None]]]:
    """The physics warm-up as ``(what, run)`` steps (module docstring)."""
    from ..episode.physics import SENSORS, TIMINGS, Physics
    from .commands import load_simulator

    load_simulator("mujoco")
    from ..sim.robots import ROBOTS

    def physical(robot="navigate", t_max=3, **phys) -> Callable[[], None]:
        return lambda: _episode("simple", t_max=t_max, sim="mujoco", robot=robot,
                                physics=Physics.of(**phys).to_json())

    steps = [(f"mujoco: timing {t}", physical(timing=t)) for t in TIMINGS]
    steps.append(("mujoco: corrective human",
                  lambda: _episode("simple", t_max=3, sim="mujoco", delta_t=1,
                                   push_rule="corrective delay=0 miss=0.0",
                                   physics=Physics.of(timing="decision").to_json())))
    steps += [(f"mujoco: sensor {s}", physical(sensor=s, timing="interval")) for s in SENSORS]
    steps += [("mujoco: faulty sensor", physical(timing="interval", sensor_drift_n=1.0,
                                                 sensor_thermal_n=2.0))]
    steps.append(("mujoco: diffdrive base", physical(base="diffdrive", timing="interval")))
    steps.append(("mujoco: legacy body", lambda: _episode("simple", t_max=3, sim="mujoco",
                                                          physics="legacy")))
    for robot in ROBOTS:
        for t in ("decision", "interval", "guidance"):
            steps.append((f"mujoco: carry on {robot}, {t}",
                          physical("carry", timing=t, robot_model=robot)))
        steps.append((f"mujoco: {robot} base", physical(timing="interval", robot_model=robot)))
    steps += [(f"dm_control: {t}", lambda t=t: _task(t)) for t in
              ("navigate", "navigate_control", "carry", "carry_control")]
    return steps


def _task(name: str, steps: int = 30) -> None:
    """A few steps of the dm_control task ``name`` with its own policy's actions."""
    import pathpref_tasks

    env = pathpref_tasks.load(name, task_kwargs={"map": "simple", "seed": 62, "t_max": 4})
    ts = env.reset()
    for _ in range(steps):
        if ts.last():
            break
        ts = env.step(env.task.policy_action())


def warm(planning: bool = True, physics: bool = True,
         progress: Callable[[str], None] | None = None) -> dict:
    """Run the warm-up (module docstring); returns ``{"kernels", "signatures", "compiled",
    "cpu_s", "unreached"}``: how many kernels there are, their compiled signatures after it,
    how many of those numba compiled (not loaded from its cache), the CPU seconds taken and
    the kernels still unreached."""
    from numba.core import event

    from . import doctor

    steps = (planning_steps() if planning else []) + (physics_steps() if physics else [])
    steps.append(("the doctor's probes", doctor.diagnose))
    t0 = time.process_time()
    with event.install_recorder("numba:compile") as rec:
        for what, run in steps:
            if progress is not None:
                progress(what)
            run()
    return {"kernels": len(kernels()), "signatures": signatures(),
            "compiled": sum(1 for _, e in rec.buffer if e.is_start),
            "cpu_s": time.process_time() - t0, "unreached": unreached()}
