"""The physical parameters of an episode as three typed values: the robot's sensing chain
(:class:`Sensing`), the simulated human (:class:`HumanModel`) and the base's drive
(:class:`Drive`), composed in :class:`Physics`.

An :class:`~.spec.EpisodeSpec` holds them typed (``spec.physical``, ``spec.human_model``) and
serialises them once, as canonical flat JSON in ``physics``, for its key; the empty string is
the *legacy* physics every row written before this field existed ran with (ideal sensor, one
30 N / 0.3 s half-sine push at each input step while the base stands, the original base and
``carry`` controllers), so old rows replay bit for bit. This module only describes and checks
the parameters (the episode layer never imports the simulator); the simulator package acts on
them. ``docs/physics.md`` gives the sources of the defaults.

A grid episode has no sensing chain and no drive, but it has a human: its ``physics`` is the
canonical JSON of a :class:`HumanModel` alone when the human is not the default (so
``gamma_h`` works in grid episodes), else empty.

Groups (the flat field names are the JSON keys and the ``--`` flags):

* sensing (:class:`Sensing`): ``sensor`` preset (``ideal``, ``ft300s``, ``realistic``) and
  optional fault overrides ``sensor_noise_n``, ``sensor_bias_n``, ``sensor_drift_n`` (negative:
  the preset's);
* detection: ``on_n``, ``on_s``, ``off_n``, ``off_s`` (hysteresis thresholds);
* the human (:class:`HumanModel`): ``timing`` (``decision``: at input steps, at rest, as in the
  paper; ``interval``: every ``interval_s`` with uniform jitter ``+-jitter`` of it, at any
  moment of motion; ``rate``: a Poisson process of mean interval ``interval_s``; ``corrective``:
  after a reaction time, when the robot starts a move the human finds wrong, with probability
  ``p_correct``, or a right one, with ``p_needless``; ``guidance``: Bajcsy et al.'s sustained
  corrections, at the ``interval`` times the human holds the handle (at most a log-normal
  time of median ``hold_s``) while the base drives, the base complies and the belief is
  updated online from the deformation, below; ``guide``: the guiding person, ``closed`` or
  ``open``; with the episode's ``--push-rule corrective ...`` the guiding person takes the
  handle when the robot starts a move off their route instead of on the clock,
  the simulator's ``guiding_human``); ``interval_s`` 0 means ``delta_t``
  decision steps of :meth:`Physics.step_s` seconds (the one rule); push strength log-normal with
  median ``peak_n`` and geometric spread ``peak_spread``, clipped to ``[peak_min_n,
  peak_max_n]``; duration log-normal with median ``duration_s`` and spread ``duration_spread``,
  clipped to ``[0.1, duration_max_s]``; ``shape`` ``half_sine`` or ``bell``; angle noise
  ``noise_deg``; the human's rationality ``gamma_h`` (SPEC 4); ``strength_confidence`` ``c``:
  the human pushes harder when surer, median strength ``peak_n exp(c (q - 1/2))`` with ``q`` the
  drawn heading's probability over the most likely one's (0: strength independent of the
  heading);
* the robot's reading of a cue (in :class:`Sensing`): whether it weighs a cue by its strength
  (``use_strength``: the likelihood to the power ``clip(F / peak_n, 0.5, 2)``);
* the base (:class:`Drive`): ``base`` (``holonomic`` or ``diffdrive``; the attribute
  ``Drive.kind``), ``v_max`` (m/s) and ``a_max`` (m/s^2)
  the controller plans with (defaults: the Clearpath Ridgeback's velocity limit, 1.0 m/s, and
  0.8 m/s^2, inside its 1.0 m/s^2 acceleration limit because 120 N moves its 135 kg at
  0.89 m/s^2 at most), ``force_limit_n`` (actuator force limit per axis, N),
  ``admittance_b`` (N s/m, how the base yields while a cue is under way), ``mass_kg`` (the
  whole base) and ``friction_n`` (the floor's Coulomb resistance to sliding, per axis, N);
  ``admittance_m`` (kg): the guided base's admittance ``M dv/dt + b v = F_hat``, ``v`` added to
  its tracking command (``guidance`` timing: the push deforms the motion, Bajcsy et al. 2017);
  ``robot_model`` (:data:`ROBOT_MODELS`: ``disk``, the default, or ``tidybot``, MuJoCo
  Menagerie's Stanford TidyBot at 1 m per cell, whose own drive defaults fill the fields not
  given).

**Guidance** (``timing = guidance``): the person takes the handle on the ``interval`` clock
and the base complies (the simulator's ``guidance``); the person is closed-loop by default
(``guide = closed``: pushes toward their route, harder the further the base is off it, lets go
when it heads the right way, the simulator's ``guiding_human``) or holds one drawn heading
(``open``). Every ``GUIDANCE_PERIOD_S`` of a push under way the robot updates its belief with
the direction ``theta`` of the *deformation* (where the push took the plan over that period),
by the continuous likelihood ``P(theta | s, g, p) = sum_h P(h | s, g, p) VM(theta; mu_h,
kappa)`` (``kappa = DIRECTION_KAPPA``) to the power ``|D| / 0.1 m`` (a push that has moved
the plan 0.1 m is one observation, as a tap is; at most ``GUIDANCE_MAX_EVIDENCE`` per push).
A guided decision step lasts exactly :meth:`Physics.step_s` in every door: the drive ends
when the base settles or when a push ends (the base then stays where the push left it), and
the next decision, with the updated belief and the push's heading as its input, comes at the
step's end.
  The drive must deliver what the controller plans: ``a_max <= (force_limit_n - friction_n) /
  mass_kg`` and ``v_max`` within the velocity servos' range (``DRIVE_V_MAX``); other
  combinations are refused with one line.
"""

