"""The torque of the person's push about the handle's force sensor (pathpref.sim.grip), on
offsets worked out from the models: the disk's handle is a capsule from z = -0.15 to 0.05 m in
the handle body with the sensor at its origin (navigate.xml), so its centre of mass, where the
push acts, is 0.05 m below the sensor; the TidyBot's is a capsule from 0 to 0.6 m with the
sensor at its top (tidybot_base.HANDLE_LENGTH), 0.3 m below."""

import os

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from pathpref.sim.grip import rest_offset, torque  # noqa: E402


@pytest.mark.parametrize("task", ["navigate", "carry"])
@pytest.mark.parametrize("model, h", [("disk", 0.05), ("tidybot", 0.3)])
def test_rest_offset_is_the_grip_below_the_sensor(task, model, h):
    assert np.allclose(rest_offset(task, model), (0.0, 0.0, -h), rtol=0, atol=1e-9)


def test_torque_of_a_horizontal_push():
    """``r x F`` with ``r = (0, 0, -h)``: ``(h F_y, -h F_x, 0)``; one force or rows."""
    r = (0.0, 0.0, -0.05)
    assert np.allclose(torque(r, (10.0, 0.0)), (0.0, -0.5, 0.0), rtol=0, atol=1e-12)
    assert np.allclose(torque(r, [(0.0, 20.0), (3.0, -4.0)]),
                       [(1.0, 0.0, 0.0), (-0.2, -0.15, 0.0)], rtol=0, atol=1e-12)
