"""Study files: the trials of a force-interaction study and their order per participant.

A study is a JSON or TOML file (TOML read with the standard library's ``tomllib``)::

    {"name": "demo", "order": "fixed", "seed": 0,
     "defaults": {"map": "simple", "method": "path_preference", "preset": "robust",
                  "queries": 500, "time_limit_s": 30},
     "trials": [{"name": "left", "start": [1, 1], "goal": [1, 8],
                 "candidates": [[1, 8], [5, 8], [10, 8]], "route": [[1, 1], [1, 8]],
                 "condition": {"belief": "shown"}}, ...]}

Per trial (a field missing from a trial is taken from ``defaults``):

* ``map``: a built-in map or a map file (relative to the study file);
* ``method`` (``compliant``, ``goal_only``, ``path_preference``, ``blended``; the reference
  methods read the goal and are refused) and ``preset`` (``robust-slack``, the default,
  ``robust-check``, ``robust-wait``, ``robust``, ``paper``, ``original``),
  ``queries`` (planner queries per decision, 1..100000; default: the preset's, as every door's);
* ``start``, ``goal``: free cells ``[x, y]``; ``candidates``: the goal candidates the robot
  infers over (free cells, the goal among them; default: the free cells of the map's
  ``goal_band`` reachable from the start);
* ``route``: waypoints ``[x, y]`` the participant is asked to convey, start to goal; shown to
  the participant, never to the robot. It also scores the trial: the route's preference
  (:func:`~pathpref.geometry.preference.preference_from_route`, open route) counts violations;
* ``time_limit_s`` (1..3600): simulated seconds (real seconds for a person);
* ``condition``: labels (strings) for the analysis; ``"belief": "hidden"`` hides the robot's
  goal probabilities from the participant (shown otherwise);
* ``physics``: the physical parameters the trial runs with, an object of
  :class:`~pathpref.episode.physics.Physics` flat fields (``{"sensor": "ideal"}``, ``{"base":
  "diffdrive", "v_max": 0.8}``; the fields left out keep their defaults) or ``"legacy"`` (the
  ideal sensor and original base of the first studies); default: ``Physics()``, as every
  door's. The simulated human's fields (``gamma_h``, ``peak_n``, ...) are refused: a trial's
  human is the participant; ``timing`` may be ``guidance``: the base complies to the
  participant's push (Bajcsy-style guidance, every door's guided decision step) and the trial
  is judged along the base's path, the crossings made while the participant pushes reported
  beside the robot's own; ``robot_model`` must stay ``disk`` (a study's exports place cells
  at its 0.5 m);
* ``robot``: ``navigate`` (the base) or ``carry`` (the Jaco arm on the base; the participant
  pushes its tray); default ``navigate``.

``questionnaire``: ``"nasa-tlx"`` has the browser ask the NASA-TLX (six 0..100 scales) after
every trial; the answers are recorded per participant (:mod:`.conduct`).

``order``: ``fixed`` (file order for everyone) or ``latin``: a balanced Latin square (Williams
design). Row ``r`` of ``n`` trials is ``r, r+1, r+n-1, r+2, r+n-2, ...`` (mod n); with an odd
``n`` the ``n`` mirrored rows are added. The participant's row is the SHA-256 of the participant
id (UTF-8) as an integer, modulo the number of rows. Every trial then appears equally often at
every position and after every other trial across a full set of rows.

Every problem is one line naming the field, e.g. ``trials[1].goal (5, 5) lies on an obstacle``.
"""

from __future__ import annotations

import hashlib
import json
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..episode import EpisodeSpec, cached_world
from ..episode.instances import seed_for
from ..episode.physics import FIELDS, Physics
from ..errors import ConfigError, PathprefError
from ..geometry.preference import preference_from_route
from ..geometry.world import World
from ..planning.pomdp import DEFAULT_PRESET, PRESETS

STUDY_METHODS = ("compliant", "goal_only", "path_preference", "blended")
TRIAL_FIELDS = {"name", "map", "method", "preset", "queries", "start", "goal", "candidates",
                "route", "time_limit_s", "condition", "physics", "robot"}
