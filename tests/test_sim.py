"""The MuJoCo layer: scenes from maps, pushes, cue detection from the robot's own sensing,
tracking, physics episodes, the dm_env task."""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from pathpref.errors import ConfigError  # noqa: E402
from pathpref.geometry.world import load_world  # noqa: E402
from pathpref.sim import scene as scene_mod  # noqa: E402
from pathpref.sim.force_cue import HumanPush, PushProfile  # noqa: E402
from pathpref.sim.mobile_base import MobileBase  # noqa: E402
from pathpref.sim.scene import build_scene  # noqa: E402

ROTATED = {"name": "rot", "width": 8, "height": 6, "obstacles": [
    {"vertices": [[3, 2], [5.5, 3.2], [4.3, 5.7], [1.8, 4.5]]},
    {"cells": {"lower_left": [7, 1], "size": [1, 2]}}]}


@pytest.fixture(scope="module")
def simple_base(worlds):
    return MobileBase(build_scene(worlds["simple"]))


def test_scene_from_maps(worlds):
    for name, n_obs in (("simple", 1), ("office", 12), ("classroom", 8)):
        sc = build_scene(worlds[name])
        names = [sc.model.geom(i).name for i in range(sc.model.ngeom)]
        assert sum(n.startswith("obstacle_") for n in names) == n_obs
        assert sum(n.startswith("wall_") for n in names) == 4
    sc = build_scene(load_world(ROTATED))
    assert sc.model.nmesh == 1  # the rotated polygon is a convex mesh prism, the rectangle a box


def test_missing_mjcf_is_a_clear_error(worlds, monkeypatch, tmp_path):
    monkeypatch.setattr(scene_mod, "MJCF_DIR", tmp_path)
    with pytest.raises(ConfigError, match="navigate.xml is missing"):
        build_scene(worlds["simple"])
    (tmp_path / "navigate.xml").write_text("<mujoco><worldbody><bad")
    with pytest.raises(ConfigError, match="does not load"):
        build_scene(worlds["simple"])


@pytest.mark.parametrize("noise,need", [(0.0, 1.0), (10.0, 0.95)])
def test_cue_detection_accuracy(worlds, simple_base, noise, need):
    """200 pushes: the detected sector equals the human's intended sector."""
    w, base = worlds["simple"], simple_base
    rng = np.random.default_rng(1)
    profile = PushProfile(noise_deg=noise)
    hits = 0
    for _ in range(200):
        base.reset(int(rng.integers(w.n_cells)))
        h = int(rng.integers(8))
        cue = base.receive_push(HumanPush.sample(h, 0.0, profile, rng))
        hits += cue is not None and cue.heading == h
    assert hits / 200 >= need


def test_no_false_cues_while_driving(worlds, simple_base):
    w, base = worlds["simple"], simple_base
    rng = np.random.default_rng(2)
    base.reset(w.cell((1, 1)))
    n0 = len(base.felt)
    t0 = base.data.time
    while base.data.time - t0 < 100.0:  # 100 s of driving between random neighbours
        s = base.cell
        moves = np.flatnonzero(~w.motion.blocked[s])
        base.move_to(int(w.motion.next_cell[s, rng.choice(moves)]))
    assert len(base.felt) == n0  # no cue read: no push was made


def test_base_yields_and_recovers(worlds, simple_base):
    w, base = worlds["simple"], simple_base
    c = w.cell((3, 3))
    base.reset(c)
    start = base.position
    push = HumanPush(angle=0.0, t0=0.0, profile=PushProfile(), intended_heading=2)
    moved = 0.0
    for _ in range(200):
        base.substep(push)
        moved = max(moved, np.linalg.norm(base.position - start))
    assert moved > 0.02  # yields to the push (impedance), visibly
    assert base.move_to(c) == c
    assert np.linalg.norm(base.position - start) < 0.03  # and returns to its cell


def test_collisions_are_physics(worlds, simple_base):
    """Pushed hard into the table, the base stops at its edge (no penetration)."""
    w, base = worlds["simple"], simple_base
    base.reset(w.cell((4, 5)))  # table occupies x in [2, 3] m, base radius 0.15 m
    push = HumanPush(angle=0.0, t0=0.0, profile=PushProfile(peak_n=200, duration_s=1.5),
                     intended_heading=2)
    for _ in range(700):
        base.substep(push)
    assert base.position[0] <= 2.0 - 0.15 + 0.005


