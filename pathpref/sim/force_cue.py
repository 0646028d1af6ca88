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

import math
from dataclasses import dataclass

import numba as nb
import numpy as np

from ..errors import ConfigError
from ..geometry.grid import ACTION_ANGLES

#: the push shapes (module docstring), in :func:`push_magnitude`'s numbering
SHAPES = ("half_sine", "bell", "plateau")


@nb.njit(cache=True)
def push_magnitude(shape, peak, duration, t):
    """The force magnitude (N) ``t`` s after a push of ``shape`` (0 half-sine, 1 bell, 2
    plateau; module docstring) began, of ``peak`` N over ``duration`` s: 0 outside
    ``[0, duration]``. The one arithmetic of the Python step and the compiled move (the C
    library's ``sin`` and ``cos``, as NumPy's scalars)."""
    if t < 0 or t > duration:
        return 0.0
    if shape == 1:
        s = t / duration
        return 16.0 * peak * s * s * (1.0 - s) * (1.0 - s)
    if shape == 2:
        half = 0.5 * duration
        r = half if half < 0.2 else 0.2
        edge = duration - t if duration - t < t else t
        return peak * (0.5 - 0.5 * math.cos(math.pi * edge / r)) if edge < r else peak
    return peak * math.sin(math.pi * t / duration)


#: the force above which a hand counts as pushing (N; the contact time of the effort measures)
CONTACT_N = 0.1


@nb.njit(cache=True)
def push_effort(shape, peak, duration, until, dt):
    """``(sum |F| dt, max |F|, dt * #{|F| >= CONTACT_N})`` over ``t = k dt`` in ``[0,
    until]`` of a push of :func:`push_magnitude` (the person's effort measures: impulse N s,
    peak N, contact s; the half-sine's impulse tends to ``2 peak duration / pi``)."""
    impulse, top, contact = 0.0, 0.0, 0.0
    n = int(math.floor(until / dt + 1e-9)) if until >= 0 else -1
    for k in range(n + 1):
        f = push_magnitude(shape, peak, duration, k * dt)
        impulse += f * dt
        if f > top:
            top = f
        if f >= CONTACT_N:
            contact += dt
    return impulse, top, contact


@nb.njit(cache=True)
def push_force(shape, peak, duration, angle, t, out):
    """The world-frame force (N) ``t`` s into a push along ``angle`` (radians) into ``out``
    (3): ``|F| (cos angle, sin angle, 0)``, ``|F|`` of :func:`push_magnitude`."""
    f = push_magnitude(shape, peak, duration, t)
    out[0], out[1], out[2] = f * math.cos(angle), f * math.sin(angle), 0.0


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
        if self.shape not in SHAPES:
            raise ConfigError(f"push shape must be half_sine, bell or plateau, got "
                              f"{self.shape!r}")

    @property
    def shape_code(self) -> int:
        """The shape's index in :data:`SHAPES` (:func:`push_magnitude`'s ``shape``)."""
        return SHAPES.index(self.shape)

    def magnitude(self, t: float) -> float:
        """Force magnitude at time ``t`` since the push began (:func:`push_magnitude`)."""
        return push_magnitude(self.shape_code, self.peak_n, self.duration_s, float(t))


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
        """World-frame force (3,) at simulation time ``t`` (:func:`push_force`)."""
        out, p = np.zeros(3), self.profile
        push_force(p.shape_code, p.peak_n, p.duration_s, self.angle, float(t) - self.t0, out)
        return out

    def record(self) -> np.ndarray:
        """The push as :func:`push_force`'s arguments: ``(t0, duration, peak, angle,
        shape)`` (the compiled move's push record)."""
        p = self.profile
        return np.array([self.t0, p.duration_s, p.peak_n, self.angle, p.shape_code])

    def active(self, t: float) -> bool:
        """Whether the push acts at simulation time ``t``."""
        return self.t0 <= t <= self.t0 + self.profile.duration_s

    def effort(self, dt: float, t_end: float) -> tuple[float, float, float]:
        """What the push cost the person up to ``t_end``, on the physics steps ``t0 + k dt``
        it acts at: the impulse ``sum |F| dt`` (N s), the peak ``|F|`` (N) and the contact
        time (s, the steps with ``|F| >= CONTACT_N`` times ``dt``) (:func:`push_effort`)."""
        p = self.profile
        return push_effort(p.shape_code, p.peak_n, p.duration_s,
                           min(p.duration_s, t_end - self.t0), dt)

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
