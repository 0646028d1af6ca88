"""Search the Jaco's carrying postures on the disk: every IK solution that holds the tray level
at a tray offset from the base, with its plan reach, and the one to carry with.

    .venv/bin/python scripts/carry_posture.py [--restarts 400] [--seed 0] \\
        [--offset 0.05 0 0.75]

The Jaco has six joints and the tray's pose six coordinates, so a tray pose has finitely many
arm postures (modulo 2 pi on the unlimited joints 1, 4, 5, 6). The script finds them by
random restarts (seeded): from a posture drawn uniformly (joints 2 and 3 within their ranges,
the others in [-pi, pi)), damped least squares on the tray's pose error relative to the base
(position, and the rotation's axis-angle from the level, base-aligned tray), at most 200
iterations; a restart counts when the error is below 1e-8 (m, rad). Distinct postures (their
joints within 1e-3 rad, modulo 2 pi) are listed with

* ``reach``: the plan reach at the posture (:func:`~pathpref.sim.reach.plan_reach_m`, m),
* ``near``: the carrying body's reach, the posture and 64 postures within 0.1 rad of it
  (:func:`~pathpref.sim.reach.carry_reach_m`, m),
* ``margin``: the smallest distance from a joint limit (rad; joints 2 and 3 are limited),
* ``contacts``: contacts among the robot's own geoms (arm, base, tray) at the posture,
* ``arm_m``: the arm's and tray's own plan reach at the posture (the base's cylinder left
  out: how far inside the footprint the arm stays),
* ``sigma``: the smallest singular value of the tray's 6 x 6 Jacobian in the arm's joints
  (m or rad per rad; near 0, a singular posture),

and the chosen one printed last: the widest margin among the contact-free postures whose
``near`` is within the disk's 0.15 m footprint (``ROBOT_MODELS["disk"].footprint_m``); none is
a line saying so.
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("MUJOCO_GL", "disable")

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from pathpref.episode.physics import ROBOT_MODELS, Physics  # noqa: E402
from pathpref.geometry.world import load_world  # noqa: E402
from pathpref.sim.arm import TRAY_OFFSET  # noqa: E402
from pathpref.sim.body import base_params, build_base, scene_for  # noqa: E402
from pathpref.sim.reach import carry_reach_m, plan_reach_m  # noqa: E402

ITERATIONS = 200
TOLERANCE = 1e-8


def _wrap(q: np.ndarray, limited: np.ndarray) -> np.ndarray:
    """Unlimited joints into [-pi, pi)."""
    return np.where(limited, q, (q + np.pi) % (2 * np.pi) - np.pi)


def solve(m, d, arm_q, arm_v, root, tray, offset, q0, lim, limited) -> tuple[np.ndarray, float]:
    """Damped least squares from ``q0`` to the level tray at ``offset`` from ``root``: the
    posture and its final error (the larger of the position's and the rotation's norm)."""
    q = q0.copy()
    jp, jr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
    err = np.inf
    for _ in range(ITERATIONS):
        d.qpos[arm_q] = q
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        Rb = d.xmat[root].reshape(3, 3)
        ep = d.xpos[root] + Rb @ offset - d.xpos[tray]
        Rt = d.xmat[tray].reshape(3, 3)
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, (Rb @ Rt.T).ravel())  # the rotation taking the tray to level
        er = np.zeros(3)
        mujoco.mju_quat2Vel(er, quat, 1.0)
        err = max(float(np.linalg.norm(ep)), float(np.linalg.norm(er)))
        if err < TOLERANCE:
            break
        mujoco.mj_jacBody(m, d, jp, jr, tray)
        J = np.vstack([jp[:, arm_v], jr[:, arm_v]])
        e = np.concatenate([ep, er])
        dq = J.T @ np.linalg.solve(J @ J.T + 1e-6 * np.eye(6), e)
        q = q + dq
        q = np.where(limited, np.clip(q, lim[:, 0], lim[:, 1]), q)
    return _wrap(q, limited), err


def self_contacts(m, d, tree: int) -> int:
    """Contacts at the posture between two geoms of the robot's tree."""
    mujoco.mj_forward(m, d)
    n = 0
    for c in d.contact[:d.ncon]:
        b1, b2 = m.geom_bodyid[c.geom1], m.geom_bodyid[c.geom2]
        n += int(m.body_rootid[b1] == tree and m.body_rootid[b2] == tree)
    return n


