"""Fuzz the map loader for a bounded time: random bytes and mutated valid files never raise
anything but MapError."""

from __future__ import annotations

import copy
import json

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pathpref.errors import MapError
from pathpref.geometry.maps import load_map
from pathpref.geometry.world import load_world

FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=list(HealthCheck))
VALID = load_map("office").to_dict()
VALID["preference"] = {"route": [[1, 1], [10, 1], [10, 9]], "closed": True}

json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-10**12, 10**12)
    | st.floats(allow_nan=True, allow_infinity=True) | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=5) | st.dictionaries(st.text(max_size=6), inner,
                                                                max_size=4),
    max_leaves=12,
)


@FUZZ
@given(st.binary(max_size=400))
def test_random_bytes(tmp_path_factory, data):
    path = tmp_path_factory.mktemp("fuzz") / "map.json"
    path.write_bytes(data)
    try:
        load_world(path)
    except MapError:
        pass


def paths(obj, prefix=()):
    yield prefix
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from paths(v, (*prefix, k))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            yield from paths(v, (*prefix, i))


ALL_PATHS = [p for p in paths(VALID) if p]


@FUZZ
@given(st.lists(st.tuples(st.sampled_from(ALL_PATHS), st.booleans(), json_values), min_size=1,
                max_size=3))
def test_mutated_valid_maps(mutations):
    raw = copy.deepcopy(VALID)
    for path, delete, value in mutations:
        node = raw
        try:
            for k in path[:-1]:
                node = node[k]
            if delete:
                del node[path[-1]]
            else:
                node[path[-1]] = value
        except (KeyError, IndexError, TypeError):
            continue
    try:
        load_world(json.loads(json.dumps(raw, allow_nan=True)))
    except MapError:
        pass
