"""Train PPO (stable-baselines3) on ``pathpref/Navigate-v1`` over generated floor plans and
evaluate it on held-out instances of those plans and on built-in maps it never saw.

One action is one decision (a move to a grid neighbour, or stay) while the simulated human
pushes the handle at every decision (``delta_t=1``); the reward is the ``-v1`` ids' (the
person's route is its optimum, a violation of their preference ends the episode:
``pathpref_tasks.route_reward``, ``docs/tasks.md``). The observations have the same spaces on
every map (``pathpref_tasks.gym_v1``), so one agent runs on all of them; it reads
:data:`AGENT_KEYS` (the detected push, the belief's likeliest exits of the current polytope and
their directions, the expected goal direction, the occupancy around the base, the time left)::

    pip install "pathpref[rl]"          # stable-baselines3, torch, moviepy
    MUJOCO_GL=egl nice -n 10 python examples/train_ppo.py --out ppo_out --seed 0 --steps 6000

Training episodes are drawn round the :data:`TRAIN_PLANS` generated plans
(:func:`pathpref.geometry.generate.floor_plan`, 24 x 16 cells, a preferred route through four
waypoints; a random plan per episode), each plan's episodes from its own seed, with the
consistent person (``--human``: their route leads to the true goal); training stops
after ``--steps`` environment steps (decisions), whatever the CPU time (``--cpu-minutes``,
off by default, adds a CPU cap as the earlier example had). Then the saved agent,
deterministic, is evaluated on ``--eval`` episodes of each of: held-out instances of the
training plans (seeds from :data:`EVAL_SEED`, never drawn in training) and each built-in map of
``--maps`` (never seen), with success and its Wilson 95% interval.

``ppo_out/``: ``curve.png`` (success and return of the training episodes against environment
steps), ``agent.zip`` (the model), ``summary.json``, ``episodes.json`` (the training episodes)
and ``video/`` (one held-out episode on ``office`` filmed by Gymnasium's ``RecordVideo``, which
needs moviepy: the ``rl`` extra). One JSON progress line is printed per rollout.

**torch and MuJoCo's EGL.** With the CUDA build of torch, importing torch (or triton) after a
MuJoCo EGL context exists has crashed the process (Mesa's EGL and triton); this script imports
torch first, before any environment, which is the order that works. The CPU-only wheel (no
triton) imports in any order on this project's machines. Without rendering,
``MUJOCO_GL=disable`` avoids GL altogether for training runs (``--video-size 0x0``).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import time
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

import torch  # noqa: E402,F401  # before any MuJoCo EGL context (module docstring)
from stable_baselines3 import PPO  # noqa: E402
from stable_baselines3.common.callbacks import BaseCallback  # noqa: E402

# isort: split
import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402
import pathpref_tasks  # noqa: E402,F401  # registers the Gymnasium ids
from pathpref_tasks.route_reward import DISCOUNT  # noqa: E402

from pathpref.errors import MapError  # noqa: E402
from pathpref.geometry.generate import floor_plan  # noqa: E402

ENV_ID = "pathpref/Navigate-v1"
#: the task: the person pushes at every decision, the paper's method for the belief the agent
#: observes (the map is each plan's), the consistent person (``--human``: the true goal is
#: one their route leads to; with the map's person most generated-plan instances cannot be
#: succeeded at all, so the agent would never see a success)
TASK = {"method": "path_preference", "delta_t": 1, "human": "consistent"}
#: the generated plans the agent trains on by default (seeds of ``floor_plan``, the first
#: ``--plans`` of them; a seed whose plan is too fragmented is skipped)
TRAIN_PLANS = tuple(range(16))
#: the observations the agent reads (of ``pathpref_tasks.gym_v1.PathprefEnvV1``)
AGENT_KEYS = ("heading", "detector_active", "goal_direction", "goal_entropy", "exit_probs",
              "exit_vectors", "local_occupancy", "time_left")
#: the episode metrics the learning curve and the summary keep
KEEP = ("success", "goal_reached", "violations", "pushes", "return", "steps")
#: the seed of the held-out evaluation episodes (each training plan's training episodes are
#: drawn from seed ``1000 * run seed + plan``: disjoint from it)
EVAL_SEED = 100_000


def cpu_seconds() -> float:
    """User and system CPU seconds of this process."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """The Wilson score interval of ``k`` successes in ``n`` trials (95% for ``z = 1.96``)."""
    if n == 0:
        return 0.0, 1.0
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)  # no -0.0 of rounding


def train_plans(n: int = len(TRAIN_PLANS)) -> list[dict]:
    """The map dictionaries of the first ``n`` of :data:`TRAIN_PLANS` (too fragmented ones
    left out)."""
    plans = []
    for seed in TRAIN_PLANS[:n]:
        try:
            plans.append(floor_plan(seed, name=f"plan{seed}"))
        except MapError:
            continue
    return plans


class AgentView(gym.ObservationWrapper):
    """The observations the agent reads (:data:`AGENT_KEYS`)."""

    def __init__(self, env: gym.Env):
        super().__init__(env)
        self.observation_space = gym.spaces.Dict(
            {k: env.observation_space[k] for k in AGENT_KEYS})

    def observation(self, observation):
        """The agent's keys of ``observation``."""
        return {k: observation[k] for k in AGENT_KEYS}