#: what a trial (and the study's ``defaults``) leaves out: the planner's defaults are every
#: door's (``pathpref.planning.pomdp.DEFAULT_PRESET`` and its queries; None: the preset's)
DEFAULTS = {"method": "path_preference", "preset": DEFAULT_PRESET, "queries": None,
            "time_limit_s": 60.0, "condition": {}, "physics": None, "robot": "navigate"}
#: the robots of a trial: the MuJoCo body's tasks (``pathpref.sim.body.MujocoBody.tasks``)
STUDY_ROBOTS = ("navigate", "carry")
#: the trial timings: the participant pushes; under ``guidance`` the base also complies
STUDY_TIMINGS = ("decision", "guidance")
MAX_TRIALS = 1000


@dataclass(frozen=True)
class Trial:
    """One trial of a study, validated. Cells are 1-based ``(x, y)`` tuples."""

    index: int
    name: str
    map: str
    method: str
    preset: str
    queries: int
    start: tuple[int, int]
    goal: tuple[int, int]
    candidates: tuple[tuple[int, int], ...]
    route: tuple[tuple[int, int], ...]
    time_limit_s: float
    condition: dict[str, str] = field(default_factory=dict, hash=False, compare=False)
    #: canonical JSON of the trial's :class:`~pathpref.episode.physics.Physics` ("": legacy)
    physics: str = field(default_factory=lambda: Physics().to_json())
    robot: str = "navigate"

    @property
    def show_belief(self) -> bool:
        """The participant sees the robot's goal probabilities (condition ``belief``)."""
        return self.condition.get("belief", "shown") != "hidden"

    @property
    def world(self) -> World:
        """The trial's map."""
        return cached_world(self.map)

    @property
    def goal_index(self) -> int:
        """Index of the goal among the candidates."""
        return self.candidates.index(self.goal)

    def episode_spec(self, seed: int) -> EpisodeSpec:
        """The trial as an episode of the MuJoCo body (the robot infers over the candidates
        from the start, one decision step per input, seeds from the study's ``seed`` and the
        trial's index): what :class:`~.session.TrialRunner` runs."""
        fixed = json.dumps({"start": list(self.start), "goals": [list(c) for c in
                                                                  self.candidates],
                            "true_goal": self.goal_index}, sort_keys=True)
        return EpisodeSpec(map=self.map, method=self.method, delta_t=1, instance=self.index,
                           run=0, instance_seed=seed_for(seed, self.index),
                           run_seed=seed_for(seed, self.index, 0), preset=self.preset,
                           queries=self.queries, t_max=self.world.spec.t_max,
                           n_goals=len(self.candidates), sim="mujoco", fixed=fixed,
                           physics=self.physics, robot=self.robot)

    def route_preference(self) -> np.ndarray:
        """The preference the route conveys, per polytope (-1: none): the open-route rule."""
        w = self.world
        return preference_from_route(w.arrangement, w.graph, w.motion,
                                     [list(c) for c in self.route], closed=False)


@dataclass(frozen=True)
class Study:
    """A validated study file: its trials, order rule, seed and content hash."""

    path: str
    name: str
    order: str
    seed: int
    trials: tuple[Trial, ...]
    hash: str
    #: ``"nasa-tlx"``: the browser asks the NASA-TLX after every trial (None: no questionnaire)
    questionnaire: str | None = None

    def order_for(self, participant: str) -> list[Trial]:
        """The participant's trials in order (module docstring)."""
        n = len(self.trials)
        if self.order == "fixed" or n == 1:
            return list(self.trials)
        rows = latin_rows(n)
        r = int.from_bytes(hashlib.sha256(participant.encode()).digest(), "big") % len(rows)
        return [self.trials[k] for k in rows[r]]


def latin_rows(n: int) -> list[list[int]]:
    """The rows of a balanced Latin square (Williams design) of ``n`` treatments: ``n`` rows,
    plus their mirror images when ``n`` is odd (module docstring)."""
    first = [0]
    lo, hi = 1, n - 1
    while len(first) < n:
        first.append(lo)
        lo += 1
        if len(first) < n:
            first.append(hi)
            hi -= 1
    rows = [[(c + r) % n for c in first] for r in range(n)]
    if n % 2:
        rows += [row[::-1] for row in rows]
    return rows


