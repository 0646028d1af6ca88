"""The physical carry arm's arithmetic of one physics step (:class:`~.arm.ArmBase`, module
docstring "Compliant arm"): the tray impedance's joint torques and the servo targets that
realise them. One copy, compiled: the Python step (:meth:`~.arm.ArmBase._control_physical`)
and the compiled move (:mod:`.coasting`) both call :func:`arm_step`."""

from __future__ import annotations

import math

import numba as nb

from .native import mj_jacBody


@nb.njit(cache=True, inline="always")
def tray_impedance_into(data, arm, scratch):  # pragma: no cover - compiled
    """The arm joints' torques of the tray impedance (module docstring, "Compliant arm"), N m,
    into the scratch's ``tau``, on MuJoCo's arrays (allocating nothing: the compiled move
    calls it too). The records (:meth:`~.arm.ArmBase.arm_args`): ``data`` = MuJoCo's
    ``(xpos, xmat, qvel, qpos, ctrl)``; ``arm`` = ``(bodies, rel, jac, dofs, qadr, q_kin,
    gains, kp, ctrl_idx)``: ``bodies`` = (base, tray) body ids, ``rel`` the 3x4
    ``[R_rel | p_rel]`` (the tray's pose relative to the base in the kinematic
    configuration), ``jac`` the tray's 6 x nv Jacobian (translational rows over rotational,
    ``mj_jacBody``), ``dofs``, ``qadr`` the arm joints' velocity and position addresses,
    ``gains`` = (K, D, K_r, D_r, k_0); ``scratch`` = ``(R_d, f, m, tau)`` (3 x 3, 3, 3, the
    joints')::

        p_d = p_b + R_b p_rel,  R_d = R_b R_rel
        F   = K (p_d - p) - D J_p q_dot,   M = K_r e_r - D_r J_r q_dot
        e_r = 1/2 sum_i r_i x r_d,i   (r_i, r_d,i the columns of R, R_d)
        tau = J_p^T F + J_r^T M + k_0 (q_kin - q)
    """
    xpos, xmat, qvel, qpos = data[0], data[1], data[2], data[3]
    bodies, rel, jac, dofs, qadr, q_kin, gains = arm[0], arm[1], arm[2], arm[3], arm[4], \
        arm[5], arm[6]
    Rd, f, m, tau = scratch
    base, tray = bodies[0], bodies[1]
    k, dmp, kr, dr, k0 = gains[0], gains[1], gains[2], gains[3], gains[4]
    Rb = xmat[base].reshape(3, 3)
    R = xmat[tray].reshape(3, 3)
    for a in range(3):
        for c in range(3):
            Rd[a, c] = Rb[a, 0] * rel[0, c] + Rb[a, 1] * rel[1, c] + Rb[a, 2] * rel[2, c]
    n = dofs.shape[0]
    for a in range(3):
        v = 0.0
        w = 0.0
        for j in range(n):
            qd = qvel[dofs[j]]
            v += jac[a, dofs[j]] * qd
            w += jac[3 + a, dofs[j]] * qd
        p_d = xpos[base, a] + Rb[a, 0] * rel[0, 3] + Rb[a, 1] * rel[1, 3] + Rb[a, 2] * rel[2, 3]
        b, c = (a + 1) % 3, (a + 2) % 3
        e = 0.0
        for i in range(3):  # (r_i x r_d,i)_a
            e += R[b, i] * Rd[c, i] - R[c, i] * Rd[b, i]
        f[a] = k * (p_d - xpos[tray, a]) - dmp * v
        m[a] = kr * (0.5 * e) - dr * w
    for j in range(n):
        t = k0 * (q_kin[j] - qpos[qadr[j]])
        for a in range(3):
            t += jac[a, dofs[j]] * f[a] + jac[3 + a, dofs[j]] * m[a]
        tau[j] = t


@nb.njit(cache=True)
def arm_step(mj, data, arm, scratch):  # pragma: no cover - compiled
    """The physical arm's servo targets of one physics step (:meth:`ArmBase.
    _control_physical`): the tray's Jacobian (MuJoCo's ``mj_jacBody``, the C function the
    bindings call, on ``mj`` = the ``MjModel``'s and ``MjData``'s addresses), the impedance
    torques (:func:`tray_impedance_into`, whose records these are), then ``ctrl = q + tau /
    kp`` per arm joint (the servo's force ``kp (ctrl - q) - kv q_dot`` is then ``tau - kv
    q_dot``). The Python step and the compiled move both call it."""
    qvel, qpos, ctrl = data[2], data[3], data[4]
    jac, dofs, qadr, kp, ctrl_idx = arm[2], arm[3], arm[4], arm[7], arm[8]
    tau = scratch[3]
    nv = qvel.shape[0]
    mj_jacBody(mj[0], mj[1], jac.ctypes.data, jac.ctypes.data + 3 * nv * 8, arm[0][1])
    tray_impedance_into(data, arm, scratch)
    for j in range(dofs.shape[0]):
        ctrl[ctrl_idx[j]] = qpos[qadr[j]] + tau[j] / kp[j]


@nb.njit(cache=True)
def tilt_from(r_zz):
    """The tray's tilt (degrees) from its orientation's ``R_zz`` (``xmat[tray, 8]``):
    ``acos(R_zz)``, the entry clipped to [-1, 1]; CPython's ``math.degrees`` is the product by
    ``180 / pi``, as here. The one arithmetic of the Python step and the compiled move."""
    return math.degrees(math.acos(min(1.0, max(-1.0, r_zz))))
