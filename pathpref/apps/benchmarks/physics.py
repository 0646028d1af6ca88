"""``physics`` and ``arm`` sections: MuJoCo cue detection (ideal and realistic sensing),
latency, false cues while driving, episode time, rendering, IK and tray tilt."""

from __future__ import annotations

import contextlib
import copy
import time
from statistics import median
from typing import Any

import numpy as np

from ...episode import EpisodeSpec, cached_world, run_episode
from ...episode.physics import CELL_SIZE_M
from ...geometry.world import World


# --- physics: MuJoCo sensing, episodes, rendering, arm --------------------------------------
def scene_for(world: World, cell_size: float = CELL_SIZE_M, task: str = "navigate"):
    """The compiled MuJoCo scene (imports the simulator on first use)."""
    from ...sim.body import scene_for as build

    return build(world, cell_size, task)


def cue_accuracy(n: int = 200, noise_deg: float = 10.0, seed: int = 0) -> float:
    """Share of ``n`` pushes whose detected sector equals the human's intended one."""
    from ...sim.force_cue import HumanPush, PushProfile
    from ...sim.mobile_base import MobileBase

    world = cached_world("simple")
    base = MobileBase(scene_for(world))
    rng = np.random.default_rng(seed)
    profile = PushProfile(noise_deg=noise_deg)
    hits = 0
    for _ in range(n):
        base.reset(int(rng.integers(world.n_cells)))
        h = int(rng.integers(8))
        cue = base.receive_push(HumanPush.sample(h, 0.0, profile, rng))
        hits += cue is not None and cue.heading == h
    return hits / n


def false_cues(seconds: float = 1000.0, seed: int = 0) -> tuple[int, float]:
    """Cues detected while driving random legal moves for ``seconds`` of simulated time."""
    from ...sim.mobile_base import MobileBase

    world = cached_world("office")
    base = MobileBase(scene_for(world))
    rng = np.random.default_rng(seed)
    base.reset(world.cell((1, 1)))
    while base.data.time < seconds:
        s = base.cell
        moves = np.flatnonzero(~world.motion.blocked[s])
        base.move_to(int(world.motion.next_cell[s, rng.choice(moves)]))
    return len(base.felt), float(base.data.time)  # every cue read (no push was made)


def realistic_pushes(n: int, seed: int = 0, noise_deg: float = 10.0) -> list[tuple]:
    """``n`` pushes of the realistic benchmark on ``simple``: a random walk of legal moves and
    at each cell a push toward a random sector, peak U[10, 60] N over U[0.1, 0.5] s, heading
    noise ``noise_deg``; rows ``(cell, heading, angle, profile)``."""
    from ...sim.force_cue import HumanPush, PushProfile

    world = cached_world("simple")
    rng = np.random.default_rng(seed)
    cell, rows = world.cell((3, 3)), []
    for _ in range(n):
        moves = np.flatnonzero(~world.motion.blocked[cell])
        cell = int(world.motion.next_cell[cell, rng.choice(moves)])
        h = int(rng.integers(8))
        profile = PushProfile(peak_n=float(rng.uniform(10.0, 60.0)),
                              duration_s=float(rng.uniform(0.1, 0.5)), noise_deg=noise_deg)
        rows.append((cell, h, HumanPush.sample(h, 0.0, profile, rng).angle, profile))
    return rows


def run_pushes(pushes: list[tuple], sensor_model=None, seed: int = 0, rest_s: float = 0.3,
               estimator=None) -> dict[str, Any]:
    """Give ``pushes`` (from :func:`realistic_pushes`) to one base with ``sensor_model``:
    drive to each push's cell, wait ``rest_s``, push. Hits (detected sector = intended),
    onset latencies (push onset to the detector going active) and release latencies (push
    end to the cue)."""
    from ...sim.force_cue import HumanPush
    from ...sim.mobile_base import MobileBase

    world = cached_world("simple")
    base = MobileBase(scene_for(world), sensor_model=sensor_model,
                      rng=np.random.default_rng(seed + 1), estimator=estimator)
    base.reset(world.cell((3, 3)))
    hits, onset, release = [], [], []
    for cell, h, angle, profile in pushes:
        base.move_to(cell)
        t_end = base.data.time + rest_s
        while base.data.time < t_end:
            base.substep()
        push = HumanPush(angle, 0.0, profile, h)
        cue = base.receive_push(push)
        hits.append(cue is not None and cue.heading == h)
        if base.decision.onset_s is not None:
            onset.append(base.decision.onset_s)
        if cue is not None:
            release.append(float(base.data.time) - push.t0 - profile.duration_s)
    return {"hits": hits, "onset_s": onset, "release_s": release,
            "accuracy": float(np.mean(hits)) if hits else 0.0}


def cue_accuracy_realistic(n: int = 200, seed: int = 0) -> dict[str, Any]:
    """The same ``n`` pushes (:func:`realistic_pushes`) sensed by the ideal sensor and by
    ``SensorModel.realistic()`` (2 N noise per axis at 100 Hz, 6 N bias drifting by
    0.05 N/sqrt(s), inertia with 0.6 kg sensed) through the estimator and the filtered
    detector: both accuracies, their ratio, latencies (ms, medians)."""
    from ...sim.sensing import SensorModel

    pushes = realistic_pushes(n, seed)
    ideal = run_pushes(pushes, None, seed)
    real = run_pushes(pushes, SensorModel.realistic(), seed)

    def ms(xs: list[float]) -> float:
        return 1e3 * float(np.median(xs)) if xs else float("nan")

    return {
        "cue_accuracy_realistic": real["accuracy"] / max(ideal["accuracy"], 1e-12),
        "cue_accuracy_realistic_raw": real["accuracy"],
        "cue_accuracy_ideal_raw": ideal["accuracy"],
        "cue_latency_ms": ms(real["onset_s"]),
        "cue_latency_ideal_ms": ms(ideal["onset_s"]),
        "cue_latency_p90_ms": (1e3 * float(np.quantile(real["onset_s"], 0.9))
                               if real["onset_s"] else float("nan")),
        "cue_release_ms": ms(real["release_s"]),
        "cue_release_ideal_ms": ms(ideal["release_s"]),
        "cue_missed_realistic": int(n - len(real["release_s"])),
        "cue_missed_ideal": int(n - len(ideal["release_s"])),
        "cue_pushes_realistic": n,
    }


