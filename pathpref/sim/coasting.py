"""A move or a push phase, compiled: the same physics steps at a fraction of the Python.

95 % of a physical episode's steps are a base driving to a cell with nobody pushing it, 4 % a
push phase (``docs/physics.md``, section 11). Each is, in Python: the profiled controller's
law, the push's force, one ``mj_step``, the realistic sensor's window (with the extra mass's
inertia), every fifth step a sensor sample (drift and noise drawn, the estimator's inertial
compensation and bias tracking), the detector's low-pass, calibration and hysteresis, the
measurements and the phase's end check. :func:`_coast` runs these steps in one numba call,
operation for operation as :meth:`~.mobile_base.MobileBase.substep` and
:meth:`~.decision.DecisionStep.advance` do them (the methods it mirrors are named at each
part; each part is one compiled function that the Python step calls too), with the C
functions of :mod:`.native` (the same ``mj_step``, the same BLAS kernels, CPython's
``hypot``) and the sensor's own NumPy ``Generator`` (numba draws the same normals from the
same bit generator). So an episode is the same bit for bit whichever path runs it:
``tests/test_coasting.py`` runs episodes both ways and compares every state, cue and metric
exactly.

The kernel hands back to Python, before or within a step, whenever something it does not mirror
may happen: a cue begins, goes active, ends or is given (after the detector's step: the cue
stream and the push phase's end run in Python, :data:`DETECT`), the base touches something
(the contact measurements, :data:`CONTACTS`), an ``on_substep`` hook acts (a polytope change
for the path's crossing hook, a path recorder's sample: :data:`CROSS`), or the move or push
phase ends (:data:`END`: settled, or its time is up). It runs only where it applies
(:meth:`Coaster.applies`, :meth:`Coaster.ready`): each part it runs declares so in its own
class, with the modes it runs (:mod:`.kernel_parts`: safe by default, a part or mode that
does not declare keeps the Python path); so: a plain :class:`~.mobile_base.MobileBase`, or
the physical carry arm's (:class:`~.arm.ArmBase`: its servo targets of the tray impedance,
:func:`~.arm_step.arm_step`, at every step, the tilt recorded; its IK solve runs before the
kernel's steps, :meth:`~.arm.ArmBase.kernel_prepare`, and the next one due hands back, as a
contact does), on the profiled controller's float path, the faulty sensor without thermal drift
and its estimator, the filtered detector (idle, or through a push phase's cue), a push phase's
one push or none, no pushes at any time or external forces, a guided base's admittance at most
in its tail (no cue under way; the command through the safety filter), no ``pre_substep`` hook
but a quiet one (the simulated human of pushes at any time runs the kernel up to its next
push), no ``on_substep`` hook but the path's crossing hook and quiet ones, a scene with the
contact sensor it reads (:data:`CONTACT_SENSOR`). A control-rate task's drive runs on it too
(:meth:`Coaster.drive`: the agent's velocity held, :class:`~.controller.HeldVelocity`, no move
to end; :meth:`Coaster.push` through a push phase), and a timed move (guidance: its drive,
then the hold). Every other step takes the Python path. ``PATHPREF_COMPILED_STEPS=0`` (or
``false``, ``off``: :mod:`pathpref.switches`) turns it off (read when a base is built).
"""

from __future__ import annotations

import math

import mujoco
import numba as nb
import numpy as np

from ..switches import switch
from . import native
from .arm_step import arm_step, tilt_from
from .controller import HeldVelocity, profiled_goal, ramp_step, settled_at
from .cue_detector import ABOVE, ACTIVE, D_OFF, D_ON, D_VAR, decide_step, filter_step
from .decision import PUSH as PUSH_PHASE
from .estimator import E_AT_REST, E_ESTIMATES, E_QUIET, estimate_step
from .force_cue import push_force
from .guidance import admit_step
from .keep_clear import keep_clear_xy
from .kernel_parts import declared, runs
from .measurements import (
    M_ESTIMATE,
    M_PEAK,
    M_PEAK_FORCE,
    M_PEAK_PUSHED,
    M_T,
    M_TOUCHING,
    M_VX,
    M_VY,
    planar_accel,
)
from .native import hypot, mj_step
from .path_crossings import PathCrossings
from .path_record import PathRecorder
from .scene import grid_cell
from .sensing import W_MEAN, W_WINDOW_S, emit_step, window_step

