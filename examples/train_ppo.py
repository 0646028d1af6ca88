"""Train PPO (stable-baselines3) on ``pathpref/Navigate-v0``: one action is one decision (a
move to a grid neighbour, or stay) while the simulated human pushes the handle at every
decision; the reward is the Gymnasium ids' loop-free one (the move cost, a stay costing as
much as a straight move, the person's preferred route as a potential, +50 at the goal:
``docs/tasks.md``). The agent observes the
detected push (``heading``), the belief over the candidate goals, the goals seen from the base
(``goal_vectors``, ``goal_direction``) and the current polytope (``polytope_onehot``). Writes
the learning curve, the trained agent, its evaluation and a video::

    pip install torch --index-url https://download.pytorch.org/whl/cpu   # CPU-only torch
    pip install "pathpref[rl]"                                         # stable-baselines3
    MUJOCO_GL=egl nice -n 10 python examples/train_ppo.py --out ppo_out --seed 0

``ppo_out/``: ``curve.png`` (success and return of the training episodes against environment
steps), ``agent.zip`` (the PPO model), ``summary.json`` (training CPU seconds, the success of
the deterministic agent on ``--eval`` held-out episodes with its Wilson interval),
``episodes.json`` and ``agent.mp4`` (one held-out episode, the task drawn). Training stops at
``--steps`` or at ``--cpu-minutes`` of this process's CPU time, whichever comes first. The
default hyperparameters (256 steps per rollout, batch 64, 10 epochs, lr 1e-3, gamma 0.95,
entropy 0.005, two hidden layers of 64) are those of the documented run (``docs/tasks.md``),
which reaches held-out success >= 0.6 within 20 CPU-minutes; one JSON progress line is
printed per rollout. The
saved agent is filmed again on any seed with ``pathpref render``::

    pathpref render --task navigate --map simple --method path_preference --delta-t 1 \\
        --policy ppo_out/agent.zip --out agent.mp4

**torch and MuJoCo's EGL.** With the CUDA build of torch, importing torch (or triton) after a
MuJoCo EGL context exists has crashed the process (Mesa's EGL and triton); this script imports
torch first, before any environment, which is the order that works. The CPU-only wheel (no
triton) imports in any order on this project's machines. Without rendering,
``MUJOCO_GL=disable`` avoids GL altogether for training runs.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

import torch  # noqa: E402,F401  # before any MuJoCo EGL context (module docstring)
from stable_baselines3 import PPO  # noqa: E402
from stable_baselines3.common.callbacks import BaseCallback  # noqa: E402

# isort: split
import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402
import pathpref_tasks  # noqa: E402,F401  # registers the Gymnasium ids
from pathpref_tasks.policies import AGENT_KEYS, agent_observation  # noqa: E402

ENV_ID = "pathpref/Navigate-v0"
#: the task: the paper's simple map, the person pushes at every decision, the paper's method
#: for the belief the agent observes
TASK = {"map": "simple", "method": "path_preference", "delta_t": 1}
#: the episode metrics the learning curve and the summary keep
KEEP = ("success", "goal_reached", "violations", "pushes", "return", "steps")
#: the first seed of the held-out evaluation episodes (training uses seeds 0, 1, ...)
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
    return centre - half, centre + half


class AgentView(gym.ObservationWrapper):
    """The observations the agent reads (:data:`pathpref_tasks.policies.AGENT_KEYS`)."""

    def __init__(self, env: gym.Env):
        super().__init__(env)
        self.observation_space = gym.spaces.Dict(
            {k: env.observation_space[k] for k in AGENT_KEYS})

    def observation(self, observation):
        """The agent's keys of ``observation``."""
        return agent_observation(observation)


class EpisodeLog(gym.Wrapper):
    """Keeps each finished episode's metrics (the last ``info``) and the environment steps
    taken when it ended; every ``reset`` without a seed starts the next training seed."""

    def __init__(self, env: gym.Env, seed: int):
        super().__init__(env)
        self.episodes: list[dict] = []
        self.steps = 0
        self.next_seed = seed

    def reset(self, *, seed=None, options=None):
        """The next training episode (its own seed, so the run is reproducible)."""
        if seed is None:
            seed, self.next_seed = self.next_seed, self.next_seed + 1
        return self.env.reset(seed=seed, options=options)

    def step(self, action):
        """The wrapped step; a finished episode's last ``info`` is kept."""
        obs, r, term, trunc, info = self.env.step(action)
        self.steps += 1
        if term or trunc:
            self.episodes.append({**{k: info[k] for k in KEEP}, "at_step": self.steps})
        return obs, r, term, trunc, info


class CpuBudget(BaseCallback):
    """Stops training once this process has used ``seconds`` of CPU time; after each rollout
    prints one JSON line of progress (steps, CPU seconds, the success and mean return of the
    last 100 training episodes of ``log``)."""

    def __init__(self, seconds: float, log: EpisodeLog):
        super().__init__()
        self.seconds = seconds
        self.log = log

    def _on_step(self) -> bool:
        return cpu_seconds() < self.seconds

    def _on_rollout_end(self) -> None:
        last = self.log.episodes[-100:]
        print(json.dumps({"steps": self.log.steps, "cpu_s": round(cpu_seconds(), 1),
                          "episodes": len(self.log.episodes),
                          "success_last_100": float(np.mean([e["success"] for e in last]))
                          if last else None,
                          "return_last_100": round(float(np.mean([e["return"] for e in last])),
                                                   2) if last else None}), flush=True)


