"""Shared fixtures: built worlds (built once per session) and the authors' reference data."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

os.environ.setdefault("MUJOCO_GL", "egl")

from pathpref.geometry.world import load_world  # noqa: E402

DATA = Path(__file__).parent / "data"
PAPER_NAMES = {"Map 1": "simple", "Map 2": "office", "Map 3": "classroom"}


@pytest.fixture(scope="session")
def paper_maps() -> dict:
    """The authors' maps (copied from shared/data/paper_maps.json), keyed by our names."""
    raw = json.loads((DATA / "paper_maps.json").read_text())
    return {PAPER_NAMES[m["paper_name"]]: m for m in raw["maps"]}


@pytest.fixture(scope="session")
def worlds() -> dict:
    return {name: load_world(name) for name in ("simple", "office", "classroom")}


@pytest.fixture(scope="session")
def simple(worlds):
    return worlds["simple"]