def repeated_push_recall(n: int = 20, peak_n: tuple[float, float] = (12.0, 15.0),
                         duration_s: float = 0.6, rest_s: float = 0.5,
                         seed: int = 0) -> dict[str, Any]:
    """``n`` pushes (peak ``U[peak_n]``, ``duration_s`` half-sine, a random sector each) on a
    fresh physical base with realistic sensing standing at ``simple``'s (3, 3), ``rest_s``
    of rest before each: the recall (share detected in the intended sector) and the largest
    on-threshold the detector used (a detector that learns pushes as noise goes deaf)."""
    from ...geometry.grid import ACTION_ANGLES
    from ...sim.force_cue import HumanPush, PushProfile

    world = cached_world("simple")
    base = physical_base(world, seed=seed)
    home = world.cell((3, 3))
    base.reset(home)
    rng = np.random.default_rng(seed)
    hits, on = 0, []
    for _ in range(n):
        base.hold(rest_s)
        h = int(rng.integers(8))
        prof = PushProfile(peak_n=float(rng.uniform(*peak_n)), duration_s=duration_s)
        cue = base.receive_push(HumanPush(float(ACTION_ANGLES[h]), 0.0, prof, h))
        hits += cue is not None and cue.heading == h
        on.append(float(base.sensing.detector.on_n))
        base.move_to(home)
    return {"recall": hits / n, "on_n_max": max(on)}


def resting_hand_push(hand_n: float = 6.0, hand_s: float = 3.0, push_n: float = 25.0,
                      heading: int = 2, hand_heading: int = 2, seed: int = 0) -> list:
    """A hand resting on the handle (a constant ``hand_n`` toward ``hand_heading`` from 0.3 s
    after reset, kept on) and after ``hand_s`` a 0.3 s half-sine ``push_n`` push toward
    ``heading``, on a physical base with realistic sensing: the headings of the cues felt
    from the push's onset to 1.2 s after it."""
    from ...geometry.grid import ACTION_ANGLES
    from ...sim.force_cue import HumanPush, PushProfile

    world = cached_world("simple")
    base = physical_base(world, seed=seed)
    base.reset(world.cell((3, 3)))
    base.hold(0.3)
    a = float(ACTION_ANGLES[hand_heading])
    t0 = float(base.data.time)
    base.pushes = [SteadyPush(hand_n * np.array([np.cos(a), np.sin(a)]), t0, hand_s + 1.2)]
    while base.data.time < t0 + hand_s:
        base.substep()
    t1 = float(base.data.time)
    base.pushes.append(HumanPush(float(ACTION_ANGLES[heading]), t1,
                                 PushProfile(peak_n=push_n, duration_s=0.3), heading))
    got = []
    while base.data.time < t1 + 1.2:
        cue = base.substep()
        if cue is not None:
            got.append(cue.heading)
    return got


def cue_calibration(quick: bool = False) -> dict[str, Any]:
    """The detector stays calibrated (``cue_detector.FilteredCueDetector``): recall of 20
    repeated 12-15 N, 0.6 s pushes on a fresh base (seeds 0..k), and the share of 25 N
    pushes after a 6 N resting hand (3 s, every relative direction) felt once, in the right
    sector; the same after a 12 N hand leaning 10 s (above the onset threshold)."""
    seeds = range(2 if quick else 5)
    rep = [repeated_push_recall(seed=s) for s in seeds]
    trials = [(s, r) for s in seeds for r in range(8)]
    ok = sum(resting_hand_push(heading=2, hand_heading=(2 + r) % 8, seed=s) == [2]
             for s, r in trials)
    lean = sum(resting_hand_push(hand_n=12.0, hand_s=10.0, heading=2, hand_heading=(2 + r) % 8,
                                 seed=s) == [2] for s, r in trials)
    return {"cue_recall_repeated_15n": float(np.mean([r["recall"] for r in rep])),
            "cue_on_threshold_repeated_15n_max": max(r["on_n_max"] for r in rep),
            "cue_recall_after_resting_hand": ok / len(trials),
            "cue_recall_after_leaning_hand": lean / len(trials)}


def lean_probes(hand_n: float = 40.0, seed: int = 0) -> dict[str, Any]:
    """A ``hand_n`` lean held 10 s (:func:`resting_hand_push`), then a 25 N push east with the
    lean toward the same direction, 90 degrees off and opposite: the probes read as one cue
    east (``lean_40n_probes_read``, of 3)."""
    read = sum(resting_hand_push(hand_n=hand_n, hand_s=10.0, heading=2,
                                 hand_heading=(2 + r) % 8, seed=seed) == [2] for r in (0, 2, 4))
    return {f"lean_{hand_n:g}n_probes_read": read}


