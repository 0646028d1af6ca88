"""What determines an episode: :class:`EpisodeSpec`, its identity and its planner settings."""

from __future__ import annotations

import math
import numbers
from dataclasses import asdict, dataclass, field, fields
from typing import Any

from ..errors import ConfigError, PathprefError
from ..geometry.maps import MAX_T_MAX
from ..inference.priors import check_prior
from ..planning.pomdp import (
    DEFAULT_PRESET,
    PRESETS,
    Preset,
    get_preset,
)
from .cache import cached_map
from .corrective import parse_push_rule
from .instances import HUMANS, seed_for
from .physics import HumanModel, Physics, grid_human

#: the documented range of every number a user gives (command line and Python API):
#: name -> (lowest, highest, whole number); checked by :func:`check_number`
LIMITS: dict[str, tuple[float, float, bool]] = {
    "delta_t": (1, MAX_T_MAX, True),
    "t_max": (1, MAX_T_MAX, True),
    "queries": (1, 10**7, True),
    "seed": (0, 2**63 - 1, True),
    "instances": (1, 10**6, True),
    "runs": (1, 10**6, True),
    "goals": (1, 1000, True),
    "workers": (1, 1024, True),
    "frame_size": (16, 4096, True),
    "ucb_c": (1e-6, 1e6, False),
    "time_budget_ms": (1e-3, 1e7, False),
    "episode_timeout": (1, 1e6, False),  # or 0: none (the API takes any 0..1e6)
    "record_path": (50, 1e4, False),  # or 0: no path recorded
    "trial": (1, 100_000, True),  # a study trial's position (replay)
    "port": (0, 65535, True),  # a TCP port (0: any free one)
    "plan_side": (4, 200, True),  # map generate --width, --height
    "plan_obstacles": (0, 200, True),  # map generate --rotated, --boxes
    "plan_obstacle_size": (1e-3, 1e3, False),  # map generate --sizes LO HI (cells)
}
#: the limits whose option also takes 0 (none)
ZERO_OK = ("episode_timeout", "record_path")
#: fields that say how an episode is run, not what it is: left out of its key and its stored
#: columns (they do not change its result)
RUN_OPTIONS = ("timeout_s", "record_path_hz")
#: fields stored (key, database columns) under an older name: field -> stored name
STORED_NAMES = {"robot": "task"}
#: most episodes one sweep may hold (the product of its sizes, checked before building specs)
MAX_EPISODES = 10**7


def _show(value: Any) -> str:
    if isinstance(value, numbers.Integral) and not isinstance(value, bool) and \
            int(value).bit_length() > 120:
        return f"an integer of {int(value).bit_length()} bits"
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def range_error(option: str, lo: float, hi: float, integer: bool, shown: str,
                zero_ok: bool = False) -> ConfigError:
    """The one-line refusal of an out-of-range number, e.g. ``--queries must be an integer in
    1..10000000, got 18446744073709551616``."""
    kind = "an integer" if integer else "a number"
    span = f"{int(lo)}..{int(hi)}" if integer else f"{lo:g}..{hi:g}"
    zero = "0 (none) or " if zero_ok else ""
    return ConfigError(f"{option} must be {zero}{kind} in {span}, got {shown}")


def check_number(option: str, value: Any, lo: float, hi: float, integer: bool = True,
                 zero_ok: bool = False) -> int | float:
    """``value`` as an int (Python or NumPy integer, no bool) or a finite float in
    ``lo..hi`` (or 0 when ``zero_ok``); :func:`range_error` otherwise."""
    ok = not isinstance(value, bool)
    if integer:
        ok = ok and isinstance(value, numbers.Integral)
    else:
        ok = ok and isinstance(value, numbers.Real) and math.isfinite(value)
    if ok and (lo <= value <= hi or (zero_ok and value == 0)):
        return int(value) if integer else float(value)
    raise range_error(option, lo, hi, integer, _show(value), zero_ok)


def check_limit(option: str, value: Any, name: str) -> int | float:
    """:func:`check_number` against ``LIMITS[name]`` (those of :data:`ZERO_OK` also take
    0)."""
    lo, hi, integer = LIMITS[name]
    return check_number(option, value, lo, hi, integer, zero_ok=name in ZERO_OK)


