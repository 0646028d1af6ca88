"""Priors are plug-ins (:mod:`pathpref.inference.priors`): one registered from a test module, or
declared by another package's entry point, runs an episode by name."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from pathpref.episode import EpisodeSpec, run_episode
from pathpref.errors import ConfigError
from pathpref.inference.belief import PreferenceBelief
from pathpref.inference.priors import PRIORS, PriorInputs, make_belief, register_prior
from pathpref.planning.pomdp import get_preset

from .plugin_helpers import install_package

BUILT_IN = ["independent", "routes", "learned-gamma", "homotopy", "circulation"]


class Recording:
    """A prior that is the independent one, and records what it was built from."""

    def __init__(self):
        self.calls: list[PriorInputs] = []

    def __call__(self, inputs: PriorInputs) -> PreferenceBelief:
        self.calls.append(inputs)
        return PreferenceBelief(inputs.model, prior=inputs.goal_prior, coupling=inputs.coupling)


@pytest.fixture
def recording():
    prior = Recording()
    register_prior("recording", prior)
    yield prior
    PRIORS.pop("recording", None)


def _cells(res):
    return [(s.x, s.y) for s in res.log]


def test_a_registered_prior_runs_an_episode(recording):
    """The path-preference method under prior ``recording`` builds its belief from the
    registered factory (once, from the episode's model and the robot's start) and, since that
    belief is the independent prior's, moves exactly as under ``independent``; the episode's
    key names the prior."""
    kw = dict(t_max=8, queries=50, preset="paper")
    spec = EpisodeSpec.single("simple", "path_preference", 1, seed=3, prior="recording", **kw)
    res = run_episode(spec)
    ref = run_episode(EpisodeSpec.single("simple", "path_preference", 1, seed=3,
                                         prior="independent", **kw))
    assert len(recording.calls) == 1
    inputs = recording.calls[0]
    assert inputs.coupling is get_preset("paper").coupling
    assert tuple(inputs.model.world.cells[inputs.start]) == (res.log[0].x, res.log[0].y)
    assert _cells(res) == _cells(ref) and res.steps == ref.steps
    assert "prior=recording" in spec.key()


def test_unknown_priors_are_one_line_errors(recording):
    with pytest.raises(ConfigError) as e:
        EpisodeSpec.single("simple", "path_preference", 5, prior="nothing").validate()
    assert str(e.value) == ("unknown prior 'nothing'; choose " + ", ".join(BUILT_IN)
                            + " or recording")
    with pytest.raises(ConfigError, match="unknown prior 'nothing'"):
        make_belief("nothing", PriorInputs(None))


PACKAGE = '''
from pathpref.inference.routes import RouteBelief


def tree(inputs):
    """The route prior under another name."""
    return RouteBelief(inputs.model, prior=inputs.goal_prior)


NOT_A_PRIOR = 3
'''


@pytest.fixture
def prior_package(tmp_path, monkeypatch):
    install_package(tmp_path, monkeypatch, "pathpref_example_priors", PACKAGE, """\
        [pathpref.priors]
        tree = pathpref_example_priors:tree
        notaprior = pathpref_example_priors:NOT_A_PRIOR
        """)
    yield
    sys.modules.pop("pathpref_example_priors", None)
    for name in ("tree", "notaprior"):
        PRIORS.pop(name, None)


def test_a_package_adds_a_prior(prior_package):
    """A prior declared in the entry-point group ``pathpref.priors`` is found by name: the
    preset takes it and the episode's belief is the route prior's (its ``route_prior``
    switch on); a non-callable entry is a one-line error."""
    assert get_preset("robust", prior="tree").prior == "tree"
    spec = EpisodeSpec.single("simple", "path_preference", 5, seed=1, prior="tree",
                              preset="robust", t_max=5, queries=40)
    res = run_episode(spec)
    assert res.steps >= 1
    from pathpref.geometry.world import load_world
    from pathpref.inference.human import ObservationModel
    world = load_world("simple")
    model = ObservationModel.build(world, np.array([world.cell((1, 8))]))
    assert make_belief("tree", PriorInputs(model)).route_prior is True
    with pytest.raises(ConfigError, match="must name a prior") as e:
        get_preset("paper", prior="notaprior")
    assert "\n" not in str(e.value)