def noisy_pushes(noise_n: float, n: int = 40, peak_n: float = 30.0, seed: int = 0
                 ) -> dict[str, Any]:
    """``n`` pushes of ``peak_n`` (0.3 s half-sine, no heading noise, a random sector each,
    0.5 s of rest before each) on a standing physical base whose realistic sensor has
    ``noise_n`` of noise per axis: the recall (a cue in the intended sector within 1.3 s of
    the onset), the other cues felt, and the stuck cues: released by the detector's bound
    (``released``) or open since before a push at the end of its 1.3 s window."""
    from ...geometry.grid import ACTION_ANGLES
    from ...sim.cue_detector import DURATION
    from ...sim.force_cue import HumanPush, PushProfile

    world = cached_world("simple")
    base = physical_base(world, seed=seed, sensor_noise_n=noise_n)
    base.reset(world.cell((3, 3)))
    base.hold(1.0)
    det, rng = base.sensing.detector, np.random.default_rng(seed)
    hits = other = stuck = 0
    for _ in range(n):
        t_rest = float(base.data.time) + 0.5
        while base.data.time < t_rest:
            other += base.substep() is not None
        h = int(rng.integers(8))
        t0 = float(base.data.time)
        base.pushes = [HumanPush(float(ACTION_ANGLES[h]), t0,
                                 PushProfile(peak_n=peak_n, duration_s=0.3, noise_deg=0.0), h)]
        got = []
        while base.data.time < t0 + 1.3:
            cue = base.substep()
            if cue is not None:
                got.append(cue.heading)
        hits += h in got
        other += len(got) - (h in got)
        stuck += det.active and det.st[DURATION] > 1.3
        base.pushes = []
    return {"recall": hits / n, "other_cues": other, "stuck": stuck + det.released,
            "on_n": float(det.on_n)}


def noise_sweep(levels: tuple = (2.0, 5.0, 10.0, 20.0, 50.0), n: int = 40) -> dict[str, Any]:
    """:func:`noisy_pushes` at each noise level (N per axis): ``noise_10n_recall``, the
    recall at every level, the other cues and the stuck cues summed over the sweep
    (``noise_stuck_cues``, target 0)."""
    rows = {lv: noisy_pushes(lv, n) for lv in levels}
    out: dict[str, Any] = {f"noise_{lv:g}n_recall": r["recall"] for lv, r in rows.items()}
    out["noise_stuck_cues"] = int(sum(r["stuck"] for r in rows.values()))
    out["noise_other_cues"] = sum(r["other_cues"] for r in rows.values())
    out["noise_sweep_pushes"] = n
    return out


def pushes_while_driving(pushes: list[tuple], sensor_model=None, seed: int = 0) -> dict:
    """Pushes at random moments of motion: for each push of :func:`realistic_pushes` the base
    (pushes at any time: splitting detector, admittance, stop on a cue) starts driving to the
    push's cell, and the push begins ``U[0.05, 0.6]`` s into the move (accelerating,
    cruising or braking). Hits (the felt cue's sector = intended; the first cue felt after
    the onset), latencies (onset to first felt), and misses."""
    from ...sim.force_cue import HumanPush
    from ...sim.mobile_base import MobileBase

    world = cached_world("simple")
    base = MobileBase(scene_for(world), sensor_model=sensor_model,
                      rng=np.random.default_rng(seed + 1))
    base.enable_pushes_any_time()
    base.reset(world.cell((3, 3)))
    base.hold(0.5)
    rng = np.random.default_rng(seed + 2)
    hits, onset, speeds = [], [], []
    for cell, h, angle, profile in pushes:
        if cell == base.cell:
            cell = int(world.motion.next_cell[cell, int(np.flatnonzero(
                ~world.motion.blocked[cell])[0])])
        t0 = float(base.data.time) + float(rng.uniform(0.05, 0.6))
        base.pushes.append(HumanPush(angle, t0, profile, h))
        n0 = len(base.felt)
        base.target = base.scene.cell_centre(cell)
        t_end = t0 + profile.duration_s + 1.0
        while base.data.time < t_end and len(base.felt) == n0:
            base.substep()
            if abs(base.data.time - t0) < 0.5 * base.dt:
                speeds.append(float(np.linalg.norm(base.velocity)))
        felt = [f for f in base.felt[n0:] if f.t_felt >= t0 - 1e-9]
        hits.append(bool(felt) and felt[0].heading == h)
        if felt:
            onset.append(felt[0].t_felt - t0)
        base.hold(0.3)  # the push's tail and release
    return {"hits": hits, "onset_s": onset, "accuracy": float(np.mean(hits)) if hits else 0.0,
            "speed_at_onset_mps": speeds}


def cue_accuracy_while_driving(n: int = 200, seed: int = 0) -> dict[str, Any]:
    """:func:`pushes_while_driving` with the ideal sensor and with
    ``SensorModel.realistic()`` on the same pushes: accuracies and their ratio (the
    ``cue_accuracy_while_driving`` key), median latency, median speed at push onset."""
    from ...sim.sensing import SensorModel

    pushes = realistic_pushes(n, seed + 7)
    ideal = pushes_while_driving(pushes, None, seed)
    real = pushes_while_driving(pushes, SensorModel.realistic(), seed)
    return {
        "cue_accuracy_while_driving": real["accuracy"] / max(ideal["accuracy"], 1e-12),
        "cue_accuracy_while_driving_raw": real["accuracy"],
        "cue_accuracy_while_driving_ideal_raw": ideal["accuracy"],
        "cue_latency_while_driving_ms": 1e3 * float(np.median(real["onset_s"]))
        if real["onset_s"] else float("nan"),
        "push_onset_speed_mps": float(np.median(real["speed_at_onset_mps"]))
        if real["speed_at_onset_mps"] else float("nan"),
        "cue_pushes_while_driving": n,
    }


def two_pushes(gap_s: float = 0.02) -> dict[str, Any]:
    """Two 30 N, 0.3 s pushes, east then north, ``gap_s`` apart, on the driving base with
    pushes at any time: the felt cues' angles (degrees); two cues near 0 and 90 expected."""
    from ...sim.force_cue import HumanPush, PushProfile
    from ...sim.mobile_base import MobileBase

    world = cached_world("simple")
    base = MobileBase(scene_for(world))
    base.enable_pushes_any_time()
    base.stop_on_cue = False
    base.reset(world.cell((3, 3)))
    base.target = base.scene.cell_centre(world.cell((5, 3)))
    t0, prof = 0.3, PushProfile()
    base.pushes = [HumanPush(0.0, t0, prof, 2), HumanPush(np.pi / 2, t0 + 0.3 + gap_s, prof, 0)]
    while base.data.time < t0 + 1.2:
        base.substep()
    return {"two_push_cues": len(base.felt),
            "two_push_angles_deg": [round(float(np.degrees(f.angle)), 1)
                                    for f in base.felt]}


