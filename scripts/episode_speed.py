"""Wall time of the ``episode_s`` episodes (``pathpref bench --json``, key under "physics": simple,
path preference, Delta_T 5, seed 11, 30 decisions, ``Physics()``: realistic sensing, no
rendering) for this tree against an older commit, in one run: the two trees take turns in
fresh processes (so a load that comes and goes hits both alike), each episode's wall time is
set against bare MuJoCo plus planning (``physics.overhead_vs_bare_mujoco``: the time outside
its decision phases plus its physics steps at the bare ``mj_step`` time of its scene) and each
run's results are digested (every step's cell, action, heading, belief, and the metrics), so
the script also says whether the two trees give the same episodes.

    MUJOCO_GL=egl python scripts/episode_speed.py --before 1b13162 --rounds 3
    python scripts/episode_speed.py --before HEAD~1 --physics legacy    # the legacy physics

The older tree is ``git archive``-d into a temporary directory and put first on
``PYTHONPATH`` (the editable install of this tree stays the fallback).
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CONDITIONS = ("realistic", "legacy", "interval", "diffdrive")


def child(n: int, which: str) -> None:
    """Run ``n`` episodes of condition ``which`` after a warm-up; print times and digest."""
    os.environ.setdefault("MUJOCO_GL", "egl")
    import pathpref
    import pathpref.sim  # noqa: F401 - registers the MuJoCo body
    from pathpref.episode import EpisodeSpec, Physics
    from pathpref.episode.runner import EpisodeRunner, run_episode

    physics = {"realistic": Physics(), "legacy": None, "interval": Physics.of(timing="interval"),
               "diffdrive": Physics.of(base="diffdrive")}[which]
    ph = "" if physics is None else physics.to_json()

    def spec(i: int, t_max: int) -> EpisodeSpec:
        return EpisodeSpec.single("simple", "path_preference", 5, seed=11, instance=i,
                                  sim="mujoco", t_max=t_max, physics=ph)

    run_episode(spec(0, 3))  # compile the scene and the planner first
    times, overhead, python_us, h = [], [], [], hashlib.sha256()
    for i in range(n):
        runner = EpisodeRunner(spec(i, 30))
        base = runner.body.base
        bare = bare_step_s(base.model, base.data)
        spent = [0.0]
        with timed_phases(spent):
            t = time.perf_counter()
            while not runner.done:
                runner.step()
            times.append(time.perf_counter() - t)
        res = runner.result
        steps = round(float(base.data.time) / base.dt)
        # the episode against bare MuJoCo plus planning (physics.overhead_vs_bare_mujoco)
        overhead.append(times[-1] / (times[-1] - spent[0] + steps * bare))
        python_us.append(1e6 * (spent[0] / steps - bare))
        h.update(repr([(s.t, s.x, s.y, s.action, s.heading, s.p_true_goal, s.goal_entropy)
                       for s in res.log]).encode())
        h.update(repr(sorted(res.metrics.items())).encode())
    print(json.dumps({"file": pathpref.__file__, "times": times, "overhead": overhead,
                      "python_us": python_us, "digest": h.hexdigest()[:16]}))


def bare_step_s(model, data, steps: int = 2000) -> float:
    """Seconds of one bare ``mj_step`` from a copy of ``data`` (best of 3; as
    ``pathpref.apps.benchmarks.physics.bare_step_us``, which the older tree may not have)."""
    import copy

    import mujoco

    best = float("inf")
    for _ in range(3):
        d = copy.copy(data)
        t = time.perf_counter()
        for _ in range(steps):
            mujoco.mj_step(model, d)
        best = min(best, time.perf_counter() - t)
    return best / steps


@contextlib.contextmanager
def timed_phases(spent: list[float]):
    """Add the wall time of every decision-step phase (``DecisionStep.run``) to ``spent[0]``
    (as ``pathpref.apps.benchmarks.physics.timed_phases``, which the older tree may not have)."""
    from pathpref.sim.decision import DecisionStep

    run = DecisionStep.run

    def timed(self):
        t = time.perf_counter()
        try:
            return run(self)
        finally:
            spent[0] += time.perf_counter() - t

    DecisionStep.run = timed
    try:
        yield
    finally:
        DecisionStep.run = run


def main() -> None:
    """Parse arguments; alternate the two trees; print medians, ratios and the digests."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--before", required=True, help="git revision to compare against")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--episodes", type=int, default=5)
    ap.add_argument("--physics", choices=CONDITIONS, default="realistic")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.child:
        child(a.episodes, a.physics)
        return
    with tempfile.TemporaryDirectory() as tmp:
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", a.before, "pathpref",
                                  "tasks", "mjcf"], capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", tmp], input=archive, check=True)
        runs: dict[str, list[list[float]]] = {"before": [], "after": []}
        ratios: dict[str, list[float]] = {"before": [], "after": []}
        python_us: dict[str, list[float]] = {"before": [], "after": []}
        digests: dict[str, set[str]] = {"before": set(), "after": set()}
        for _ in range(a.rounds):
            for name in ("before", "after"):
                env = dict(os.environ, MUJOCO_GL=os.environ.get("MUJOCO_GL", "egl"))
                if name == "before":
                    env["PYTHONPATH"] = tmp
                out = subprocess.run([sys.executable, __file__, "--before", a.before,
                                      "--episodes", str(a.episodes), "--physics", a.physics,
                                      "--child"], env=env, cwd=tmp, capture_output=True,
                                     text=True, check=True).stdout.strip().splitlines()[-1]
                d = json.loads(out)
                runs[name].append(d["times"])
                ratios[name] += d["overhead"]
                python_us[name] += d["python_us"]
                digests[name].add(d["digest"])
                print(f"{name:6s} {' '.join(f'{t:5.2f}' for t in d['times'])}  "
                      f"({d['file']}, digest {d['digest']})", flush=True)
    med = {k: statistics.median(t for r in v for t in r) for k, v in runs.items()}
    total = {k: sum(map(sum, v)) for k, v in runs.items()}
    same = digests["before"] == digests["after"] and len(digests["after"]) == 1
    print(f"{a.physics}: median episode {med['before']:.2f} s before, {med['after']:.2f} s "
          f"after: {med['before'] / med['after']:.2f}x (totals "
          f"{total['before'] / total['after']:.2f}x); same episodes: {same}")
    print(f"episode / (bare mj_step + planning), median: {statistics.median(ratios['before']):.2f}"
          f" before, {statistics.median(ratios['after']):.2f} after; Python per physics step "
          f"{statistics.median(python_us['before']):.1f} us before, "
          f"{statistics.median(python_us['after']):.1f} us after")


if __name__ == "__main__":
    main()