#: hand-back reasons of :func:`_coast` (``CROSS``: an ``on_substep`` hook acts at this step:
#: the base entered another polytope, or a cell the grid's lookup does not hold, with a
#: :class:`~.path_crossings.PathCrossings` hook, or a quiet hook's step count ran out)
READY, END, DETECT, CONTACTS, DIVERGED, CROSS = range(6)
#: the kernel's own floats (the parts' state is in their records, read and written in
#: place): whether the detector gave a cue at a hand-back, the velocity a contact met, the
#: simulated time (MjData's, advanced as mj_step advances it)
CUE, VPX_OLD, VPY_OLD, TIME, N_FS = range(5)
#: constants: controller, sensor, estimator, detector, the move
(KP, V_MAX, BRAKE, A_MAX, C_DT, K_YAW, TOL, DT, PERIOD, DRIFT_STEP, NOISE, EXTRA_M, T0, MIN_S,
 T_END, STILL, T_STOP, H, ALPHA, CELL, RADIUS, A_BRAKE, N_CS) = range(23)
#: integers: addresses, flags, the polytope the base is in and the step a quiet hook is due
(IX, IY, IYAW, A0, A1, A2, VX, VY, SADR, BODY, HOLD_N, MEASURE, DRIFT, AUTORESET, CADR,
 HELD, FILTER, GUIDED, POLY, HOOK_IN, PUSHING, INTERACT, N_IS) = range(23)
#: the scene's sensor that counts the contacts of the last collision pass (``mjcf/navigate.xml``)
CONTACT_SENSOR = "contact_count"
#: mjtWarning's bad-state warnings: mj_step resets the data on one (unless autoreset is off)
BAD_STATE = np.array([int(mujoco.mjtWarning.mjWARN_BADQPOS),
                      int(mujoco.mjtWarning.mjWARN_BADQVEL),
                      int(mujoco.mjtWarning.mjWARN_BADQACC)])


@nb.njit(cache=True, inline="always")
def _bad_states(warnings):
    """How many bad-state warnings MuJoCo has counted (``mjData.warning[i].number``)."""
    n = 0
    for i in BAD_STATE:
        n += warnings[i]
    return n


@nb.njit(cache=True)
def _arm_part(arm, step):
    """The physical carry arm's part of kernel step ``step`` (``ArmBase._control_physical``
    between IK solves): True (hand back before the step) when an IK solve is due and has
    not run (:meth:`~.arm.ArmBase.kernel_prepare`) or the tilt record is full, else the servo
    targets of the tray impedance (:func:`~.arm_step.arm_step`) and the tray's tilt recorded
    (:func:`~.arm_step.tilt_from`). ``arm`` is ``(arm_step's arguments, tilts, ak)``, ``ak``
    = (steps since the reset, IK period in steps, the step whose IK ran); None (no arm)
    compiles to nothing (numba prunes the branch of an argument typed None)."""
    if arm is None:
        return False
    arm_args, tilts, ak = arm
    if (ak[0] % ak[1] == 0 and ak[2] != ak[0]) or step >= tilts.shape[0]:
        return True
    ak[0] += 1
    arm_step(*arm_args)
    tilts[step] = tilt_from(arm_args[1][1][arm_args[2][0][1], 8])  # xmat[tray, 8]
    return False


