"""Scripted participants (pilots, tests): a file of timed pushes sent through the front-end
code path (:meth:`~.controls.Controls.handle`), as a person's browser would.

Format (JSON)::

    {"pushes": [{"t": 0.5, "fx": 0, "fy": 35, "duration": 0.4}, ...],
     "trials": {"right": [{"t": 0.5, "fx": 35, "fy": 0, "duration": 0.4}]}}

``t`` is the push's start in seconds since the trial began (simulated time), ``fx``, ``fy``
the force (N, world x-y; capped like a person's at 60 N), ``duration`` its length in seconds
(0.05..10). ``trials`` gives the pushes of the trials it names; ``pushes`` those of every
other trial. At each physics step the script sends ``push`` when a push starts and
``release`` when it ends.

A simulated gamepad: ``"gamepad": {"rest": [x, y], "reach": r}`` (a calibration as the page
would send it) makes the script calibrate once, before its first trial, and send each push as
the stick axes that give its force under that calibration
(:func:`~.controls.stick_axes`), and each release as the stick back at rest.

A questionnaire: ``"tlx": {"right": {"mental": 40, "physical": 65, ...}}`` answers the NASA-TLX
(the six scales, integers 0..100) after the trials it names, as the page's ``tlx`` message.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ConfigError
from .controls import Controls, StickCalibration, finite_number, stick_axes


def _pushes(raw: Any, where: str) -> list[tuple[float, float, float, float]]:
    if not isinstance(raw, list):
        raise ConfigError(f"{where} must be a list of pushes {{t, fx, fy, duration}}")
    out = []
    for k, p in enumerate(raw):
        w = f"{where}[{k}]"
        if not isinstance(p, dict) or set(p) != {"t", "fx", "fy", "duration"}:
            raise ConfigError(f"{w} must be an object with exactly t, fx, fy, duration")
        vals = [p[n] for n in ("t", "fx", "fy", "duration")]
        if not all(finite_number(v) for v in vals):
            raise ConfigError(f"{w}: t, fx, fy and duration must be finite numbers")
        t, fx, fy, d = map(float, vals)
        if not 0 <= t <= 3600:
            raise ConfigError(f"{w}.t must be in 0..3600 s, got {t:g}")
        if not 0.05 <= d <= 10:
            raise ConfigError(f"{w}.duration must be in 0.05..10 s, got {d:g}")
        out.append((t, fx, fy, d))
    out.sort()
    for (t0, _, _, d0), (t1, _, _, _) in zip(out[:-1], out[1:], strict=True):
        if t1 < t0 + d0:
            raise ConfigError(f"{where}: the push at t={t1:g} s starts before the one at "
                              f"t={t0:g} s ends")
    return out


def _tlx(raw: Any, path: str) -> dict[str, dict[str, int]]:
    """The ``tlx`` answers of a push file: trial name -> the six scales (0..100 integers)."""
    from .controls import TLX_SCALES

    if not isinstance(raw, dict):
        raise ConfigError(f"{path}: tlx must map trial names to NASA-TLX answers")
    out = {}
    for name, scores in raw.items():
        if not (isinstance(scores, dict) and set(scores) == set(TLX_SCALES) and all(
                type(v) is int and 0 <= v <= 100 for v in scores.values())):
            raise ConfigError(f"{path}: tlx.{str(name)[:40]} must give exactly "
                              f"{', '.join(TLX_SCALES)}, each an integer 0..100")
        out[name] = {k: scores[k] for k in TLX_SCALES}
    return out


class PushScript:
    """A validated push file (module docstring)."""

    def __init__(self, raw: Any, path: str = "<script>"):
        if not isinstance(raw, dict) or not raw or set(raw) - {"pushes", "trials", "gamepad",
                                                                "tlx"}:
            raise ConfigError(f"{path}: a push file is an object with 'pushes' and/or 'trials' "
                              "(and optionally 'gamepad', 'tlx')")
        self.tlx = _tlx(raw.get("tlx", {}), path)
        self.gamepad: StickCalibration | None = None
        if "gamepad" in raw:
            pad = raw["gamepad"]
            cal = (StickCalibration.parse({**pad, "device": "simulated gamepad"})
                   if isinstance(pad, dict) and set(pad) <= {"rest", "reach"} else
                   "an object with rest [x, y] and reach")
            if isinstance(cal, str):
                raise ConfigError(f"{path}: gamepad: {cal}")
            self.gamepad = cal
        self.default = _pushes(raw.get("pushes", []), "pushes")
        named = raw.get("trials", {})
        if not isinstance(named, dict):
            raise ConfigError("trials must map trial names to lists of pushes")
        self.named = {n: _pushes(v, f"trials.{n}") for n, v in named.items()}

    @classmethod
    def load(cls, path: str | Path) -> PushScript:
        """Read and validate a push file."""
        try:
            raw = json.loads(Path(path).read_bytes())
        except OSError as e:
            raise ConfigError(f"cannot read push file {path}: {e.strerror}") from None
        except ValueError as e:
            raise ConfigError(f"{path} is not valid JSON: {e}") from None
        except RecursionError:
            raise ConfigError(f"{path} is nested too deeply to be a push file") from None
        return cls(raw, str(path))

    def check_names(self, study) -> None:
        """Every trial the file names is a trial of ``study`` (one line naming it if not)."""
        have = {t.name for t in study.trials}
        for name in (*self.named, *self.tlx):
            if name not in have:
                raise ConfigError(f"push file trials.{str(name)[:40]}: the study has no trial "
                                  f"of that name; its trials: {', '.join(sorted(have))[:200]}")

    def for_trial(self, name: str) -> list[tuple[float, float, float, float]]:
        """The pushes ``(t, fx, fy, duration)`` of the trial ``name``."""
        return self.named.get(name, self.default)


class ScriptedParticipant:
    """Plays one trial's pushes into ``controls`` at their simulated times: call it once per
    physics step with the trial time (a hook of the trial's physics)."""

    def __init__(self, controls: Controls, pushes: list[tuple[float, float, float, float]],
                 gamepad: StickCalibration | None = None):
        self.controls = controls
        self.pushes = pushes
        self.gamepad = gamepad
        self.k = 0
        self.active = False

    def tick(self, t: float) -> None:
        """Send ``push``/``release`` messages due at trial time ``t``."""
        if self.active:
            t0, _, _, d = self.pushes[self.k]
            if t >= t0 + d:
                self.controls.handle(self._message(0.0, 0.0))
                self.active = False
                self.k += 1
        if not self.active and self.k < len(self.pushes) and t >= self.pushes[self.k][0]:
            _, fx, fy, _ = self.pushes[self.k]
            self.controls.handle(self._message(fx, fy))
            self.active = True

    def _message(self, fx: float, fy: float) -> str:
        """The message of force ``(fx, fy)`` (zero: a release): a push, or the stick's axes."""
        if self.gamepad is not None:
            ax, ay = stick_axes(np.array([fx, fy]), self.gamepad)
            return json.dumps({"type": "stick", "ax": ax, "ay": ay})
        if fx == 0.0 and fy == 0.0:
            return '{"type": "release"}'
        return json.dumps({"type": "push", "fx": fx, "fy": fy})


class ScriptedFrontEnd:
    """The front end of a scripted participant: no screen; each trial's pushes
    (:meth:`PushScript.for_trial`) go through :class:`~.controls.Controls` as a browser's
    messages do. Runs as fast as the machine allows (no real-time pacing)."""

    name = "script"
    #: never shown: the script answers the questionnaire by its ``tlx`` entries
    questionnaire: str | None = None

    def __init__(self, script: PushScript):
        self.script = script
        self.controls = Controls()

    def source(self) -> Controls:
        """The participant's push source: the controls the script writes to."""
        return self.controls

    def begin_trial(self, position: int, total: int, runner) -> None:
        """Start at once; play the trial's pushes at their simulated times."""
        self.position = position
        self.controls.reset()
        pad = self.script.gamepad
        if pad is not None and self.controls.calibration is None:  # the calibration step
            self.controls.handle(json.dumps({"type": "calibrate", "rest": list(pad.rest),
                                             "reach": pad.reach, "device": pad.device}))
        self.controls.handle('{"type": "start"}')
        player = ScriptedParticipant(self.controls, self.script.for_trial(runner.trial.name),
                                     pad)
        runner.base.on_substep.append(lambda base, push: player.tick(runner.time_s))

    def after_decision(self, runner) -> None:
        """Nothing to show."""

    def end_trial(self, runner, outcome: dict) -> None:
        """Answer the questionnaire when the script has answers for this trial."""
        scores = self.script.tlx.get(runner.trial.name)
        if scores is not None:
            self.controls.ask_tlx(self.position)
            self.controls.handle(json.dumps({"type": "tlx", "trial": self.position,
                                             "scores": scores}))

    def close(self) -> None:
        """Nothing to release."""
