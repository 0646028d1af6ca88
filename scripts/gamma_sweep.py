"""A mis-specified planner against a learned one: the human's rationality.

    .venv/bin/python scripts/gamma_sweep.py --json docs/gamma_sweep.json

The simulated human picks headings with rationality ``gamma_h`` (0.5, 1.5 or 5: the episode's
``--gamma-h``); robust path preference (consistent human) plans with one of three beliefs over
the same episodes (common random numbers: seed 0, instance ``i``, run ``r``):

* ``assumed``: the independent prior with the model's gamma 1.5 (``--prior independent``);
* ``learned``: gamma inferred with goal and preference, exact over (0.5, 1.5, 5)
  (``--prior learned-gamma``, :mod:`pathpref.inference.rationality`);
* ``known``: a reference told the human's gamma (a method registered here, not offered).

Prints, per ``gamma_h`` and ``Delta_T``, strict and homotopy-level success pooled over the maps
with Wilson 95 % intervals, and writes every cell to ``--json``.
"""

from __future__ import annotations

import argparse
import json
import os

os.environ.setdefault("MUJOCO_GL", "disable")

from pathpref.episode import EpisodeSpec  # noqa: E402
from pathpref.episode.runner import run_episode  # noqa: E402
from pathpref.experiments.report import wilson  # noqa: E402
from pathpref.inference.belief import PreferenceBelief  # noqa: E402
from pathpref.inference.human import ObservationModel  # noqa: E402
from pathpref.planning.policies import PlannerPolicy, register_method  # noqa: E402

KNOWN = "path_preference_known_gamma"


def known_gamma_method(gamma: float):
    """Path preference whose independent-prior belief uses the human's true ``gamma``."""
    def make(ctx):
        m = ctx.model
        belief = PreferenceBelief(ObservationModel(m.world, m.tables, gamma, m.normalize),
                                  coupling=ctx.preset.coupling)
        return PlannerPolicy(ctx, belief, ctx.preset.path_preference)
    return make


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--maps", nargs="+", default=["simple", "office"])
    ap.add_argument("--gamma-h", nargs="+", type=float, default=[0.5, 1.5, 5.0])
    ap.add_argument("--delta-t", nargs="+", type=int, default=[1, 5])
    ap.add_argument("--instances", type=int, default=10)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--json", default="")
    args = ap.parse_args()
    cells = []
    for gamma_h in args.gamma_h:
        register_method(KNOWN, known_gamma_method(gamma_h))
        for dt in args.delta_t:
            for belief, method, prior in (("assumed", "path_preference", "independent"),
                                          ("learned", "path_preference", "learned-gamma"),
                                          ("known", KNOWN, "independent")):
                s = h = n = 0
                for name in args.maps:
                    for i in range(args.instances):
                        for r in range(args.runs):
                            res = run_episode(EpisodeSpec.single(
                                name, method, dt, seed=0, instance=i, run=r, preset="robust",
                                human="consistent", prior=prior,
                                physics=json.dumps({"gamma_h": gamma_h})))
                            s, h, n = s + res.success, h + res.homotopy_success, n + 1
                cell = {"gamma_h": gamma_h, "delta_t": dt, "belief": belief, "n": n,
                        "success": s / n, "success_ci": wilson(s, n),
                        "homotopy": h / n, "homotopy_ci": wilson(h, n)}
                cells.append(cell)
                print(f"gamma_h {gamma_h:g} dT {dt} {belief:8s} strict {s / n:.2f} "
                      f"[{cell['success_ci'][0]:.2f}, {cell['success_ci'][1]:.2f}]  homotopy "
                      f"{h / n:.2f} [{cell['homotopy_ci'][0]:.2f}, "
                      f"{cell['homotopy_ci'][1]:.2f}]  n={n}", flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"maps": args.maps, "instances": args.instances, "runs": args.runs,
                       "cells": cells}, f, indent=1)


if __name__ == "__main__":
    main()
