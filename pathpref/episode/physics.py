"""Every physical parameter of a MuJoCo episode in one value: :class:`Physics`.

An :class:`~.spec.EpisodeSpec` stores it as canonical JSON in ``physics``; the empty string is
the *legacy* physics every row written before this field existed ran with (ideal sensor, one
30 N / 0.3 s half-sine push at each input step while the base stands, the original base and
``carry`` controllers), so old rows replay bit for bit. This module only describes and checks
the parameters (the episode layer never imports the simulator); the simulator package acts on
them. ``docs/physics.md`` gives the sources of the defaults.

Groups (field prefixes):

* sensing: ``sensor`` preset (``ideal``, ``ft300s``, ``realistic``) and optional fault
  overrides ``sensor_noise_n``, ``sensor_bias_n``, ``sensor_drift_n`` (negative: the preset's);
* detection: ``on_n``, ``on_s``, ``off_n``, ``off_s`` (hysteresis thresholds);
* the human: ``timing`` (``decision``: at input steps, at rest, as in the paper; ``interval``:
  every ``interval_s`` with uniform jitter ``+-jitter`` of it, at any moment of motion;
  ``rate``: a Poisson process of mean interval ``interval_s``; ``corrective``: after a
  reaction time, when the robot starts a move the human finds wrong, with probability
  ``p_correct``, or a right one, with ``p_needless``); ``interval_s`` 0 means ``delta_t``
  seconds (one nominal second per decision step); push strength log-normal with median
  ``peak_n`` and geometric spread ``peak_spread``, clipped to ``[peak_min_n, peak_max_n]``;
  duration log-normal with median ``duration_s`` and spread ``duration_spread``, clipped to
  ``[0.1, duration_max_s]``; ``shape`` ``half_sine`` or ``bell``; angle noise ``noise_deg``;
  the human's rationality ``gamma_h`` (SPEC 4); ``strength_confidence`` ``c``: the human
  pushes harder when surer, median strength ``peak_n exp(c (q - 1/2))`` with ``q`` the drawn
  heading's probability over the most likely one's (0: strength independent of the heading);
  whether the robot weighs a cue by its strength (``use_strength``: the likelihood to the power
  ``clip(F / peak_n, 0.5, 2)``);
* the base: ``base`` (``holonomic`` or ``diffdrive``), ``v_max`` (m/s) and ``a_max`` (m/s^2)
  the controller plans with (defaults: the Clearpath Ridgeback's velocity limit, 1.0 m/s, and
  0.8 m/s^2, inside its 1.0 m/s^2 acceleration limit because 120 N moves its 135 kg at
  0.89 m/s^2 at most), ``force_limit_n`` (actuator force limit per axis, N),
  ``admittance_b`` (N s/m, how the base yields while a cue is under way).
"""

from __future__ import annotations

import json
import math
import numbers
from dataclasses import asdict, dataclass, fields

from ..errors import ConfigError

SENSORS = ("ideal", "ft300s", "realistic")
TIMINGS = ("decision", "interval", "rate", "corrective")
SHAPES = ("half_sine", "bell")
BASES = ("holonomic", "diffdrive")

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
    "v_max": (0.05, 3.0), "a_max": (0.1, 10.0), "force_limit_n": (1.0, 2000.0),
    "admittance_b": (5.0, 2000.0),
}
#: the overrides that may be left at "the preset's" (stored as -1)
PRESET_DEFAULT = ("sensor_noise_n", "sensor_bias_n", "sensor_drift_n")
CHOICES: dict[str, tuple[str, ...]] = {"sensor": SENSORS, "timing": TIMINGS, "shape": SHAPES,
                                       "base": BASES}


#: the error of a physics value nested too deeply to read (its fields are flat)
TOO_DEEP = ("physics nests lists/objects too deeply to read; it is one flat object of the "
            "physical parameters, e.g. {\"sensor\": \"ideal\"}")


def flag(name: str) -> str:
    """The command-line flag of a field (``sensor_noise_n`` -> ``--sensor-noise-n``)."""
    return "--" + name.replace("_", "-")


#: metres per grid unit of every physical scene (the MuJoCo bodies, the tasks, the studies, the
#: rerun recordings): one home for the scale
CELL_SIZE_M = 0.5
#: the push detector's thresholds, one home for every detector and for :class:`Physics`: a cue
#: begins when the force stays above ``on_n`` (N) for ``on_s`` (s) and ends when it stays below
#: ``off_n`` for ``off_s``
DETECTOR = {"on_n": 8.0, "on_s": 0.025, "off_n": 4.0, "off_s": 0.05}


