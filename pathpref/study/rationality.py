"""A participant's rationality ``gamma_h`` fitted from the recorded pushes.

**Observations.** Every cue the robot's detector found in the participant's finished trials
(``trial_cues``: the cell ``s_i`` the base was in and the heading sector ``h_i``).

**Model.** The Boltzmann human of :mod:`pathpref.inference.human` (paper Eq. 1, SPEC 4) with
the trial's goal among its candidates and the preference its route conveys
(:meth:`~.plan.Trial.route_preference`), normalised over the 8 headings::

    P_gamma(h | s) = exp(-gamma Delta(s, h)) / sum_h' exp(-gamma Delta(s, h'))

Because ``log P_1(h | s) = -Delta(s, h) - log Z_1(s)``, ``P_gamma(h | s) = P_1(h | s)^gamma /
sum_h' P_1(h' | s)^gamma``: the model built once per trial at ``gamma = 1``
(``ObservationModel(world, tables, 1, normalize=True)``) gives the log-likelihood at every
``gamma``::

    l(gamma) = sum_i [gamma log P_1(h_i | s_i) - log sum_h' P_1(h' | s_i)^gamma]

``l`` is concave in ``gamma`` (a linear term minus log-sum-exps of linear terms).

**Estimate.** The maximiser of ``l`` over :data:`GRID` (:data:`GRID_N` log-spaced points of
``[0.1, 10]``, steps of 1.2%). **Interval (95%).** The likelihood-ratio set ``{gamma :
2 (l(gamma_hat) - l(gamma)) <= 3.841}`` (``chi^2_1`` 95% quantile, Wilks), an interval because
``l`` is concave, given by its lowest and highest grid points. A bound on the grid's edge is
*open*: the data do not bound ``gamma`` there (shown ``<= 0.1`` or ``>= 10``; e.g. every push
along the best heading makes ``l`` increase for ever). No cue: no fit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ConfigError
from ..experiments.store import ResultStore
from ..experiments.trial_rows import checked
from ..experiments.trials import has_study_tables, read_rows
from ..inference.human import ObservationModel, SimulatedHuman
from .plan import Trial, trial_from_row

GRID_N = 401
GRID = np.geomspace(0.1, 10.0, GRID_N)
#: 95% quantile of chi^2 with one degree of freedom
CHI2_1_95 = 3.841458820694124


@dataclass(frozen=True)
class RationalityFit:
    """``gamma_h`` of one participant: ``n`` cues, the grid maximiser ``gamma`` and the 95%
    likelihood-ratio interval ``[low, high]`` (``low_open``/``high_open``: the bound is the
    grid's edge; all NaN when ``n`` is 0)."""

    n: int
    gamma: float
    low: float
    high: float
    low_open: bool
    high_open: bool

    def text(self) -> str:
        """``1.52 [1.10, 2.07]``, an open bound as ``<= 0.1`` / ``>= 10``, ``-`` without cues."""
        if self.n == 0:
            return "-"
        lo = f"<= {GRID[0]:g}" if self.low_open else f"{self.low:.2f}"
        hi = f">= {GRID[-1]:g}" if self.high_open else f"{self.high:.2f}"
        return f"{self.gamma:.2f} [{lo}, {hi}]"


def trial_human(trial: Trial) -> SimulatedHuman:
    """The trial's Boltzmann human at ``gamma = 1`` (normalised; module docstring)."""
    world = trial.world
    goals = np.array([world.cell(c) for c in trial.candidates])
    model = ObservationModel.build(world, goals, gamma=1.0, normalize=True)
    return SimulatedHuman(model, trial.goal_index, trial.route_preference())


def heading_log_probs(trial: Trial, cells: list[tuple[int, int]],
                      human: SimulatedHuman | None = None) -> np.ndarray:
    """``(len(cells), 8)`` ``log P_1(h | s)`` of the trial's human (module docstring) at the
    cells ``(x, y)`` (``human``: :func:`trial_human` of the trial, built when not given)."""
    world = trial.world
    human = human or trial_human(trial)
    with np.errstate(divide="ignore"):
        return np.array([np.log(human.probs(world.cell(c))) for c in cells]).reshape(-1, 8)


def log_likelihood(logp: np.ndarray, headings: np.ndarray, gammas: np.ndarray = GRID
                   ) -> np.ndarray:
    """``l(gamma)`` for every ``gammas`` (module docstring) of headings ``headings`` observed
    where the ``gamma = 1`` log-probabilities are ``logp`` (one row per observation)."""
    logp = np.asarray(logp, float).reshape(-1, 8)
    h = np.asarray(headings, int)
    g = np.asarray(gammas, float)[:, None, None]
    scaled = g * logp[None]  # (gammas, observations, 8)
    top = scaled.max(axis=2, keepdims=True)
    lse = top[..., 0] + np.log(np.exp(scaled - top).sum(axis=2))
    chosen = scaled[:, np.arange(len(h)), h]
    return (chosen - lse).sum(axis=1)


def fit_gamma(logp: np.ndarray, headings: np.ndarray) -> RationalityFit:
    """The grid estimate and 95% likelihood-ratio interval of ``gamma_h`` (module
    docstring)."""
    n = len(headings)
    if n == 0:
        return RationalityFit(0, math.nan, math.nan, math.nan, False, False)
    ll = log_likelihood(logp, headings)
    best = int(np.argmax(ll))
    inside = np.flatnonzero(2.0 * (ll[best] - ll) <= CHI2_1_95)
    lo, hi = int(inside[0]), int(inside[-1])
    return RationalityFit(n, float(GRID[best]), float(GRID[lo]), float(GRID[hi]),
                          lo == 0, hi == GRID_N - 1)


def participant_fits(db: str | Path) -> dict[str, RationalityFit]:
    """``gamma_h`` per participant of ``db`` from the cues of their finished trials (none
    without study tables)."""
    with ResultStore(db, create=False) as store:
        c = store.conn
        if not has_study_tables(c):
            return {}
        trials = list(checked("trials", read_rows(
            c, "trials", "WHERE status = 'done' ORDER BY participant, trial"), db))
        cues = list(checked("trial_cues", read_rows(
            c, "trial_cues", "ORDER BY participant, trial, k"), db))
    by_trial: dict[tuple[str, int], list[dict]] = {}
    for q in cues:
        by_trial.setdefault((q["participant"], q["trial"]), []).append(q)
    rows: dict[str, tuple[list[np.ndarray], list[int]]] = {}
    humans: dict[tuple, SimulatedHuman] = {}  # one per distinct task (at most one per row)
    for r in trials:
        logps, heads = rows.setdefault(r["participant"], ([], []))
        seen = by_trial.get((r["participant"], r["trial"]), [])
        if not seen:
            continue
        if any(not 0 <= q["heading"] <= 7 for q in seen):
            raise ConfigError(f"{db}: trial {r['trial']} of {r['participant']!r} has a cue "
                              "heading outside 0..7 (trial_cues.heading); the file was changed")
        trial = trial_from_row(r)
        task = (trial.map, trial.candidates, trial.goal, trial.route)
        if task not in humans:
            humans[task] = trial_human(trial)
        logps.append(heading_log_probs(trial, [(q["x"], q["y"]) for q in seen], humans[task]))
        heads += [q["heading"] for q in seen]
    return {p: fit_gamma(np.concatenate(lp) if lp else np.zeros((0, 8)), np.array(h, int))
            for p, (lp, h) in rows.items()}


def rationality_table(fits: dict[str, RationalityFit]) -> str:
    """Markdown: per participant the cues and ``gamma_h`` [95% likelihood-ratio interval]."""
    lines = ["**Human rationality per participant** (gamma_h of the Boltzmann model fitted "
             "to the cue headings; 95% likelihood-ratio interval)", "",
             "| participant | cues | gamma_h |", "|---|---|---|"]
    lines += [f"| {p} | {f.n} | {f.text()} |" for p, f in sorted(fits.items())]
    return "\n".join(lines)