from __future__ import annotations

import json
import math
import numbers
from dataclasses import asdict, dataclass, field, fields, replace

from ..errors import ConfigError

SENSORS = ("ideal", "ft300s", "realistic")
TIMINGS = ("decision", "interval", "rate", "corrective", "guidance")
SHAPES = ("half_sine", "bell")
BASES = ("holonomic", "diffdrive")


@dataclass(frozen=True)
class RobotModel:
    """A body a physical episode can run (the drive's ``robot_model``): the metres per grid
    unit its scenes are built at and the drive settings that differ from :class:`Drive`'s
    defaults (each with its source in ``docs/physics.md``).

    The scale is the body's: a map's moves are made for a footprint of 0.3 cells (the maps'
    default), so a body of plan radius ``footprint_m`` needs at least ``footprint_m / 0.3`` m
    per cell. The simulator's parts of the body (the scene it stands in per task, the arm its
    ``carry`` drives) are in the simulator's robot table (``ROBOTS``), whose record of the same
    name holds this one as its ``model`` (this layer names no simulator module)."""

    cell_size_m: float
    #: the plan radius (m) from the base's centre: what the scale is chosen for
    footprint_m: float
    drive: dict = field(default_factory=dict)
    #: the drives (:data:`BASES`) the body has
    bases: tuple[str, ...] = BASES


#: the bodies (the flat field ``robot_model``; ``disk`` is the original 12 kg cylinder whose
#: drive the physical defaults make a Clearpath Ridgeback; ``tidybot`` the Stanford TidyBot of
#: MuJoCo Menagerie, 0.284 m from its centre to its bumper's corner, so 1 m per cell): its
#: mass is Menagerie's (the base's 60 kg, the Gen3 arm, the gripper and the push handle:
#: :func:`pathpref.sim.tidybot_base.navigation_mass_kg`), its limits those TidyBot++'s simulated
#: base controller plans with (0.5 m/s and 0.5 m/s^2, ``mujoco_env.py``'s Ruckig limits)
ROBOT_MODELS: dict[str, RobotModel] = {
    "disk": RobotModel(cell_size_m=0.5, footprint_m=0.15),
    "tidybot": RobotModel(cell_size_m=1.0, footprint_m=0.284,
                          drive={"mass_kg": 69.29, "v_max": 0.5, "a_max": 0.5},
                          bases=("holonomic",)),
}