def physical_base(world, task: str = "navigate", sensor: str = "realistic",
                  kind: str = "holonomic", seed: int = 0, **fields):
    """A base as a physical episode builds it (``Physics()`` defaults, the sensor preset
    ``sensor``, base ``kind``, other flat fields ``fields``, e.g. ``sensor_noise_n`` or
    ``robot_model``): the body's own construction, not a copy of it."""
    import dataclasses

    from ...episode import Physics
    from ...sim.body import MujocoBody

    ph = Physics.of(sensor=sensor, base=kind, **fields)
    spec = EpisodeSpec.single(world.name, "path_preference", 5, sim="mujoco", robot=task,
                              physics=ph.to_json())
    spec = dataclasses.replace(spec, map=world.name)
    return MujocoBody(world, spec, np.random.default_rng(seed)).base


class SteadyPush:
    """A constant horizontal force ``f`` (N, world x-y) from ``t0`` for ``duration_s``."""

    def __init__(self, f, t0: float, duration_s: float):
        from ...sim.force_cue import PushProfile

        self.f, self.t0 = np.array([f[0], f[1], 0.0]), t0
        self.profile = PushProfile(peak_n=float(np.hypot(*f)), duration_s=duration_s)

    def active(self, t: float) -> bool:
        """Whether the force acts at ``t``."""
        return self.t0 <= t <= self.t0 + self.profile.duration_s

    def force(self, t: float) -> np.ndarray:
        """The force at ``t`` (N, 3)."""
        return self.f if self.active(t) else np.zeros(3)


def runaway(force_n: float = 130.0, seconds: float = 3.0, physical: bool = True,
            any_time: bool = False, sensor: str = "realistic") -> dict[str, float]:
    """A push above the drive's 120 N limit (``force_n`` east for ``seconds``) on the standing
    base at cell (1, 3) of ``simple``: the largest displacement (m) and the distance from the
    start 3 s after the push ended (the recovery; the base holds its cell). ``physical``: the
    physical base (else the original one); ``any_time``: pushes sensed at any time, the base
    not stopping on a cue."""
    from ...sim.body import scene_for as scene

    world = cached_world("simple")
    if physical:
        base = physical_base(world, sensor=sensor)
        if any_time:
            base.enable_pushes_any_time()
            base.stop_on_cue = False
    else:
        from ...sim.mobile_base import MobileBase

        base = MobileBase(scene(world))
    base.reset(world.cell((1, 3)))
    base.hold(0.3)
    p0 = base.position.copy()
    base.pushes = [SteadyPush((force_n, 0.0), float(base.data.time), seconds)]
    worst = 0.0
    t_end = base.data.time + seconds + 3.0
    while base.data.time < t_end:
        base.substep()
        worst = max(worst, float(np.linalg.norm(base.position - p0)))
    return {"runaway_m": worst, "runaway_recovered_m": float(np.linalg.norm(base.position - p0))}


def carry_drift(force_n: float = 30.0, seconds: float = 3.0, physical: bool = True
                ) -> dict[str, float]:
    """A sustained push on the tray, north and then south (``force_n`` for ``seconds``) on the
    standing ``carry`` robot: the base's largest displacement *against* the push (mm; the
    ``carry_drift_mm`` key, the worse direction) and along it."""
    from ...sim.arm import ArmBase
    from ...sim.body import scene_for as scene

    world = cached_world("simple")
    against, along = [], []
    for sign in (1.0, -1.0):
        base = physical_base(world, task="carry") if physical else \
            ArmBase(scene(world, 0.5, "carry"))
        base.reset(world.cell((3, 3)))
        base.hold(0.2)
        p0, u = base.position.copy(), np.array([0.0, sign])
        base.pushes = [SteadyPush(force_n * u, float(base.data.time), seconds)]
        worst, most = 0.0, 0.0
        while base.data.time < base.pushes[0].t0 + seconds:
            base.substep()
            d = float((base.position - p0) @ u)
            worst, most = max(worst, -d), max(most, d)
        against.append(1e3 * worst)
        along.append(1e3 * most)
    return {"carry_drift_mm": max(against), "carry_yield_mm": max(along)}


#: the distances (m) within which :func:`tray_push` times the tray's return: 10 mm (the
#: ``recovery_s`` keys) and 1 mm (``recovery_1mm_s``; a push whose peak stays under 10 mm is
#: "back" at the first step after the release by the first, never by the second)
RECOVERY_M = (0.010, 0.001)