class PlanMix(gym.Env):
    """Episodes drawn round several environments of the same spaces (one per map): each
    ``reset`` picks one at random (``np.random.default_rng(seed)``) and starts its next
    episode; keeps each finished episode's metrics and the steps taken when it ended."""

    def __init__(self, envs: list[gym.Env], seed: int):
        self.envs = envs
        self.observation_space = envs[0].observation_space
        self.action_space = envs[0].action_space
        assert all(e.observation_space == self.observation_space for e in envs)
        self.rng = np.random.default_rng(seed)
        self.current = envs[0]
        self.episodes: list[dict] = []
        self.steps = 0
        self.started: set[int] = set()

    def reset(self, *, seed=None, options=None):
        """The next episode of a randomly drawn environment (its own episode sequence)."""
        super().reset(seed=seed)
        i = int(self.rng.integers(len(self.envs)))
        self.current = self.envs[i]
        return self.current.reset()

    def step(self, action):
        """The current environment's step; a finished episode's last ``info`` is kept."""
        obs, r, term, trunc, info = self.current.step(action)
        self.steps += 1
        if term or trunc:
            self.episodes.append({**{k: info[k] for k in KEEP}, "at_step": self.steps})
        return obs, r, term, trunc, info

    def close(self):
        """Close every environment."""
        for e in self.envs:
            e.close()


def make_env(map_, seed: int, **changes) -> gym.Env:
    """The agent's view of ``pathpref/Navigate-v1`` on ``map_`` (:data:`TASK` with
    ``changes``), its episodes those of the task's ``seed`` (``reset`` without a seed moves to
    the next one)."""
    return AgentView(gym.make(ENV_ID, map=map_, seed=seed, **{**TASK, **changes}))


class Progress(BaseCallback):
    """After each rollout prints one JSON line: steps, wall and CPU seconds, the success and
    mean return of the last 100 training episodes; stops training past ``cpu_limit_s`` of
    this process's CPU time (``--cpu-minutes``, off by default)."""

    def __init__(self, log: PlanMix, cpu_limit_s: float = math.inf):
        super().__init__()
        self.log = log
        self.t0 = time.monotonic()
        self.cpu_limit_s = cpu_limit_s

    def _on_step(self) -> bool:
        return cpu_seconds() < self.cpu_limit_s

    def _on_rollout_end(self) -> None:
        last = self.log.episodes[-100:]
        print(json.dumps({"steps": self.log.steps, "wall_s": round(time.monotonic() - self.t0),
                          "cpu_s": round(cpu_seconds(), 1), "episodes": len(self.log.episodes),
                          "success_last_100": float(np.mean([e["success"] for e in last]))
                          if last else None,
                          "return_last_100": round(float(np.mean([e["return"] for e in last])),
                                                   2) if last else None}), flush=True)


def run_episodes(model: PPO, env: gym.Env, n: int) -> list[dict]:
    """``n`` episodes of the deterministic agent on ``env`` (its next ``n``): their metrics."""
    out = []
    for _ in range(n):
        obs, _ = env.reset()
        for _ in range(10_000):  # the task's T_max ends it first
            obs, _, term, trunc, info = env.step(model.predict(obs, deterministic=True)[0])
            if term or trunc:
                break
        out.append({k: info[k] for k in KEEP})
    return out


