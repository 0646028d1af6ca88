"""``pathpref bench --json --quick``: every section's keys exist and hold figures within the
bounds the docs state (docs/benchmarks.md). Its own file: the longest single test, so the
suite's two processes (``make test``) can run it beside the rest of ``test_cli.py``."""

from __future__ import annotations

import json

from pathpref.planning.pomdp import DEFAULT_PRESET

from .test_cli import run


def test_bench_json_keys():
    p = run("bench", "--json", "--quick", "--maps", "simple")
    assert p.returncode == 0, p.stderr
    res = json.loads(p.stdout)
    m = res["maps"]["simple"]
    for k in ("arrangement_build_s", "belief_update_ms", "pomcp_decision_ms",
              "pomcp_queries_per_s", "route_update_ms"):
        assert m[k] > 0
    assert m["crossing_check_ms"] is None or m["crossing_check_ms"] > 0
    # the default preset's first decision (CPU) and the robust preset's search, each named
    assert m["robust_decision_preset"] == m["default_preset"] == DEFAULT_PRESET
    for k in ("robust_decision_ms", "robust_goal_only_decision_ms", "preset_robust_decision_ms",
              "preset_robust_goal_only_decision_ms", "default_decision_ms"):
        assert m[k] > 0
    ph = res["physics"]
    assert ph["cue_sector_accuracy_no_noise"] == 1.0 and ph["cue_sector_accuracy"] >= 0.9
    assert ph["false_cues_per_hour"] == 0 and ph["episode_s"] > 0 and ph["render_fps"] > 0
    assert ph["render_fps_video"] > 0 and ph["control_steps_per_s"] > 0
    assert ph["decision_steps_per_s"] > 0 and ph["control_steps_per_s_20hz"] > 0
    arm = res["arm"]
    assert arm["ik_solves_per_s"] > 0 and arm["cue_sector_accuracy"] >= 0.9
    assert arm["tilt_rms_deg"] <= 3.0 and arm["max_penetration_mm"] <= 5.0
    assert arm["carry_episode_vs_bare"] > 1.0
    assert ph["guidance_carry_push_displacement_m"] >= 0.3  # the carry base complies
    tb = res["tidybot"]
    assert tb["robot_model"] == "tidybot" and tb["whole_body_base_share"] >= 0.2
    assert tb["tray_deviation_30n_3s_mm"] <= 60.0 and tb["tray_recovery_s"] <= 1.0
    assert tb["tray_recovery_1mm_s"] >= tb["tray_recovery_s"]
    assert tb["whole_body_tray_deviation_30n_3s_mm"] < tb["tray_deviation_30n_3s_mm"]
    # the TidyBot as an episode body: its compiled move may beat a Python loop of mj_step
    # (below 1); its carry arm steps in Python (above 1)
    assert tb["navigate_episode_vs_bare"] > 0.3
    assert tb["carry_episode_vs_bare"] > 1.0
    st = res["study"]  # every push reaches the belief; the target is <= 200 ms
    assert st["study_cues_seen"] == st["study_pushes"] and 0 < st["study_latency_ms"] < 1000
