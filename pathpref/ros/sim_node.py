"""``pathpref ros sim``: the MuJoCo base (disk or TidyBot) as a ROS 2 robot.

The episode of the spec runs as under ``pathpref evaluate --sim mujoco``: the same
:class:`~pathpref.episode.runner.EpisodeRunner` on the same :class:`~pathpref.sim.body.
MujocoBody` (the simulated person's pushes drawn from the same streams), except that every
decision step's action comes from the planner's waypoint instead of the runner's policy. The
robot publishes, stamped with the simulated time (ns since the episode's reset):

* the handle's wrench at every physics step (``dt`` 2 ms: 500 Hz): the sensing chain's push
  estimate (N, ``map`` frame; the ideal sensor's raw reading, or the faulty sensor through the
  estimator), and its torque about the sensor's origin, ``(p_grip - p_sensor) x F`` (N m): the
  person's grip is the handle's centre of mass, 5 cm below the sensor, so every push has one;
* odometry (``map`` -> ``base_link``; the twist in ``base_link``) and ``/pose`` at the path
  rate (``--path-hz``, every ``floor(1 / (hz dt))`` physics steps; 100 Hz by default), and
  once more at the end of every step;
* the step mark (:class:`~pathpref.ros.streams.StepMark`) when a decision step ends (the move,
  then the person's push when one is due).

It takes the planner's next waypoint (``PoseStamped`` stamped with the mark it answers): the
cell under it must be the robot's cell (STAY) or one of its eight grid neighbours; another
waypoint is refused with one line. It drives there with its own tracking controller, as the
MuJoCo body does. Without ``--realtime`` it runs as fast as it can and waits for each
waypoint (lockstep); with it, the physics is paced to the wall clock.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from ..episode.runner import EpisodeRunner
from ..episode.spec import EpisodeSpec
from ..errors import ConfigError
from ..geometry.grid import STAY
from ..sim.grip import grip_ids, grip_offset, torque
from ..sim.path_record import sample_every
from .streams import BadMessage, stamp_ns


def _warn(text: str) -> None:
    print(f"pathpref ros sim: {text}", file=sys.stderr, flush=True)


class SimRobot:
    """The episode of ``spec`` on the MuJoCo body, its physics steps handed to ``emit``
    (module docstring): ``emit("wrench", ns, force, torque)``, ``emit("odom", ns, x, y, yaw,
    vx, vy, wz)`` and ``emit("step", mark...)``."""

    def __init__(self, spec: EpisodeSpec, emit, path_hz: float = 100.0,
                 realtime: float = 0.0, drive: str = "waypoint"):
        if spec.sim != "mujoco":
            raise ConfigError("pathpref ros sim runs the MuJoCo body (sim 'mujoco')")
        physics = spec.physical
        if physics is not None and physics.human.timing != "decision":
            raise ConfigError(f"--timing {physics.human.timing}: the ROS loop runs the "
                              "decision timing (pushes at decision steps); use --timing "
                              "decision")
        self.emit, self.realtime = emit, float(realtime)
        self.runner = EpisodeRunner(spec)
        self.body = self.runner.body
        self.base = base = self.body.base
        self.every = sample_every(path_hz, base.dt)
        self._n = 0
        self.n_wrench = self.n_odom = 0
        self.step_index = 0
        self.mark_ns = 0
        self._d, self._grip = base.data, grip_ids(base.model)
        self._wall0: float | None = None
        self.cells = [self.runner.cell]
        base.on_substep.append(self._after_step)
        #: called at every odometry message while the physics runs (the node takes the
        #: velocity commands that came meanwhile)
        self.poll = None
        if drive not in ("waypoint", "cmd_vel"):
            raise ConfigError(f"--drive {drive!r}: choose waypoint or cmd_vel")
        self.drive = drive
        if drive == "cmd_vel":
            if self.realtime <= 0:
                raise ConfigError("--drive cmd_vel needs --realtime (e.g. 1): the base follows "
                                  "the planner's velocity commands as they come")
            from ..sim.controller import HeldVelocity

            c = base.controller
            base.controller = HeldVelocity(v_max=c.v_max, a_max=c.a_max, dt=base.dt,
                                           time_limit_s=c.time_limit_s, tol_m=c.tol_m,
                                           still_mps=c.still_mps)
            base.controller.reset()

    def velocity(self, vx: float, vy: float, wz: float) -> None:
        """A velocity command (m/s in ``base_link``): held by the base's drive until the next
        (:class:`~pathpref.sim.controller.HeldVelocity`: reached within ``a_max``, the yaw
        regulated to zero; ``--drive cmd_vel``); ignored when the base tracks waypoints."""
        if self.drive != "cmd_vel":
            return
        yaw = float(self._d.qpos[self.base.yaw])
        c, s = np.cos(yaw), np.sin(yaw)
        self.base.controller.hold(np.array([c * vx - s * vy, s * vx + c * vy]))

    def ns(self) -> int:
        """The simulated time now (ns since the reset)."""
        return int(round(float(self._d.time) * 1e9))

    def torque(self, f: np.ndarray) -> np.ndarray:
        """The wrench's torque about the sensor's origin of a horizontal force ``f`` at the
        grip (N m, ``map`` axes; :mod:`pathpref.sim.grip`)."""
        return torque(grip_offset(self._d, self._grip), f)

    def publish_odom(self) -> None:
        """The base's odometry now."""
        b, d = self.base, self._d
        x, y = (float(v) for v in d.qpos[b.xy])
        vx, vy = (float(v) for v in d.qvel[b.vxy])
        yaw = float(d.qpos[b.yaw])
        wz = float(d.qvel[int(b.model.joint("yaw").dofadr[0])])
        self.n_odom += 1
        self.emit("odom", self.ns(), x, y, yaw, vx, vy, wz)

    def _after_step(self, base, push) -> None:
        f = base.sensing.force_estimate
        self.n_wrench += 1
        self.emit("wrench", self.ns(), (float(f[0]), float(f[1]), 0.0), self.torque(f))
        self._n += 1
        if self._n % self.every == 0:
            self.publish_odom()
            if self.poll is not None:
                self.poll()
        if self.realtime > 0:
            if self._wall0 is None:
                self._wall0 = time.perf_counter() - float(self._d.time) / self.realtime
            ahead = float(self._d.time) / self.realtime - (time.perf_counter() - self._wall0)
            if ahead > 0.002:
                time.sleep(ahead)

    def _mark(self, closed: bool) -> None:
        self.publish_odom()
        self.mark_ns = self.ns()
        self.emit("step", self.step_index, self.mark_ns, self.n_wrench, self.n_odom, closed)

    def begin(self) -> None:
        """The person's first push (when due) and the first step mark."""
        self.publish_odom()  # the base at its start
        n = len(self.body.readings)
        self.runner.begin()
        self._mark(len(self.body.readings) > n)

    def action_to(self, cell: int) -> int | None:
        """The grid action from the robot's cell to ``cell`` (STAY: the same cell); None
        when ``cell`` is no neighbour."""
        here = self.runner.cell
        if cell == here:
            return STAY
        hits = np.flatnonzero(self.runner.world.motion.next_cell[here] == cell)
        return int(hits[0]) if len(hits) else None

    def waypoint(self, msg) -> bool:
        """A waypoint message: the decision step toward it, then the next mark; False (one
        line) when it is refused."""
        try:
            t = stamp_ns(msg, "waypoint")
            p = msg.pose.position
            x, y = float(p.x), float(p.y)
            frame = str(msg.header.frame_id)
        except (BadMessage, AttributeError, TypeError, ValueError) as e:
            _warn(f"waypoint refused: {e if isinstance(e, BadMessage) else 'not a PoseStamped'}")
            return False
        if self.runner.done:
            return False
        if t != self.mark_ns:
            _warn(f"waypoint for stamp {t} ns refused: the robot waits for the answer to "
                  f"step {self.step_index} (stamp {self.mark_ns} ns)")
            return False
        if frame != "map" or not (np.isfinite(x) and np.isfinite(y)):
            _warn(f"waypoint refused: it must be finite and in frame 'map' (got {frame!r})")
            return False
        cell = self.body.scene.cell_at(np.array([x, y]))
        action = self.action_to(cell)
        if action is None:
            _warn(f"waypoint ({x:.3f}, {y:.3f}) m refused: cell {cell} is not the robot's "
                  f"cell or a neighbour of it")
            return False
        n = len(self.body.readings)
        self.runner.step(action)
        self.cells.append(self.runner.cell)
        self.step_index += 1
        self._mark(len(self.body.readings) > n)
        return True


