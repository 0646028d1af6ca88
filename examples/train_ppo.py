"""Train PPO (stable-baselines3) on ``pathpref/NavigateControl-v0``: the agent drives the base's
velocity at 10 Hz while the simulated human pushes; it is rewarded by the paper's rule at every
cell change (SPEC 6: the goal, the move cost, the human's preferred route). Writes the
learning curve, the trained agent and a video of it::

    pip install torch --index-url https://download.pytorch.org/whl/cpu   # CPU-only torch
    pip install "pathpref[rl]"                                         # stable-baselines3
    MUJOCO_GL=egl nice -n 10 python examples/train_ppo.py --out ppo_out --steps 40000

``ppo_out/``: ``curve.png`` (episode return and success against environment steps),
``agent.zip`` (the PPO model), ``agent.mp4`` (one episode of the trained agent, the task drawn:
goals by belief, the preferred route, pushes and cues), ``summary.json``. The saved agent can
be filmed again on any seed with ``pathpref render``::

    PYTHONPATH=examples PATHPREF_AGENT=ppo_out/agent.zip pathpref render \\
        --task navigate_control --map simple --method goal_only --delta-t 3 --queries 20 \\
        --policy train_ppo:agent_policy --out agent.mp4

(``pathpref render`` runs the task at its default 50 Hz; the agent was trained at 10 Hz.)

**torch and MuJoCo's EGL.** With the CUDA build of torch, importing torch (or triton) after a
MuJoCo EGL context exists has crashed the process (Mesa's EGL and triton); this script imports
torch first, before any environment, which is the order that works. The CPU-only wheel (no
triton) imports in any order on this project's machines (checked: an environment created and
rendered with EGL, then ``import torch``, exits 0). Without rendering, ``MUJOCO_GL=disable``
avoids GL altogether for training runs.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

import torch  # noqa: E402,F401  # before any MuJoCo EGL context (module docstring)
from stable_baselines3 import PPO  # noqa: E402
from stable_baselines3.common.monitor import Monitor  # noqa: E402

# isort: split
import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402
import pathpref_tasks  # noqa: E402,F401  # registers the Gymnasium ids
from pathpref_tasks.gym import gym_observation  # noqa: E402

ENV_ID = "pathpref/NavigateControl-v0"
#: the task: the paper's simple map, a cue every 3 decisions' worth of time, 10 Hz control
TASK = {"map": "simple", "method": "goal_only", "delta_t": 3, "queries": 20}
ENVIRONMENT = {"control_timestep": 0.1}
#: simulated seconds of one training episode (400 control steps)
TIME_LIMIT_S = 40.0
#: the episode metrics the learning curve and the summary keep
KEEP = ("success", "goal_reached", "violations", "pushes")


class EpisodeLog(gym.Wrapper):
    """Keeps each finished episode's metrics (the last ``info``: ``return``, ``success``, ...)
    and the environment steps taken when it ended."""

    def __init__(self, env: gym.Env):
        super().__init__(env)
        self.episodes: list[dict] = []
        self.steps = 0

    def step(self, action):
        """The wrapped step; a finished episode's last ``info`` is kept."""
        obs, r, term, trunc, info = self.env.step(action)
        self.steps += 1
        if term or trunc:
            self.episodes.append({**{k: info[k] for k in (*KEEP, "return")},
                                  "at_step": self.steps})
        return obs, r, term, trunc, info


def make_env(seed: int = 0) -> EpisodeLog:
    """The training environment: its episodes kept (:class:`EpisodeLog`) and recorded by
    SB3's ``Monitor`` (its ``ep_rew_mean`` log)."""
    env = gym.make(ENV_ID, environment_kwargs=ENVIRONMENT, time_limit=TIME_LIMIT_S,
                   seed=seed, **TASK)
    return EpisodeLog(Monitor(env))


def plot_curve(log: EpisodeLog, path: Path, window: int = 10) -> None:
    """Episode return (and its running mean over ``window`` episodes) against the
    environment steps at each episode's end."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    returns = np.array([e["return"] for e in log.episodes], float)
    steps = np.array([e["at_step"] for e in log.episodes])
    fig, ax = plt.subplots(figsize=(6, 3.5), dpi=120)
    ax.plot(steps, returns, ".", alpha=0.4, label="episode return")
    if len(returns) >= window:
        mean = np.convolve(returns, np.ones(window) / window, mode="valid")
        ax.plot(steps[window - 1:], mean, "-", label=f"mean of {window}")
    ax.set_xlabel("environment steps")
    ax.set_ylabel("return (paper's reward)")
    ax.set_title(f"PPO on {ENV_ID}")
    ax.legend(loc="lower right")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def policy_of(model: PPO, space) -> callable:
    """The trained agent as a policy of a dm_env time step (``pathpref render --policy``)."""
    def act(time_step):
        obs = gym_observation(space, time_step.observation)
        return model.predict(obs, deterministic=True)[0]

    return act


_AGENT: dict = {}


def agent_policy(time_step):
    """The agent saved at ``$PATHPREF_AGENT``, for ``pathpref render --policy
    train_ppo:agent_policy`` (loaded at the first call)."""
    if "act" not in _AGENT:
        env = make_env()
        _AGENT["act"] = policy_of(PPO.load(os.environ["PATHPREF_AGENT"], device="cpu"),
                                  env.observation_space)
        env.close()
    return _AGENT["act"](time_step)


def main(argv: list[str] | None = None) -> dict:
    """Train, plot, save and film (module docstring); the summary."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default="ppo_out", help="output folder")
    ap.add_argument("--steps", type=int, default=40_000, help="environment steps to train")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--video-size", default="480x360", help="WxH of the agent's video")
    args = ap.parse_args(argv)
    if not 256 <= args.steps <= 10_000_000:
        raise SystemExit(f"--steps must be in 256..10000000, got {args.steps}")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(1)  # the machine's cores are shared; the MLP is small
    env = make_env(args.seed)
    model = PPO("MultiInputPolicy", env, n_steps=min(1024, args.steps), batch_size=128,
                learning_rate=3e-4, gamma=0.99, seed=args.seed, device="cpu", verbose=0)
    started = time.perf_counter()
    model.learn(total_timesteps=args.steps)
    train_s = time.perf_counter() - started
    model.save(out / "agent.zip")
    plot_curve(env, out / "curve.png")
    from pathpref.apps.film import film_policy

    w, h = (int(v) for v in args.video_size.lower().split("x"))
    metrics, frames = film_policy("navigate_control", policy_of(model, env.observation_space),
                                  out / "agent.mp4", w, h, {**TASK, "seed": args.seed + 1000},
                                  environment_kwargs=ENVIRONMENT, time_limit=TIME_LIMIT_S)
    eps = env.episodes
    fifth = max(1, len(eps) // 5)
    first, last = eps[:fifth], eps[-fifth:]
    summary = {
        "steps": args.steps, "train_s": round(train_s, 1), "episodes": len(eps),
        "mean_return_first_fifth": float(np.mean([e["return"] for e in first])) if eps
        else None,
        "mean_return_last_fifth": float(np.mean([e["return"] for e in last])) if eps
        else None,
        "success_rate_last_fifth": float(np.mean([e["success"] for e in last])) if eps
        else None,
        "filmed_episode": {k: metrics[k] for k in (*KEEP, "return", "steps")},
        "video_frames": frames}
    (out / "summary.json").write_text(json.dumps(summary, indent=1))
    (out / "episodes.json").write_text(json.dumps(eps))
    print(json.dumps(summary))
    env.close()
    return summary


if __name__ == "__main__":
    main()
