"""The robot's continuous path, sampled while an episode runs (``--record-path HZ``).

A :class:`PathRecorder` is an ``on_substep`` hook of a base (:mod:`.mobile_base`): it only
reads the state after each physics step, so the episode runs exactly as without it (the same
steps, cues and results). The compiled steps (:mod:`.coasting`) run the steps between two
samples without it (:meth:`PathRecorder.quiet_steps`, :meth:`PathRecorder.skip`) and hand the
sampled step back to Python.

Samples: one at the reset (time 0, the base at the start cell's centre), then every ``every``
physics steps, ``every = max(1, floor(1 / (hz dt)))`` (``dt`` the physics step), so the
spacing is at most ``1 / hz`` seconds (2 ms steps: 100 Hz is every 5th step, exactly 100 Hz;
60 Hz every 8th, 62.5 Hz), and a last one when the path is taken at the episode's end (unless
a sample was just taken). Each is a :data:`~pathpref.episode.body.PATH_FIELDS` tuple: time
(``data.time``), the base's ``x, y`` and ``yaw`` joints, the end effector (the arm's tray;
None for the plain base) and the force applied to the pushed body at that step
(``xfrc_applied``, world x-y: the simulated human's push; 0 while nobody pushes).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from ..errors import ConfigError

if TYPE_CHECKING:  # (the base's compiled steps import this module)
    from .mobile_base import MobileBase


def sample_every(hz: float, dt: float) -> int:
    """Physics steps between two samples for at least ``hz`` samples per second with steps of
    ``dt`` seconds; ConfigError above the physics rate ``1 / dt``."""
    rate = 1.0 / dt
    if hz > rate * (1 + 1e-9):
        raise ConfigError(f"--record-path {hz:g}: at most the physics rate, {rate:g} Hz (a "
                          f"{1e3 * dt:g} ms step)")
    return max(1, math.floor(rate / hz + 1e-9))


class PathRecorder:
    """Samples ``base``'s path at least ``hz`` times per simulated second (module
    docstring); attach with :meth:`attach`, restart with :meth:`reset`, read with
    :meth:`take`."""

    def __init__(self, base: MobileBase, hz: float):
        self.base = base
        self.every = sample_every(hz, base.dt)
        self.rows: list[tuple] = []
        self._steps = 0

    def attach(self) -> None:
        """Sample after every physics step of the base from now on."""
        self.base.on_substep.append(self)

    def reset(self) -> None:
        """Forget the samples; the first one is the base as it stands now (reset)."""
        self.rows, self._steps = [], 0
        self._sample()

    def __call__(self, base: MobileBase, push) -> None:
        """After a physics step: a sample every :attr:`every` steps."""
        self._steps += 1
        if self._steps % self.every == 0:
            self._sample()

    def quiet_steps(self) -> int:
        """How many of the next physics steps take no sample (the compiled steps of
        :mod:`.coasting` run them without calling the hook, then :meth:`skip` them)."""
        return self.every - 1 - self._steps % self.every

    def skip(self, n: int) -> None:
        """``n`` physics steps passed without a call, none of them due a sample."""
        self._steps += n

    def _sample(self) -> None:
        b = self.base
        d = b.data
        ee = b.end_effector
        e = (None, None, None) if ee is None else tuple(float(v) for v in ee[:3])
        f = d.xfrc_applied[b.pushed_body]
        self.rows.append((float(d.time), float(d.qpos[b.xy[0]]), float(d.qpos[b.xy[1]]),
                          float(d.qpos[b.yaw]), *e, float(f[0]), float(f[1])))

    def take(self) -> list[tuple]:
        """The samples so far, with one of the state now when the last one is older."""
        if self.rows and self.rows[-1][0] < float(self.base.data.time):
            self._sample()
        return list(self.rows)