def run_sim(spec: EpisodeSpec, topics: dict, path_hz: float = 100.0, realtime: float = 0.0,
            timeout_s: float = 120.0, wait_s: float = 30.0, live_port: int | None = None,
            ros_args=None, drive: str = "waypoint") -> dict:
    """Run the sim node until the episode ends (or ``timeout_s`` of wall time); its outcome
    (the runner's result fields)."""
    from . import require_ros

    rclpy = require_ros()
    from geometry_msgs.msg import PoseStamped, Twist, WrenchStamped
    from nav_msgs.msg import Odometry
    from std_msgs.msg import UInt64MultiArray

    from . import messages as mk

    rclpy.init(args=ros_args)
    try:
        node = rclpy.create_node("pathpref_sim")
        pubs = {"wrench": node.create_publisher(WrenchStamped, topics["wrench"], mk.STREAM_QOS),
                "odom": node.create_publisher(Odometry, topics["odom"], mk.STREAM_QOS),
                "pose": node.create_publisher(PoseStamped, topics["pose"], mk.STREAM_QOS),
                "step": node.create_publisher(UInt64MultiArray, topics["step"], mk.MARK_QOS)}

        live = None
        if live_port is not None:
            from ..episode.cache import cached_world
            from ..episode.instances import episode_instance
            from ..study.live import LiveView

            world = cached_world(spec.map)
            inst, _ = episode_instance(world, spec.fixed, spec.instance_seed, spec.n_goals,
                                       spec.human, spec.t_max)
            live = LiveView(live_port)
            live.show(time.time_ns(), world, world.cells[inst.start], world.cells[list(inst.goals)],
                      world.cells[inst.goal_cell])

        def emit(kind, *a):
            if kind == "wrench":
                pubs["wrench"].publish(mk.wrench(a[0], "map", a[1], a[2]))
            elif kind == "odom":
                pubs["odom"].publish(mk.odometry(*a))
                pubs["pose"].publish(mk.pose(a[0], a[1], a[2], a[3]))
                if live is not None:
                    live.pose(*a[:4])
            else:
                pubs["step"].publish(mk.step_mark(*a))

        robot = SimRobot(spec, emit, path_hz, realtime, drive)
        inbox: list = []
        node.create_subscription(PoseStamped, topics["waypoint"], inbox.append, mk.MARK_QOS)
        twists: list = []

        def on_twist(m) -> None:
            twists.append(1)
            try:
                v = [float(m.linear.x), float(m.linear.y), float(m.angular.z)]
            except (AttributeError, TypeError, ValueError):
                _warn("cmd_vel refused: not a geometry_msgs/Twist")
                return
            if not all(np.isfinite(v)):
                _warn(f"cmd_vel refused: not finite: {v}")
                return
            robot.velocity(*v)

        node.create_subscription(Twist, topics["cmd_vel"], on_twist, 10)
        deadline = time.monotonic() + wait_s
        while time.monotonic() < deadline and not (
                pubs["wrench"].get_subscription_count() and pubs["odom"].get_subscription_count()
                and pubs["step"].get_subscription_count()
                and node.count_publishers(topics["waypoint"])):
            rclpy.spin_once(node, timeout_sec=0.05)
        if time.monotonic() >= deadline:
            raise ConfigError(f"no planner met on {topics['wrench']}, {topics['odom']}, "
                              f"{topics['step']} and {topics['waypoint']} within {wait_s:g} s: "
                              "start 'pathpref ros planner' with the same topics")
        from .messages import executor

        ex = executor()
        ex.add_node(node)

        def poll() -> None:  # the commands that came while the physics ran
            for _ in range(8):
                ex.spin_once(timeout_sec=0)

        if drive == "cmd_vel":
            robot.poll = poll
        robot.begin()
        end = time.monotonic() + timeout_s
        while not robot.runner.done and time.monotonic() < end:
            ex.spin_once(timeout_sec=0.05)
            while inbox and not robot.runner.done:
                robot.waypoint(inbox.pop(0))
        r = robot.runner.result
        out = {"done": robot.runner.done, "steps": r.steps, "goal_reached": r.goal_reached,
               "violations": r.violations, "inputs": r.inputs, "cells": robot.cells,
               "felt": [(f.cell, f.heading) for f in robot.base.felt],
               "wrenches": robot.n_wrench, "cmd_vel": len(twists)}
        if not robot.runner.done:
            _warn(f"stopped after {timeout_s:g} s at step {r.steps}: the planner did not "
                  "answer")
        t_flush = time.monotonic() + 1.0  # let the last mark reach the planner
        while time.monotonic() < t_flush:
            ex.spin_once(timeout_sec=0.05)
        ex.shutdown()
        node.destroy_node()
        if live is not None:
            live.close()
        return out
    finally:
        rclpy.try_shutdown()