@nb.njit(cache=True, _nrt=False)
def _coast(mj, robot, drive, sensor, rng, eparams, est, det, guide, arm, meas, fs, cs, ns,
           max_steps):
    """Physics steps of the move phase, a push phase (``ns[PUSHING]``: :meth:`Coaster.push`)
    or a drive (:meth:`Coaster.drive`) until a hand-back (module docstring); returns
    ``(reason, steps)``. Every array is the part's own, updated in place: the sensor's held
    sample receives each new sample, ``est`` (:func:`~.estimator.estimate_step`'s arrays) the
    estimator's acceleration and estimate, and the sensor's window and the estimator's record
    number them (:data:`~.sensing.W_SAMPLES`, :data:`~.estimator.E_ESTIMATES`). The records:
    ``mj`` the ``MjModel``'s and ``MjData``'s addresses; ``robot`` MuJoCo's ``(qpos, qvel,
    ctrl, sensordata)``, the sensor site's rotation and MuJoCo's warning counts
    (``mjData.warning[i].number``);
    ``drive`` the controller's last command, the target, a scratch pair, the held goal
    velocity (``ns[HELD]``: :class:`~.controller.HeldVelocity`), the task's filtered force
    (``ns[FILTER]``: low-passed by ``cs[ALPHA]`` at the end of every step), the push record
    (:meth:`~.force_cue.HumanPush.record`), the pushed body's ``xfrc_applied`` row and the
    task's interaction record (:class:`~pathpref_tasks.stage.StepInteraction`'s ``rec``:
    ``[active_s]`` gains the timestep at every step the detector is active,
    ``ns[INTERACT]``); ``sensor`` the faulty sensor's drift bias, its held sample, its window
    (:func:`~.sensing.window_step`'s ``win``, the sensor's own) and scratch; ``rng`` its
    ``Generator``'s pointers (:func:`~.sensing.emit_step`); ``eparams`` the estimator's
    constants and its record (:data:`~.estimator.E_QUIET`, ...); ``det``
    :func:`~.cue_detector.filter_step`'s arrays and constants, then the detector's state,
    rule and scratch (:func:`~.cue_detector.decide_step`) and its record
    (:data:`~.cue_detector.D_VAR`, ...); ``guide`` the map for a guided
    base at rest or a motion off the grid's clear moves (``ns[GUIDED]``: the command through
    :func:`~.keep_clear.keep_clear_xy`, the
    map's ``Clearance.arrays`` and rows) and for its path's crossings (``ns[POLY] >= 0``: the
    polytope the base is in; the grid's ``cell_index`` and ``cell_polytope``), then the
    guidance's record (``[moving]``); ``arm`` the physical carry arm's record
    (:func:`_arm_part`; None: no arm); ``meas`` the measurements' record
    (:data:`~.measurements.M_VX`, ...). The parts' records are each part's own ``rec``,
    read and written in place (:class:`~.kernel_parts.Slot`). Simulated time is
    ``fs[TIME]``, advanced by ``mj_step``'s own operation (``time += timestep``)."""
    mp, dp = mj
    qpos, qvel, ctrl, sensordata, R, warnings = robot
    last, target, err, goal, filt, pp, wrench, irec = drive
    sbias, held, win, scratch = sensor
    eparams, erec = eparams
    f, baseline, dring, dqueue, dparams, st, rule, dbuf, drec = det
    clr, rows, cell_index, cell_polytope, gv, gdef, gparams, grec = guide
    nq, nv = qpos.shape[0], qvel.shape[0]
    eforce, equeue = est[7], est[6]
    for step in range(max_steps):
        if fs[TIME] >= cs[T_STOP]:  # a pre_substep hook acts now (Coaster.ready: not at 0)
            return READY, step
        # --- MobileBase.substep's push (HumanPush.active, apply: the whole wrench written;
        # a force that is not finite is Python's to refuse), else the wrench cleared
        if ns[PUSHING]:
            tp = fs[TIME]
            if pp[0] <= tp <= pp[0] + pp[1]:
                push_force(int(pp[4]), pp[2], pp[1], pp[3], tp - pp[0], wrench)
                if not (math.isfinite(wrench[0]) and math.isfinite(wrench[1])):
                    return READY, step
            else:
                wrench[0] = wrench[1] = wrench[2] = 0.0
            wrench[3] = wrench[4] = wrench[5] = 0.0
        # --- ArmBase._control_physical (an arm's record; None: no arm)
        if _arm_part(arm, step):
            return READY, step
        # --- MobileBase._control: a guided base's admittance tail (Guidance.admit, no cue
        # under way: Coaster.ready), then the float path: ProfiledController.goal_xy
        # (HeldVelocity's: the held command) and ramp_xy
        if grec[0] != 0.0:
            grec[0] = 1.0 if admit_step(gv, target, gdef, gv, False, gparams, clr) else 0.0
        if ns[HELD]:
            gx, gy = goal[0], goal[1]
        else:
            gx, gy = profiled_goal(qpos[ns[IX]], qpos[ns[IY]], target[0], target[1], cs[KP],
                                   cs[V_MAX], cs[BRAKE], cs[A_MAX])
        lx, ly = ramp_step(gx, gy, last, cs[A_MAX] * cs[C_DT])
        if ns[GUIDED]:  # MobileBase._base_command under guidance: the admittance's velocity
            if grec[0] != 0.0:  # as feedforward within v_max, then the safety filter
                lx, ly = lx + gv[0], ly + gv[1]
                speed = hypot(lx, ly)
                if speed > cs[V_MAX]:
                    q = cs[V_MAX] / speed
                    lx, ly = lx * q, ly * q
            lx, ly = keep_clear_xy(qpos[ns[IX]], qpos[ns[IY]], lx, ly, cs[CELL], cs[RADIUS],
                                   cs[A_BRAKE], clr, rows)
        ctrl[ns[A0]], ctrl[ns[A1]], ctrl[ns[A2]] = lx, ly, -cs[K_YAW] * qpos[ns[IYAW]]
        # --- mj_step and the divergence check
        bad = _bad_states(warnings)
        mj_step(mp, dp)
        # mj_step's time: its integrator adds the timestep (d->time += m->opt.timestep),
        # after resetting the data (time 0) on a bad state unless autoreset is off
        if ns[AUTORESET] and _bad_states(warnings) != bad:
            fs[TIME] = 0.0
        fs[TIME] += cs[H]
        for i in range(nq):
            if not math.isfinite(qpos[i]):
                return DIVERGED, step + 1
        for i in range(nv):
            if not math.isfinite(qvel[i]):
                return DIVERGED, step + 1
        t = fs[TIME]
        # a cue under way (SensingChain.under_way) before this step's sample
        under_way = st[ACTIVE] != 0.0 or st[ABOVE] > 0.0
        # --- FaultySensor.read: the window, with the extra mass's inertia
        a = ns[SADR]
        fresh = window_step(mp, dp, ns[BODY], sensordata[a:a + 3], R, cs[EXTRA_M], scratch, win,
                            t, cs[DT], cs[PERIOD])
        measured = False
        if fresh:
            # FaultySensor._emit (no thermal offset: Coaster.ready)
            emit_step(rng, win[W_MEAN:W_MEAN + 3], sbias, ns[DRIFT] != 0, cs[DRIFT_STEP],
                      cs[NOISE], held)
            # ForceEstimator.update (fresh; the bias tracked only with no cue under way)
            estimate_step(mp, dp, ns[BODY], held, R, qvel, win[W_WINDOW_S], not under_way,
                          eparams, erec, est)
            measured = True
        elif under_way:  # ForceEstimator.update between samples, a cue under way
            erec[E_QUIET], erec[E_AT_REST] = 0.0, 0.0
            equeue[0], equeue[1] = 0, 0
        # --- FilteredCueDetector.update (the estimate held between samples): the low-pass
        # and calibration, then, unless the idle test answers, decide_step; a cue given, or
        # a cue under way begun, active or over hands the rest of the step to Python
        x, y = eforce[0], eforce[1]
        if math.isfinite(x) and math.isfinite(y):
            drec[D_VAR], drec[D_ON], drec[D_OFF], ex, ey, quiet = filter_step(
                x, y, not under_way, erec[E_AT_REST] != 0.0, f, baseline, dring, dqueue,
                drec[D_VAR], drec[D_ON], drec[D_OFF], dparams, ns[HOLD_N])
            if not quiet:
                was_active = st[ACTIVE]
                given = decide_step(ex, ey, st, baseline, dqueue, drec[D_ON], drec[D_OFF], rule,
                                    dbuf)
                if given or st[ACTIVE] != was_active or \
                        (st[ACTIVE] != 0.0 or st[ABOVE] > 0.0) != under_way:
                    fs[CUE] = given
                    return DETECT, step + 1
        # --- Measurements.update (nothing pushes: Coaster.ready)
        if ns[MEASURE]:
            vx, vy = qvel[ns[VX]], qvel[ns[VY]]
            acc = planar_accel(vx, vy, meas[M_VX], meas[M_VY], t, meas[M_T], cs[DT])
            fs[VPX_OLD], fs[VPY_OLD] = meas[M_VX], meas[M_VY]
            meas[M_VX], meas[M_VY], meas[M_T] = vx, vy, t
            if acc > meas[M_PEAK_PUSHED]:
                meas[M_PEAK_PUSHED] = acc
            # (not while a push acts or within 0.1 s of its end: MobileBase._pushed_now)
            if acc > meas[M_PEAK] and not (ns[PUSHING] and pp[0] <= t <= pp[0] + pp[1] + 0.1):
                meas[M_PEAK] = acc
            if measured:  # a new estimate (Measurements.update: by its number)
                meas[M_ESTIMATE] = erec[E_ESTIMATES]
                h = hypot(eforce[0], eforce[1])
                if h > meas[M_PEAK_FORCE]:
                    meas[M_PEAK_FORCE] = h
            if sensordata[ns[CADR]] > 0.0:  # mjData.ncon, from the contact sensor
                return CONTACTS, step + 1
            meas[M_TOUCHING] = 0.0
        # --- PathCrossings (the on_substep hook; nothing pushes): the polytope under the base
        # (Scene.cell_at's grid lookup); another one, or a cell off the lookup, in Python
        if ns[POLY] >= 0:
            idx = grid_cell(qpos[ns[IX]], qpos[ns[IY]], cs[CELL], cell_index)
            if idx < 0 or cell_polytope[idx] != ns[POLY]:
                return CROSS, step + 1
        if step + 1 >= ns[HOOK_IN]:  # a quiet on_substep hook is due (PathRecorder's sample)
            return CROSS, step + 1
        # --- DecisionStep.move_ended: settled (TrackingController.settled; not yielding,
        # as nothing pushes) or time up; the push phase's end (its time up: the detector's
        # reset is Python's, before the task's part of the step)
        if t - cs[T0] >= cs[MIN_S]:
            if settled_at(target[0], target[1], qpos[ns[IX]], qpos[ns[IY]], qvel[ns[VX]],
                          qvel[ns[VY]], cs[TOL], cs[STILL], err):
                return END, step + 1
        if t >= cs[T_END]:
            return END, step + 1
        # --- the task's part of the step: the low-pass of the estimate (navigate_control:
        # stage.ForceFilter.update) and the detector's active time (StepInteraction.update)
        if ns[FILTER]:
            f0, f1 = filt[0], filt[1]
            filt[0], filt[1] = f0 + cs[ALPHA] * (eforce[0] - f0), f1 + cs[ALPHA] * (eforce[1] - f1)
        if ns[INTERACT] and st[ACTIVE] != 0.0:
            irec[0] += cs[H]
    return READY, max_steps


