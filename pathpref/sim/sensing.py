"""What the robot measures of a push: the handle's force sensor rotated into the world frame.

The force sensor at ``handle_site`` reports, in the site frame, the force between the handle and
the base; a push ``F`` on the handle reads ``-F`` (minus the handle's own weight and inertia).
So the horizontal interaction force in the world frame is ``-(R f)_xy`` with ``R`` the site's
rotation (``site_xmat``). The robot never reads ``xfrc_applied``.
"""

from __future__ import annotations

import numpy as np


class HandleSensor:
    """Reads the horizontal interaction force at a site with a force sensor."""

    def __init__(self, model, sensor: str = "handle_force", site: str = "handle_site"):
        self.adr = int(model.sensor(sensor).adr[0])
        self.site = int(model.site(site).id)

    def force_xy(self, data) -> np.ndarray:
        """The horizontal interaction force (N) in the world frame."""
        f_site = data.sensordata[self.adr:self.adr + 3]
        R = data.site_xmat[self.site].reshape(3, 3)
        return -(R @ f_site)[:2]