def _cell(value: Any, where: str) -> tuple[int, int]:
    if (not isinstance(value, list | tuple) or len(value) != 2
            or not all(isinstance(v, int) and not isinstance(v, bool) for v in value)):
        raise ConfigError(f"{where} must be a cell [x, y] of two whole numbers, got "
                          f"{json.dumps(value)[:40]}")
    return int(value[0]), int(value[1])


def _free(world: World, cell: tuple[int, int], where: str) -> int:
    try:
        return world.cell(cell, where)
    except PathprefError as e:
        raise ConfigError(str(e)) from None


def _trial(i: int, raw: Any, defaults: dict[str, Any], folder: Path) -> Trial:
    where = f"trials[{i}]"
    if not isinstance(raw, dict):
        raise ConfigError(f"{where} must be an object of trial fields")
    unknown = sorted(set(raw) - TRIAL_FIELDS)
    if unknown:
        raise ConfigError(f"{where}.{unknown[0]} is not a trial field; fields: "
                          f"{', '.join(sorted(TRIAL_FIELDS))}")
    t = {**DEFAULTS, **defaults, **raw}
    for need in ("map", "start", "goal", "route"):
        if need not in t:
            raise ConfigError(f"{where}.{need} is missing (give it in the trial or defaults)")
    name = t.get("name", f"trial{i + 1}")
    if not isinstance(name, str) or not name:
        raise ConfigError(f"{where}.name must be a non-empty string")
    m = t["map"]
    if not isinstance(m, str):
        raise ConfigError(f"{where}.map must be a built-in map name or a map file")
    if m.endswith(".json") and not Path(m).is_absolute():
        m = str(folder / m)
    try:
        world = cached_world(m)
    except PathprefError as e:
        raise ConfigError(f"{where}.map: {e}") from None
    except OSError as e:
        raise ConfigError(f"{where}.map: cannot read {m}: {e.strerror}") from None
    if t["method"] not in STUDY_METHODS:
        raise ConfigError(f"{where}.method must be one of {', '.join(STUDY_METHODS)}, got "
                          f"{str(t['method'])[:40]!r}")
    if t["preset"] not in PRESETS:
        raise ConfigError(f"{where}.preset must be one of {', '.join(sorted(PRESETS))}, got "
                          f"{str(t['preset'])[:40]!r}")
    q = t["queries"] if t["queries"] is not None else PRESETS[t["preset"]].queries
    if not isinstance(q, int) or isinstance(q, bool) or not 1 <= q <= 100_000:
        raise ConfigError(f"{where}.queries must be a whole number in 1..100000, got {str(q)[:40]}")
    lim = t["time_limit_s"]
    if not isinstance(lim, int | float) or isinstance(lim, bool) or not 1 <= lim <= 3600:
        raise ConfigError(f"{where}.time_limit_s must be a number of seconds in 1..3600, got "
                          f"{str(lim)[:40]}")
    start = _cell(t["start"], f"{where}.start")
    goal = _cell(t["goal"], f"{where}.goal")
    s, g = _free(world, start, f"{where}.start"), _free(world, goal, f"{where}.goal")
    if s == g:
        raise ConfigError(f"{where}.goal must differ from the start")
    reach = world.motion.distances_from(np.array([s]))[0]
    if "candidates" in t:
        if not isinstance(t["candidates"], list) or not t["candidates"]:
            raise ConfigError(f"{where}.candidates must be a non-empty list of cells [x, y]")
        cands = [_cell(c, f"{where}.candidates[{k}]") for k, c in enumerate(t["candidates"])]
        idx = [_free(world, c, f"{where}.candidates[{k}]") for k, c in enumerate(cands)]
        if len(set(idx)) != len(idx) or s in idx:
            raise ConfigError(f"{where}.candidates must be distinct cells other than the start")
    else:
        band = world.spec.goal_band
        if not band:
            raise ConfigError(f"{where}.candidates is missing and map '{world.name}' has no "
                              "goal_band to draw them from")
        cells = world.cells
        idx = [int(c) for c in np.flatnonzero(
            (cells[:, 0] >= band["x"][0]) & (cells[:, 0] <= band["x"][1])
            & (cells[:, 1] >= band["y"][0]) & (cells[:, 1] <= band["y"][1])
            & np.isfinite(reach)) if c != s]
        cands = [tuple(int(v) for v in cells[c]) for c in idx]
    if goal not in cands:
        raise ConfigError(f"{where}.goal {goal} is not among the candidates")
    for k, c in zip(idx, cands, strict=True):
        if not np.isfinite(reach[k]):
            raise ConfigError(f"{where}.candidates: {c} cannot be reached from the start")
    if not isinstance(t["route"], list) or len(t["route"]) < 2:
        raise ConfigError(f"{where}.route must list at least 2 waypoints [x, y]")
    route = [_cell(c, f"{where}.route[{k}]") for k, c in enumerate(t["route"])]
    for k, c in enumerate(route):
        _free(world, c, f"{where}.route[{k}]")
    if route[0] != start or route[-1] != goal:
        raise ConfigError(f"{where}.route must run from the start {start} to the goal {goal}")
    cond = t["condition"]
    if not isinstance(cond, dict) or not all(isinstance(k, str) and isinstance(v, str)
                                             for k, v in cond.items()):
        raise ConfigError(f"{where}.condition must map labels to strings, e.g. "
                          '{"belief": "hidden"}')
    if cond.get("belief", "shown") not in ("shown", "hidden"):
        raise ConfigError(f"{where}.condition.belief must be shown or hidden")
    trial = Trial(i, name, m, t["method"], t["preset"], q, start, goal, tuple(cands),
                  tuple(route), float(lim), dict(cond), _physics(t["physics"], where),
                  _robot(t["robot"], where))
    try:
        trial.route_preference()
    except PathprefError as e:
        raise ConfigError(f"{where}.route: {e}") from None
    try:
        trial.episode_spec(0).validate()
    except PathprefError as e:
        raise ConfigError(f"{where}: {e}") from None
    return trial