def summarise(eps: list[dict]) -> dict:
    """Success (with its Wilson 95% interval), mean return and violations of ``eps``."""
    k = sum(bool(e["success"]) for e in eps)
    lo, hi = wilson(k, len(eps))
    return {"n": len(eps), "successes": k, "success": k / len(eps) if eps else None,
            "success_wilson95": [round(lo, 3), round(hi, 3)],
            "mean_return": round(float(np.mean([e["return"] for e in eps])), 2) if eps else None,
            "with_violation": sum(int(e["violations"]) > 0 for e in eps)}


def evaluate(model: PPO, plans: list[dict], maps: list[str], n: int) -> dict:
    """Held-out instances of the training plans (``n`` episodes round the plans, each plan's
    from :data:`EVAL_SEED`) and ``n`` episodes of each unseen built-in map, with the
    training person (``TASK["human"]``); when that is the consistent person, the maps also
    with the map's person (``"<map>:map_human"``: the paper's protocol, where the person's
    route may not lead to the true goal)."""
    envs = [make_env(p, EVAL_SEED) for p in plans]
    held = []
    for i in range(n):
        held += run_episodes(model, envs[i % len(envs)], 1)
    for e in envs:
        e.close()
    out = {"held_out_plans": summarise(held)}
    for m in maps:
        env = make_env(m, EVAL_SEED)
        out[m] = summarise(run_episodes(model, env, n))
        env.close()
        if TASK["human"] != "map":
            env = make_env(m, EVAL_SEED, human="map")
            out[f"{m}:map_human"] = summarise(run_episodes(model, env, n))
            env.close()
    return out


def film(model: PPO, folder: Path, width: int, height: int, map_: str = "office") -> None:
    """One held-out episode on ``map_`` filmed by Gymnasium's ``RecordVideo`` (moviepy)."""
    from gymnasium.wrappers import RecordVideo

    env = gym.make(ENV_ID, map=map_, seed=EVAL_SEED, render_mode="rgb_array", width=width,
                   height=height, **TASK)
    env = AgentView(RecordVideo(env, str(folder), name_prefix=f"agent-{map_}",
                                episode_trigger=lambda k: k == 0, disable_logger=True))
    obs, _ = env.reset(seed=EVAL_SEED)
    for _ in range(10_000):
        obs, _, term, trunc, _ = env.step(model.predict(obs, deterministic=True)[0])
        if term or trunc:
            break
    env.close()