def sigma_min(m, d, tray, arm_v) -> float:
    """The smallest singular value of the tray's Jacobian in the arm's joints."""
    jp, jr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
    mujoco.mj_jacBody(m, d, jp, jr, tray)
    return float(np.linalg.svd(np.vstack([jp[:, arm_v], jr[:, arm_v]]), compute_uv=False)[-1])


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--restarts", type=int, default=400)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--offset", type=float, nargs=3, default=list(TRAY_OFFSET),
                    help="the tray's position relative to the base body (m)")
    args = ap.parse_args(argv)
    p = Physics.of(robot_model="disk")
    scene = scene_for(load_world("simple"), p.cell_size_m, "carry", base_params(p), "disk")
    base = build_base(scene, "carry", p, np.random.default_rng(0))
    base.reset(3)
    m, d = scene.model, base.data
    joints = [m.joint(j).id for j in base.arm.joints]
    lim, limited = m.jnt_range[joints], m.jnt_limited[joints].astype(bool)
    root, tray = m.body(base.arm.base_body).id, base.tray
    offset = np.asarray(args.offset, float)
    rng = np.random.default_rng(args.seed)
    found: list[np.ndarray] = []
    for _ in range(args.restarts):
        q0 = np.where(limited, rng.uniform(lim[:, 0], lim[:, 1]),
                      rng.uniform(-np.pi, np.pi, len(joints)))
        q, err = solve(m, d, base.arm_qpos, base.arm_dofs, root, tray, offset, q0, lim,
                       limited)
        if err >= TOLERANCE:
            continue
        if not any(np.abs(_wrap(q - f, limited)).max() < 1e-3 for f in found):
            found.append(q)
    footprint = ROBOT_MODELS["disk"].footprint_m
    rows = []
    home = base.home.copy()
    for q in found:
        d.qpos[base.arm_qpos] = q
        mujoco.mj_forward(m, d)
        reach = plan_reach_m(m, d, root)
        own = plan_reach_m(m, d, root, exclude=(m.geom("base_geom").id,))
        sigma = sigma_min(m, d, tray, base.arm_dofs)
        contacts = self_contacts(m, d, m.body_rootid[root])
        base.home = q
        near = carry_reach_m(base)
        margin = float(np.min(np.minimum(q - lim[:, 0], lim[:, 1] - q)[limited]))
        rows.append((near, reach, margin, contacts, q, own, sigma))
    base.home = home
    print(f"tray offset {offset.tolist()} m; {len(found)} distinct postures from "
          f"{args.restarts} restarts (seed {args.seed})")
    print(" near_m reach_m margin_rad contacts  arm_m  sigma  posture (rad)")
    for near, reach, margin, contacts, q, own, sigma in sorted(rows, key=lambda r: r[:2]):
        print(f"{near:7.3f} {reach:7.3f} {margin:10.3f} {contacts:8d} {own:6.3f} {sigma:6.3f}  "
              f"[{', '.join(f'{x:.4f}' for x in q)}]")
    fit = [r for r in rows if r[0] <= footprint + 1e-9 and r[3] == 0]  # as check_footprint
    if not fit:
        print(f"no contact-free posture within the disk's {footprint} m footprint")
        return
    near, reach, margin, _, q, own, _ = max(fit, key=lambda r: r[2])
    print(f"chosen (widest margin within {footprint} m): reach {reach:.3f} m, near "
          f"{near:.3f} m, the arm's own {own:.3f} m, margin {margin:.3f} rad: "
          f"[{', '.join(f'{x:.4f}' for x in q)}]")


if __name__ == "__main__":
    main()