def check_body_drive(robot_model: str, base: str) -> None:
    """The one rule of which drive a body has (:attr:`RobotModel.bases`): a ConfigError
    naming the fix otherwise (the TidyBot's base is holonomic). Checked by :class:`Physics`,
    so every command refuses the pair before any work, and by the scene that builds the
    body."""
    model = ROBOT_MODELS.get(robot_model)
    if model is not None and base not in model.bases:
        raise ConfigError(f"--robot-model {robot_model} has a {' or '.join(model.bases)} "
                          f"base, not --base {base}: use --base {model.bases[0]} (or another "
                          "--robot-model)")
#: the simulated person under ``guidance`` timing: ``closed``, who pushes toward their route
#: and lets go when the robot heads the right way (the simulator's ``guiding_human``), or
#: ``open``, who holds one drawn heading for the whole push
GUIDES = ("closed", "open")

#: allowed range of each number: name -> (lowest, highest); the CLI flag is ``--`` + the name
#: with dashes
RANGES: dict[str, tuple[float, float]] = {
    "sensor_noise_n": (0.0, 50.0), "sensor_bias_n": (0.0, 100.0),
    "sensor_drift_n": (0.0, 10.0),
    "on_n": (0.5, 200.0), "on_s": (0.002, 1.0), "off_n": (0.1, 200.0), "off_s": (0.002, 1.0),
    "interval_s": (0.0, 600.0), "jitter": (0.0, 0.95),
    "reaction_s": (0.05, 5.0), "p_correct": (0.0, 1.0), "p_needless": (0.0, 1.0),
    "peak_n": (1.0, 300.0), "peak_spread": (1.0, 5.0), "peak_min_n": (0.5, 300.0),
    "peak_max_n": (1.0, 300.0),
    "duration_s": (0.05, 10.0), "duration_spread": (1.0, 5.0), "duration_max_s": (0.1, 10.0),
    "noise_deg": (0.0, 90.0), "gamma_h": (0.01, 100.0), "strength_confidence": (0.0, 3.0),
    "v_max": (0.05, 1.5), "a_max": (0.1, 10.0), "force_limit_n": (1.0, 2000.0),
    "admittance_b": (5.0, 2000.0), "mass_kg": (20.0, 1000.0), "friction_n": (0.0, 500.0),
    "hold_s": (0.5, 10.0), "admittance_m": (1.0, 500.0), "arm_stiffness": (100.0, 20000.0),
    "sensor_thermal_n": (0.0, 50.0),
}
#: the overrides that may be left at "the preset's" (stored as -1)
PRESET_DEFAULT = ("sensor_noise_n", "sensor_bias_n", "sensor_drift_n")
CHOICES: dict[str, tuple[str, ...]] = {"sensor": SENSORS, "timing": TIMINGS, "shape": SHAPES,
                                       "base": BASES, "guide": GUIDES,
                                       "robot_model": tuple(ROBOT_MODELS)}


#: the error of a physics value nested too deeply to read (its fields are flat)
TOO_DEEP = ("physics nests lists/objects too deeply to read; it is one flat object of the "
            "physical parameters, e.g. {\"sensor\": \"ideal\"}")


def flag(name: str) -> str:
    """The command-line flag of a field (``sensor_noise_n`` -> ``--sensor-noise-n``)."""
    return "--" + name.replace("_", "-")


#: how long after a push ends the detector may still release its cue (s)
RELEASE_WINDOW_S = 0.4
#: what a move is given beyond the drive's profile to settle on its target (s; the
#: differential drive's turn included)
SETTLE_S = 0.5
#: the velocity servos' command range (m/s, ``ctrlrange`` of the physical base's drive)
DRIVE_V_MAX = 1.5
#: fields added after rows were stored: left out of the canonical JSON at their default, so
#: the keys of stored episodes are unchanged
QUIET_DEFAULTS = {"mass_kg": 135.0, "friction_n": 0.0, "hold_s": 2.0, "admittance_m": 20.0,
                  "arm_stiffness": 1000.0, "sensor_thermal_n": 0.0, "guide": "closed",
                  "robot_model": "disk"}
#: quiet fields written whatever their value under a timing (a guided episode names its
#: person, so rows of the earlier open-loop person never share a key with it)
NAMED_UNDER = {"guide": "guidance"}


