"""The Stanford TidyBot vendored from MuJoCo Menagerie: it loads, a missing file is one line
naming it, its footprint is its own, whole-body IK moves the base, and a push on the tray meets
the arm's joint stiffness. One compiled model for the module (meshes are slow to load)."""

from __future__ import annotations

import os
import shutil

os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from pathpref.episode.cache import cached_world  # noqa: E402
from pathpref.errors import ConfigError  # noqa: E402
from pathpref.sim import tidybot  # noqa: E402
from pathpref.sim.scene import check_footprint  # noqa: E402


@pytest.fixture(scope="module")
def model():
    return tidybot.build_tidybot()


@pytest.fixture(scope="module")
def body(model):
    return tidybot.WholeBody(model)


def test_the_menagerie_model_loads_with_its_own_figures(model):
    assert tidybot.robot_model(model) == "tidybot"
    fig = tidybot.physical_figures(model)
    assert fig["base_mass_kg"] == 60.0  # Menagerie's mass="60" on the base's body mesh
    # the arm (Gen3 link masses 1.697 + 1.3773 + 2 x 1.1636 + 0.9302 + 2 x 0.6781 + 0.5 =
    # 8.188 kg), the 2F-85 (0.7774 kg and two linkages of 0.0613 kg) and the tray (0.2 kg)
    assert fig["robot_mass_kg"] == pytest.approx(60.0 + 8.188 + 0.900 + 0.2, abs=0.01)
    assert fig["timestep_s"] == 0.002
    nq = model.nq
    assert nq == 18  # x, y, yaw, seven arm joints, eight gripper joints
    for j in (*tidybot.BASE_JOINTS, *tidybot.ARM_JOINTS):
        assert model.joint(j).id >= 0


def test_the_base_has_menageries_corrected_inertia(model):
    """The base's inertia is its body mesh's at 60 kg (Menagerie pull request #281), not the
    placeholder 0.001 kg m^2: principal moments as Menagerie's pull request #307 measured them
    on the same edits ([1.902995, 1.218462, 1.213058] kg m^2), 1.903 kg m^2 about the vertical
    (the base's yaw entry of the joint-space inertia less the arm's at the same posture)."""
    b = model.body("base_link").id
    assert sorted(model.body_inertia[b]) == pytest.approx(sorted((1.902995, 1.218462,
                                                                  1.213058)), abs=1e-5)
    assert model.body_mass[b] == 60.0
    d = mujoco.MjData(model)
    mujoco.mj_forward(model, d)
    r = d.ximat[b].reshape(3, 3)
    assert (r @ np.diag(model.body_inertia[b]) @ r.T)[2, 2] == pytest.approx(1.903, abs=1e-3)


def test_a_missing_mesh_is_one_line_naming_the_file(tmp_path, monkeypatch):
    copy = tmp_path / "stanford_tidybot"
    shutil.copytree(tidybot.TIDYBOT_DIR, copy)
    (copy / "assets" / "gen3" / "forearm_link.stl").unlink()
    monkeypatch.setattr(tidybot, "TIDYBOT_DIR", copy)
    with pytest.raises(ConfigError) as err:
        tidybot.build_tidybot()
    msg = str(err.value)
    assert "\n" not in msg and "forearm_link.stl" in msg


def test_a_broken_model_is_one_line_naming_the_file(tmp_path, monkeypatch):
    copy = tmp_path / "stanford_tidybot"
    shutil.copytree(tidybot.TIDYBOT_DIR, copy)
    xml = copy / "tidybot.xml"
    xml.write_text(xml.read_text().replace('<joint name="joint_1"/>',
                                           '<joint name="joint_1" type="nonsense"/>'))
    monkeypatch.setattr(tidybot, "TIDYBOT_DIR", copy)
    with pytest.raises(ConfigError) as err:
        tidybot.build_tidybot()
    assert "\n" not in str(err.value) and "tidybot.xml" in str(err.value)


def test_the_base_is_wider_than_the_maps_footprint(model):
    r = tidybot.footprint_radius_m(model)
    # a 0.482 m square bumper with rounded corners: between its half width and half diagonal
    assert 0.241 <= r <= 0.241 * np.sqrt(2.0)
    with pytest.raises(ConfigError, match="more than the footprint"):
        check_footprint(cached_world("simple"), 0.5, r, "the TidyBot base")
    fp = tidybot.footprint(model, 0.5)
    assert fp.radius == pytest.approx(r / 0.5) and fp.clearance == pytest.approx(0.1)


def test_the_carrying_posture_holds_the_tray_level(body):
    body.reset()
    z = body.data.xmat[body.body].reshape(3, 3)[:, 2]
    assert z[2] == pytest.approx(1.0, abs=1e-6)
    assert np.linalg.norm(body.base_xy) < 1e-3  # the arm alone levelled it


def test_whole_body_ik_moves_the_base_toward_a_far_target(body):
    out = tidybot.base_share(body, 0.3, 3.0)
    assert out["error_m"] < 0.005  # the tray reached its target
    # the posture draws the arm home and nothing holds the base: the base takes a share
    assert 0.2 <= out["share"] <= 1.0 + 1e-3


def test_a_push_on_the_tray_deflects_it_by_the_arms_joint_compliance(model, body):
    """Static deflection under ``F``: ``J K^-1 J^T F`` with ``K`` the arm servos' ``kp`` (the
    base's servos are 500x stiffer); the peak of a steady push is within 15% of it."""
    body.reset()
    jacp = np.zeros((3, model.nv))
    mujoco.mj_jacBody(model, body.data, jacp, None, body.body)
    J = jacp[:, body.dofs[3:]]
    compliance = J @ np.diag(1.0 / model.actuator_gainprm[body.act[3:], 0]) @ J.T
    for heading in (0.0, 90.0):
        u = np.array([np.cos(np.radians(heading)), np.sin(np.radians(heading)), 0.0])
        static_mm = 1e3 * np.linalg.norm(compliance @ (30.0 * u))
        out = tidybot.tray_push(body, 30.0, 3.0, after_s=1.0, headings=(heading,))
        assert out["deviation_mm"] == pytest.approx(static_mm, rel=0.15)
        assert out["recovery_s"] < 1.0
        # the peak stays under 10 mm, so "back within 10 mm" is the first sample after the
        # release (two steps: the release takes effect at the next step); within 1 mm later
        assert out["recovery_s"] <= 2 * body.dt + 1e-9
        assert out["recovery_1mm_s"] > out["recovery_s"]


def test_under_guidance_the_tidybot_follows_a_push_on_its_tray(body):
    """The base's admittance takes the force the tray's sensor feels: the closed form's travel
    (the project's guidance defaults) within 5%, the tray still level."""
    from pathpref.episode import Physics
    from tests.admittance_helpers import admittance_travel

    drive = Physics().drive
    moved = tidybot.guided_push(body, drive.admittance_m, drive.admittance_b, 25.0, 2.0, 1.0)
    body.admittance = None
    assert moved == pytest.approx(admittance_travel(25.0, 2.0, 1.0, drive.admittance_m,
                                                    drive.admittance_b, drive.v_max), rel=0.05)
    assert body.data.xmat[body.body].reshape(3, 3)[2, 2] == pytest.approx(1.0, abs=1e-3)
