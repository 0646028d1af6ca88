"""What an episode produced: its flags, counts and per-step log, and their stored row."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

from .instances import Instance
from .safety import contact_safe
from .spec import EpisodeSpec


@dataclass
class StepLog:
    """One decision step: the robot's cell after it, the action, the observed heading (-1:
    none), the belief's ``P(true goal)`` and goal entropy (nats), and ``is_intervention``: 1
    when the human pushed at this cell right after this step (row 0: before step 1), else 0
    (the rows of an episode sum to its ``inputs``); None (stored NULL: not measured) for a
    body that gives the pushes itself, at times of its own (``EpisodeRunner.continuous``)."""

    t: int
    x: int
    y: int
    action: int
    heading: int
    p_true_goal: float
    goal_entropy: float
    is_intervention: int | None = 0


@dataclass
class EpisodeResult:
    """An episode's outcome. Success = goal reached within ``T_max``, no preference violation
    (a polytope left by a face other than ``p_v``), no unsafe contact with the static world
    (:mod:`.safety`), and the episode ran (``status == "ok"``).
    ``homotopic``: the robot's path (start to goal) goes the same way round every obstacle as
    the human's route (:func:`~pathpref.geometry.following.human_route`, judged by
    :func:`~pathpref.geometry.homotopy.same_class`); set when the goal is reached.
    ``slack``: the time to spare, ``T_max`` minus the moves of the human's route from the start
    to the true goal (:func:`route_slack`); None where it was not measured (a failed episode's
    placeholder, rows written before the column).
    ``path``: the body's continuous path when the spec asks for it (``record_path_hz``), one
    tuple of :data:`~.body.PATH_FIELDS` per sample; stored beside the episode, not in its row."""

    spec: EpisodeSpec
    instance: Instance
    instance_cells: dict[str, Any] = field(default_factory=dict)
    goal_reached: bool = False
    violations: int = 0
    back_crossings: int = 0
    steps: int = 0
    inputs: int = 0
    wall_s: float = 0.0
    status: str = "ok"
    reason: str = ""
    log: list[StepLog] = field(default_factory=list)
    metrics: dict[str, float] = field(default_factory=dict)
    homotopic: bool = False
    slack: int | None = None
    path: list[tuple] = field(default_factory=list)

    @property
    def pref_followed(self) -> bool:
        """Every polytope change followed the human's preference."""
        return self.violations == 0

    @property
    def contact_safe(self) -> bool:
        """No contact with the static world broke a limit (:mod:`.safety`)."""
        return contact_safe(self.metrics)

    @property
    def success(self) -> bool:
        """Goal reached, preference followed, contact-safe, episode ran to its end."""
        return self.goal_reached and self.pref_followed and self.contact_safe and \
            self.status == "ok"

    @property
    def homotopy_success(self) -> bool:
        """Goal reached in the human route's homotopy class (winding numbers round every
        obstacle, :mod:`pathpref.geometry.homotopy`), contact-safe, episode ran to its end;
        reported beside the strict :attr:`success`, which stays the headline."""
        return self.goal_reached and self.homotopic and self.contact_safe and \
            self.status == "ok"


def result_row(res: EpisodeResult) -> dict[str, Any]:
    """Flat dictionary of an episode for the results store."""
    d = res.spec.stored()
    inst = res.instance
    return {
        **d,
        "key": res.spec.key(),
        "map_hash": res.spec.map_hash,
        "start": json.dumps(res.instance_cells.get("start")),
        "goals": json.dumps(res.instance_cells.get("goals")),
        "true_goal": inst.true_goal,
        "status": res.status,
        "reason": res.reason,
        "goal_reached": int(res.goal_reached),
        "pref_followed": int(res.pref_followed),
        "success": int(res.success),
        "homotopy_success": int(res.homotopy_success),
        "steps": res.steps,
        "inputs": res.inputs,
        "violations": res.violations,
        "back_crossings": res.back_crossings,
        "wall_s": res.wall_s,
        "metrics": json.dumps(res.metrics, sort_keys=True),
        "slack": res.slack,
    }


def route_slack(t_max: int, route: list[int]) -> int | None:
    """The slack of an episode: ``T_max - (len(route) - 1)``, the decision steps to spare when
    the robot walks the human's route (``route``: its cells, start to true goal, one move per
    step; :func:`~pathpref.geometry.following.human_route`, which is the oracle's path whenever
    the human's preference leads to the goal). Negative: even that route is out of time. None
    for an empty route (the goal cannot be reached)."""
    return int(t_max) - (len(route) - 1) if route else None