def make_env(seed: int = 0) -> EpisodeLog:
    """The training environment (:class:`AgentView`, :class:`EpisodeLog`)."""
    return EpisodeLog(AgentView(gym.make(ENV_ID, **TASK)), seed)


def evaluate(model: PPO, n: int, seed: int = EVAL_SEED) -> list[dict]:
    """``n`` held-out episodes (seeds ``seed``, ``seed + 1``, ...) of the deterministic
    agent: their metrics."""
    env = AgentView(gym.make(ENV_ID, **TASK))
    out = []
    for i in range(n):
        obs, _ = env.reset(seed=seed + i)
        for _ in range(10_000):  # the TimeLimit (60 decisions) ends it first
            obs, _, term, trunc, info = env.step(model.predict(obs, deterministic=True)[0])
            if term or trunc:
                break
        out.append({k: info[k] for k in KEEP})
    env.close()
    return out


def plot_curve(episodes: list[dict], path: Path, window: int = 50) -> None:
    """Success and return of the training episodes (running means over ``window``) against
    the environment steps at each episode's end."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    steps = np.array([e["at_step"] for e in episodes])
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(6, 5), dpi=120, sharex=True)
    for ax, key, label in ((ax1, "success", "success"), (ax2, "return", "return")):
        y = np.array([float(e[key]) for e in episodes])
        ax.plot(steps, y, ".", alpha=0.15)
        if len(y) >= window:
            ax.plot(steps[window - 1:], np.convolve(y, np.ones(window) / window, "valid"),
                    "-", label=f"mean of {window} episodes")
            ax.legend(loc="lower right")
        ax.set_ylabel(label)
    ax2.set_xlabel("environment steps (decisions)")
    ax1.set_title(f"PPO on {ENV_ID} (simple, a push every decision)")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def main(argv: list[str] | None = None) -> dict:
    """Train, plot, evaluate, save and film (module docstring); the summary."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default="ppo_out", help="output folder")
    ap.add_argument("--steps", type=int, default=100_000, help="environment steps to train")
    ap.add_argument("--cpu-minutes", type=float, default=20.0,
                    help="stop training after this much CPU time of the process")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--n-steps", type=int, default=256, help="PPO rollout length")
    ap.add_argument("--batch-size", type=int, default=64)
    ap.add_argument("--gamma", type=float, default=0.95, help="discount")
    ap.add_argument("--ent-coef", type=float, default=0.005, help="entropy bonus")
    ap.add_argument("--learning-rate", type=float, default=1e-3)
    ap.add_argument("--net", default="64,64", help="hidden layer sizes of policy and value")
    ap.add_argument("--eval", type=int, default=100, help="held-out evaluation episodes")
    ap.add_argument("--video-size", default="480x360", help="WxH of the agent's video (0x0: "
                    "no video)")
    args = ap.parse_args(argv)
    if not 64 <= args.steps <= 10_000_000:
        raise SystemExit(f"--steps must be in 64..10000000, got {args.steps}")
    if not 0 <= args.eval <= 100_000:
        raise SystemExit(f"--eval must be in 0..100000, got {args.eval}")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(1)  # the machine's cores are shared; the MLP is small
    env = make_env(args.seed)
    net = [int(v) for v in args.net.split(",")]
    model = PPO("MultiInputPolicy", env, n_steps=min(args.n_steps, args.steps),
                batch_size=args.batch_size, n_epochs=10, learning_rate=args.learning_rate,
                gamma=args.gamma, ent_coef=args.ent_coef, seed=args.seed,
                policy_kwargs={"net_arch": net}, device="cpu", verbose=0)
    cpu0 = cpu_seconds()
    model.learn(total_timesteps=args.steps,
                callback=CpuBudget(cpu0 + 60.0 * args.cpu_minutes, env))
    train_cpu_s = cpu_seconds() - cpu0
    model.save(out / "agent.zip")
    eps = env.episodes
    plot_curve(eps, out / "curve.png")
    loaded = PPO.load(out / "agent.zip", device="cpu")  # what is evaluated is what was saved
    held_out = evaluate(loaded, args.eval)
    k = sum(bool(e["success"]) for e in held_out)
    lo, hi = wilson(k, len(held_out))
    summary = {
        "env": ENV_ID, "task": TASK, "seed": args.seed, "steps": env.steps,
        "train_cpu_s": round(train_cpu_s, 1), "episodes": len(eps),
        "success_rate_last_200_training": float(np.mean([e["success"] for e in eps[-200:]]))
        if eps else None,
        "eval_n": len(held_out), "eval_successes": k,
        "eval_success": k / len(held_out) if held_out else None,
        "eval_success_wilson95": [round(lo, 3), round(hi, 3)],
        "eval_mean_return": float(np.mean([e["return"] for e in held_out])) if held_out
        else None}
    w, h = (int(v) for v in args.video_size.lower().split("x"))
    if w > 0 and h > 0:
        from pathpref_tasks.policies import checkpoint_policy

        from pathpref.apps.film import film_policy

        metrics, frames = film_policy("navigate", checkpoint_policy(out / "agent.zip"),
                                      out / "agent.mp4", w, h,
                                      {**TASK, "seed": EVAL_SEED, "reward": "potential"})
        summary["filmed_episode"] = {k: metrics[k] for k in KEEP}
        summary["video_frames"] = frames
    (out / "summary.json").write_text(json.dumps(summary, indent=1))
    (out / "episodes.json").write_text(json.dumps(eps))
    print(json.dumps(summary))
    env.close()
    return summary


if __name__ == "__main__":
    main()
