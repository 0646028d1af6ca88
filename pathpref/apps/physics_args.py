"""Command-line options for every physical parameter of a MuJoCo episode.

Each field of :class:`~pathpref.episode.physics.Physics` is a flag named after it
(``sensor_noise_n`` -> ``--sensor-noise-n``; ``use_strength`` is ``--use-strength``).
``--physics legacy`` asks for the legacy physics of rows written before the field existed
(ideal sensor, the original base); otherwise a MuJoCo episode runs with ``Physics()`` and the
flags given. With ``--sim grid`` only the human's flags apply (``--gamma-h``: a grid episode
has a human but no sensing chain or drive); a physical flag there, or any flag with ``--physics
legacy``, is refused; values are checked by :class:`Physics` (one line naming the field and
its range).
"""

from __future__ import annotations

import argparse

from ..episode.physics import CHOICES, FIELDS, PRESET_DEFAULT, RANGES, Physics, flag
from ..errors import ConfigError


def physics_options(sp: argparse.ArgumentParser) -> None:
    """Add ``--physics`` and one flag per :class:`Physics` field to ``sp``."""
    g = sp.add_argument_group("physical parameters (MuJoCo; docs/physics.md)")
    g.add_argument("--physics", choices=["default", "legacy"], default="default",
                   help="default: realistic sensing and the physical base, with the flags "
                   "below; legacy: the ideal sensor and original base of old results")
    defaults = Physics().flat()
    for name in FIELDS:
        default = defaults[name]
        if name == "use_strength":
            g.add_argument(flag(name), action="store_true", default=None,
                           help="weigh a cue by its push's strength in the belief update")
        elif name in CHOICES:
            g.add_argument(flag(name), choices=CHOICES[name], default=None,
                           help=f"default {default}")
        elif name in PRESET_DEFAULT:  # stored -1: the --sensor preset's own value
            lo, hi = RANGES[name]
            g.add_argument(flag(name), type=float, default=None, metavar="X",
                           help=f"{lo:g}..{hi:g}, default: the --sensor preset's "
                           "(docs/sensing.md)")
        else:
            lo, hi = RANGES[name]
            g.add_argument(flag(name), type=float, default=None, metavar="X",
                           help=f"{lo:g}..{hi:g}, default {default:g}")


def physics_json(args: argparse.Namespace, sim: str) -> str:
    """The ``physics`` string of the episodes ``args`` ask for (``""``: legacy, or the grid's
    default human; a grid episode's human settings otherwise)."""
    given = {name: getattr(args, name) for name in FIELDS
             if getattr(args, name, None) is not None}
    mode = getattr(args, "physics", "default")
    if sim == "grid" and mode != "legacy":
        physical = [k for k in given if FIELDS[k][0] != "human"]
        if physical:
            raise ConfigError(f"{flag(physical[0])} is a physical parameter: it needs --sim "
                              f"mujoco (a grid episode takes only the human's flags, e.g. "
                              f"--gamma-h)")
        return Physics.of(**given).human.stored()
    if sim != "mujoco" or mode == "legacy":
        if given:
            name = next(iter(given))
            why = "--physics legacy" if sim == "mujoco" else f"--sim {sim}"
            raise ConfigError(f"{flag(name)} is a physical parameter: it needs --sim mujoco "
                              f"without --physics legacy (got {why})")
        return ""
    return Physics.of(**given).to_json()