def tray_push(force_n: float = 30.0, seconds: float = 3.0, shape: str = "steady",
              headings: tuple[int, ...] = (0, 2, 4, 6), after_s: float = 4.0,
              stiffness: float | None = None, robot_model: str = "disk"
              ) -> dict[str, float]:
    """A push on the tray of the standing physical ``carry`` robot ``robot_model`` (the body
    ``--robot carry --robot-model`` runs in episodes) at ``simple``'s (3, 3) (``steady``: a
    constant ``force_n`` for ``seconds``; ``half_sine``: the simulated human's pulse of that
    peak and duration), toward each of ``headings`` (default north, east, south and west: the
    Jaco's weak plane is east-west at its carrying posture, north-south at the earlier one;
    a diagonal gave way 1.0 mm more than the worst of these at 30 N, 1.8 mm at 60 N): the
    tray's largest distance from where it stood before the push (mm), its largest
    tilt (degrees), and the time from the release until it is back within 10 mm
    (``recovery_s``) and within 1 mm (``recovery_1mm_s``) of that place for good (s;
    ``after_s`` when it never is); the worst heading each. ``stiffness``: the arm's tray
    stiffness (N/m; None: ``arm.TRAY_STIFFNESS``)."""
    from ...geometry.grid import ACTION_ANGLES
    from ...sim.arm import tilt_deg
    from ...sim.force_cue import HumanPush, PushProfile

    world = cached_world("simple")
    dev, tilt, rec = [], [], {r: [] for r in RECOVERY_M}
    for h in headings:
        base = physical_base(world, task="carry", robot_model=robot_model)
        if stiffness is not None:
            base.stiffness = float(stiffness)
        base.reset(world.cell((3, 3)))
        base.hold(0.5)
        p0, t0 = base.end_effector.copy(), float(base.data.time)
        a = float(ACTION_ANGLES[h])
        if shape == "steady":
            push = SteadyPush(force_n * np.array([np.cos(a), np.sin(a)]), t0, seconds)
        else:
            push = HumanPush(a, t0, PushProfile(peak_n=force_n, duration_s=seconds), h)
        base.pushes = [push]
        worst, most = 0.0, 0.0
        back: dict[float, float | None] = dict.fromkeys(RECOVERY_M)
        while base.data.time < t0 + seconds + after_s:
            base.substep()
            e = float(np.linalg.norm(base.end_effector - p0))
            worst, most = max(worst, e), max(most, tilt_deg(base.data, base.tray))
            if base.data.time > t0 + seconds:
                for r in RECOVERY_M:
                    if e > r:
                        back[r] = None
                    elif back[r] is None:
                        back[r] = float(base.data.time) - t0 - seconds
        dev.append(1e3 * worst)
        tilt.append(most)
        for r in RECOVERY_M:
            rec[r].append(after_s if back[r] is None else back[r])
    return {"deviation_mm": max(dev), "tilt_deg": max(tilt),
            "recovery_s": max(rec[RECOVERY_M[0]]), "recovery_1mm_s": max(rec[RECOVERY_M[1]])}


def tray_compliance(quick: bool = False) -> dict[str, float]:
    """The ``arm`` bench's compliance keys (:func:`tray_push`): a 30 N push for 3 s and the
    default human's largest push (60 N, 0.6 s half-sine)."""
    s30 = tray_push(30.0, 3.0)
    s60 = tray_push(60.0, 0.6, shape="half_sine")
    return {"tray_deviation_30n_3s_mm": s30["deviation_mm"],
            "tray_recovery_s": s30["recovery_s"],
            "tray_recovery_1mm_s": s30["recovery_1mm_s"],
            "tray_tilt_30n_deg": s30["tilt_deg"],
            "tray_deviation_60n_mm": s60["deviation_mm"],
            "tray_recovery_60n_s": s60["recovery_s"],
            "tray_tilt_60n_deg": s60["tilt_deg"]}


def carry_moves(n: int = 30, seed: int = 0, physical: bool = True) -> dict[str, float]:
    """``n`` random legal one-cell moves of the ``carry`` robot on ``simple``: the overshoot
    of each (mm past the target along the move, 0 when it never passes it), the deepest
    arm/obstacle penetration (every physics step in physical mode), peak base acceleration."""
    from ...sim.arm import ArmBase
    from ...sim.body import scene_for as scene

    world = cached_world("simple")
    base = physical_base(world, task="carry") if physical else \
        ArmBase(scene(world, 0.5, "carry"))
    base.reset(world.cell((3, 3)))
    rng, over = np.random.default_rng(seed), []
    for _ in range(n):
        s = base.cell
        moves = np.flatnonzero(~world.motion.blocked[s])
        tgt = base.scene.cell_centre(int(world.motion.next_cell[s, rng.choice(moves)]))
        u = tgt - base.position
        u = u / max(float(np.linalg.norm(u)), 1e-9)
        worst = 0.0

        def watch(b, _push, tgt=tgt, u=u):
            nonlocal worst
            worst = max(worst, float((b.position - tgt) @ u))

        base.on_substep.append(watch)
        base.move_to(base.scene.cell_at(tgt))
        base.on_substep.remove(watch)
        over.append(1e3 * worst)
    return {"carry_overshoot_mm": float(np.median(over)),
            "carry_overshoot_max_mm": float(max(over)),
            "carry_moves_penetration_mm": 1e3 * base.deepest,
            "carry_base_peak_accel": base.measurements.peak_accel}


def hard_driving(base, seconds: float, rng: np.random.Generator) -> list:
    """Drive ``base`` hard for ``seconds`` of simulated time: an aggressive controller (gain
    8, 1 m/s: the actuators saturate at 120 N, about 10 m/s^2) whose target jumps every
    U[0.2, 1.0] s to a random legal neighbour of the current cell (hard starts, braking and
    reversals). Returns the cues detected (all false: nobody pushes)."""
    from ...sim.controller import TrackingController

    world = base.scene.world
    base.controller = TrackingController(kp=8.0, v_max=1.0)
    cues, t_end = [], base.data.time + seconds
    while base.data.time < t_end:
        s = base.cell
        moves = np.flatnonzero(~world.motion.blocked[s])
        base.target = base.scene.cell_centre(int(world.motion.next_cell[s, rng.choice(moves)]))
        t_switch = base.data.time + rng.uniform(0.2, 1.0)
        while base.data.time < min(t_switch, t_end):
            cue = base.substep()
            if cue is not None:
                cues.append(cue)
    return cues


def false_cues_realistic(seconds: float = 1000.0, seed: int = 0, sensor_model=None,
                         estimator=None) -> tuple[int, float, float]:
    """False cues during :func:`hard_driving` on ``office`` with ``sensor_model`` (default
    ``SensorModel.realistic()``): count, simulated seconds, peak |push estimate| (N)."""
    from ...sim.mobile_base import MobileBase
    from ...sim.sensing import SensorModel

    world = cached_world("office")
    model = SensorModel.realistic() if sensor_model is None else sensor_model
    base = MobileBase(scene_for(world), sensor_model=model, rng=np.random.default_rng(seed + 1),
                      estimator=estimator)
    base.reset(world.cell((1, 1)))
    peak = [0.0]

    def watch(b, _push):
        s = b.sensing
        f = s.force_estimate if s.sensor_model is not None else s.sensor.force_xy(b.data)
        peak[0] = max(peak[0], float(np.hypot(f[0], f[1])))

    base.on_substep.append(watch)
    t0 = base.data.time
    cues = hard_driving(base, seconds, np.random.default_rng(seed))
    return len(cues), float(base.data.time - t0), peak[0]


