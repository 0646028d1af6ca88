"""Write tests/data/paper_pomcp_golden.json: actions and root visit counts of paper-preset POMCP
searches on the three maps, so that any change to the compiled search that alters a paper
decision fails a test. Run it only to re-pin after an intended change to the paper's planner."""

from __future__ import annotations

import json
import sys

import numpy as np

from pathpref.geometry.world import load_world
from pathpref.inference.belief import GoalBelief, PreferenceBelief
from pathpref.inference.human import ObservationModel
from pathpref.planning.pomcp import POMCP
from pathpref.planning.pomdp import get_preset


def cases():
    """(map, goals, observations, cell, depth, seed, planner) for each pinned search."""
    rng = np.random.default_rng(2024)
    for name, depth in (("simple", 30), ("office", 30), ("classroom", 60)):
        world = load_world(name)
        for k in range(4):
            goals = rng.choice(world.n_cells, size=10, replace=False)
            obs = [(int(rng.integers(world.n_cells)), int(rng.integers(8))) for _ in range(k * 2)]
            cell = int(rng.integers(world.n_cells))
            for planner in ("path_preference", "goal_only"):
                yield name, world, goals, obs, cell, depth, int(rng.integers(2**31)), planner


def run(world, goals, obs, cell, depth, seed, planner):
    model = ObservationModel.build(world, goals)
    preset = get_preset("paper")
    if planner == "path_preference":
        belief, rewards = PreferenceBelief(model, coupling=True), preset.path_preference
    else:
        belief, rewards = GoalBelief(model), preset.goal_only
    for s, h in obs:
        belief.update(s, h)
    res = POMCP(world, goals, rewards, queries=2000).search(cell, belief, depth, seed)
    return {"action": res.action, "visits": res.visits.tolist(), "nodes": res.nodes}


def main(out: str) -> None:
    rows = []
    for name, world, goals, obs, cell, depth, seed, planner in cases():
        rows.append({"map": name, "planner": planner, **run(world, goals, obs, cell, depth, seed,
                                                              planner)})
    with open(out, "w") as f:
        json.dump(rows, f, indent=0)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "tests/data/paper_pomcp_golden.json")
