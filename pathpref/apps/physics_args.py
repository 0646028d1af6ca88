"""Command-line options for every physical parameter of a MuJoCo episode.

Each field of :class:`~pathpref.episode.physics.Physics` is a flag named after it
(``sensor_noise_n`` -> ``--sensor-noise-n``; ``use_strength`` is ``--use-strength``).
``--physics legacy`` asks for the legacy physics of rows written before the field existed
(ideal sensor, the original base); otherwise a MuJoCo episode runs with ``Physics()`` and the
flags given. A flag with ``--sim grid`` or with ``--physics legacy`` is refused; values are
checked by :class:`Physics` (one line naming the field and its range).
"""

from __future__ import annotations

import argparse
from dataclasses import fields

from ..episode.physics import CHOICES, RANGES, Physics, flag
from ..errors import ConfigError


def physics_options(sp: argparse.ArgumentParser) -> None:
    """Add ``--physics`` and one flag per :class:`Physics` field to ``sp``."""
    g = sp.add_argument_group("physical parameters (MuJoCo; docs/physics.md)")
    g.add_argument("--physics", choices=["default", "legacy"], default="default",
                   help="default: realistic sensing and the physical base, with the flags "
                   "below; legacy: the ideal sensor and original base of old results")
    base = Physics()
    for f in fields(Physics):
        default = getattr(base, f.name)
        if f.name == "use_strength":
            g.add_argument(flag(f.name), action="store_true", default=None,
                           help="weigh a cue by its push's strength in the belief update")
        elif f.name in CHOICES:
            g.add_argument(flag(f.name), choices=CHOICES[f.name], default=None,
                           help=f"default {default}")
        else:
            lo, hi = RANGES[f.name]
            g.add_argument(flag(f.name), type=float, default=None, metavar="X",
                           help=f"{lo:g}..{hi:g}, default {default:g}")


def physics_json(args: argparse.Namespace, sim: str) -> str:
    """The ``physics`` string of the episodes ``args`` ask for (``""``: legacy or grid)."""
    given = {f.name: getattr(args, f.name) for f in fields(Physics)
             if getattr(args, f.name, None) is not None}
    mode = getattr(args, "physics", "default")
    if sim != "mujoco" or mode == "legacy":
        if given:
            name = next(iter(given))
            why = "--physics legacy" if sim == "mujoco" else f"--sim {sim}"
            raise ConfigError(f"{flag(name)} is a physical parameter: it needs --sim mujoco "
                              f"without --physics legacy (got {why})")
        return ""
    return Physics(**given).to_json()