def false_cues_physical(seconds: float = 1000.0, seed: int = 0) -> tuple[int, float]:
    """False cues of the physical base with realistic sensing and pushes at any time (the
    splitting detector, admittance) during :func:`hard_driving` on ``office`` (targets jumping
    every 0.2-1 s; the 120 N drive saturates, 0.89 m/s^2 on 135 kg): count, simulated s."""
    world = cached_world("office")
    base = physical_base(world, seed=seed + 1)
    base.enable_pushes_any_time()
    base.stop_on_cue = False
    base.reset(world.cell((1, 1)))
    t0 = base.data.time
    hard_driving(base, seconds, np.random.default_rng(seed))
    return len(base.felt), float(base.data.time - t0)


def render_fps(width: int = 640, height: int = 480, frames: int = 60) -> float:
    """Frames per second of the top view of ``simple`` (one bare view, no overlay, no episode;
    ``render_fps_video`` times what a video frame costs)."""
    import mujoco

    from ...sim.render import make_renderer

    scene = scene_for(cached_world("simple"))
    data = mujoco.MjData(scene.model)
    mujoco.mj_forward(scene.model, data)
    r = make_renderer(scene.model, height, width)
    r.update_scene(data, camera="top")
    r.render()
    t = time.perf_counter()
    for _ in range(frames):
        r.update_scene(data, camera="top")
        r.render()
    fps = frames / (time.perf_counter() - t)
    r.close()
    return fps


def render_fps_video(width: int = 960, height: int = 540, frames: int = 60) -> float:
    """Frames per second of the real video path of ``pathpref render``: both views with every
    overlay, the info panel, composition and H.264 encoding (``FrameMaker.frame`` and
    ``VideoWriter.append``), on an episode of ``simple`` moving between frames (the physics
    and planning between frames are not timed)."""
    import tempfile
    from pathlib import Path

    from ...episode import EpisodeRunner, EpisodeSpec, simulator_rng
    from ...sim.body import MujocoBody
    from ...sim.render import VideoWriter
    from ..rollout import FrameMaker

    spec = EpisodeSpec.single("simple", "goal_only", 3, seed=0, sim="mujoco", queries=50)
    world = cached_world("simple")
    body = MujocoBody(world, spec, simulator_rng(spec))
    maker = FrameMaker(world, body, spec, width, height)
    runner = EpisodeRunner(spec, world, body)
    maker.attach(runner)
    body.base.on_substep.append(maker.track)
    runner.begin()
    spent, made = 0.0, 0
    with tempfile.TemporaryDirectory() as tmp:
        writer = VideoWriter(Path(tmp) / "bench.mp4")
        while made < frames:
            if runner.done:
                break
            runner.step()
            for _ in range(min(5, frames - made)):
                t = time.perf_counter()
                writer.append(maker.frame(body.base, None))
                spent += time.perf_counter() - t
                made += 1
        writer.close()
    maker.close()
    return made / spent


def bare_step_us(model, data, steps: int = 2000, repeats: int = 3,
                 clock=time.perf_counter) -> float:
    """Microseconds of one bare ``mj_step`` of ``model`` from ``data``'s state (a copy; no
    Python between the steps but the loop's), the best of ``repeats`` runs of ``steps``, on
    ``clock`` (wall time; ``time.process_time``: the process's CPU time)."""
    import mujoco

    best = float("inf")
    for _ in range(repeats):
        d = copy.copy(data)
        t = clock()
        for _ in range(steps):
            mujoco.mj_step(model, d)
        best = min(best, clock() - t)
    return 1e6 * best / steps


@contextlib.contextmanager
def timed_phases(spent: list[float]):
    """While the context lasts, the wall time of every decision-step phase run to completion
    (:meth:`~pathpref.sim.decision.DecisionStep.run`: the physics steps and their Python) is
    added to ``spent[0]``."""
    from ...sim.decision import DecisionStep

    run = DecisionStep.run

    def timed(self):
        t = time.perf_counter()
        try:
            return run(self)
        finally:
            spent[0] += time.perf_counter() - t

    DecisionStep.run = timed
    try:
        yield spent
    finally:
        DecisionStep.run = run


def episodes_vs_bare(physics, episodes: int, robot: str = "navigate"
                     ) -> tuple[list, list, list]:
    """Per episode of ``physics`` (simple, path preference, ΔT 5, ``T_max`` 30, ``robot``): the
    ratio ``T / (T - T_phys + N b)`` of :func:`physics_overhead`, the Python per physics step
    ``T_phys / N - b`` (us) and ``b`` (us)."""
    from ... import sim  # noqa: F401 - registers the MuJoCo body
    from ...episode.runner import EpisodeRunner

    ratios, python_us, bare = [], [], []
    physics = physics.to_json()
    run_episode(EpisodeSpec.single("simple", "path_preference", 5, seed=11, sim="mujoco",
                                   t_max=3, physics=physics, robot=robot))  # compile
    for i in range(episodes):
        spec = EpisodeSpec.single("simple", "path_preference", 5, seed=11, instance=i,
                                  sim="mujoco", t_max=30, physics=physics, robot=robot)
        runner = EpisodeRunner(spec)
        base = runner.body.base
        b = bare_step_us(base.model, base.data)
        spent = [0.0]
        with timed_phases(spent):
            t = time.perf_counter()
            while not runner.done:
                runner.step()
            wall = time.perf_counter() - t
        n = round(float(base.data.time) / base.dt)
        ratios.append(wall / (wall - spent[0] + n * b * 1e-6))
        python_us.append(1e6 * spent[0] / n - b)
        bare.append(b)
    return ratios, python_us, bare