def plot_curve(episodes: list[dict], path: Path, title: str, window: int = 50) -> None:
    """Success and return of the training episodes (running means over ``window``) against
    the environment steps at each episode's end."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    steps = np.array([e["at_step"] for e in episodes])
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(6, 5), dpi=120, sharex=True)
    for ax, key in ((ax1, "success"), (ax2, "return")):
        y = np.array([float(e[key]) for e in episodes])
        ax.plot(steps, y, ".", alpha=0.15)
        if len(y) >= window:
            ax.plot(steps[window - 1:], np.convolve(y, np.ones(window) / window, "valid"),
                    "-", label=f"mean of {window} episodes")
            ax.legend(loc="lower right")
        ax.set_ylabel(key)
    ax1.set_ylim(-0.05, 1.05)
    ax2.set_xlabel("environment steps (decisions)")
    ax1.set_title(title)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def main(argv: list[str] | None = None) -> dict:
    """Train, plot, evaluate, save and film (module docstring); the summary."""
    ap = argparse.ArgumentParser(description=" ".join(__doc__.split("\n\n")[0].split()))
    ap.add_argument("--out", default="ppo_out", help="output folder")
    ap.add_argument("--steps", type=int, default=6000,
                    help="environment steps (decisions) to train")
    ap.add_argument("--cpu-minutes", type=float, default=None,
                    help="also stop training after this much CPU time of the process (off by "
                    "default: the step budget alone makes runs comparable across machines)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--plans", type=int, default=len(TRAIN_PLANS),
                    help=f"generated plans to train on (1..{len(TRAIN_PLANS)})")
    ap.add_argument("--n-steps", type=int, default=128, help="PPO rollout length")
    ap.add_argument("--batch-size", type=int, default=64)
    ap.add_argument("--gamma", type=float, default=DISCOUNT,
                    help="discount (the -v1 reward's shaping discount by default)")
    ap.add_argument("--ent-coef", type=float, default=0.005, help="entropy bonus")
    ap.add_argument("--learning-rate", type=float, default=1e-3)
    ap.add_argument("--net", default="64,64", help="hidden layer sizes of policy and value")
    ap.add_argument("--human", choices=("consistent", "map"), default="consistent",
                    help="the person (as pathpref evaluate --human): consistent (pushes along "
                    "one route to the true goal) or map (the map's route, the paper's protocol)")
    ap.add_argument("--eval", type=int, default=50, help="evaluation episodes per set")
    ap.add_argument("--maps", default="simple,office",
                    help="built-in maps (never trained on) to evaluate on")
    ap.add_argument("--video-size", default="480x360", help="WxH of the filmed held-out "
                    "episode (0x0: no video)")
    args = ap.parse_args(argv)
    if not 64 <= args.steps <= 10_000_000:
        raise SystemExit(f"--steps must be in 64..10000000, got {args.steps}")
    if not 0 <= args.eval <= 100_000:
        raise SystemExit(f"--eval must be in 0..100000, got {args.eval}")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(1)  # the machine's cores are shared; the MLP is small
    if not 1 <= args.plans <= len(TRAIN_PLANS):
        raise SystemExit(f"--plans must be in 1..{len(TRAIN_PLANS)}, got {args.plans}")
    plans = train_plans(args.plans)
    # the task's gamma is the training discount: the shaping is exact for the agent's return
    TASK["gamma"] = args.gamma
    TASK["human"] = args.human
    env = PlanMix([make_env(p, 1000 * args.seed + i) for i, p in enumerate(plans)], args.seed)
    net = [int(v) for v in args.net.split(",")]
    model = PPO("MultiInputPolicy", env, n_steps=min(args.n_steps, args.steps),
                batch_size=args.batch_size, n_epochs=10, learning_rate=args.learning_rate,
                gamma=args.gamma, ent_coef=args.ent_coef, seed=args.seed,
                policy_kwargs={"net_arch": net}, device="cpu", verbose=0)
    cpu0, wall0 = cpu_seconds(), time.monotonic()
    limit = math.inf if args.cpu_minutes is None else cpu0 + 60.0 * args.cpu_minutes
    model.learn(total_timesteps=args.steps, callback=Progress(env, limit))
    train_cpu_s, train_wall_s = cpu_seconds() - cpu0, time.monotonic() - wall0
    model.save(out / "agent.zip")
    eps = env.episodes
    env.close()
    plot_curve(eps, out / "curve.png", f"PPO on {ENV_ID}, {len(plans)} generated plans, "
               f"seed {args.seed}")
    loaded = PPO.load(out / "agent.zip", device="cpu")  # what is evaluated is what was saved
    cpu1 = cpu_seconds()
    maps = [m for m in args.maps.split(",") if m]
    evaluation = evaluate(loaded, plans, maps, args.eval) if args.eval else {}
    summary = {
        "env": ENV_ID, "task": TASK, "agent_keys": AGENT_KEYS, "seed": args.seed,
        "train_plans": [p["name"] for p in plans], "steps": env.steps,
        "train_cpu_s": round(train_cpu_s, 1), "train_wall_s": round(train_wall_s, 1),
        "episodes": len(eps),
        "success_last_100_training": float(np.mean([e["success"] for e in eps[-100:]]))
        if eps else None,
        "eval": evaluation, "eval_cpu_s": round(cpu_seconds() - cpu1, 1)}
    vw, vh = (int(v) for v in args.video_size.lower().split("x"))
    if vw > 0 and vh > 0:
        film(loaded, out / "video", vw, vh)
        summary["video"] = sorted(p.name for p in (out / "video").glob("*.mp4"))
    (out / "summary.json").write_text(json.dumps(summary, indent=1))
    (out / "episodes.json").write_text(json.dumps(eps))
    print(json.dumps(summary))
    return summary


if __name__ == "__main__":
    main()
