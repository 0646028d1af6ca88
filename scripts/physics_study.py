"""What physics changes: the same episodes under six conditions.

    MUJOCO_GL=egl .venv/bin/python scripts/physics_study.py --episodes 60 --out study.json

Conditions (every condition runs the same specs: map, method, Delta_T, instance and run seeds):

* ``grid``: the grid body, headings observed exactly (SPEC 3);
* ``grid+noise``: the control: the human's heading plus N(0, 10 degrees) angle noise, binned
  into its sector, moves on the grid (what the legacy MuJoCo layer reduced to);
* ``mujoco-ideal``: the legacy MuJoCo physics (ideal sensor, 12 kg base, a 30 N / 0.3 s push at
  each input step while the base stands);
* ``realistic``: ``Physics()``: realistic sensing (2 N noise, 6 N drifting bias, inertia),
  pushes from the human's distributions (log-normal 25 N / 0.3 s medians), the 135 kg
  Ridgeback-class base within its limits, still at input steps;
* ``anytime``: the same with pushes at any time (an interval of Delta_T seconds +-50 %, while
  the base drives, brakes or stands; the move stops on a cue and the robot replans);
* ``diffdrive``: ``realistic`` on the differential-drive base;
* ``tidybot``, ``tidybot-anytime``, ``tidybot-guidance``: ``realistic``, ``anytime`` and
  ``guidance`` on the Stanford TidyBot (``robot_model`` tidybot: Menagerie's 69 kg robot at
  1 m per cell, 0.5 m/s and 0.5 m/s^2);
* ``guidance``: Bajcsy-style sustained corrections on the ``anytime`` clock: the human holds
  the handle (log-normal, median 2 s) while the base drives, the base complies (admittance
  20 kg, 80 N s/m added to its tracking) and the belief is updated online from the force's
  direction (von Mises likelihood, ``docs/physics.md``); compare with ``anytime`` (taps on the
  same clock, same instances).

Per condition: success (goal reached and preference followed) with a Wilson 95 % interval, cue
accuracy (observed sector = the human's intended one, over the pushes given; missed pushes
count as wrong) with its interval, pushes per episode, decision steps, how many episodes take
exactly the grid+noise control's cell sequence (the first condition's without it), the mean final
P(true goal) and its mean over the episode's steps (how sharp the belief was while it
mattered), and wall time per episode. `--conditions strength-ignored strength-used` asks
whether push strength helps the observation model (docs/physics.md).
"""

from __future__ import annotations

import argparse
import json
import os
import time
from dataclasses import replace

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402

import pathpref.sim  # noqa: E402,F401 - registers the MuJoCo body
from pathpref.episode import EpisodeSpec, GridBody, Physics, cached_world, run_episode  # noqa: E402
from pathpref.episode.body import Felt, make_body, simulator_rng  # noqa: E402
from pathpref.experiments.report import wilson  # noqa: E402
from pathpref.geometry.grid import ACTION_ANGLES, heading_to_action  # noqa: E402


class NoisyGridBody(GridBody):
    """The control: the grid body whose observed heading is the human's plus
    N(0, ``noise_deg``) degrees, binned into its sector."""

    def __init__(self, world, spec=None, rng=None, noise_deg: float = 10.0):
        super().__init__(world, spec, rng)
        self.rng, self.noise = rng, np.deg2rad(noise_deg)

    def push(self, heading: int) -> None:
        """The noisy sector of the human's heading, observed at the body's cell."""
        self.observe(Felt(self.cell, heading_to_action(
            float(ACTION_ANGLES[heading]) + self.noise * self.rng.standard_normal())))


class Recorder:
    """Counts (intended, observed) pairs at input steps: wraps the body's ``push`` and the
    door the runner connects (what is observed during a push is that push's reading)."""

    def __init__(self, body):
        self.pairs: list[tuple[int, int | None]] = []
        self._seen: list[int] | None = None
        inner_push, inner_connect = body.push, body.connect

        def connect(observe) -> None:
            def door(felt) -> None:
                if self._seen is not None:
                    self._seen.append(felt.heading)
                observe(felt)
            inner_connect(door)

        def push(heading: int) -> None:
            self._seen = []
            inner_push(heading)
            self.pairs.append((heading, self._seen[-1] if self._seen else None))
            self._seen = None

        body.push, body.connect = push, connect


CONDITIONS = {
    "grid": ("grid", ""),
    "grid+noise": ("grid", "noise"),
    "mujoco-ideal": ("mujoco", ""),
    "realistic": ("mujoco", Physics().to_json()),
    "anytime": ("mujoco", Physics.of(timing="interval").to_json()),
    "diffdrive": ("mujoco", Physics.of(base="diffdrive").to_json()),
    "guidance": ("mujoco", Physics.of(timing="guidance").to_json()),
    # a sensor warming up after it was zeroed: 20 N of offset, time constant 120 s
    "thermal": ("mujoco", Physics.of(sensor_thermal_n=20.0).to_json()),
    # does push strength help the observation model? a human who pushes harder when surer
    # (strength_confidence 1), the robot ignoring or using the strength
    "strength-ignored": ("mujoco", Physics.of(strength_confidence=1.0).to_json()),
    "strength-used": ("mujoco", Physics.of(strength_confidence=1.0, use_strength=True).to_json()),
    # the Stanford TidyBot (Menagerie's model, 1 m per cell, its own drive limits): realistic
    # sensing at input steps, pushes at any time, guidance
    "tidybot": ("mujoco", Physics.of(robot_model="tidybot").to_json()),
    "tidybot-anytime": ("mujoco", Physics.of(robot_model="tidybot", timing="interval").to_json()),
    "tidybot-guidance": ("mujoco", Physics.of(robot_model="tidybot",
                                              timing="guidance").to_json()),
}
STUDY = ["grid", "grid+noise", "mujoco-ideal", "realistic", "anytime", "diffdrive"]


