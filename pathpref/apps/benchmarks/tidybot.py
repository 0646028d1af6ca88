"""The ``tidybot`` section of ``pathpref bench --json``: the Stanford TidyBot from MuJoCo
Menagerie carrying the tray with whole-body IK (:mod:`pathpref.sim.tidybot`).

* ``robot_model``: the compiled model's name;
* ``tray_deviation_30n_3s_mm``, ``tray_recovery_s`` (back within 10 mm),
  ``tray_recovery_1mm_s`` (back within 1 mm): a steady 30 N push on the tray for 3 s toward
  north, east, south and west on **the episode body**, the one ``--robot carry --robot-model
  tidybot`` runs (the base's velocity servos and controller, the Gen3's tray impedance:
  :func:`~pathpref.apps.benchmarks.physics.tray_push`), the worst heading; the same push on
  the stand-alone whole-body model of :mod:`pathpref.sim.tidybot` (base position servos
  ``kp`` 1e6, which no episode runs) is ``whole_body_tray_deviation_30n_3s_mm``,
  ``whole_body_tray_recovery_s``, ``whole_body_tray_recovery_1mm_s``
  (:func:`~pathpref.sim.tidybot.tray_push`);
* ``whole_body_base_share``: the share of a 0.3 m end-effector target straight ahead reached
  by base motion after 3 s (:func:`~pathpref.sim.tidybot.base_share`), and
  ``whole_body_error_m`` the tray's distance from that target then;
* ``tidybot_guidance_push_displacement_m``: 25 N on the tray for 2 s (and 1 s after) under
  the project's guidance admittance (:func:`~pathpref.sim.tidybot.guided_push`);
* the model's figures (:func:`~pathpref.sim.tidybot.physical_figures`) and
  ``tidybot_load_s`` (compiling the model with its meshes);
* ``navigate_episode_vs_bare``, ``carry_episode_vs_bare`` (this section's: the TidyBot's;
  ``arm.carry_episode_vs_bare`` is the Jaco's) and ``navigate_python_us_per_step``,
  ``carry_python_us_per_step``: the TidyBot as an episode body (``robot_model`` tidybot,
  :mod:`pathpref.sim.tidybot_base`), a ``navigate`` and a ``carry`` episode against bare
  MuJoCo plus planning on their own scenes (:func:`~.physics.episodes_vs_bare`, median over
  3 episodes, 1 when ``quick``), and their Python per physics step (us).
"""

from __future__ import annotations

import time
from typing import Any


def bench_tidybot(quick: bool = False) -> dict[str, Any]:
    """The TidyBot's keys (module docstring); ``quick`` pushes north and east only (both
    bodies)."""
    from ...sim import tidybot

    t = time.perf_counter()
    model = tidybot.build_tidybot()
    load_s = time.perf_counter() - t
    wb = tidybot.WholeBody(model)
    share = tidybot.base_share(wb, 0.3, 3.0)
    push = tidybot.tray_push(wb, 30.0, 3.0, headings=(0.0, 90.0) if quick else
                             (0.0, 90.0, 180.0, 270.0))
    from ...episode import Physics
    from .physics import tray_push

    episode_push = tray_push(30.0, 3.0, headings=(0, 2) if quick else (0, 2, 4, 6),
                             robot_model="tidybot")

    drive = Physics().drive
    guided = tidybot.guided_push(wb, drive.admittance_m, drive.admittance_b)
    from statistics import median

    from .physics import episodes_vs_bare

    episodes = {}
    for task in ("navigate", "carry"):
        ratios, python_us, _ = episodes_vs_bare(Physics.of(robot_model="tidybot"),
                                                1 if quick else 3, robot=task)
        episodes[f"{task}_episode_vs_bare"] = median(ratios)
        episodes[f"{task}_python_us_per_step"] = median(python_us)
    return {"robot_model": tidybot.robot_model(model),
            **episodes,
            "tidybot_guidance_push_displacement_m": guided,
            "tray_deviation_30n_3s_mm": episode_push["deviation_mm"],
            "tray_recovery_s": episode_push["recovery_s"],
            "tray_recovery_1mm_s": episode_push["recovery_1mm_s"],
            "whole_body_tray_deviation_30n_3s_mm": push["deviation_mm"],
            "whole_body_tray_recovery_s": push["recovery_s"],
            "whole_body_tray_recovery_1mm_s": push["recovery_1mm_s"],
            "whole_body_base_share": share["share"],
            "whole_body_error_m": share["error_m"],
            "tidybot_load_s": load_s,
            **tidybot.physical_figures(model)}