def compiled_entry(args: tuple):
    """The compiled overload of :func:`_coast` for ``args``' numba types
    (:func:`~.native.entry_point`: numba's dispatcher would type all ~50 arrays on every
    call, half the Python of a 10-step call; a :class:`Coaster` resolves it once per setup,
    the constants' key: the arrays it passes are the same kinds, shapes and layouts for as
    long as that key holds)."""
    return native.entry_point(_coast, args)


def enabled() -> bool:
    """Compiled steps are on (the switch ``PATHPREF_COMPILED_STEPS``, :mod:`pathpref.switches`:
    on unless ``0``, ``false`` or ``off``) and available."""
    return switch("PATHPREF_COMPILED_STEPS") and native.ready()


class Coaster:
    """Runs the move phase of one base through :func:`_coast` (module docstring)."""

    #: the most steps one kernel call takes before it hands back (a bound; a move is shorter)
    MAX_STEPS = 1_000_000

    def __init__(self, base):
        self.base = base
        self._data = None

    def __getstate__(self) -> dict:
        """A copy's state (``copy.deepcopy``, a task's snapshot): the base only; the copy binds
        its arrays and addresses (:meth:`_bind`) and resolves its constants at its first run."""
        return {"base": self.base, "_data": None}

    @staticmethod
    def applies(base) -> bool:
        """The base's setup is one the kernel mirrors: a sensor with faults, and the base,
        its detector, controller, measurements and guidance (if any) each of a class that
        declares the kernel runs it (:func:`~.kernel_parts.declared`: safe by default; the
        base checks whether compiled steps are on, :func:`enabled`, with the scene's contact
        sensor: ``base.compiled_steps``)."""
        s = base.sensing
        return (s.sensor_model is not None and declared(base) and declared(s.detector)
                and declared(base.controller) and declared(base.measurements)
                and (base.guidance is None or declared(base.guidance)))

    def _quiet_until(self) -> float:
        """The time before which every ``pre_substep`` hook does nothing (each says so with a
        ``quiet_until()``, e.g. :class:`~.pushing_human.PushingHuman`; -inf: one cannot)."""
        t = math.inf
        for hook in self.base.pre_substep:
            quiet = getattr(hook, "quiet_until", None)
            t = min(t, -math.inf if quiet is None else quiet())
        return t

    def ready(self) -> bool:
        """The next step is one the kernel mirrors: every part in a mode the kernel runs
        (:func:`~.kernel_parts.runs`: the base, the faulty sensor, its estimator, the
        detector, the controller, the measurements, the guidance), no pushes at any time,
        no ``on_substep`` hook but one :class:`~.path_crossings.PathCrossings`, every
        ``pre_substep`` hook quiet now, no waypoint on the way
        (:meth:`.decision.DecisionStep.move`), and either no cue under way (a guidance
        admittance may still move: its tail) or the push phase of a base that neither yields
        nor is guided (its cue runs in the kernel)."""
        b = self.base
        s = b.sensing
        f = s.faulty
        if b.decision.phase == PUSH_PHASE:
            cues = b.admittance_b is None and b.guidance is None
        else:
            cues = not b.cue_open and not s.under_way
        return (cues and b.decision.final is None and not b.pushes and self._hooks_mirrored()
                # (the base, detector, controller, measurements and guidance declare:
                # applies, asked with the coaster; the sensor and estimator exist after a reset)
                and b.kernel_ready() and f is not None and runs(f) and runs(s.estimator)
                and s.detector.kernel_ready() and b.controller.kernel_ready()
                and b.measurements.kernel_ready()
                and (b.guidance is None or b.guidance.kernel_ready())
                and (not b.pre_substep or b.data.time < self._quiet_until())
                and not b.external_forces)

    def _hooks_mirrored(self) -> bool:
        """Every ``on_substep`` hook is one the kernel runs without: at most one
        :class:`~.path_crossings.PathCrossings` (reset: its polytope known, no crossing
        pending: its hysteresis is Python's), whose polytope check the kernel makes, and
        path recorders (:class:`~.path_record.PathRecorder`), which say how many steps they
        stay quiet (``quiet_steps()``, ``skip(n)``)."""
        crossings = 0
        for hook in self.base.on_substep:
            if type(hook) is PathCrossings:
                crossings += 1
                if hook.v < 0 or hook.pending is not None:
                    return False
            elif type(hook) is not PathRecorder:
                return False
        return crossings <= 1

    def _hook_state(self) -> tuple[int, int]:
        """The polytope of the base's :class:`~.path_crossings.PathCrossings` (-1: none) and
        the step (1-based) of this run at which a quiet hook is due."""
        poly, due = -1, self.MAX_STEPS + 1
        for hook in self.base.on_substep:
            if type(hook) is PathCrossings:
                poly = hook.v
            else:
                due = min(due, hook.quiet_steps() + 1)
        return poly, due

    def _skip_hooks(self, n: int) -> None:
        """``n`` steps ran in the kernel without the quiet hooks."""
        if n > 0:
            for hook in self.base.on_substep:
                if type(hook) is not PathCrossings:
                    hook.skip(n)

    def _bind(self) -> None:
        b = self.base
        d = b.data
        self._warnings = d.warning.number
        self._R = d.site_xmat[b.sensing.sensor.site].reshape(3, 3)
        #: the kernel's temporaries (it allocates nothing: compiled without reference counts)
        self._err = np.zeros(2)
        self._data = d
        self._mj = native.addresses(b.model, d)
        # MjData's arrays (views of its buffers, which stay put)
        self._robot = (d.qpos, d.qvel, d.ctrl, d.sensordata, self._R, self._warnings)
        self._key = None  # the objects the constants were built from (_constants)
        sc = b.scene
        self._guide = (sc.clearance.arrays, sc.clearance.near_rows,
                       sc.cell_index,
                       np.ascontiguousarray(sc.world.cell_polytope, dtype=np.int64))
        #: the kernel's compiled overload for the constants' objects (:func:`compiled_entry`)
        self._entry = None
        #: the push record of no push phase (:meth:`~.force_cue.HumanPush.record`'s kind)
        self._no_push = np.zeros(5)
        #: the record of no guidance and of no interaction (the kernel leaves it at 0)
        self._no_rec = np.zeros(1)
        #: the kernel's own floats (slots ``CUE`` ...)
        self._fs = np.zeros(N_FS)

    def move(self, step) -> bool:
        """Steps of ``step``'s move phase (a :class:`~.decision.DecisionStep`) through the
        kernel and, after a hand-back within a step, the rest of that step in Python; True
        when the phase ended. A timed move runs at most its steps left, its drive with the
        move's end check, the hold after it without one
        (:meth:`~.decision.DecisionStep.kernel_bounds`)."""
        t0, min_s, t_end, left = step.kernel_bounds()
        if left is None:
            reason, _, fs = self._run(t0, min_s, t_end, self.MAX_STEPS)
            return self._hand_back(reason, step, fs)
        reason, k, fs = self._run(t0, min_s, t_end, left)
        if reason in (READY, END):  # every step taken here (else the last is move_ended's)
            step.add_steps(k)
            if reason == END:
                step.hold_after_drive(None)
            return step.timed_out()
        step.add_steps(k - 1)
        return self._hand_back(reason, step, fs)

    def push(self, step, n: int = MAX_STEPS, force_filter=None, interaction=None
             ) -> tuple[int, bool, bool]:
        """Up to ``n`` physics steps of ``step``'s push phase (a
        :class:`~.decision.DecisionStep`; the push acts, the detector runs through its cue),
        ``force_filter`` and ``interaction`` as :meth:`drive` and :meth:`_run` take them.
        Returns ``(steps, partial, ended)``: the steps taken, whether the last one was handed
        back within the step (its base part finished here, the caller's part of it still to
        do) and whether the phase ended with it (:meth:`~.decision.DecisionStep.push_ended`:
        a cue, or its time up)."""
        t0, min_s, t_end, _ = step.kernel_bounds()
        push = step.current_push
        reason, steps, fs = self._run(t0, min_s, t_end, n, force_filter, push, interaction)
        if reason == READY:
            return steps, False, False
        if reason == DIVERGED:
            self._hand_back(reason, step, fs)
        cue = None if reason == END else self._finish(reason, fs, push)
        return steps, True, step.push_ended(cue)

    def drive(self, n: int, force_filter=None) -> tuple[int, bool]:
        """Up to ``n`` physics steps of a drive with no move to end (a control-rate task's
        steps outside a push phase: the base's :class:`~.controller.HeldVelocity` or profiled
        law toward its target), ``force_filter`` (an object with ``f``, two floats low-passed
        by ``alpha``: ``f += alpha (F_hat - f)``, updated in place after every step; None:
        none). Returns ``(steps, partial)``: the physics steps taken (0 when a ``pre_substep``
        hook acts now) and whether the last one was handed back within the step (the base's
        part of it finished here in Python, the caller's per-step work after the base's
        ``substep`` still to do)."""
        reason, steps, fs = self._run(0.0, math.inf, math.inf, n, force_filter)
        if reason == DIVERGED:
            self._hand_back(reason, None, fs)
        if reason in (DETECT, CONTACTS, CROSS):
            self._finish(reason, fs)
            return steps, True
        return steps, False

    def _constants(self, force_filter) -> tuple[np.ndarray, np.ndarray]:
        """The kernel's constants ``cs`` and integers ``ns`` for the base's controller,
        sensor, detector and measurement switch (built again when one of them changes)."""
        b = self.base
        s, c = b.sensing, b.controller
        f, det = s.faulty, s.detector
        k, g = self._key, b.guidance
        if k is None or k[0] is not c or k[1] is not f or k[2] is not det or \
                k[3] != b.measure or k[4] is not force_filter or k[5] is not g:
            spec = f.spec
            self._cs = np.array([c.kp, c.v_max, c.brake, c.a_max, c.dt, c.k_yaw, c.tol_m, f.dt,
                                 f.period, f.drift_step, spec.noise_n, f.extra_m, 0.0, 0.0,
                                 0.0, c.still_mps, 0.0, b.model.opt.timestep, 0.0,
                                 b.scene.cell_size,
                                 b.scene.world.footprint.radius * b.scene.cell_size,
                                 0.5 * c.a_max])
            autoreset = not b.model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_AUTORESET
            self._ns = np.array([*b.kernel_addresses(),
                                 s.sensor.adr, f.body, det.hold_n, int(b.measure),
                                 int(spec.drift_n_per_sqrt_s > 0), int(autoreset),
                                 b.model.sensor(CONTACT_SENSOR).adr[0],
                                 int(type(c) is HeldVelocity), 0, 0, int(b.guidance is not None),
                                 -1, 0, 0, 0],
                                dtype=np.int64)
            self._guide_args = (*self._guide, *self._guidance())
            self._key = (c, f, det, b.measure, force_filter, g)
            self._entry = None  # resolved again (compiled_entry) at the next call
            self._arm = b.compiled_arm() is not None
        cs, ns = self._cs, self._ns
        cs[ALPHA] = 0.0 if force_filter is None else force_filter.alpha
        ns[FILTER] = force_filter is not None
        ns[POLY], ns[HOOK_IN] = self._hook_state()
        return cs, ns

    def _guidance(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The guidance admittance's velocity, deformation and :func:`~.guidance.admit_step`
        parameters (zeros, unused, without guidance)."""
        b, g = self.base, self.base.guidance
        if g is None:
            return self._err, self._err, np.zeros(7)
        return g.v, g.deformation, g.step_params(b)

    def _run(self, t0: float, min_s: float, t_end: float, max_steps: int, force_filter=None,
             push=None, interaction=None) -> tuple[int, int, list]:
        """One kernel call on the parts' own state: ``(reason, steps, fs)``, ``fs`` the
        kernel's floats after it (a list, slots as :data:`CUE` ...). The parts' arrays (the
        estimator's, detector's, measurements', guidance's and interaction's ``rec``, the
        sensor's window and held sample, the estimator's estimate, the controller's ramp, the
        task's filter) are read and written in place, nothing copied: a new sample and a new
        estimate are told by their numbers in the parts' records, as on the Python path
        (:attr:`~.sensing.FaultySensor.samples`, :attr:`~.estimator.ForceEstimator.estimates`,
        the measurements' :meth:`~.measurements.Measurements.holds`). The move's
        start ``t0``, shortest time ``min_s`` and end ``t_end`` (s); ``push`` the push phase's
        :class:`~.force_cue.HumanPush` (None: no push phase), ``interaction`` an object whose
        record ``rec[0]`` (its ``active_s``) gains the timestep at every step the detector is
        active (None: none)."""
        b = self.base
        if self._data is not b.data:
            self._bind()
        b.kernel_prepare()
        s, c, m = b.sensing, b.controller, b.measurements
        f, est, det = s.faulty, s.estimator, s.detector
        g, d = b.guidance, self._data
        fs = self._fs
        fs[CUE], fs[TIME] = 0.0, d.time
        cs, ns = self._constants(force_filter)
        # the safety filter: under guidance, and on a motion off the grid's clear moves
        # (MobileBase.keep_clear; no guidance's record: its admittance stays off)
        ns[GUIDED] = int(g is not None or b.keep_clear)
        ns[PUSHING], ns[INTERACT] = push is not None, interaction is not None
        cs[T0], cs[MIN_S], cs[T_END] = t0, min_s, t_end
        cs[T_STOP] = self._quiet_until() if b.pre_substep else math.inf
        wrench = b.pushed_wrench()
        filt = self._err if force_filter is None else force_filter.f
        arm = b.compiled_arm() if self._arm else None
        goal = c.u if type(c) is HeldVelocity else self._err
        args = (self._mj, self._robot,
                (c.last, b.target, self._err, goal, filt,
                 self._no_push if push is None else push.record(), wrench,
                 self._no_rec if interaction is None else interaction.rec),
                f.step_arrays(), f.rng_pointers, (est.params, est.rec),
                est.step_arrays(), det.step_arrays(),
                (*self._guide_args, self._no_rec if g is None else g.rec), arm, m.rec,
                fs, cs, ns, max_steps)
        entry = self._entry
        if entry is None:
            entry = self._entry = compiled_entry(args)
        reason, steps = entry(*args)
        b.kernel_finish(steps)  # an arm's steps (each ran the arm's part: module docstring)
        # the quiet hooks learn of the steps they were not called for (the last step's hooks
        # run in Python after a hand-back within it)
        if b.on_substep:
            self._skip_hooks(steps - (reason in (DETECT, CONTACTS, CROSS)))
        fs = fs.tolist()
        if fs[TIME] != d.time:  # pragma: no cover - mj_step advances time by its timestep
            raise RuntimeError(f"the compiled move's time {fs[TIME]!r} is not MjData's "
                               f"{d.time!r}")
        return reason, steps, fs

    def _hand_back(self, reason: int, step, fs: list) -> bool:
        """Finish the step the kernel handed back within (Python), then the move's end check;
        True when the phase ended."""
        from ..errors import EpisodeError

        b = self.base
        if reason == DIVERGED:
            raise EpisodeError(f"simulation diverged at t = {b.data.time:.3f} s "
                               "(non-finite state)")
        if reason == READY:
            return False
        if reason == END:
            step.phase = None
            return True
        return step.move_ended(self._finish(reason, fs))

    def _finish(self, reason: int, fs: list, push=None):
        """The rest of the step the kernel handed back within (:data:`DETECT`: the cue stream,
        the measurements and hooks after the detector's step; :data:`CONTACTS`: the contact
        measurements and the hooks; :data:`CROSS`: the hooks), ``push`` the push that
        acted in it (None: none); the step's cue (None: none)."""
        b = self.base
        if reason == DETECT:
            det = b.sensing.detector
            return b.after_read(det.given_cue() if fs[CUE] else None, push)
        if reason == CONTACTS:
            b.measurements.measure_contacts(b.data, (fs[VPX_OLD], fs[VPY_OLD]))
        b.run_hooks(push)
        return None