@dataclass(frozen=True)
class EpisodeSpec:
    """Everything that determines an episode. ``key()`` identifies it in the results store.

    ``queries``, ``ucb_c``, ``coupling`` and ``prior`` left as None take the preset's values
    (resolved at construction, so the key holds them); :meth:`planner` is the one place the
    preset and these overrides meet. ``coupling`` (on in the ``paper`` and ``original`` presets,
    as in the authors' code) applies the paper's back-edge remark to the robot's belief at every
    real polytope change; without it the paper's reward can be farmed by crossing a confidently
    preferred edge back and forth (see docs/reproduction.md, "Reproducing Table I").

    ``fixed`` optionally pins the instance: JSON of ``{"start": [x, y], "goals": [[x, y], ...],
    "true_goal": k, "free_goal_polytope": bool}``; otherwise it is drawn from
    ``instance_seed``. ``run_seed`` drives the human, the planner and the body's noise.
    ``sim`` names the body (:mod:`.body`): ``grid``, or one a simulator package registers.
    """

    map: str
    method: str
    delta_t: int
    instance: int
    run: int
    instance_seed: int
    run_seed: int
    preset: str = DEFAULT_PRESET
    queries: int | None = None
    #: mission time in decision steps; None: the map's (its ``t_max`` field, else its size
    #: rule), as every door (CLI, tasks, studies) resolves it
    t_max: int | None = None
    n_goals: int = 10
    normalize: bool = True
    coupling: bool | None = None
    sim: str = "grid"
    fixed: str = ""  # JSON of the pinned instance, "" for a sampled one
    #: which robot a physical body is: the plain base (``navigate``) or the arm on the base
    #: carrying a tray (``carry``); stored (key, database column) as ``task``, its old name
    robot: str = "navigate"
    ucb_c: float | None = None
    #: robust search's wall-time budget per decision (0: the query count only)
    time_budget_ms: float = 0.0
    #: the human's preference: "map" (the map's, the paper's protocol) or "consistent" (the
    #: true goal is drawn among candidates the map's preference leads to, and the human's
    #: preference is the map's completed into routes that all lead to the goal; instances.py)
    human: str = "map"
    #: the physical parameters of a MuJoCo episode: canonical JSON of :class:`.physics.Physics`,
    #: or "" for the legacy physics of rows written before the field (left out of the key then,
    #: so their keys are unchanged). None: the defaults for a physical body (``Physics()``,
    #: realistic sensing), nothing for the grid; the legacy physics only by name ("legacy").
    #: A grid episode takes the human's settings only (``gamma_h`` ...; physics.grid_human).
    #: Parsed once into ``physical`` and ``human_model`` (typed, not fields)
    physics: str | None = None
    #: the path-preference belief's prior, a name of :mod:`pathpref.inference.priors`:
    #: "independent" (the paper's), "routes", "learned-gamma", "homotopy", "circulation" or a
    #: registered plug-in; left out of the key
    #: when "independent", so the keys of episodes stored before the field existed (all
    #: independent) stay as they were
    prior: str | None = None
    #: when the human pushes: "" every delta_t steps (the paper's), or the corrective human's
    #: rule ``corrective delay=D miss=M`` (:mod:`.corrective`; delta_t 1); left out of the key
    #: when "", so the keys stored before the field existed stay as they were
    push_rule: str = ""
    #: wall-clock limit in seconds (0: none); not part of the key, it does not change results
    timeout_s: float = field(default=0.0, compare=False)
    #: record the body's continuous path at this rate (samples per simulated second, >= 50;
    #: 0: none), for a body that can (:meth:`~.body.Body.record_path`); stored beside the
    #: episode (``EpisodeResult.path``), not part of the key: it does not change the result
    record_path_hz: float = field(default=0.0, compare=False)

    def __post_init__(self) -> None:
        if self.t_max is None and isinstance(self.map, str):  # the map's mission time
            try:
                object.__setattr__(self, "t_max", cached_map(self.map).t_max)
            except PathprefError:
                pass  # validate() names the map's problem
        if self.physics is None:
            object.__setattr__(self, "physics", "" if self.sim == "grid" else
                               Physics().to_json())
        elif self.physics == "legacy":
            object.__setattr__(self, "physics", "")
        elif isinstance(self.physics, Physics | dict):
            object.__setattr__(self, "physics", Physics.coerce(self.physics))
        self._type_physics()
        preset = PRESETS.get(self.preset)  # an unknown name is reported by validate()
        for name in ("queries", "ucb_c", "coupling", "prior"):
            if getattr(self, name) is None:
                object.__setattr__(self, name,
                                   getattr(preset, name) if preset else
                                   getattr(PRESETS["paper"], name))

    def _type_physics(self) -> None:
        """Parse ``physics`` once into the typed values ``physical`` (a :class:`Physics`, None
        for the grid and the legacy physics) and ``human_model`` (the simulated human of any
        body); a grid episode's ``physics`` is made canonical (:func:`grid_human`). A bad
        value leaves both None for :meth:`validate` to name."""
        physical, human = None, None
        if isinstance(self.physics, str) and isinstance(self.sim, str):
            try:
                if self.sim == "grid":
                    human = grid_human(self.physics)
                    object.__setattr__(self, "physics", human.stored())
                else:
                    physical = Physics.from_json(self.physics)
                    human = HumanModel() if physical is None else physical.human
            except PathprefError:
                pass
        object.__setattr__(self, "physical", physical)
        object.__setattr__(self, "human_model", human)

    @classmethod
    def single(cls, map: str, method: str, delta_t: int = 5, seed: int = 0, instance: int = 0,
               run: int = 0, **fields) -> EpisodeSpec:
        """Episode ``(instance, run)`` of seed ``seed`` by the sweeps' rule (common random
        numbers): the instance is drawn from ``seed_for(seed, instance)``, the run's human and
        planner from ``seed_for(seed, instance, run)``; ``fields`` set the rest."""
        return cls(map=map, method=method, delta_t=int(delta_t), instance=instance, run=run,
                   instance_seed=seed_for(seed, instance),
                   run_seed=seed_for(seed, instance, run), **fields)

    def stored(self) -> dict[str, Any]:
        """The fields by their stored names (the database columns; :data:`STORED_NAMES`)."""
        d = asdict(self)
        for name, old in STORED_NAMES.items():
            d[old] = d.pop(name)
        return d

    @classmethod
    def field_names(cls) -> dict[str, str]:
        """Every field's stored name -> its name (the run options are not stored,
        :data:`RUN_OPTIONS`)."""
        return {STORED_NAMES.get(f.name, f.name): f.name for f in fields(cls)
                if f.name not in RUN_OPTIONS}

    def planner(self) -> Preset:
        """The preset with this episode's overrides: every setting a policy reads."""
        return get_preset(self.preset, queries=self.queries, ucb_c=self.ucb_c,
                          coupling=self.coupling, time_budget_ms=self.time_budget_ms,
                          prior=self.prior)

    @property
    def map_hash(self) -> str:
        """Content hash of the map (:attr:`MapSpec.content_hash`): the map's identity."""
        return cached_map(self.map).content_hash

    def key(self) -> str:
        """The episode's identity: every field but the map's path and the run options
        (:data:`RUN_OPTIONS`), plus the map's content hash (so an edited map runs new episodes
        and the same map under another path reuses them)."""
        d = self.stored()
        for name in RUN_OPTIONS:
            d.pop(name)
        if d["physics"] == "":
            d.pop("physics")
        d.pop("map")
        if d["prior"] == "independent":
            d.pop("prior")
        if d["push_rule"] == "":
            d.pop("push_rule")
        d["map_hash"] = self.map_hash
        return "|".join(f"{k}={d[k]}" for k in sorted(d))

    def validate(self) -> None:
        """Refuse settings no episode can run with (one line naming the field and the fix).
        Whether the body offers the task is checked where the body is chosen (:mod:`.body`)."""
        if not isinstance(self.map, str):
            raise ConfigError(f"map must be a string, got {_show(self.map)}")
        if self.t_max is None:  # the map could not be read: its own error
            cached_map(self.map)
        preset = get_preset(self.preset)
        for option, value, name in (
            ("--delta-t", self.delta_t, "delta_t"), ("--t-max", self.t_max, "t_max"),
            ("--queries", self.queries, "queries"), ("--goals", self.n_goals, "goals"),
            ("--ucb-c", self.ucb_c, "ucb_c"),
            ("instance_seed", self.instance_seed, "seed"), ("run_seed", self.run_seed, "seed"),
        ):
            check_limit(option, value, name)
        check_number("--episode-timeout", self.timeout_s, 0, LIMITS["episode_timeout"][1],
                     integer=False)
        check_limit("--record-path", self.record_path_hz, "record_path")
        for option, value in (("instance", self.instance), ("run", self.run)):
            check_number(option, value, 0, 2**63 - 1)
        if self.time_budget_ms != 0:
            check_limit("--time-budget-ms", self.time_budget_ms, "time_budget_ms")
        for option, value in (("map", self.map), ("method", self.method),
                              ("preset", self.preset), ("sim", self.sim), ("robot", self.robot),
                              ("fixed", self.fixed), ("physics", self.physics)):
            if not isinstance(value, str):
                raise ConfigError(f"{option} must be a string, got {_show(value)}")
        check_prior(self.prior)
        if self.human not in HUMANS:
            raise ConfigError(f"unknown human preference '{self.human}'; choose "
                              f"{' or '.join(HUMANS)}")
        rule = parse_push_rule(self.push_rule)
        if rule is not None and rule.text != self.push_rule:
            raise ConfigError(f"push_rule {self.push_rule!r}: write it {rule.text!r}")
        if rule is not None and self.delta_t != 1:
            raise ConfigError("--push-rule corrective watches every step: use --delta-t 1")
        if self.human_model is None:  # the parse failed: name why
            grid_human(self.physics) if self.sim == "grid" else Physics.from_json(self.physics)
        physics = self.physical
        if physics is not None:
            if physics.drive.kind == "diffdrive" and self.robot == "carry":
                raise ConfigError("physics base diffdrive runs the navigate task only (the "
                                  "arm is mounted on the holonomic base); use base holonomic")
        if self.time_budget_ms > 0 and preset.search != "robust":
            raise ConfigError("--time-budget-ms needs the robust search: add --preset robust")
