"""The base's one cue stream: every cue its detector gives, in any phase, becomes one
:class:`~pathpref.episode.body.Felt` record (the cell and simulated time at which it was first
felt, when it was read, its heading, peak force, impulse and duration), appended to the base's
``felt`` and handed to its one ``listener`` (the episode runner's door, connected by the body).

Under guidance (:mod:`.guidance`) a push is also read while it lasts: every
``GUIDANCE_PERIOD_S`` of a cue under way a *partial* record carries the period's deformation as
evidence (to the listener, not to ``felt``); the cue's final record carries the rest.

The base keeps ``_onset``: ``(time, cell)`` where the cue under way was first felt (None:
none), which the compiled move also asks after (``base.cue_open``; :mod:`.coasting`: no cue
under way).
"""

from __future__ import annotations

from ..episode.body import Felt


def track_cue(base, cue) -> None:
    """After a physics step of ``base`` (a :class:`~.mobile_base.MobileBase`) whose sensing
    chain gave ``cue`` (None: none ended): note where and when the cue under way was first
    felt, give a guided push's partial record when a period is full, and turn an ended cue
    into a record of the stream (module docstring)."""
    under_way, g = base.sensing.under_way, base.guidance
    if g is not None and (under_way or cue is not None):
        if g.feel(base.sensing.force_estimate, base.dt) and cue is None:
            t = float(base.data.time)
            t0 = base._onset[0] if base._onset is not None else t
            partial = g.partial(base.cell, t0, t)  # to the listener; not in felt
            if base.listener is not None:
                base.listener(partial)
    if cue is not None:
        t = float(base.data.time)
        t0, cell = base._onset if base._onset is not None else (t, base.cell)
        felt = Felt(cell, cue.heading, t0, t, float(cue.peak_n),
                    (float(cue.impulse[0]), float(cue.impulse[1])), float(cue.duration_s),
                    evidence=None if g is None else g.take())
        if g is not None:
            g.given = 0.0  # the next cue has its own evidence
        base.felt.append(felt)
        base._onset = (t, base.cell) if under_way else None
        if base.listener is not None:
            base.listener(felt)
    elif under_way:
        if base._onset is None:
            base._onset = (float(base.data.time), base.cell)
    elif base._onset is not None:
        base._onset = None
