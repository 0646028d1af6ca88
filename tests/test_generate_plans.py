"""One home for generated floor plans: ``floor_plan`` (pathpref/geometry/generate.py) writes the
held-out plans of scripts/homotopy_prior_eval.py byte for byte as they are stored."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

from pathpref.errors import MapError
from pathpref.geometry.generate import PLAN_DEFAULTS, floor_plan


def _script():
    spec = importlib.util.spec_from_file_location("homotopy_prior_eval",
                                                  "scripts/homotopy_prior_eval.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_the_held_out_plans_come_out_byte_identical():
    mod = _script()
    files = 0
    for kind, seeds in mod.SEEDS.items():
        for s in seeds:
            name = f"heldout_{s}.json" if kind == "open" else f"heldout_{kind}_{s}.json"
            stored = (Path("docs/results/heldout_plans") / name).read_text()
            assert json.dumps(mod.held_out_plan(s, kind), indent=1) == stored, name
            files += 1
    assert files == 24


def test_defaults_and_refusals():
    assert PLAN_DEFAULTS == {"width": 24, "height": 16, "rotated": 7, "boxes": 2,
                             "size_range": (1.5, 4.0)}
    plan = floor_plan(9001)
    assert "description" not in plan and plan["name"] == "random_24x16_7r2b_9001"
    with pytest.raises(MapError, match="too fragmented"):
        floor_plan(1, width=8, height=6, rotated=10, boxes=3, size_range=(2, 4))
    with pytest.raises(ValueError, match="route must be one of"):
        floor_plan(1, route="zigzag")