def guided_push(task: str = "carry", force_n: float = 25.0, seconds: float = 2.0,
                after_s: float = 1.0) -> float:
    """A steady push of ``force_n`` east for ``seconds`` on the standing robot of ``task`` under
    guidance (``Physics.of(timing="guidance")``: the body's own construction and
    :meth:`~pathpref.sim.body.MujocoBody.enable_guidance`) at ``simple``'s (3, 3): the base's
    largest displacement (m) until ``after_s`` past the release. For ``carry`` the push is
    on the tray: the arm's impedance takes it and the base's guidance admittance follows
    (``guidance_carry_push_displacement_m``)."""
    from ...episode import Physics
    from ...sim.body import MujocoBody

    world = cached_world("simple")
    spec = EpisodeSpec.single(world.name, "path_preference", 5, sim="mujoco", robot=task,
                              physics=Physics.of(timing="guidance").to_json())
    body = MujocoBody(world, spec, np.random.default_rng(0))
    body.enable_guidance()
    base = body.base
    base.reset(world.cell((3, 3)))
    base.hold(0.3)
    p0, t0 = base.position.copy(), float(base.data.time)
    base.pushes = [SteadyPush((force_n, 0.0), t0, seconds)]
    worst = 0.0
    while base.data.time < t0 + seconds + after_s:
        base.substep()
        worst = max(worst, float(np.linalg.norm(base.position - p0)))
    return worst


def guidance_overhead(episodes: int = 3) -> dict[str, float]:
    """``guidance_episode_vs_bare``: a guided episode (``timing`` guidance, the closed-loop
    person) against bare MuJoCo plus planning, as :func:`physics_overhead` measures the
    default episode (median over ``episodes``); ``guidance_python_us_per_step``."""
    from ...episode import Physics

    ratios, python_us, _ = episodes_vs_bare(Physics.of(timing="guidance"), episodes)
    return {"guidance_episode_vs_bare": median(ratios),
            "guidance_python_us_per_step": median(python_us)}


def carry_overhead(episodes: int = 3) -> dict[str, float]:
    """``carry_episode_vs_bare``: a physical ``carry`` episode (``Physics()``) against bare
    MuJoCo plus planning on its own scene, as :func:`physics_overhead` measures the default
    episode (median over ``episodes``); ``carry_python_us_per_step``."""
    from ...episode import Physics

    ratios, python_us, _ = episodes_vs_bare(Physics(), episodes, robot="carry")
    return {"carry_episode_vs_bare": median(ratios),
            "carry_python_us_per_step": median(python_us)}


def physics_overhead(episodes: int = 5) -> dict[str, float]:
    """The Python cost of the physics step, on the ``episode_s`` episodes (``Physics()``).

    An episode of wall time ``T`` spends ``T_phys`` in its ``N`` physics steps and the rest,
    ``T - T_phys``, in planning and bookkeeping; with ``b`` the bare ``mj_step`` time of its
    scene (:func:`bare_step_us`), ``overhead_vs_bare_mujoco = T / (T - T_phys + N b)``: the
    episode against bare MuJoCo plus planning (1 when the step has no Python), and
    ``python_us_per_step = T_phys / N - b``; medians over the episodes.
    ``overhead_vs_bare_mujoco_control``: ``navigate_control`` (``Physics()``, random velocity
    commands at 50 Hz, resets excluded) against ``b`` per physics step of its steps, also
    under the name ``navigate_control_vs_bare``; ``navigate_control_vs_bare_cpu`` the same
    ratio of CPU times (the process's, ``time.process_time``, both sides in the same run)."""
    from ...episode import Physics

    ratios, python_us, bare = episodes_vs_bare(Physics(), episodes)
    from pathpref_tasks import load

    env = load("navigate_control", task_kwargs={"map": "simple", "method": "goal_only",
                                                "seed": 0, "queries": 50})
    env.reset()
    base = env.task.base
    b = bare_step_us(base.model, base.data)
    b_cpu = bare_step_us(base.model, base.data, clock=time.process_time)
    spec, rng = env.action_spec(), np.random.default_rng(0)
    spent, spent_cpu, steps = 0.0, 0.0, 0
    for a in rng.uniform(spec.minimum, spec.maximum, size=(500, *spec.shape)):
        t0, t, c = float(base.data.time), time.perf_counter(), time.process_time()
        last = env.step(a).last()
        spent += time.perf_counter() - t
        spent_cpu += time.process_time() - c
        steps += round((float(base.data.time) - t0) / base.dt)
        if last:
            env.reset()
            base = env.task.base
    control = spent / (steps * b * 1e-6)
    return {"overhead_vs_bare_mujoco": median(ratios),
            "python_us_per_step": median(python_us),
            "bare_step_us": median(bare),
            "overhead_vs_bare_mujoco_control": control,
            "navigate_control_vs_bare": control,
            "navigate_control_vs_bare_cpu": spent_cpu / (steps * b_cpu * 1e-6)}