#: why a trial refuses the simulated human's physics fields (the study file's and ``study run``'s)
NOT_THE_PARTICIPANT = "is the simulated human's; a trial's human is the participant: leave it out"


def disk_only(got: str) -> str:
    """Why a study's trials run on the disk robot only, for a request of robot model ``got``:
    the one message of the study file's ``robot_model`` and of ``study run --robot-model``."""
    return (f"must be disk: a study's exports place its cells at the disk's 0.5 m; got "
            f"{got!r} (the TidyBot runs in --sim mujoco episodes, the tasks and the videos)")


def _physics(value: Any, where: str) -> str:
    """The canonical ``physics`` of a trial field (module docstring)."""
    if value is None or value == "legacy":
        return Physics.coerce(value)
    if not isinstance(value, dict):
        raise ConfigError(f"{where}.physics must be an object of physics fields, e.g. "
                          '{"sensor": "realistic"}, or "legacy"')
    human = sorted(k for k in value if FIELDS.get(k, ("",))[0] == "human" and k != "timing")
    if value.get("timing", "decision") not in STUDY_TIMINGS:
        raise ConfigError(f"{where}.physics.timing must be {' or '.join(STUDY_TIMINGS)} "
                          "(decision: the participant's pushes are read as cues; guidance: the "
                          "base also complies to them), got "
                          f"{str(value.get('timing'))[:40]!r}")
    if human:
        raise ConfigError(f"{where}.physics.{human[0]} {NOT_THE_PARTICIPANT}")
    if value.get("robot_model", "disk") != "disk":
        raise ConfigError(f"{where}.physics.robot_model "
                          f"{disk_only(str(value.get('robot_model'))[:40])}")
    try:
        return Physics.coerce(value)
    except PathprefError as e:
        raise ConfigError(f"{where}.{e}") from None


def _robot(value: Any, where: str) -> str:
    if value not in STUDY_ROBOTS:
        raise ConfigError(f"{where}.robot must be {' or '.join(STUDY_ROBOTS)}, got "
                          f"{str(value)[:40]!r}")
    return value


