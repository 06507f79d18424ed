"""The simulator node: drives :class:`auv_sim.simulator.Simulator` on the ROS graph.

Run it as ``ros2 run auv_sim simulator [--ros-args -p name:=value ...]`` or ``auv sim
[options]`` (each option mirrors a parameter; options win over ``--ros-args``).

Parameters (see :class:`auv_sim.sim_settings.SimSettings`; each declared with a descriptor
giving its description with its unit, its range and further limits,
:data:`auv_sim.sim_settings.PARAMETERS`; validated at start, where a bad one ends the node with
one line ``error: ...`` and exit status 1, and again on every change, where a bad one is
refused with a reason and changes nothing, a good one applied once ROS has stored it):
``vehicle_file`` (default ``config/a18m.yaml``, found relative to the working directory,
``$AUV_ROOT`` or the source tree), ``effects_file`` ('' none), ``publish_rate`` [Hz], ``dt``
[s] (0: the vehicle file's), ``real_time_factor`` (0: as fast as possible), ``use_sim_clock``,
``initial_trim``, ``initial_depth`` [m], ``initial_speed`` [m/s], ``initial_pitch`` [rad],
``initial_heading`` [rad], ``lockstep``, ``control_period`` [s], ``lockstep_timeout`` and
``lockstep_startup_timeout`` [wall s], ``lockstep_channels`` (``bar``; ``bar,helm,thrust`` for
a mission), ``start_subscribers`` (``state``), ``start_stream_subscribers`` (``odom``,
``hydrodynamic_forces``, ``/clock``) and ``start_odom_subscribers`` (``odom`` alone, when more:
a controller on ``odom`` besides the recorders): subscribers to wait for before t = 0,
``await_recorder`` (wait for a recorder's progress before t = 0), ``recorder_timeout`` [wall
s], ``stop_time`` [s of simulated time; 0: run until stopped], ``report_file`` (JSON written
at exit: messages published per topic, control instants that went on without their answer,
whether the recorder pacing gave up). Only ``publish_rate``, ``real_time_factor`` and
``lockstep_timeout`` may change while it runs.

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

Lockstep protocol (``lockstep:=true``, simulated time only; written out with its rationale
in ``docs/lockstep.md``). The other side is the depth pilot, a mission or any controller; it
makes a graph run deterministic and as fast as the processes allow:

1. Before ``t = 0`` the simulator waits (at most ``lockstep_startup_timeout`` wall seconds)
   until its ``state`` or ``odom`` publisher has a matched subscriber and the subscription of
   every lockstep channel a matched publisher.
2. The control instants are ``t_k = k * control_period`` (a whole number of steps). At each,
   the simulator publishes ``state`` (with ``odom``, forces and ``/clock``) stamped ``t_k`` and
   does not advance past ``t_k`` until it has received, on every channel of
   ``lockstep_channels`` (``bar_command`` by default), a command whose ``header.stamp`` is
   ``t_k`` within :data:`LOCKSTEP_TOLERANCE_NS` (1 us: a stamp computed as a float,
   ``Time(seconds=j * 0.02)``, is a nanosecond off at some instants). That command is applied
   at ``t_k`` and held (zero-order hold) until the next instant's command. A NaN or
   out-of-range answer is rejected as usual (the last valid command stays) but still releases
   the wait.
3. If the answers do not all arrive within ``lockstep_timeout`` wall seconds, the simulator
   logs a warning, counts the instant as missed (``report_file``) and goes on with the last
   valid commands. With a ``stop_time`` that is a control instant, the simulator also waits
   for the answer to that last state before it exits, so a recording holds the whole
   exchange.
4. A lockstep-channel command stamped otherwise (late, early, or unstamped) is ignored with a
   warning: only answers to the awaited instant act, which is what makes the run
   deterministic. Channels not in ``lockstep_channels`` act when they arrive.
5. Between control instants the simulator publishes at ``publish_rate`` as usual without
   waiting. The controller's side: on receipt of a ``state`` whose stamp is a control
   instant, compute and publish its commands with that same stamp (make sure its publishers
   are matched before answering the first state).

Recorder pacing (as fast as possible, ``real_time_factor`` 0, simulated time): a recorder
reports on ``recorder/progress`` (namespaced) the stamp up to which it has written the
graph's stamped streams (``state``, ``odom``, forces, ``/clock`` and the pilot's
``bar_command``; ``builtin_interfaces/Time``, see :mod:`auv_bringup.record_node`). While
such a publisher is matched, the simulator does not run more than half its output history
(``STREAM_QOS`` depth / 2 publish periods, 10 s at 50 Hz) ahead of that stamp, so a recorder
starved of CPU slows the run instead of losing samples; at ``stop_time`` it also waits until
the recorder has written the last instant of every stream, since samples still on their way
die with their publishers' processes. It waits at most ``recorder_timeout`` wall seconds
without progress (5 s by default; ``auv launch`` gives 120 s, with a warning every 10 s), then
says so, stops waiting for that run and records the fact in its ``report_file``; a recorder
whose progress publisher leaves the graph ends the wait at once. With ``await_recorder`` it
waits (start-up timeout) for the recorder's progress publisher before ``t = 0``, so the first
samples are paced too. Pacing changes wall time only, never the numbers:
the pilot's answer to a control instant is taken from the moment that state is published, also
while the simulator waits for the recorder.

One graph per namespace: before ``t = 0`` and during its first :data:`CONFLICT_WATCH` wall
seconds, the simulator looks for another node publishing its ``state`` topic (a second graph
on the same namespace, whose simulators and pilots would fight over the topics); it then
ends with one line ``error: ...`` and exit status 1.

Same inputs, same numbers: given the initial state and the command sequence with the instants
it acts at, :meth:`SimSetup.simulator` stepped offline gives the node's states bit for bit.
On SIGINT or SIGTERM the node stops at the next step and exits 0. Before it exits it waits
(at most :data:`ACK_TIMEOUT` wall seconds) until every reliable subscriber has acknowledged
what it published: samples still on their way die with the publishing process.
"""
from __future__ import annotations