def bench_physics(quick: bool = False) -> dict[str, Any]:
    """Cue detection (with and without heading noise), false cues, episode time, rendering;
    the same with realistic sensing (``*_realistic``, :func:`cue_accuracy_realistic`,
    :func:`false_cues_realistic`; ``docs/sensing.md``)."""
    from ...episode import Physics

    n_push = 50 if quick else 200
    secs = 100.0 if quick else 1000.0
    n_cues, sim_s = false_cues(secs)
    legacy_times, times, accel, accel_dd = [], [], [], []
    for i in range(2 if quick else 5):
        for physics, out in (("", legacy_times), (Physics().to_json(), times)):
            spec = EpisodeSpec.single("simple", "path_preference", 5, seed=11, instance=i,
                                      sim="mujoco", t_max=30, physics=physics)
            t = time.perf_counter()
            res = run_episode(spec)
            out.append(time.perf_counter() - t)
            if physics:
                accel.append(res.metrics["base_peak_accel"])
        spec = EpisodeSpec.single("simple", "path_preference", 5, seed=11, instance=i,
                                  sim="mujoco", t_max=30,
                                  physics=Physics.of(base="diffdrive",
                                                  timing="interval").to_json())
        accel_dd.append(run_episode(spec).metrics["base_peak_accel"])
    from ...sim.estimator import EstimatorConfig
    from ...sim.sensing import SensorModel

    drive = 120.0 if quick else 1000.0
    n_real, real_s, real_peak = false_cues_realistic(drive)
    n_unc, unc_s, unc_peak = false_cues_realistic(
        drive, estimator=EstimatorConfig(compensate_inertia=False))
    inertia_only = SensorModel(extra_mass_kg=0.4)  # no noise, no bias: the inertia alone
    _, _, raw_peak = false_cues_realistic(30.0, sensor_model=inertia_only,
                                          estimator=EstimatorConfig(compensate_inertia=False))
    _, _, comp_peak = false_cues_realistic(30.0, sensor_model=inertia_only)
    return {
        **cue_accuracy_realistic(100 if quick else 400),
        **cue_accuracy_while_driving(60 if quick else 200),
        **two_pushes(),
        **cue_calibration(quick),
        **lean_probes(40.0),
        **noise_sweep(n=20 if quick else 40),
        "false_cues_per_hour_realistic": n_real / real_s * 3600.0,
        "false_cue_drive_realistic_s": real_s,
        "force_estimate_peak_driving_n": real_peak,
        "false_cues_per_hour_realistic_uncompensated": n_unc / unc_s * 3600.0,
        "force_estimate_peak_driving_uncompensated_n": unc_peak,
        "inertia_peak_raw_n": raw_peak,
        "inertia_peak_compensated_n": comp_peak,
        "cue_sector_accuracy": cue_accuracy(n_push, 10.0),
        "cue_sector_accuracy_no_noise": cue_accuracy(n_push, 0.0),
        "cue_pushes": n_push,
        "false_cues_per_hour": n_cues / sim_s * 3600.0,
        "false_cue_drive_s": sim_s,
        **runaway(),
        "false_cues_per_hour_physical": (lambda n_s: n_s[0] / n_s[1] * 3600.0)(
            false_cues_physical(120.0 if quick else 1000.0)),
        "runaway_legacy_m": runaway(physical=False)["runaway_m"],
        "base_peak_accel": max(accel),
        "base_peak_accel_diffdrive": max(accel_dd),
        "base_accel_limit": 1.0,  # Clearpath Ridgeback, ridgeback_control/config/control.yaml
        "episode_s": median(times),  # Physics() defaults: realistic sensing, physical base
        "episode_max_s": max(times),
        "episode_legacy_s": median(legacy_times),
        "render_fps": render_fps(frames=20 if quick else 60),
        "render_fps_video": render_fps_video(frames=20 if quick else 60),
        **physics_overhead(2 if quick else 5),
        **guidance_overhead(1 if quick else 3),
        "guidance_carry_push_displacement_m": guided_push("carry"),
        "guidance_navigate_push_displacement_m": guided_push("navigate"),
    }


def bench_arm(quick: bool = False) -> dict[str, Any]:
    """IK rate, tray tilt over pushed episodes, detection through the end-effector."""
    from ...sim.arm import ArmBase
    from ...sim.force_cue import HumanPush, PushProfile

    world = cached_world("simple")
    arm = ArmBase(scene_for(world, 0.5, "carry"))
    arm.reset(world.cell((3, 3)))
    n = 200 if quick else 1000
    t = time.perf_counter()
    for _ in range(n):
        arm.solve_ik()
    ik_rate = n / (time.perf_counter() - t)
    rng = np.random.default_rng(0)
    pushes, hits = (40 if quick else 200), 0
    for _ in range(pushes):
        h = int(rng.integers(8))
        cue = arm.receive_push(HumanPush.sample(h, 0.0, PushProfile(), rng))
        hits += cue is not None and cue.heading == h
        arm.move_to(arm.cell)
    from ...episode import Physics

    tilts, pens, times, legacy_pens, tips = [], [], [], [], []
    for i in range(2 if quick else 5):
        spec = EpisodeSpec.single("simple", "path_preference", 3, seed=13, instance=i,
                                  sim="mujoco", robot="carry")
        t = time.perf_counter()
        res = run_episode(spec)
        times.append(time.perf_counter() - t)
        tilts.append(res.metrics["tilt_rms_deg"])
        legacy_pens.append(res.metrics["max_penetration_mm"])
        phys = run_episode(EpisodeSpec.single("simple", "path_preference", 3, seed=13,
                                              instance=i, sim="mujoco", robot="carry",
                                              physics=Physics().to_json()))
        pens.append(phys.metrics["max_penetration_mm"])  # every physics step
        tips.append(phys.metrics["tip_margin"])
    return {
        **tray_compliance(quick),
        **carry_drift(),
        "carry_drift_legacy_mm": carry_drift(physical=False)["carry_drift_mm"],
        **carry_moves(20 if quick else 60),
        "carry_overshoot_legacy_mm": carry_moves(20 if quick else 60,
                                                 physical=False)["carry_overshoot_mm"],
        **carry_overhead(1 if quick else 3),
        "max_penetration_mm_move_ends": max(legacy_pens),
        "tip_margin_min": min(tips),
        "ik_solves_per_s": ik_rate,
        "cue_sector_accuracy": hits / pushes,
        "cue_pushes": pushes,
        "tilt_rms_deg": max(tilts),
        "tilt_rms_deg_mean": float(np.mean(tilts)),
        "max_penetration_mm": max(pens),
        "episode_s": median(times),
    }