def _canonical(flat: dict) -> str:
    """Canonical JSON of flat fields: sorted keys, the fields of ``QUIET_DEFAULTS`` only when
    not at their default (or under their :data:`NAMED_UNDER` timing); every field for a body
    other than the disk (its drive defaults are its own, so none is left implicit)."""
    timing = flat.get("timing")
    every = flat.get("robot_model", QUIET_DEFAULTS["robot_model"]) != QUIET_DEFAULTS["robot_model"]
    d = {k: v for k, v in flat.items() if every or k not in QUIET_DEFAULTS or
         v != QUIET_DEFAULTS[k] or NAMED_UNDER.get(k) == timing}
    return json.dumps(d, sort_keys=True, separators=(",", ":"))
#: the robot's model of how far a push's direction strays from the heading the human chose:
#: von Mises concentration ``1 / sigma^2`` for the human model's default 10 degrees
#: (:meth:`~pathpref.inference.belief.Belief.update_direction`)
DIRECTION_KAPPA = 1.0 / math.radians(10.0) ** 2
#: the most evidence one sustained push gives (in observations), however long it lasts
GUIDANCE_MAX_EVIDENCE = 2.0
#: how often a sustained push's direction updates the belief while it lasts (s)
GUIDANCE_PERIOD_S = 0.1

#: metres per grid unit of the disk's scenes (the MuJoCo bodies, the tasks, the studies, the
#: rerun recordings); another body's is its :data:`ROBOT_MODELS` entry's
CELL_SIZE_M = ROBOT_MODELS["disk"].cell_size_m
#: the push detector's thresholds, one home for every detector and for :class:`Physics`: a cue
#: begins when the force stays above ``on_n`` (N) for ``on_s`` (s) and ends when it stays below
#: ``off_n`` for ``off_s``
DETECTOR = {"on_n": 8.0, "on_s": 0.025, "off_n": 4.0, "off_s": 0.05}


def _check(obj) -> None:
    """One line naming the field and its allowed range or values for any bad setting of a
    group (its flat names)."""
    for f in fields(obj):
        v = getattr(obj, f.name)
        name = FLAT_OF.get(f.name, f.name)
        if name in CHOICES:
            if v not in CHOICES[name]:
                raise ConfigError(f"physics {name} ({flag(name)}) must be one of "
                                  f"{', '.join(CHOICES[name])}, got {v!r}")
        elif name == "use_strength":
            if not isinstance(v, bool):
                raise ConfigError(f"physics use_strength (--use-strength) must be true or "
                                  f"false, got {v!r}")
        else:
            lo, hi = RANGES[name]
            try:  # an integer of hundreds of digits does not convert to a float
                ok = isinstance(v, numbers.Real) and not isinstance(v, bool) and \
                    math.isfinite(v) and (lo <= v <= hi or
                                          (name in PRESET_DEFAULT and v == -1.0))
            except OverflowError:
                ok = False
            if not ok:
                extra = " (or -1: the preset's)" if name in PRESET_DEFAULT else ""
                shown = repr(v) if len(repr(v)) <= 40 else repr(v)[:37] + "..."
                raise ConfigError(f"physics {name} ({flag(name)}) must be a number in "
                                  f"{lo:g}..{hi:g}{extra}, got {shown}")


@dataclass(frozen=True)
class Sensing:
    """The robot's sensing chain: the force sensor (preset and fault overrides, -1: the
    preset's), the push detector's hysteresis thresholds (:data:`DETECTOR`) and whether the
    belief weighs a cue by its strength."""

    sensor: str = "realistic"
    sensor_noise_n: float = -1.0
    sensor_bias_n: float = -1.0
    sensor_drift_n: float = -1.0
    on_n: float = DETECTOR["on_n"]
    on_s: float = DETECTOR["on_s"]
    off_n: float = DETECTOR["off_n"]
    off_s: float = DETECTOR["off_s"]
    use_strength: bool = False
    #: the sensor's thermal warm-up offset after zeroing (N; :class:`~pathpref.sim.sensing.
    #: SensorModel` ``thermal_n``; 0: none)
    sensor_thermal_n: float = QUIET_DEFAULTS["sensor_thermal_n"]

    def __post_init__(self) -> None:
        _check(self)
        if self.off_n >= self.on_n:
            raise ConfigError(f"physics off_n must be below on_n ({self.on_n:g} N), got "
                              f"{self.off_n:g}")

    @property
    def detector(self) -> dict[str, float]:
        """The detector's thresholds (the keyword arguments of the cue detectors)."""
        return {"on_n": self.on_n, "on_s": self.on_s, "off_n": self.off_n, "off_s": self.off_s}