import argparse
import dataclasses
import functools
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
from rcl_interfaces.msg import SetParametersResult
from rclpy.context import Context
from rclpy.duration import Duration
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock

from auv_contract import CHANNELS
from auv_contract.blas import use_one_blas_thread
from auv_contract.dds import use_dds_profile
from auv_contract.lockstep import LOCKSTEP_TOLERANCE_NS, NS_PER_S
from auv_msgs.msg import ActuatorSetpoint, HydrodynamicForces, VehicleState
from auv_sim.errors import (
    AuvSimError,
    CommandError,
    DivergenceError,
    GraphConflictError,
    ParameterError,
)
from auv_sim.frames import state_to_odometry
from auv_sim.node_report import write_report
from auv_sim.parameter_descriptor import descriptor
from auv_sim.sim_settings import (
    BOOL_FIELDS,
    FLOAT_FIELDS,
    PARAMETERS,
    RUNTIME_FIELDS,
    SimSettings,
    SimSetup,
    build_setup,
    check_settings,
    lockstep_channels,
    next_multiple,
    whole_steps,
)

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
_RECORDER_WARN_PERIOD = 10.0  # wall s between two warnings while waiting for a recorder
CONFLICT_WATCH = 3.0  # wall s after t = 0 during which another graph is looked for
_CONFLICT_POLL = 0.25  # wall s between two looks
ACK_TIMEOUT = 2.0  # wall s, longest wait at exit for the subscribers' acknowledgements
#: Recorder progress (the stamp up to which it has written; see auv_bringup.record_node) and
#: its QoS: reliable, keep the last 10.
PROGRESS_TOPIC = 'recorder/progress'  # relative: /auv/recorder/progress by default
PROGRESS_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                          reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.VOLATILE)

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
        # ranges after the check, so that a bad value at start gets the message naming it
        for spec in PARAMETERS.values():
            self.declare_parameter(spec.name, spec.default, descriptor(spec, ranged=False))
        self.settings = self._read_settings()
        check_settings(self.settings)  # ParameterError ends the start
        # Publishers and subscriptions before the files and the compiled model are loaded
        # (build_setup): the graph's discovery goes on meanwhile, and a pilot that waits for
        # this node's subscription sends its first command the sooner. Callbacks run only
        # once the node spins, after this constructor.
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
        self.setup: SimSetup = build_setup(self.settings)  # ParameterError ends the start
        for spec in PARAMETERS.values():
            if spec.range is not None:
                self.set_descriptor(spec.name, descriptor(spec))
        # a change validated by _on_set_parameters, applied by _post_set_parameters
        self._candidate: tuple[SimSetup, dict[str, Any]] | None = None
        self.sim = self.setup.simulator()
        self._stop = threading.Event()
        self._lockstep_channels = lockstep_channels(self.settings)
        self._awaiting_ns: int | None = None
        self._unanswered: set[str] = set()  # lockstep channels not yet answered at the instant
        self.lockstep_missed = 0  # control instants that went on without every answer
        self._recorded_ns = -1  # stamp of the last state a recorder reported written [ns]
        self._recorder_paced = True  # False after a recorder failed to keep up in time
        self.published: dict[str, int] = {}  # topic -> messages published (or dropped)
        self._conflict_next = 0.0  # time.monotonic() of the next look for another graph

        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.add_post_set_parameters_callback(self._post_set_parameters)
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
        """Validate a change (nothing is applied here: see :meth:`_post_set_parameters`).

        Parameters
        ----------
        params : list of rclpy.parameter.Parameter
            Set at once; rclpy's own (``use_sim_time``) are let through untouched.

        Returns
        -------
        SetParametersResult
            Refused, with the reason, for a parameter applied at start only or a value
            :func:`~auv_sim.sim_settings.check_settings` refuses (its range, a publish period
            that is not a whole number of steps).
        """
        self._candidate = None
        changes: dict[str, Any] = {}
        for p in params:
            if p.name not in PARAMETERS:
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
        setup = dataclasses.replace(
            self.setup, settings=new,
            steps_per_publish=whole_steps(1.0 / new.publish_rate, self.setup.dt, 'publish'))
        self._candidate = (setup, changes)
        return SetParametersResult(successful=True)

    def _post_set_parameters(self, params: list[Parameter[Any]]) -> None:
        """Apply the change :meth:`_on_set_parameters` accepted: the settings and the publish
        period in steps.

        Parameters
        ----------
        params : list of rclpy.parameter.Parameter
            The parameters set (the candidate holds them, checked).
        """
        del params
        candidate, self._candidate = self._candidate, None
        if candidate is None:
            return
        self.setup, changes = candidate
        self.settings = self.setup.settings
        self.get_logger().info(f'parameters changed: {changes}')

    # ----- commands -----
    def _command_callback(self, channel: str) -> Callable[[ActuatorSetpoint], None]:
        def callback(msg: ActuatorSetpoint) -> None:
            if self.settings.lockstep and channel in self._lockstep_channels:
                ns = stamp_to_ns(msg.header.stamp)
                if self._awaiting_ns is None or channel not in self._unanswered \
                        or abs(ns - self._awaiting_ns) > LOCKSTEP_TOLERANCE_NS:
                    waiting = ('nothing' if self._awaiting_ns is None
                               or channel not in self._unanswered
                               else f'{self._awaiting_ns} ns')
                    self.get_logger().warning(
                        f'lockstep: ignored {channel} command stamped {ns} ns (awaiting '
                        f'{waiting})')
                    return
                self._unanswered.discard(channel)
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
        never dies on a publish. Counted in :attr:`published` either way."""
        topic = publisher.topic_name
        self.published[topic] = self.published.get(topic, 0) + 1
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

        timeout = self.settings.recorder_timeout
        start = time.monotonic()
        next_warning = start + _RECORDER_WARN_PERIOD
        gone = False

        def caught_up() -> bool:
            nonlocal next_warning, gone
            if now_ns - self._recorded_ns <= window // 2:
                return True
            if time.monotonic() >= next_warning:
                next_warning += _RECORDER_WARN_PERIOD
                gone = self._sub_progress.get_publisher_count() == 0
                if not gone:
                    self.get_logger().warning(
                        f'recorder pacing: waiting {time.monotonic() - start:.0f} s for the '
                        f'recorder at t = {self.sim.t:.2f} s (it has written up to '
                        f'{self._recorded_ns / 1e9:.2f} s; machine busy?)')
            return gone
        if self._spin_until(executor, start + timeout, caught_up) and not gone:
            return
        if self._stop.is_set():
            return
        self._recorder_paced = False
        why = 'its progress publisher left the graph' if gone else \
            f'no progress within {timeout} s'
        self.get_logger().error(
            f'recorder pacing: {why} at t = {self.sim.t:.2f} s (last state written at '
            f'{self._recorded_ns / 1e9:.2f} s); running on without waiting for it, the '
            'recording may miss messages')

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

    def check_no_other_graph(self) -> None:
        """Raise :class:`GraphConflictError` if another node publishes this node's ``state``
        topic (a second graph on the namespace). Looks at most every :data:`_CONFLICT_POLL`
        wall seconds (a graph query)."""
        if time.monotonic() < self._conflict_next:
            return
        self._conflict_next = time.monotonic() + _CONFLICT_POLL
        topic = self._pub_state.topic_name
        others = [f'{i.node_namespace.rstrip("/")}/{i.node_name}'
                  if '_UNKNOWN_' not in i.node_name else 'another node'
                  for i in self.get_publishers_info_by_topic(topic)
                  if (i.node_name, i.node_namespace) != (self.get_name(),
                                                         self.get_namespace())]
        if others:
            raise GraphConflictError(
                f'{", ".join(sorted(set(others)))} publishes {topic} already: another graph '
                f'runs on namespace {self.get_namespace()} (stop it, or give this one its '
                'own namespace)')

    def _startup_waits(self) -> list[tuple[str, Callable[[], bool]]]:
        """What to wait for before t = 0: (what, condition) pairs (see the module
        docstring)."""
        s = self.settings
        waits: list[tuple[str, Callable[[], bool]]] = []
        wanted = int(s.start_subscribers)
        if wanted > 0:
            waits.append((f'{wanted} subscriber(s) of {self._pub_state.topic_name}',
                          lambda: self._pub_state.get_subscription_count() >= wanted))
        streams = int(s.start_stream_subscribers)
        counts = [(self._pub_odom, max(streams, int(s.start_odom_subscribers))),
                  (self._pub_forces, streams)]
        if self._pub_clock is not None:
            counts.append((self._pub_clock, streams))
        for pub, count in counts:
            if count > 0:
                waits.append((f'{count} subscriber(s) of {pub.topic_name}',
                              functools.partial(_has_subscribers, pub, count)))
        if s.await_recorder:
            waits.append((f'a recorder on {self._sub_progress.topic_name}',
                          lambda: self._sub_progress.get_publisher_count() > 0))
        if s.lockstep:
            waits.append(('a controller subscribed to state or odom',
                          lambda: (self._pub_state.get_subscription_count() > 0
                                   or self._pub_odom.get_subscription_count() > 0)))
            for channel in self._lockstep_channels:
                sub = self._subs[channel]
                waits.append((f'a publisher of {sub.topic_name}',
                              functools.partial(_has_publishers, sub)))
        return waits

    def _wait_for_graph(self, executor: SingleThreadedExecutor) -> None:
        """Before t = 0: wait (``lockstep_startup_timeout``) for what
        :meth:`_startup_waits` lists, looking for another graph meanwhile."""
        waits = self._startup_waits()
        timeout = self.settings.lockstep_startup_timeout

        def ready() -> bool:
            self.check_no_other_graph()
            return all(done() for _, done in waits)
        if waits:
            self.get_logger().info(f'waiting up to {timeout:g} s for '
                                   + ', '.join(what for what, _ in waits))
        if self._spin_until(executor, time.monotonic() + timeout, ready):
            if waits:
                self.get_logger().info('graph ready')
        elif not self._stop.is_set():
            missing = [what for what, done in waits if not done()]
            self.get_logger().warning(f'after {timeout:g} s still no {", ".join(missing)}; '
                                      'starting anyway')

    def _expect_command(self) -> None:
        """Accept the controller's answers to the control instant about to be published: from
        here on, also while the recorder pacing serves callbacks before
        :meth:`_await_command`."""
        self._awaiting_ns = self.setup.stamp_ns(self.sim.k)
        self._unanswered = set(self._lockstep_channels)

    def _await_command(self, executor: SingleThreadedExecutor) -> None:
        """Wait (``lockstep_timeout``) for the answers :meth:`_expect_command` set up."""
        timeout = self.settings.lockstep_timeout
        try:
            ok = self._spin_until(executor, time.monotonic() + timeout,
                                  lambda: not self._unanswered)
            missing = sorted(self._unanswered)
        finally:
            self._awaiting_ns = None
            self._unanswered = set()
        if not ok and not self._stop.is_set():
            self.lockstep_missed += 1
            self.get_logger().warning(
                f'lockstep: no {"/".join(missing)} command stamped t = {self.sim.t:.3f} s '
                f'within {timeout} s; keeping the last command')

    def run_loop(self, executor: SingleThreadedExecutor) -> None:
        """Step, publish and serve callbacks until :meth:`stop`. DivergenceError and
        GraphConflictError propagate."""
        self._wait_for_graph(executor)
        self.check_no_other_graph()
        watch_until = time.monotonic() + CONFLICT_WATCH
        next_pub = next_ctrl = self.sim.k
        anchor_wall, anchor_k = time.monotonic(), self.sim.k
        warm = False
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
            if time.monotonic() < watch_until:
                self.check_no_other_graph()  # itself at most every _CONFLICT_POLL
            control_instant = s.lockstep and k == next_ctrl
            if control_instant:
                self._expect_command()
            if k == next_pub or control_instant:
                self._publish()
                if not warm:
                    # The compiled kernels load after the first state went out (its forces
                    # load the first): the controller answers it meanwhile. Not lag.
                    self.sim.warm_up()
                    warm = True
                    anchor_wall = time.monotonic()
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

    def recorded_to_the_end(self) -> bool:
        """Whether a recorder reported every stream written up to the last instant."""
        return self._recorder_paced and self._recorded_ns >= self.setup.stamp_ns(self.sim.k)

    def wait_for_acknowledgements(self, timeout: float = ACK_TIMEOUT) -> list[str]:
        """Wait (``timeout`` wall s in all) until every reliable subscriber acknowledged
        what this node published; returns the topics still unacknowledged."""
        pubs = [self._pub_state, self._pub_odom, self._pub_forces]
        if self._pub_clock is not None:
            pubs.append(self._pub_clock)
        end = time.monotonic() + timeout
        late = []
        for pub in pubs:
            left = max(0.0, end - time.monotonic())
            try:
                if not pub.wait_for_all_acked(Duration(nanoseconds=int(left * NS_PER_S))):
                    late.append(pub.topic_name)
            except RuntimeError:  # the context is gone (shutdown)
                late.append(pub.topic_name)
        return late

    def report(self) -> dict[str, Any]:
        """What the node did, for ``report_file``: messages published per topic, lockstep
        instants missed, whether the recorder pacing gave up, simulated time reached [s]."""
        return {'node': self.get_fully_qualified_name(), 'published': dict(self.published),
                'lockstep_missed': self.lockstep_missed,
                'recorder_pacing_given_up': not self._recorder_paced,
                't_end': float(self.sim.t)}


def _has_subscribers(pub: Any, wanted: int) -> bool:
    return bool(pub.get_subscription_count() >= wanted)


def _has_publishers(sub: Any) -> bool:
    return bool(sub.get_publisher_count() > 0)


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
        opt(field.name, kind, f'{PARAMETERS[field.name].description} (default: '
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
    use_dds_profile()  # before the first participant (auv_contract.dds)
    use_one_blas_thread()  # small matrices: one BLAS thread (auv_contract.blas)
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
        except (DivergenceError, GraphConflictError) as exc:
            node.get_logger().error(str(exc))
            print(f'error: {exc}', file=sys.stderr)
            return 1
        # a recorder that paced the run to its end has every message; others are waited for
        late = [] if node.recorded_to_the_end() else node.wait_for_acknowledgements()
        if late:
            node.get_logger().warning(f'not acknowledged within {ACK_TIMEOUT:g} s by every '
                                      f'subscriber: {", ".join(late)}')
        node.get_logger().info(f'stopped at t = {node.sim.t:.3f} s')
        return 0
    finally:
        executor.shutdown(timeout_sec=0.0)
        if node is not None:
            write_report(node.settings.report_file, node.report())
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
