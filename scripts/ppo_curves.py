"""The learning curves of several ``examples/train_ppo.py`` runs on one figure: success and
return of the training episodes (running means over ``--window`` episodes) against the
environment steps (decisions), one line per run, and the share of episodes ended by a
violation of the person's preference::

    python scripts/ppo_curves.py ppo_s0 ppo_s1 --out docs/ppo_v1_curve.png

Each run folder holds ``episodes.json`` and ``summary.json`` (its seed labels the line)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np


def running_mean(y: np.ndarray, window: int) -> np.ndarray:
    """The mean of each ``window`` consecutive values (``len(y) - window + 1`` of them)."""
    return np.convolve(y, np.ones(window) / window, "valid")


def main(argv: list[str] | None = None) -> None:
    """Plot the runs (module docstring)."""
    ap = argparse.ArgumentParser(description="PPO learning curves of train_ppo.py runs")
    ap.add_argument("runs", nargs="+", help="output folders of examples/train_ppo.py")
    ap.add_argument("--out", required=True, help="the PNG to write")
    ap.add_argument("--window", type=int, default=50)
    args = ap.parse_args(argv)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = (("success", "success"), ("return", "return"), ("violations", "ended by a violation"))
    fig, axes = plt.subplots(len(keys), 1, figsize=(6, 6.5), dpi=120, sharex=True)
    title = ""
    for run in args.runs:
        eps = json.loads((Path(run) / "episodes.json").read_text())
        summary = json.loads((Path(run) / "summary.json").read_text())
        title = f"PPO on {summary['env']}, {len(summary['train_plans'])} generated plans"
        steps = np.array([e["at_step"] for e in eps])
        w = min(args.window, len(eps))
        for ax, (key, label) in zip(axes, keys, strict=True):
            y = np.array([float(e[key] > 0) if key == "violations" else float(e[key])
                          for e in eps])
            if w:
                ax.plot(steps[w - 1:], running_mean(y, w), "-", label=f"seed {summary['seed']}")
            ax.set_ylabel(label)
    for ax in axes[::2]:
        ax.set_ylim(-0.05, 1.05)
    axes[0].legend(loc="upper left")
    axes[0].set_title(f"{title}\n(means of {args.window} training episodes)", fontsize=10)
    axes[-1].set_xlabel("environment steps (decisions)")
    fig.tight_layout()
    fig.savefig(args.out)
    plt.close(fig)


if __name__ == "__main__":
    main()