def parse_study(raw: Any, path: str = "<study>", folder: Path | None = None) -> Study:
    """Validate a study given as parsed JSON/TOML (module docstring)."""
    folder = folder or Path(".")
    if not isinstance(raw, dict):
        raise ConfigError(f"{path}: a study file is an object with 'trials'")
    unknown = sorted(set(raw) - {"name", "order", "seed", "defaults", "trials",
                                 "questionnaire"})
    if unknown:
        raise ConfigError(f"{path}: '{unknown[0]}' is not a study field; fields: name, order, "
                          "seed, defaults, trials, questionnaire")
    questionnaire = raw.get("questionnaire")
    if questionnaire not in (None, "nasa-tlx"):
        raise ConfigError(f"questionnaire must be nasa-tlx (or left out), got "
                          f"{str(questionnaire)[:40]!r}")
    order = raw.get("order", "fixed")
    if order not in ("fixed", "latin"):
        raise ConfigError(f"order must be fixed or latin, got {str(order)[:40]!r}")
    seed = raw.get("seed", 0)
    if not isinstance(seed, int) or isinstance(seed, bool) or not 0 <= seed < 2**63:
        raise ConfigError(f"seed must be a whole number in 0..2^63-1, got {str(seed)[:40]}")
    defaults = raw.get("defaults", {})
    if not isinstance(defaults, dict):
        raise ConfigError("defaults must be an object of trial fields")
    bad = sorted(set(defaults) - TRIAL_FIELDS)
    if bad:
        raise ConfigError(f"defaults.{bad[0]} is not a trial field")
    trials = raw.get("trials")
    if not isinstance(trials, list) or not 1 <= len(trials) <= MAX_TRIALS:
        raise ConfigError(f"trials must be a list of 1..{MAX_TRIALS} trials")
    parsed = tuple(_trial(i, t, defaults, folder) for i, t in enumerate(trials))
    names = [t.name for t in parsed]
    dup = next((n for n in names if names.count(n) > 1), None)
    if dup is not None:
        raise ConfigError(f"trials: the name {dup!r} is used twice; trial names must differ")
    digest = hashlib.sha256(json.dumps(raw, sort_keys=True).encode()).hexdigest()[:16]
    name = raw.get("name", Path(path).stem)
    if not isinstance(name, str):
        raise ConfigError("name must be a string")
    return Study(str(path), name, order, seed, parsed, digest, questionnaire)


def load_study(path: str | Path) -> Study:
    """Read and validate a study file (``.json`` or ``.toml``)."""
    p = Path(path)
    if p.suffix not in (".json", ".toml"):
        raise ConfigError(f"{p}: a study file is .json or .toml")
    try:
        text = p.read_bytes()
    except OSError as e:
        raise ConfigError(f"cannot read study file {p}: {e.strerror}") from None
    try:
        raw = tomllib.loads(text.decode()) if p.suffix == ".toml" else json.loads(text)
    except (ValueError, UnicodeDecodeError) as e:
        raise ConfigError(f"{p} is not valid {p.suffix[1:].upper()}: "
                          f"{str(e).splitlines()[0]}") from None
    except RecursionError:
        raise ConfigError(f"{p} is nested too deeply to be a study file") from None
    return parse_study(raw, str(p), p.parent)


def trial_from_row(r: dict[str, Any]) -> Trial:
    """The trial as it ran, from its stored ``trials`` row (:mod:`pathpref.experiments.trials`):
    its settings, physics and robot; a row of a file written before the ``physics`` and
    ``robot`` columns existed (NULL) ran the default physics ``Physics()`` on the ``navigate``
    robot."""
    def cells(key: str) -> tuple:
        return tuple(tuple(c) for c in json.loads(r[key]))

    setup = {k: r[k] for k in ("physics", "robot") if r.get(k) is not None}
    return Trial(index=r["study_index"], name=r["name"], map=r["map"], method=r["method"],
                 preset=r["preset"], queries=r["queries"],
                 start=tuple(json.loads(r["start"])), goal=tuple(json.loads(r["goal"])),
                 candidates=cells("candidates"), route=cells("route"),
                 time_limit_s=r["time_limit_s"], condition=json.loads(r["condition"] or "{}"),
                 **setup)
