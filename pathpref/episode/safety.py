"""Contact safety: an episode in which the robot struck the static world is not a success.

A physical body measures its contacts with obstacles and walls (``pathpref/sim/measurements.py``):
``collisions`` (contacts begun), ``contact_impact_speed`` (m/s, the base's planar speed just
before a contact began, the largest) and ``contact_peak_force_n`` (the largest normal force of a
contact, N). An episode is *contact-safe* unless some contact broke a limit of
:data:`CONTACT_LIMITS`:

- an impact speed above 0.05 m/s (a base that drives or is pushed into an obstacle, rather than
  settling against it), or
- a peak contact force above 20 N (a touch a person steadying a cart would not call a bump).

These are the project's limits for contacts with the *static world* (obstacles, walls), not the
ISO/TS 15066 limits for contacts with people. An episode without contact measurements (the grid
world, rows written before them) is contact-safe. A contact-unsafe episode is a failure in every
report: its ``success`` and ``homotopy_success`` are 0 and its failure kind is ``contact``
(:mod:`pathpref.experiments.outcomes`), whatever else it achieved.
"""

from __future__ import annotations

import json
from typing import Any

#: the limits of a contact with the static world (module docstring): metric key -> the largest
#: value that is still safe
CONTACT_LIMITS = {"contact_impact_speed": 0.05, "contact_peak_force_n": 20.0}


def contact_safe(metrics: dict[str, Any] | str | None) -> bool:
    """Whether an episode's metrics (a dictionary, or the stored JSON text; None or empty for
    no measurements) break no limit of :data:`CONTACT_LIMITS` (module docstring). Text that
    is not a JSON object of numbers holds no readable measurement: safe (the store's row
    checks report such a row)."""
    if isinstance(metrics, str):
        try:
            metrics = json.loads(metrics) if metrics else {}
        except ValueError:
            return True
    if not isinstance(metrics, dict) or not metrics.get("collisions"):
        return True
    try:
        return all(float(metrics.get(k) or 0.0) <= limit for k, limit in CONTACT_LIMITS.items())
    except (TypeError, ValueError):
        return True
