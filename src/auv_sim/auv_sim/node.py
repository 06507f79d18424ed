"""The simulator node: drives :class:`auv_sim.simulator.Simulator` on the ROS graph.

Run it as ``ros2 run auv_sim simulator [--ros-args -p name:=value ...]`` or ``auv sim
[options]`` (each option mirrors a parameter; options win over ``--ros-args``).

Parameters (see :class:`auv_sim.sim_settings.SimSettings`; validated at start, where a bad one
ends the node with one line ``error: ...`` and exit status 1, and again on every change, where
a bad one is refused with a reason): ``vehicle_file`` (default ``config/a18m.yaml``, found
relative to the working directory, ``$AUV_ROOT`` or the source tree), ``effects_file`` (''
none), ``publish_rate`` [Hz], ``dt`` [s] (0: the vehicle file's), ``real_time_factor`` (0: as
fast as possible), ``use_sim_clock``, ``initial_trim``, ``initial_depth`` [m],
``initial_speed`` [m/s], ``initial_pitch`` [rad], ``initial_heading`` [rad], ``lockstep``,
``control_period`` [s], ``lockstep_timeout`` and ``lockstep_startup_timeout`` [wall s],
``stop_time`` [s of simulated time; 0: run until stopped]. Only
``publish_rate``, ``real_time_factor`` and ``lockstep_timeout`` may change while it runs.

Topics (namespace ``/auv`` by default, remappable with ``-r __ns:=...``):

* subscribes ``bar_command``, ``helm_command`` [rad], ``thrust_command`` [N]
  (``auv_msgs/ActuatorSetpoint``). A NaN, infinite or out-of-range value is rejected with a
  warning naming it, and the last valid command stays in force.
* publishes, at ``publish_rate`` on simulated time, all with one stamp:
  ``state`` (``auv_msgs/VehicleState``, frame_id ``ned``: NED position and ZYX Euler angles,
  FRD body velocities; the *measured* state, i.e. with the sensor biases of the effects file),
  ``odom`` (``nav_msgs/Odometry``, frame ``odom`` (ENU) / child ``base_link`` (FLU), REP-103/105,
  from the same measured state, covariances unknown = 0), ``hydrodynamic_forces``
  (``auv_msgs/HydrodynamicForces``, frame_id ``base_link_frd``: the four body-FRD wrenches of
  the true state), then ``/clock`` (``rosgraph_msgs/Clock``) when ``use_sim_clock``.

Time: simulated time is ``t_k = k dt`` with ``k`` the integration-step counter; a stamp is the
integer ``k * dt_ns`` nanoseconds (exact, no float drift). With ``use_sim_clock`` every stamp is
simulated time and ``/clock`` is published; otherwise stamps are the wall clock. The simulator
is paced by the wall clock scaled by ``real_time_factor``; with 0 it runs as fast as it can,
still serving its subscriptions between publish instants so commands arrive.

Lockstep protocol (``lockstep:=true``, simulated time only). The other side is the depth
pilot (or any controller); it makes a graph run deterministic and as fast as the processes
allow:

1. Before ``t = 0`` the simulator waits (at most ``lockstep_startup_timeout`` wall seconds)
   until its ``state`` publisher has a matched subscriber and its ``bar_command`` subscription
   a matched publisher.
2. The control instants are ``t_k = k * control_period`` (a whole number of steps). At each,
   the simulator publishes ``state`` (with ``odom``, forces and ``/clock``) stamped ``t_k`` and
   does not advance past ``t_k`` until it receives a ``bar_command`` whose ``header.stamp``
   equals ``t_k`` exactly (compared as integer nanoseconds). That command is applied at
   ``t_k`` and held (zero-order hold) until the next instant's command. A NaN or out-of-range
   answer is rejected as usual (the last valid command stays) but still releases the wait.
3. If no such command arrives within ``lockstep_timeout`` wall seconds, the simulator logs a
   warning and goes on with the last valid command. With a ``stop_time`` that is a control
   instant, the simulator also waits for the answer to that last state before it exits, so
   a recording holds the whole exchange.
4. A ``bar_command`` stamped otherwise (late, early, or unstamped) is ignored with a warning:
   only answers to the awaited instant act, which is what makes the run deterministic.
   ``helm_command`` and ``thrust_command`` are not part of the protocol; they act when they
   arrive.
5. Between control instants the simulator publishes at ``publish_rate`` as usual without
   waiting. The pilot's side: on receipt of a ``state`` whose stamp is a control instant,
   compute and publish ``bar_command`` with that same stamp (make sure its publisher is
   matched before answering the first state).

Recorder pacing (as fast as possible, ``real_time_factor`` 0, simulated time): a recorder
reports on ``recorder/progress`` (namespaced) the stamp up to which it has written the
graph's stamped streams (``state``, ``odom``, forces, ``/clock`` and the pilot's
``bar_command``; ``builtin_interfaces/Time``, see :mod:`auv_bringup.record_node`). While
such a publisher is matched, the simulator does not run more than half its output history
(``STREAM_QOS`` depth / 2 publish periods, 10 s at 50 Hz) ahead of that stamp, so a recorder
starved of CPU slows the run instead of losing samples; at ``stop_time`` it also waits until
the recorder has written the last instant of every stream, since samples still on their way
die with their publishers' processes. It waits at most ``_RECORDER_TIMEOUT`` wall seconds,
then says so and stops waiting for that run. Pacing changes wall time only, never the numbers:
the pilot's answer to a control instant is taken from the moment that state is published, also
while the simulator waits for the recorder.

Same inputs, same numbers: given the initial state and the command sequence with the instants
it acts at, :meth:`SimSetup.simulator` stepped offline gives the node's states bit for bit.
On SIGINT or SIGTERM the node stops at the next step and exits 0.
"""
from __future__ import annotations