@dataclass(frozen=True)
class HumanModel:
    """The simulated human: when it pushes (``timing`` and its parameters), how (strength,
    duration and shape distributions, angle noise) and how rationally it chooses the heading
    (``gamma_h``, SPEC 4; also the grid episodes' human). Module docstring for each field."""

    timing: str = "decision"
    interval_s: float = 0.0
    jitter: float = 0.5
    reaction_s: float = 0.4
    p_correct: float = 0.8
    p_needless: float = 0.1
    peak_n: float = 25.0
    peak_spread: float = 1.5
    peak_min_n: float = 10.0
    peak_max_n: float = 60.0
    duration_s: float = 0.3
    duration_spread: float = 1.4
    duration_max_s: float = 0.6
    shape: str = "half_sine"
    noise_deg: float = 10.0
    gamma_h: float = 1.5
    strength_confidence: float = 0.0
    #: ``guidance`` timing: the median of how long the human holds the handle (s)
    hold_s: float = QUIET_DEFAULTS["hold_s"]
    #: ``guidance`` timing: the person (:data:`GUIDES`)
    guide: str = QUIET_DEFAULTS["guide"]

    def __post_init__(self) -> None:
        _check(self)
        if self.peak_min_n > self.peak_max_n:
            raise ConfigError(f"physics peak_min_n must be at most peak_max_n "
                              f"({self.peak_max_n:g} N), got {self.peak_min_n:g}")

    def to_json(self) -> str:
        """Canonical JSON (sorted keys; every field, but those of :data:`NAMED_UNDER` only
        under their timing or when not at their default)."""
        d = asdict(self)
        for k, timing in NAMED_UNDER.items():
            if d[k] == QUIET_DEFAULTS[k] and d["timing"] != timing:
                del d[k]
        return json.dumps(d, sort_keys=True, separators=(",", ":"))

    def stored(self) -> str:
        """A grid episode's ``physics``: ``""`` for the default human (grid keys unchanged),
        else :meth:`to_json`."""
        return "" if self == HumanModel() else self.to_json()


@dataclass(frozen=True)
class Drive:
    """The base's drive: ``kind`` (flat name ``base``: ``holonomic`` or ``diffdrive``), the
    limits its controller plans with, its actuators' force limit, how it yields, its mass and
    the floor's friction (module docstring)."""

    kind: str = "holonomic"
    v_max: float = 1.0
    a_max: float = 0.8
    force_limit_n: float = 120.0
    admittance_b: float = 80.0
    mass_kg: float = QUIET_DEFAULTS["mass_kg"]
    friction_n: float = QUIET_DEFAULTS["friction_n"]
    #: the admittance's virtual mass while guided (kg; ``guidance`` timing)
    admittance_m: float = QUIET_DEFAULTS["admittance_m"]
    #: the carry arm's end-effector (tray) stiffness (N/m: 30 N deflects it about 25 mm)
    arm_stiffness: float = QUIET_DEFAULTS["arm_stiffness"]
    #: the body (:data:`ROBOT_MODELS`; built from flat fields, its drive defaults apply)
    robot_model: str = QUIET_DEFAULTS["robot_model"]

    def __post_init__(self) -> None:
        _check(self)
        if self.friction_n >= self.force_limit_n:
            raise ConfigError(f"physics friction_n must be below force_limit_n "
                              f"({self.force_limit_n:g} N): the drive could not move the base, "
                              f"got {self.friction_n:g}")
        reach = (self.force_limit_n - self.friction_n) / self.mass_kg
        if self.a_max > reach:
            raise ConfigError(f"physics a_max ({flag('a_max')}) must be at most {reach:.3g} "
                              f"m/s^2, what {self.force_limit_n:g} N less {self.friction_n:g} N "
                              f"of friction gives {self.mass_kg:g} kg; got {self.a_max:g} "
                              f"(lower --a-max or raise --force-limit-n)")