@dataclass(frozen=True)
class Physics:
    """The physical parameters of a MuJoCo episode (module docstring). Defaults: realistic
    sensing, pushes at input steps drawn from the literature's distributions, the holonomic
    base at the limits of a Clearpath Ridgeback (``docs/physics.md``)."""

    sensor: str = "realistic"
    sensor_noise_n: float = -1.0
    sensor_bias_n: float = -1.0
    sensor_drift_n: float = -1.0
    on_n: float = DETECTOR["on_n"]
    on_s: float = DETECTOR["on_s"]
    off_n: float = DETECTOR["off_n"]
    off_s: float = DETECTOR["off_s"]
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
    use_strength: bool = False
    strength_confidence: float = 0.0
    base: str = "holonomic"
    v_max: float = 1.0
    a_max: float = 0.8
    force_limit_n: float = 120.0
    admittance_b: float = 80.0

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        """One line naming the field and its allowed range or values for any bad setting."""
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name in CHOICES:
                if v not in CHOICES[f.name]:
                    raise ConfigError(f"physics {f.name} ({flag(f.name)}) must be one of "
                                      f"{', '.join(CHOICES[f.name])}, got {v!r}")
            elif f.name == "use_strength":
                if not isinstance(v, bool):
                    raise ConfigError(f"physics use_strength (--use-strength) must be true or "
                                      f"false, got {v!r}")
            else:
                lo, hi = RANGES[f.name]
                try:  # an integer of hundreds of digits does not convert to a float
                    ok = isinstance(v, numbers.Real) and not isinstance(v, bool) and \
                        math.isfinite(v) and (lo <= v <= hi or
                                              (f.name in PRESET_DEFAULT and v == -1.0))
                except OverflowError:
                    ok = False
                if not ok:
                    extra = " (or -1: the preset's)" if f.name in PRESET_DEFAULT else ""
                    shown = repr(v) if len(repr(v)) <= 40 else repr(v)[:37] + "..."
                    raise ConfigError(f"physics {f.name} ({flag(f.name)}) must be a number in "
                                      f"{lo:g}..{hi:g}"
                                      f"{extra}, got {shown}")
        if self.off_n >= self.on_n:
            raise ConfigError(f"physics off_n must be below on_n ({self.on_n:g} N), got "
                              f"{self.off_n:g}")
        if self.peak_min_n > self.peak_max_n:
            raise ConfigError(f"physics peak_min_n must be at most peak_max_n "
                              f"({self.peak_max_n:g} N), got {self.peak_min_n:g}")
        if self.force_limit_n <= self.on_n:
            raise ConfigError(f"physics force_limit_n must be above the detector's on_n "
                              f"({self.on_n:g} N): the base could not feel a push it cannot "
                              f"resist, got {self.force_limit_n:g}")

    def to_json(self) -> str:
        """Canonical JSON (sorted keys): the spec's ``physics`` string and key part."""
        return json.dumps(asdict(self), sort_keys=True, separators=(",", ":"))

    @classmethod
    def from_json(cls, text: str) -> Physics | None:
        """The parameters of a spec's ``physics`` string; None for ``""`` (legacy). Unknown
        fields or bad values are a ConfigError naming the field."""
        if text == "":
            return None
        try:
            raw = json.loads(text)
        except (TypeError, ValueError) as e:
            raise ConfigError(f"physics must be JSON of the physical parameters: {e}") from None
        except RecursionError:
            raise ConfigError(TOO_DEEP) from None
        if not isinstance(raw, dict):
            raise ConfigError("physics must be a JSON object of the physical parameters")
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(raw) - known)
        if unknown:
            raise ConfigError(f"physics has unknown field '{unknown[0]}'; known: "
                              f"{', '.join(sorted(known))}")
        for k, v in raw.items():  # the fields are flat: a list or object is refused here
            if isinstance(v, dict | list):
                raise ConfigError(f"physics {k} must be a number, a string or true/false, "
                                  f"got a JSON {'object' if isinstance(v, dict) else 'list'}")
        return cls(**raw)

    @classmethod
    def coerce(cls, value) -> str:
        """The spec string of a Python API argument: a :class:`Physics`, a dict of its
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

    def check_episode(self, t_max: int) -> None:
        """Settings that contradict the episode: a push that cannot fit (the longest push
        against the episode's nominal length, one second per decision step)."""
        longest = self.duration_max_s
        if longest >= t_max:
            raise ConfigError(f"physics duration_max_s must be below the episode's length "
                              f"({t_max} decision steps of about 1 s), got {longest:g}")