import argparse
import dataclasses
import gc
import signal
import sys
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

import rclpy
import rclpy.exceptions
import rclpy.utilities
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Wrench
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock

from auv_contract import CHANNELS
from auv_msgs.msg import ActuatorSetpoint, HydrodynamicForces, VehicleState
from auv_sim.errors import AuvSimError, DivergenceError, ParameterError
from auv_sim.frames import state_to_odometry
from auv_sim.sim_settings import (
    BOOL_FIELDS,
    FLOAT_FIELDS,
    NS_PER_S,
    RUNTIME_FIELDS,
    SimSettings,
    SimSetup,
    build_setup,
    check_settings,
    next_multiple,
    whole_steps,
)
from auv_sim.simulator import CommandError

NODE_NAME = 'simulator'
DEFAULT_NAMESPACE = '/auv'
STATE_FRAME = 'ned'
BODY_FRAME_FRD = 'base_link_frd'
ODOM_FRAME = 'odom'
ODOM_CHILD_FRAME = 'base_link'
#: Reliable, volatile, last 1000 (20 s of states at 50 Hz): a sample lost on the way (bursts
#: of a faster-than-real-time run overflow the transport) is resent from this history, so a
#: recorder that falls behind for a while still gets every message.
# 1000 samples (20 s at 50 Hz) for a recorder that falls behind in a lockstep run as fast as
# possible; a deeper history (10 000) cost a fifth of the lockstep real-time factor.
STREAM_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000,
                        reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.VOLATILE)
_MAX_LAG = 0.25  # wall s behind schedule after which pacing re-anchors instead of bursting
_SPIN_SLICE = 0.05  # wall s: longest single wait, so a stop request is seen promptly
_FAST_SPIN_PERIOD = 0.002  # wall s between callback polls when running as fast as possible
_RECORDER_TIMEOUT = 5.0  # wall s the simulator waits for a recorder's progress (pacing)
#: Recorder progress (the stamp up to which it has written; see auv_bringup.record_node) and
#: its QoS: reliable, keep the last 10.
PROGRESS_TOPIC = 'recorder/progress'  # relative: /auv/recorder/progress by default
PROGRESS_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                          reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.VOLATILE)