#: the group of every flat field name: name -> (group attribute of :class:`Physics`, its
#: attribute in the group)
GROUPS = {"sensing": Sensing, "human": HumanModel, "drive": Drive}
FLAT_OF = {"kind": "base"}  # a group attribute whose flat name differs
FIELDS: dict[str, tuple[str, str]] = {
    FLAT_OF.get(f.name, f.name): (group, f.name)
    for group, cls in GROUPS.items() for f in fields(cls)}


@dataclass(frozen=True, init=False)
class Physics:
    """The physical parameters of a MuJoCo episode (module docstring): the sensing chain, the
    simulated human and the base's drive. Defaults: realistic sensing, pushes at input steps
    drawn from the literature's distributions, the holonomic base at the limits of a Clearpath
    Ridgeback (``docs/physics.md``). Built from the groups, from flat field names
    (``Physics(sensor="ideal", base="diffdrive")``, :meth:`of`) or both (the flat names then
    set fields of the groups given)."""

    sensing: Sensing = field(default_factory=Sensing)
    human: HumanModel = field(default_factory=HumanModel)
    drive: Drive = field(default_factory=Drive)

    def __init__(self, sensing: Sensing | None = None, human: HumanModel | None = None,
                 drive: Drive | None = None, **flat) -> None:
        given = {"sensing": sensing, "human": human, "drive": drive}
        parts: dict[str, dict] = {name: {} for name in GROUPS}
        for k, v in flat.items():
            if k not in FIELDS:
                raise ConfigError(f"physics has unknown field '{k}'; known: "
                                  f"{', '.join(sorted(FIELDS))}")
            group, attr = FIELDS[k]
            parts[group][attr] = v
        robot = parts["drive"].get("robot_model")
        if given["drive"] is None and robot in ROBOT_MODELS:  # the body's own drive defaults
            parts["drive"] = {**ROBOT_MODELS[robot].drive, **parts["drive"]}
        for name, cls in GROUPS.items():
            value = given[name]
            if value is None:
                value = cls(**parts[name])
            elif parts[name]:
                value = replace(value, **parts[name])
            object.__setattr__(self, name, value)
        self.__post_init__()

    def __post_init__(self) -> None:
        for name, cls in GROUPS.items():
            if not isinstance(getattr(self, name), cls):
                raise ConfigError(f"physics {name} must be a {cls.__name__}, got "
                                  f"{type(getattr(self, name)).__name__}")
        check_body_drive(self.drive.robot_model, self.drive.kind)
        if self.human.timing == "guidance" and self.drive.kind != "holonomic":
            raise ConfigError("physics timing guidance needs base holonomic (the guided base "
                              "yields in every direction); use --base holonomic")
        if self.drive.force_limit_n <= self.sensing.on_n:
            raise ConfigError(f"physics force_limit_n must be above the detector's on_n "
                              f"({self.sensing.on_n:g} N): the base could not feel a push it "
                              f"cannot resist, got {self.drive.force_limit_n:g}")

    @classmethod
    def of(cls, **flat) -> Physics:
        """The parameters with the flat fields ``flat`` set (``Physics.of(sensor="ideal",
        base="diffdrive")``); an unknown name is a ConfigError listing the known ones."""
        return cls(**flat)

    def flat(self) -> dict:
        """Every field by its flat name (the JSON keys and flags)."""
        return {k: getattr(getattr(self, g), a) for k, (g, a) in FIELDS.items()}

    def to_json(self) -> str:
        """Canonical flat JSON (sorted keys; the fields of ``QUIET_DEFAULTS`` only when not at
        their default): the spec's ``physics`` string and key part."""
        return _canonical(self.flat())

    @staticmethod
    def parse(text: str) -> dict:
        """The flat fields of a ``physics`` JSON string (no defaults filled in); a ConfigError
        names what is wrong."""
        try:
            raw = json.loads(text)
        except (TypeError, ValueError) as e:
            raise ConfigError(f"physics must be JSON of the physical parameters: {e}") from None
        except RecursionError:
            raise ConfigError(TOO_DEEP) from None
        if not isinstance(raw, dict):
            raise ConfigError("physics must be a JSON object of the physical parameters")
        for k, v in raw.items():  # the fields are flat: a list or object is refused here
            if isinstance(v, dict | list):
                raise ConfigError(f"physics {k} must be a number, a string or true/false, "
                                  f"got a JSON {'object' if isinstance(v, dict) else 'list'}")
        return raw

    @classmethod
    def from_json(cls, text: str) -> Physics | None:
        """The parameters of a spec's ``physics`` string; None for ``""`` (legacy). Unknown
        fields or bad values are a ConfigError naming the field."""
        if text == "":
            return None
        return cls.of(**cls.parse(text))

    @classmethod
    def coerce(cls, value) -> str:
        """The spec string of a Python API argument: a :class:`Physics`, a dict of its flat
        fields, its JSON; None: the defaults (``Physics()``, as every door's); ``"legacy"``
        (or ``""``): the legacy physics, only by name."""
        if value is None:
            return cls().to_json()
        if value in ("", "legacy"):
            return ""
        if isinstance(value, Physics):
            return value.to_json()
        if isinstance(value, dict):
            try:
                text = json.dumps(value)
            except RecursionError:
                raise ConfigError(TOO_DEEP) from None
            except (TypeError, ValueError) as e:
                raise ConfigError(f"physics must be a dict of the physical parameters' "
                                  f"values: {e}") from None
            return cls.from_json(text).to_json()
        if isinstance(value, str):
            return cls.from_json(value).to_json()
        raise ConfigError(f"physics must be a Physics, a dict of its fields, JSON or None, "
                          f"got {type(value).__name__}")

    @property
    def cell_size_m(self) -> float:
        """The metres per grid unit of this body's scenes (:data:`ROBOT_MODELS`)."""
        return ROBOT_MODELS[self.drive.robot_model].cell_size_m

    def move_s(self, cell_size: float | None = None) -> float:
        """The drive's rest-to-rest time across one cell diagonally, ``d = sqrt(2) cell``
        (``cell`` default: the body's, :attr:`cell_size_m`), at its trapezoid profile:
        ``d / v + v / a`` when ``d >= v^2 / a`` (it reaches ``v_max``), else ``2 sqrt(d /
        a)``."""
        cell_size = self.cell_size_m if cell_size is None else cell_size
        d, v, a = math.sqrt(2.0) * cell_size, self.drive.v_max, self.drive.a_max
        return d / v + v / a if d >= v * v / a else 2.0 * math.sqrt(d / a)

    def push_window_s(self) -> float:
        """The longest a push phase lasts: the longest push and its release window."""
        return self.human.duration_max_s + RELEASE_WINDOW_S

    def step_s(self, cell_size: float | None = None) -> float:
        """**The one rule for how long a decision step lasts** (simulated seconds): a move
        (:meth:`move_s` plus ``SETTLE_S``) after the longest push phase
        (:meth:`push_window_s`), rounded up to 0.1 s. Every door uses it: the dm_control
        tasks' step (``control_timestep``), the simulated human's pushes (``interval_s = 0``
        means ``delta_t`` steps of it), the base's move time limit (:meth:`move_limit_s`).
        A ``--sim mujoco`` decision ends when the base has settled, so it lasts at most this
        (default physics: 3.4 s; a diagonal move 1.9 s, a straight one 1.6 s)."""
        raw = self.move_s(cell_size) + SETTLE_S + self.push_window_s()
        return math.ceil(10.0 * raw - 1e-9) / 10.0

    def move_limit_s(self, cell_size: float | None = None) -> float:
        """The longest a move may take: the step less its push phase (:meth:`step_s`)."""
        return self.step_s(cell_size) - self.push_window_s()


def grid_human(text: str) -> HumanModel:
    """The human of a grid episode's ``physics`` (``""``: the default one); sensing or drive
    fields other than their defaults are refused (a grid body has neither) with the fix. Its
    canonical ``physics`` is :meth:`HumanModel.stored`."""
    if text == "":
        return HumanModel()
    raw = Physics.parse(text)
    physical = sorted(k for k in raw if k in FIELDS and FIELDS[k][0] != "human")
    default = Physics().flat()
    moved = [k for k in physical if raw[k] != default[k]]
    if moved:
        raise ConfigError(f"physics {moved[0]} ({flag(moved[0])}) needs a physical body: add "
                          f"--sim mujoco (a grid episode takes only the human's settings)")
    return Physics.of(**{k: v for k, v in raw.items() if k not in physical}).human