def run_condition(name: str, specs: list[EpisodeSpec]) -> dict:
    """Run ``specs`` under condition ``name``; the per-condition figures (module docstring)."""
    sim, physics = CONDITIONS[name]
    world = cached_world(specs[0].map)
    success, hits, pushes, steps, cells, wall, p_goal = [], 0, 0, [], [], [], []
    p_mean, metrics = [], []
    for base in specs:
        spec = replace(base, sim=sim, physics="" if physics == "noise" else physics)
        body = NoisyGridBody(world, spec, simulator_rng(spec)) if physics == "noise" else \
            make_body(spec, world)
        rec = Recorder(body)
        t = time.perf_counter()
        res = run_episode(spec, world, body)
        wall.append(time.perf_counter() - t)
        success.append(res.success)
        p_goal.append(res.log[-1].p_true_goal)
        p_mean.append(float(np.mean([s.p_true_goal for s in res.log])))
        metrics.append(res.metrics)
        steps.append(res.steps)
        cells.append([(s.x, s.y) for s in res.log])
        if rec.pairs:
            pushes += len(rec.pairs)
            hits += sum(h == s for h, s in rec.pairs)
        else:  # pushes at any time: the body's own record
            pushes += res.inputs
            hits += int(res.metrics.get("cue_hits", 0))
    k, n = int(sum(success)), len(success)

    def total(key: str) -> float:
        return float(sum(m.get(key, 0.0) for m in metrics))

    given = total("pushes")
    lat = [m["cue_latency_ms"] for m in metrics if "cue_latency_ms" in m]
    return {"success": k / n, "success_ci": wilson(k, n), "n": n,
            "cue_accuracy": hits / max(pushes, 1), "cue_accuracy_ci": wilson(hits, pushes),
            "pushes": pushes, "pushes_per_episode": pushes / n,
            "steps_mean": float(np.mean(steps)), "wall_s_per_episode": float(np.mean(wall)),
            "p_true_goal_final": float(np.mean(p_goal)),
            "p_true_goal_mean": float(np.mean(p_mean)),
            # the body's own account (physical conditions): pushes missed / misread by the
            # detector over the pushes given, mean cue latency, contact safety
            "pushes_missed": total("pushes_missed"), "pushes_misread": total("pushes_misread"),
            "pushes_missed_ci": wilson(int(total("pushes_missed")), int(given)) if given else
            None,
            "cue_latency_ms": float(np.mean(lat)) if lat else None,
            "collisions_per_episode": total("collisions") / n,
            "impact_speed_max": max((m.get("contact_impact_speed", 0.0) for m in metrics),
                                    default=0.0),
            "contact_force_max_n": max((m.get("contact_peak_force_n", 0.0) for m in metrics),
                                       default=0.0),
            "cells": cells}


def main() -> None:
    """Run the study and print a Markdown table (module docstring)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=60)
    ap.add_argument("--map", default="simple")
    ap.add_argument("--method", default="path_preference")
    ap.add_argument("--delta-t", type=int, default=5)
    ap.add_argument("--seed", type=int, default=12)
    ap.add_argument("--preset", default="robust", help="the planner's preset (robust: the "
                    "default of applications and tasks, with its route prior)")
    ap.add_argument("--out", default=None, help="JSON of the figures")
    ap.add_argument("--conditions", nargs="+", default=STUDY, choices=list(CONDITIONS))
    args = ap.parse_args()
    specs = [EpisodeSpec.single(args.map, args.method, args.delta_t, seed=args.seed,
                                instance=i, queries=1000, preset=args.preset)
             for i in range(args.episodes)]
    out = {}
    for name in args.conditions:
        t = time.perf_counter()
        out[name] = run_condition(name, specs)
        print(f"{name}: {time.perf_counter() - t:.0f} s", flush=True)
    control = out.get("grid+noise", out[args.conditions[0]])["cells"]
    for r in out.values():
        r["same_as_control"] = sum(a == b for a, b in zip(control, r["cells"], strict=True))
    for r in out.values():
        r.pop("cells")
    print(f"\n{args.episodes} episodes per condition ({args.map}, {args.method}, "
          f"preset {args.preset}, Delta_T {args.delta_t}, 1000 queries, seed {args.seed})\n")
    print("| condition | success [95% CI] | cue accuracy [95% CI] | pushes/episode | steps | "
          "final P(true goal) | mean P(true goal) | same path as control | missed / misread "
          "pushes | cue latency ms | collisions/episode, max impact m/s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name, r in out.items():
        lo, hi = r["success_ci"]
        clo, chi = r["cue_accuracy_ci"]
        print(f"| {name} | {r['success']:.2f} [{lo:.2f}, {hi:.2f}] | {r['cue_accuracy']:.3f} "
              f"[{clo:.3f}, {chi:.3f}] | {r['pushes_per_episode']:.1f} | {r['steps_mean']:.1f} "
              f"| {r['p_true_goal_final']:.2f} | {r['p_true_goal_mean']:.2f} "
              f"| {r['same_as_control']}/{r['n']} "
              f"| {r['pushes_missed']:.0f} / {r['pushes_misread']:.0f} "
              f"| {'-' if r['cue_latency_ms'] is None else format(r['cue_latency_ms'], '.0f')} "
              f"| {r['collisions_per_episode']:.2f}, {r['impact_speed_max']:.2f} |")
    if args.out:
        with open(args.out, "w") as f:
            json.dump({"args": vars(args), "conditions": out}, f, indent=1)


if __name__ == "__main__":
    main()