_DESCRIPTIONS = {
    'vehicle_file': 'vehicle parameter file (YAML)',
    'effects_file': "environment/effects file (YAML); '' for calm water",
    'publish_rate': 'state publish rate [Hz of simulated time]',
    'dt': "RK4 step [s]; 0: the vehicle file's",
    'real_time_factor': 'simulated seconds per wall second; 0: as fast as possible',
    'use_sim_clock': 'publish /clock and stamp on simulated time',
    'initial_trim': 'start trimmed (w, theta, BAR, thrust) at initial_speed and initial_depth',
    'initial_depth': 'initial depth [m], NED z positive down',
    'initial_speed': 'initial surge speed [m/s], body FRD',
    'initial_pitch': 'initial pitch [rad], positive nose up (only with initial_trim false)',
    'initial_heading': 'initial heading [rad], NED yaw',
    'lockstep': 'wait at each control instant for the bar command stamped with it',
    'control_period': 'lockstep control period [s of simulated time]',
    'lockstep_timeout': 'wall seconds to wait for a control instant command',
    'lockstep_startup_timeout': 'wall seconds to wait for the pilot to connect',
    'start_subscribers': 'before t = 0, wait (lockstep_startup_timeout) until /auv/state has '
                         'this many subscribers, e.g. pilot and recorder (0: do not wait)',
    'stop_time': 'simulated seconds after which the node publishes a last state and exits 0 '
                 '(0: never)',
}