def test_bad_forces_and_actions(worlds):
    with pytest.raises(ConfigError, match="positive finite"):
        PushProfile(peak_n=float("nan"))
    from pathpref.episode import EpisodeRunner, EpisodeSpec
    from pathpref.episode.instances import seed_for

    r = EpisodeRunner(EpisodeSpec(map="simple", method="compliant", delta_t=5, instance=0,
                                  run=0, instance_seed=seed_for(0, 0), run_seed=1, sim="mujoco"))
    for bad in (11, -3, float("nan"), 2.5, "N"):
        with pytest.raises(ConfigError, match="action must be"):
            r.step(bad)


def test_viewer_style_perturbation_is_detected(worlds):
    """The viewer's mouse push (mjv_applyPerturbForce on the selected handle) goes through the
    same sensing and detection as the simulated human. The viewer pulls with
    stiffness x subtree mass x distance (100 x 0.2 kg x 1 m = 20 N here)."""
    base = MobileBase(build_scene(worlds["office"]))
    w = worlds["office"]
    base.reset(w.cell((3, 2)))
    m, d = base.model, base.data
    pert = mujoco.MjvPerturb()
    pert.select = base.pushed_body
    pert.active = int(mujoco.mjtPertBit.mjPERT_TRANSLATE)
    pert.localmass = m.body_subtreemass[base.pushed_body]  # the viewer sets it on selection
    cue = None
    for k in range(400):
        mujoco.mj_forward(m, d)
        on = k < 150
        pert.refselpos[:] = d.xpos[base.pushed_body] + (np.array([0.0, 1.0, 0.0]) if on else 0.0)
        pert.localpos[:] = 0.0
        d.xfrc_applied[:] = 0.0
        if on:
            mujoco.mjv_applyPerturbForce(m, d, pert)
        d.ctrl[:3] = base.controller.command(d.qpos[:2], d.qpos[2], base.target)
        mujoco.mj_step(m, d)
        cue = cue or base.sensing.detector.update(base.sensing.sensor.force_xy(d))
    assert cue is not None and cue.heading == 0  # a push north reads as N


def test_physics_episode_end_to_end():
    from pathpref.episode import EpisodeSpec, run_episode
    from pathpref.episode.instances import seed_for

    for method in ("compliant", "path_preference"):
        spec = EpisodeSpec(map="simple", method=method, delta_t=3, instance=0, run=0,
                           instance_seed=seed_for(0, 2), run_seed=seed_for(0, 2, 0),
                           sim="mujoco", queries=1000)
        a, b = run_episode(spec), run_episode(spec)
        assert [(s.x, s.y) for s in a.log] == [(s.x, s.y) for s in b.log]  # deterministic
        assert a.inputs == len([t for t in range(a.steps) if t % 3 == 0])
        assert a.success == (a.goal_reached and a.violations == 0)


def test_study_mode_pipeline_headless():
    """A scripted 'viewer' drags the handle east during the first drive: the robot detects it
    with the same pipeline, feeds it to the belief and replans (study mode, no window)."""
    from pathpref.apps.interact import InteractiveSession

    session = InteractiveSession(map="office", method="path_preference", seed=0, queries=300,
                                 t_max=6)
    base = session.base
    m, d = base.model, base.data
    pert = mujoco.MjvPerturb()
    pert.select = base.pushed_body
    pert.active = int(mujoco.mjtPertBit.mjPERT_TRANSLATE)
    pert.localmass = m.body_subtreemass[base.pushed_body]
    state = {"k": 0}

    def viewer_like(b, push):
        state["k"] += 1
        d.xfrc_applied[:] = 0.0  # what the viewer's sync does before applying the perturbation
        if 50 <= state["k"] < 200:
            pert.refselpos[:] = d.xpos[base.pushed_body] + np.array([1.5, 0.0, 0.0])
            mujoco.mjv_applyPerturbForce(m, d, pert)

    base.on_substep.append(viewer_like)
    belief = session.runner.policy.belief
    assert not belief.tables  # nothing observed yet
    session.step()
    assert session.observed and session.observed[0] == 2  # E
    assert belief.tables  # the push reached the belief (a polytope's preference table)
    session.step()  # replans with the updated belief and keeps going
    assert session.runner.t == 2
