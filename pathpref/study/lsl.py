"""Lab Streaming Layer outlets for a live study (``study run --lsl``; ``pip install
'pathpref[lsl]'``), so EEG, motion capture or eye tracking recorded beside the study share its
clock (LSL's ``local_clock``, synchronised by LabRecorder):

* ``pathpref-force`` (type ``Force``, 4 float32 channels ``fx, fy, sensed_fx, sensed_fy`` N,
  nominal 500 Hz): every physics step, as ``trial_forces`` records it;
* ``pathpref-pose`` (type ``Position``, 5 float32 channels ``x, y, ee_x, ee_y, ee_z`` m, NaN
  for no end effector, nominal 100 Hz): every ``trial_path`` row;
* ``pathpref-events`` (type ``Markers``, one string channel, irregular): a JSON object per
  trial start and end, push, cue and belief update (``{"event": ..., "trial": ..., ...}``).

Each stream's ``source_id`` is ``pathpref-PARTICIPANT-KIND``, so a recorder reconnects to the
same stream after a restart."""

from __future__ import annotations

import json
import math
from collections.abc import Sequence

from ..errors import ConfigError

#: (kind, type, channels, nominal rate Hz, format) of each outlet
STREAMS = (("force", "Force", ("fx", "fy", "sensed_fx", "sensed_fy"), 500.0, "float32"),
           ("pose", "Position", ("x", "y", "ee_x", "ee_y", "ee_z"), 100.0, "float32"),
           ("events", "Markers", ("event",), 0.0, "string"))


def _pylsl():
    try:
        import pylsl
    except ImportError:
        raise ConfigError("--lsl needs the pylsl package: pip install 'pathpref[lsl]'"
                          ) from None
    except RuntimeError as e:  # pylsl without a loadable liblsl
        raise ConfigError(f"--lsl: liblsl cannot be loaded ({str(e)[:120]})") from None
    return pylsl


class LslOutlets:
    """The three outlets of ``participant``'s session (module docstring)."""

    def __init__(self, participant: str):
        lsl = _pylsl()
        self.outlets = {}
        for kind, typ, channels, rate, fmt in STREAMS:
            info = lsl.StreamInfo(f"pathpref-{kind}", typ, len(channels), rate,
                                  getattr(lsl, f"cf_{fmt}"), f"pathpref-{participant}-{kind}")
            chans = info.desc().append_child("channels")
            for c in channels:
                chans.append_child("channel").append_child_value("label", c)
            self.outlets[kind] = lsl.StreamOutlet(info)

    def force(self, fx: float, fy: float, sx: float, sy: float) -> None:
        """One physics step's applied and sensed force."""
        self.outlets["force"].push_sample([fx, fy, sx, sy])

    def pose(self, x: float, y: float, ee: Sequence[float | None]) -> None:
        """The base's position and the end effector's (None: NaN)."""
        self.outlets["pose"].push_sample(
            [x, y, *(math.nan if v is None else v for v in ee)])

    def event(self, event: str, trial: int, **fields) -> None:
        """A marker: ``{"event": event, "trial": trial, **fields}`` as JSON."""
        self.outlets["events"].push_sample([json.dumps(
            {"event": event, "trial": trial} | fields)])

    def close(self) -> None:
        """Drop the outlets (the streams disappear from the network)."""
        self.outlets.clear()