def stamp_from_ns(ns: int) -> Time:
    """builtin_interfaces/Time from integer nanoseconds (exact)."""
    return Time(sec=ns // NS_PER_S, nanosec=ns % NS_PER_S)


def stamp_to_ns(stamp: Time) -> int:
    """Integer nanoseconds of a builtin_interfaces/Time."""
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


def _wrench(row: Any) -> Wrench:
    w = Wrench()
    w.force.x, w.force.y, w.force.z = float(row[0]), float(row[1]), float(row[2])
    w.torque.x, w.torque.y, w.torque.z = float(row[3]), float(row[4]), float(row[5])
    return w


class SimulatorNode(Node):
    """Parameters, publishers, subscriptions and the stepping loop around one Simulator."""

    def __init__(self, context: Context, overrides: dict[str, Any] | None = None) -> None:
        super().__init__(NODE_NAME, namespace=DEFAULT_NAMESPACE, context=context,
                         parameter_overrides=[Parameter(k, value=v)
                                              for k, v in (overrides or {}).items()])
        defaults = SimSettings()
        for field in dataclasses.fields(SimSettings):
            default = getattr(defaults, field.name)
            # Doubles accept integers too (``-p real_time_factor:=0``); checked by type below.
            descriptor = ParameterDescriptor(description=_DESCRIPTIONS[field.name],
                                             dynamic_typing=field.name in FLOAT_FIELDS)
            self.declare_parameter(field.name, default, descriptor)
        self.settings = self._read_settings()
        self.setup: SimSetup = build_setup(self.settings)  # ParameterError ends the start
        self.sim = self.setup.simulator()
        self._stop = threading.Event()
        self._awaiting_ns: int | None = None
        self._answered = False
        self._recorded_ns = -1  # stamp of the last state a recorder reported written [ns]
        self._recorder_paced = True  # False after a recorder failed to keep up in time

        self._pub_state = self.create_publisher(VehicleState, 'state', STREAM_QOS)
        self._pub_odom = self.create_publisher(Odometry, 'odom', STREAM_QOS)
        self._pub_forces = self.create_publisher(HydrodynamicForces, 'hydrodynamic_forces',
                                                 STREAM_QOS)
        self._pub_clock = (self.create_publisher(Clock, '/clock', STREAM_QOS)
                           if self.settings.use_sim_clock else None)
        self._subs = {channel: self.create_subscription(
            ActuatorSetpoint, f'{channel}_command', self._command_callback(channel),
            STREAM_QOS) for channel in CHANNELS}
        self._sub_progress = self.create_subscription(
            Time, PROGRESS_TOPIC, self._on_progress, PROGRESS_QOS)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        s = self.settings
        self.get_logger().info(
            f'{self.setup.params.name} from {self.setup.params.path}: dt = {self.setup.dt} s, '
            f'publish {s.publish_rate} Hz, real-time factor {s.real_time_factor or "max"}, '
            f'{"sim" if s.use_sim_clock else "wall"} clock'
            + (f', lockstep every {s.control_period} s' if s.lockstep else '')
            + f'; start z = {self.sim.x[2]:.3f} m, u = {self.sim.x[6]:.3f} m/s, '
              f'theta = {self.sim.x[4]:.5f} rad, BAR = {self.sim.x[12]:.5f} rad')

    # ----- parameters -----
    def _read_settings(self) -> SimSettings:
        values: dict[str, Any] = {}
        for field in dataclasses.fields(SimSettings):
            value = self.get_parameter(field.name).value
            if field.name in FLOAT_FIELDS and isinstance(value, int) \
                    and not isinstance(value, bool):
                value = float(value)
            values[field.name] = value
        settings = SimSettings(**values)
        check_settings(settings)
        return settings

    def _on_set_parameters(self, params: list[Parameter[Any]]) -> SetParametersResult:
        changes: dict[str, Any] = {}
        for p in params:
            if p.name not in _DESCRIPTIONS:
                continue  # rclpy's own (use_sim_time): stamps come from the step counter
            if p.value == getattr(self.settings, p.name):
                continue
            if p.name not in RUNTIME_FIELDS:
                return SetParametersResult(
                    successful=False, reason=f'{p.name} cannot change while the simulator '
                    f'runs (changeable: {", ".join(RUNTIME_FIELDS)}); restart the node')
            value = p.value
            if p.name in FLOAT_FIELDS and isinstance(value, int) and not isinstance(value, bool):
                value = float(value)
            changes[p.name] = value
        if not changes:
            return SetParametersResult(successful=True)
        new = self.settings.replace(**changes)
        try:
            check_settings(new, vehicle_dt=self.setup.dt)
        except ParameterError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        self.settings = new
        self.setup = dataclasses.replace(
            self.setup, settings=new,
            steps_per_publish=whole_steps(1.0 / new.publish_rate, self.setup.dt, 'publish'))
        self.get_logger().info(f'parameters changed: {changes}')
        return SetParametersResult(successful=True)

    # ----- commands -----
    def _command_callback(self, channel: str) -> Callable[[ActuatorSetpoint], None]:
        def callback(msg: ActuatorSetpoint) -> None:
            if channel == 'bar' and self.settings.lockstep:
                ns = stamp_to_ns(msg.header.stamp)
                if ns != self._awaiting_ns:
                    waiting = ('nothing' if self._awaiting_ns is None
                               else f'{self._awaiting_ns} ns')
                    self.get_logger().warning(
                        f'lockstep: ignored bar command stamped {ns} ns (awaiting {waiting})')
                    return
                self._answered = True
            try:
                self.sim.command(channel, msg.value)
            except CommandError as exc:
                self.get_logger().warning(f'rejected {channel} command at t = {self.sim.t:.3f} s:'
                                          f' {exc}')
        return callback

    # ----- output -----
    def _publish(self) -> None:
        if self.settings.use_sim_clock:
            stamp = stamp_from_ns(self.setup.stamp_ns(self.sim.k))
        else:
            stamp = self.get_clock().now().to_msg()
        x = self.sim.measured_state()
        state = VehicleState()
        state.header.stamp = stamp
        state.header.frame_id = STATE_FRAME
        (state.x, state.y, state.z, state.phi, state.theta, state.psi, state.u, state.v,
         state.w, state.p, state.q, state.r) = (float(v) for v in x[:12])
        self._send(self._pub_state, state)

        odom_arrays = state_to_odometry(x)
        odom = Odometry()
        odom.header.stamp = stamp
        odom.header.frame_id = ODOM_FRAME
        odom.child_frame_id = ODOM_CHILD_FRAME
        pose = odom.pose.pose
        pose.position.x, pose.position.y, pose.position.z = map(float, odom_arrays.position)
        (pose.orientation.x, pose.orientation.y, pose.orientation.z,
         pose.orientation.w) = map(float, odom_arrays.orientation)
        twist = odom.twist.twist
        twist.linear.x, twist.linear.y, twist.linear.z = map(float, odom_arrays.linear)
        twist.angular.x, twist.angular.y, twist.angular.z = map(float, odom_arrays.angular)
        self._send(self._pub_odom, odom)

        rows = self.sim.wrenches()
        forces = HydrodynamicForces()
        forces.header.stamp = stamp
        forces.header.frame_id = BODY_FRAME_FRD
        forces.hydrodynamic = _wrench(rows[0])
        forces.coriolis = _wrench(rows[1])
        forces.restoring = _wrench(rows[2])
        forces.actuators = _wrench(rows[3])
        self._send(self._pub_forces, forces)

        if self._pub_clock is not None:
            self._send(self._pub_clock, Clock(clock=stamp))

    def _send(self, publisher: Any, msg: Any) -> None:
        """Publish; if the middleware refuses (a reader too slow to acknowledge a full
        history), retry for up to 1 s, then drop the sample with a warning: the simulator
        never dies on a publish."""
        deadline = time.monotonic() + 1.0
        while True:
            try:
                publisher.publish(msg)
                return
            except RuntimeError as exc:  # rclpy's RCLError derives from RuntimeError
                if self._stop.is_set():
                    return  # shutting down: the context may be gone already
                if time.monotonic() > deadline:
                    self.get_logger().warning(
                        f'{publisher.topic_name}: sample dropped, publish failed: {exc}',
                        throttle_duration_sec=5.0)
                    return
                time.sleep(0.01)

    def _on_progress(self, msg: Time) -> None:
        self._recorded_ns = max(self._recorded_ns, stamp_to_ns(msg))

    def _pace_recorder(self, executor: SingleThreadedExecutor, last: bool = False) -> None:
        """As fast as possible: keep within half the output history of a recorder that reports
        its progress, and with ``last`` wait until it has the last state (see the module
        docstring)."""
        window = 0 if last else \
            (STREAM_QOS.depth // 2) * self.setup.steps_per_publish * self.setup.dt_ns
        now_ns = self.setup.stamp_ns(self.sim.k)
        behind = now_ns - self._recorded_ns
        if (behind <= 0 if last else behind < window) or not self._recorder_paced \
                or self._sub_progress.get_publisher_count() == 0:
            return  # the graph query only when behind: it costs much at every publish

        def caught_up() -> bool:
            return now_ns - self._recorded_ns <= window // 2
        if not self._spin_until(executor, time.monotonic() + _RECORDER_TIMEOUT, caught_up) \
                and not self._stop.is_set():
            self._recorder_paced = False
            self.get_logger().warning(
                f'recorder pacing: no progress within {_RECORDER_TIMEOUT} s at t = '
                f'{self.sim.t:.2f} s (last state written at {self._recorded_ns / 1e9:.2f} s); '
                f'running on without waiting for it')

    # ----- the loop -----
    def stop(self) -> None:
        """Ask the loop to end at its next step (safe from a signal handler)."""
        self._stop.set()

    def _spin_until(self, executor: SingleThreadedExecutor, deadline: float,
                    done: Callable[[], bool] | None = None) -> bool:
        """Serve callbacks until ``done()`` or the wall ``deadline`` (monotonic s).

        Returns whether ``done()`` became true (True at the deadline when there is none).
        """
        while not self._stop.is_set():
            if done is not None and done():
                return True
            remaining = deadline - time.monotonic()
            if remaining <= 0.0:
                return done() if done is not None else True
            executor.spin_once(timeout_sec=min(remaining, _SPIN_SLICE))
        return False

    def _wait_for_subscribers(self, executor: SingleThreadedExecutor) -> None:
        """Before t = 0, wait (startup timeout) for ``start_subscribers`` on every output."""
        wanted = int(self.settings.start_subscribers)
        timeout = self.settings.lockstep_startup_timeout
        pubs = [self._pub_state, self._pub_odom, self._pub_forces]

        def matched() -> bool:
            return all(p.get_subscription_count() >= wanted for p in pubs[:1]) and all(
                p.get_subscription_count() >= 1 for p in pubs[1:])

        self.get_logger().info(f'waiting up to {timeout} s for {wanted} state subscriber(s)')
        if not self._spin_until(executor, time.monotonic() + timeout, matched) \
                and not self._stop.is_set():
            self.get_logger().warning(f'fewer than {wanted} subscribers after {timeout} s; '
                                      f'starting anyway')

    def _wait_for_pilot(self, executor: SingleThreadedExecutor) -> None:
        timeout = self.settings.lockstep_startup_timeout

        def connected() -> bool:
            return ((self._pub_state.get_subscription_count() > 0
                     or self._pub_odom.get_subscription_count() > 0)
                    and self._subs['bar'].get_publisher_count() > 0)

        self.get_logger().info(f'lockstep: waiting up to {timeout} s for a pilot '
                               f'(state or odom subscriber and bar_command publisher)')
        if self._spin_until(executor, time.monotonic() + timeout, connected):
            self.get_logger().info('lockstep: pilot connected')
        elif not self._stop.is_set():
            self.get_logger().warning(f'lockstep: no pilot connected within {timeout} s; '
                                      f'starting anyway')

    def _expect_command(self) -> None:
        """Accept the pilot's answer to the control instant about to be published: from here
        on, also while the recorder pacing serves callbacks before :meth:`_await_command`."""
        self._awaiting_ns = self.setup.stamp_ns(self.sim.k)
        self._answered = False

    def _await_command(self, executor: SingleThreadedExecutor) -> None:
        """Wait (``lockstep_timeout``) for the answer :meth:`_expect_command` set up."""
        timeout = self.settings.lockstep_timeout
        try:
            ok = self._spin_until(executor, time.monotonic() + timeout, lambda: self._answered)
        finally:
            self._awaiting_ns = None
        if not ok and not self._stop.is_set():
            self.get_logger().warning(
                f'lockstep: no bar command stamped t = {self.sim.t:.3f} s within {timeout} s; '
                f'keeping the last command')

    def run_loop(self, executor: SingleThreadedExecutor) -> None:
        """Step, publish and serve callbacks until :meth:`stop`. DivergenceError propagates."""
        if self.settings.start_subscribers > 0:
            self._wait_for_subscribers(executor)
        if self.settings.lockstep:
            self._wait_for_pilot(executor)
        next_pub = next_ctrl = self.sim.k
        anchor_wall, anchor_k = time.monotonic(), self.sim.k
        next_poll = 0.0
        while not self._stop.is_set():
            s, k = self.settings, self.sim.k
            if s.real_time_factor > 0.0:
                target = anchor_wall + (k - anchor_k) * self.setup.dt / s.real_time_factor
                if time.monotonic() - target > _MAX_LAG:
                    anchor_wall, anchor_k = time.monotonic(), k  # behind: re-anchor, no burst
                else:
                    self._spin_until(executor, target)
            elif time.monotonic() >= next_poll:
                # As fast as possible: poll for commands every few wall ms, not every tick
                # (a poll costs more than the steps between two publish instants).
                executor.spin_once(timeout_sec=0.0)
                next_poll = time.monotonic() + _FAST_SPIN_PERIOD
            if self._stop.is_set():
                break
            control_instant = s.lockstep and k == next_ctrl
            if control_instant:
                self._expect_command()
            if k == next_pub or control_instant:
                self._publish()
                if s.real_time_factor <= 0.0 and s.use_sim_clock:
                    self._pace_recorder(executor)
            if s.stop_time > 0.0 and self.sim.t >= s.stop_time - 0.5 * self.setup.dt:
                if k != next_pub and not control_instant:
                    self._publish()
                if control_instant:  # the pilot's answer to the last state is part of the run
                    self._await_command(executor)
                if s.real_time_factor <= 0.0 and s.use_sim_clock:
                    self._pace_recorder(executor, last=True)
                break
            if control_instant:
                self._await_command(executor)
                next_ctrl = next_multiple(k, self.setup.steps_per_control)
                if s.real_time_factor > 0.0:
                    anchor_wall, anchor_k = time.monotonic(), k  # waiting is not lag
            if k >= next_pub:
                next_pub = next_multiple(k, self.setup.steps_per_publish)
            end = min(next_pub, next_ctrl) if s.lockstep else next_pub
            self.sim.step(end - k)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``auv sim``; each sets the ROS parameter of the same name (see module doc)."""
    def opt(name: str, kind: type, help_text: str) -> None:
        flag = '--' + name.replace('_', '-')
        if name == 'vehicle_file':   # one name for the vehicle file in every command
            parser.add_argument('--vehicle', dest=name, default=None, metavar='VEHICLE.yaml',
                                help=help_text)
            parser.add_argument(flag, dest=name, default=argparse.SUPPRESS,
                                help=argparse.SUPPRESS)
            return
        if kind is bool:
            parser.add_argument(flag, dest=name, action=argparse.BooleanOptionalAction,
                                default=None, help=help_text)
        else:
            parser.add_argument(flag, dest=name, type=kind, default=None, help=help_text)

    defaults = SimSettings()
    for field in dataclasses.fields(SimSettings):
        kind = bool if field.name in BOOL_FIELDS else float if field.name in FLOAT_FIELDS \
            else str
        opt(field.name, kind, f'{_DESCRIPTIONS[field.name]} (default: '
                              f'{getattr(defaults, field.name)!r})')
    parser.add_argument('--ros-args', dest='ros_args', nargs=argparse.REMAINDER, default=None,
                        help='ROS arguments (-p name:=value, -r remaps, --log-level ...)')


def run(args: argparse.Namespace) -> int:
    """Run the simulator until SIGINT/SIGTERM (exit 0); a bad parameter prints one line
    ``error: ...`` and returns 1, as does a diverging simulation."""
    overrides = {f.name: getattr(args, f.name) for f in dataclasses.fields(SimSettings)
                 if getattr(args, f.name, None) is not None}
    ros_argv = getattr(args, 'ros_argv', None)
    if ros_argv is None:
        ros_argv = ['auv-sim'] + (['--ros-args', *args.ros_args] if args.ros_args else [])
    context = Context()
    rclpy.init(args=list(ros_argv), context=context,
               signal_handler_options=SignalHandlerOptions.NO)
    node: SimulatorNode | None = None
    previous: dict[int, Any] = {}
    stop_requested = threading.Event()

    def on_signal(signum: int, frame: Any) -> None:
        stop_requested.set()
        if node is not None:
            node.stop()

    if threading.current_thread() is threading.main_thread():
        for signum in (signal.SIGINT, signal.SIGTERM):
            previous[signum] = signal.signal(signum, on_signal)
    executor = SingleThreadedExecutor(context=context)
    try:
        try:
            node = SimulatorNode(context, overrides)
        except (AuvSimError, rclpy.exceptions.ParameterException) as exc:
            print(f'error: {exc}', file=sys.stderr)
            return 1
        if stop_requested.is_set():
            return 0
        executor.add_node(node)
        gc.collect()
        gc.freeze()  # long-lived set-up objects out of the cyclic collector's full passes
        try:
            node.run_loop(executor)
        except DivergenceError as exc:
            node.get_logger().error(str(exc))
            print(f'error: {exc}', file=sys.stderr)
            return 1
        node.get_logger().info(f'stopped at t = {node.sim.t:.3f} s')
        return 0
    finally:
        executor.shutdown(timeout_sec=0.0)
        if node is not None:
            node.destroy_node()
        if context.ok():
            context.try_shutdown()
        for number, handler in previous.items():
            signal.signal(number, handler)


def main(argv: Sequence[str] | None = None) -> None:
    """Entry point of ``ros2 run auv_sim simulator``: options as ``auv sim``, plus --ros-args."""
    argv = list(sys.argv if argv is None else argv)
    parser = argparse.ArgumentParser(prog='simulator', description=__doc__.splitlines()[0])
    add_arguments(parser)
    args = parser.parse_args(rclpy.utilities.remove_ros_args(argv)[1:])
    args.ros_argv = argv
    sys.exit(run(args))


if __name__ == '__main__':
    main()
