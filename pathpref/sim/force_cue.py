"""The simulated human's push (after Bajcsy et al., CoRL 2017), applied through ``xfrc_applied``.

When an input is due, the human draws a heading from the Boltzmann model (SPEC 4), adds angle
noise ``N(0, sigma)``, and pushes the handle horizontally with a half-sine force
``F(t) = F_peak sin(pi t / T)`` for ``0 <= t <= T`` (defaults: 30 N, 0.3 s, sigma 10 degrees),
or a bell ``F(t) = 16 F_peak s^2 (1 - s)^2``, ``s = t / T`` (the speed profile of a
minimum-jerk reach, Flash and Hogan 1985: smooth onset and release, peak at the middle), or a
``plateau``: a sustained push (guidance), raised-cosine ramps of ``r = min(0.2 s, T / 2)`` up
and down around a constant ``F_peak``.
``xfrc_applied`` is not cleared by MuJoCo, so :meth:`HumanPush.apply` writes it every substep.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..geometry.grid import ACTION_ANGLES


@dataclass(frozen=True)
class PushProfile:
    """Shape of a push: peak force (N), duration (s), heading noise (degrees, 1 sigma) and
    ``shape`` (``half_sine``, ``bell`` or ``plateau``)."""

    peak_n: float = 30.0
    duration_s: float = 0.3
    noise_deg: float = 10.0
    shape: str = "half_sine"

    def __post_init__(self):
        for name in ("peak_n", "duration_s", "noise_deg"):
            v = getattr(self, name)
            if not np.isfinite(v) or v < 0 or (name != "noise_deg" and v == 0):
                raise ConfigError(f"push {name} must be a positive finite number, got {v}")
        if self.shape not in ("half_sine", "bell", "plateau"):
            raise ConfigError(f"push shape must be half_sine, bell or plateau, got "
                              f"{self.shape!r}")

    def magnitude(self, t: float) -> float:
        """Force magnitude at time ``t`` since the push began (half-sine or bell)."""
        if t < 0 or t > self.duration_s:
            return 0.0
        if self.shape == "bell":
            s = t / self.duration_s
            return float(16.0 * self.peak_n * s * s * (1.0 - s) * (1.0 - s))
        if self.shape == "plateau":
            r = min(0.2, 0.5 * self.duration_s)
            edge = min(t, self.duration_s - t)
            return float(self.peak_n * (0.5 - 0.5 * np.cos(np.pi * edge / r)) if edge < r
                         else self.peak_n)
        return float(self.peak_n * np.sin(np.pi * t / self.duration_s))


@dataclass
class HumanPush:
    """One push along ``angle`` (radians, world frame) that starts at simulation time ``t0``."""

    angle: float
    t0: float
    profile: PushProfile
    intended_heading: int

    @classmethod
    def sample(cls, heading: int, t0: float, profile: PushProfile,
               rng: np.random.Generator) -> HumanPush:
        """A push toward ``heading`` with the profile's Gaussian angle noise, starting at ``t0``."""
        noise = np.deg2rad(profile.noise_deg) * rng.standard_normal()
        return cls(float(ACTION_ANGLES[heading] + noise), t0, profile, heading)

    def force(self, t: float) -> np.ndarray:
        """World-frame force (3,) at simulation time ``t``."""
        f = self.profile.magnitude(t - self.t0)
        return np.array([f * np.cos(self.angle), f * np.sin(self.angle), 0.0])

    def active(self, t: float) -> bool:
        """Whether the push acts at simulation time ``t``."""
        return self.t0 <= t <= self.t0 + self.profile.duration_s

    def apply(self, data, body_id: int) -> None:
        """Write this substep's force on ``body_id`` (:func:`apply_force`)."""
        apply_force(data, body_id, self.force(float(data.time)))


def apply_force(data, body_id: int, f: np.ndarray) -> None:
    """Write the force ``f`` (3,) on ``body_id`` (the rest of its wrench cleared); a
    ConfigError when it is not finite."""
    if not np.isfinite(f).all():
        raise ConfigError("push force is not finite; check the push parameters")
    data.xfrc_applied[body_id, :] = 0.0
    data.xfrc_applied[body_id, :3] = f
