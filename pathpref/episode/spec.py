"""What determines an episode: :class:`EpisodeSpec`, its identity and its planner settings."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

from ..errors import ConfigError
from ..planning.pomdp import PRESETS, Preset, get_preset
from .cache import cached_map
from .instances import HUMANS, seed_for


@dataclass(frozen=True)
class EpisodeSpec:
    """Everything that determines an episode. ``key()`` identifies it in the results store.

    ``queries``, ``ucb_c`` and ``coupling`` left as None take the preset's values (resolved at
    construction, so the key holds numbers); :meth:`planner` is the one place the preset and
    these overrides meet. ``coupling`` (on in the ``paper`` and ``original`` presets, as in the
    authors' code) applies the paper's back-edge remark to the robot's belief at every real
    polytope change; without it the paper's reward can be farmed by crossing a confidently
    preferred edge back and forth (see README, "Reproducing Table I").

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
    preset: str = "paper"
    queries: int | None = None
    t_max: int = 30
    n_goals: int = 10
    normalize: bool = True
    coupling: bool | None = None
    sim: str = "grid"
    fixed: str = ""  # JSON of the pinned instance, "" for a sampled one
    task: str = "navigate"
    ucb_c: float | None = None
    #: robust search's wall-time budget per decision (0: the query count only)
    time_budget_ms: float = 0.0
    #: the human's preference: "map" (the map's, the paper's protocol) or "consistent" (the
    #: true goal is drawn among candidates the map's preference leads to; see instances.py)
    human: str = "map"
    #: wall-clock limit in seconds (0: none); not part of the key, it does not change results
    timeout_s: float = field(default=0.0, compare=False)

    def __post_init__(self) -> None:
        preset = PRESETS.get(self.preset)  # an unknown name is reported by validate()
        for name in ("queries", "ucb_c", "coupling"):
            if getattr(self, name) is None:
                object.__setattr__(self, name,
                                   getattr(preset, name) if preset else
                                   getattr(PRESETS["paper"], name))

    @classmethod
    def single(cls, map: str, method: str, delta_t: int = 5, seed: int = 0, instance: int = 0,
               run: int = 0, **fields) -> EpisodeSpec:
        """Episode ``(instance, run)`` of seed ``seed`` by the sweeps' rule (common random
        numbers): the instance is drawn from ``seed_for(seed, instance)``, the run's human and
        planner from ``seed_for(seed, instance, run)``; ``fields`` set the rest."""
        return cls(map=map, method=method, delta_t=int(delta_t), instance=instance, run=run,
                   instance_seed=seed_for(seed, instance),
                   run_seed=seed_for(seed, instance, run), **fields)

    def planner(self) -> Preset:
        """The preset with this episode's overrides: every setting a policy reads."""
        return get_preset(self.preset, queries=self.queries, ucb_c=self.ucb_c,
                          coupling=self.coupling, time_budget_ms=self.time_budget_ms)

    @property
    def map_hash(self) -> str:
        """Content hash of the map (:attr:`MapSpec.content_hash`): the map's identity."""
        return cached_map(self.map).content_hash

    def key(self) -> str:
        """The episode's identity: every field but the map's path and the timeout, plus the
        map's content hash (so an edited map runs new episodes and the same map under another
        path reuses them)."""
        d = asdict(self)
        d.pop("timeout_s")
        d.pop("map")
        d["map_hash"] = self.map_hash
        return "|".join(f"{k}={d[k]}" for k in sorted(d))

    def validate(self) -> None:
        """Refuse settings no episode can run with (one line naming the field and the fix).
        Whether the body offers the task is checked where the body is chosen (:mod:`.body`)."""
        preset = get_preset(self.preset)
        if self.delta_t < 1:
            raise ConfigError(f"--delta-t must be at least 1, got {self.delta_t}")
        if self.t_max < 1:
            raise ConfigError(f"--t-max must be at least 1, got {self.t_max}")
        if self.queries < 1:
            raise ConfigError(f"--queries must be at least 1, got {self.queries}")
        if not self.timeout_s >= 0:
            raise ConfigError(f"--episode-timeout must be >= 0 seconds, got {self.timeout_s}")
        if not self.ucb_c > 0:
            raise ConfigError(f"--ucb-c must be positive, got {self.ucb_c}")
        if not self.time_budget_ms >= 0:
            raise ConfigError(f"--time-budget-ms must be positive, got {self.time_budget_ms}")
        if self.human not in HUMANS:
            raise ConfigError(f"unknown human preference '{self.human}'; choose "
                              f"{' or '.join(HUMANS)}")
        if self.time_budget_ms > 0 and preset.search != "robust":
            raise ConfigError("--time-budget-ms needs the robust search: add --preset robust")
