"""The depth-pilot node: ``ros2 run auv_depth_lqr depth_pilot`` / ``auv pilot``.

Topics, relative to the node's namespace (``/auv`` unless remapped with ``-r __ns:=/auv1``;
each topic also with ``-r state:=/nav/state`` etc.):

* ``depth_command`` (std_msgs/Float64, metres down) from any publisher: reliable + volatile
  (a default-QoS script, ``ros2 topic pub``, a latched publisher such as ``auv depth``) and
  best-effort + volatile (a best-effort publisher), so that every publisher matches, without
  an incompatible-QoS warning on the publisher's side; and for the first
  :data:`LATCHED_WINDOW` wall seconds after start also reliable + transient-local, which takes
  a command latched before the pilot started (it is then removed: a transient-local
  subscription makes every volatile publisher warn of incompatible durability). A sample that
  arrives through more than one is applied once (same publisher and sequence number), and one
  older than a sample of its publisher already applied is not applied (the subscriptions
  deliver independently; it is logged). What is
  lost is said (:mod:`auv_depth_lqr.command_intake`): a warning, and WARN on ``/diagnostics``,
  when a publisher's first sample to arrive is not its first (the earlier ones were published
  before DDS matched it with the pilot) or when a publisher leaves without a sample having
  arrived (a script that published once right after ``create_publisher``).
* the answer to every depth command: ``depth_command_answer``
  (diagnostic_msgs/DiagnosticStatus, reliable, transient local, last 20; level OK accepted,
  WARN clamped or refused; ``values``: ``value_m``, ``result`` (accepted, clamped, refused),
  ``depth_m`` (the command in force), ``reason``, ``publisher`` (the command's publisher GID,
  hex) and ``sequence`` (its publication sequence number)), also in the ``/diagnostics`` status
  at once (``last_command_*``; WARN after a refusal until a command is accepted).
  ``auv depth`` waits for it and exits non-zero on a refusal.
* the state: ``state`` (auv_msgs/VehicleState, NED/FRD) or, with ``state_source:=odometry``,
  ``odom`` (nav_msgs/Odometry, ``odom_frame`` ``enu_flu`` (REP-105) or ``ned_frd``, see
  :mod:`auv_depth_lqr.state_input`); reliable by default, best effort with
  ``state_reliability:=best_effort`` (an incompatible publisher is reported in a warning).
* publishes ``bar_command`` (auv_msgs/ActuatorSetpoint, rad) at a fixed rate (``rate``,
  default 10 Hz) from a timer, whether or not new state arrived (and once more at the first
  state after its start, stamped with that state's stamp, so that the vehicle gets its
  first command without waiting up to a period for the timer), and ``/diagnostics``
  (diagnostic_msgs/DiagnosticArray, absolute as the ROS convention has it) every
  ``diagnostics_period`` seconds and at once when the pilot's mode, its plane authority,
  its pitch envelope or a depth runaway changes: two statuses, ``<node>: depth control``
  (mode, command, envelope: ``pitch_envelope`` ``clear``, ``at limit`` while the pitch
  envelope selector holds the pitch limit (the change flown at the limit, as planned;
  status unchanged) or ``given way`` while it holds a limit that gave way, WARN with one
  line: :meth:`auv_depth_lqr.pilot.DepthPilot.envelope_state`, ``envelope_warning``;
  ``depth_runaway_m`` ``none``, or how far off its command the vehicle is (``below`` or
  ``above``) while the plane at its stop cannot bring it back, ERROR with one line, also
  logged as an error when it begins: :mod:`auv_depth_lqr.runaway`,
  :meth:`auv_depth_lqr.pilot.DepthPilot.runaway_warning`; the speed it schedules on, over
  ground or through the water, and the current along the heading:
  :meth:`auv_depth_lqr.pilot.DepthPilot.speed_diagnostics`; what the pilot has learned of
  its plant and the climb and dive it can fly:
  :meth:`auv_depth_lqr.pilot.DepthPilot.learning_diagnostics`) and ``<node>: plane
  authority`` (how much of the plane holding depth takes, WARN when little is left:
  :mod:`auv_depth_lqr.authority`).

All logic is in :class:`auv_depth_lqr.pilot.DepthPilot`; this module converts messages.

Lockstep (parameter ``lockstep``, with the simulator's ``lockstep``; ``docs/lockstep.md``): no
timer; each state whose stamp is a control instant ``k / rate`` (within 1 us, see
:func:`auv_contract.lockstep.control_instant`) gets its BAR command stamped with the state's
own stamp, so the simulator can wait for it (see :mod:`auv_sim.node`). A state stamped within
1 ms of an instant but farther than 1 us gets no answer and one warning.

Parameters (:mod:`auv_depth_lqr.parameters`: each declared with a descriptor giving its
description with unit, its range and its further limits; validated at start: a bad one ends
the node with one line ``error: ...`` and exit status 1; and on change, where a bad one is
refused with a reason and nothing changes, a good one applied once ROS has stored it):
``vehicle_file``, ``rate`` [Hz], ``weights`` (preset name), ``theta_max`` [rad], ``bar_max`` /
``bar_rate`` [rad, rad/s; 0 = vehicle file], ``state_timeout`` [s], ``safe_bar`` [rad;
NaN (default) = derived from the vehicle file, :func:`auv_depth_lqr.tuning.derive_tuning`],
``lockstep`` (bool), ``water_speed`` [m/s; 0 = schedule on the measured surge over ground,
else the known speed through the water, see :func:`auv_depth_lqr.pilot.water_relative`],
``publish_delay`` [s], ``depth_min`` / ``depth_max`` [m; NaN (default) = the vehicle file's
envelope], ``depth_command_mode`` (``refuse`` or ``clamp``), ``odom_frame``, the envelope
fallback ``recovery`` (bool), ``recovery_pitch_margin`` [rad],
``recovery_rate_residual`` [m/s], ``recovery_rate_window`` [s], ``recovery_resume_time``
[s], ``recovery_gain``, ``recovery_bar_fraction`` (see :mod:`auv_depth_lqr.recovery`),
at start only: ``pitch_envelope`` (bool, the pitch envelope selector,
:mod:`auv_depth_lqr.envelope`), ``plane_rate_design`` (bool, the LQR designed on the plane's
rate: :class:`auv_depth_lqr.pilot.PilotSettings`), ``diagnostics_period`` [s],
``state_source`` (``vehicle_state`` or ``odometry``), ``state_reliability``,
``realtime_priority`` (0-99; 0 = normal scheduling),
``start_subscribers`` (before its first command the node waits, at most ``startup_timeout``
[s], until ``bar_command`` has this many matched subscriptions, so that a recorder started
with the graph misses none of the first commands; 0 = do not wait),
``diagnostics_subscribers`` (the same for ``/diagnostics`` before its first status),
``report_file`` (JSON written at exit: messages published per topic, when the first command went
out; '' none).

On SIGINT or SIGTERM the node waits (at most :data:`ACK_TIMEOUT` s) until its reliable
subscribers have acknowledged what it published, writes its report and exits 0.

Real-time scheduling (``realtime_priority`` > 0): at start the node's threads move to
``SCHED_FIFO`` at that priority, as a control loop on a vehicle runs, so other processes do
not delay its wake-ups. It needs CAP_SYS_NICE or an rtprio limit (``ulimit -r``); without them
the node says so in one warning and runs with normal scheduling.

Output phase (timer on the wall clock): the command of the tick due at ``t_k`` is computed at
once and published at ``t_k + publish_delay`` (default 10 ms), so the publish period keeps the
timer's grid whatever the step took; a step that ends later publishes at once. The header
stamp is ``t_k``, the control instant the command is for. On simulated time (``use_sim_time``)
the command is published as soon as it is computed.
"""

import argparse
import functools
import gc
import math
import os
import signal
import sys
import time
from typing import Any

import rclpy
import rclpy.exceptions
import rclpy.executors
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ROSClock
from rclpy.clock_type import ClockType
from rclpy.duration import Duration
from rclpy.event_handler import (
    QoSRequestedIncompatibleQoSInfo,
    QoSSubscriptionMatchedInfo,
    SubscriptionEventCallbacks,
)
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import (
    DurabilityPolicy,
    QoSCompatibility,
    QoSPolicyKind,
    QoSProfile,
    ReliabilityPolicy,
    qos_check_compatible,
)
from rclpy.signals import SignalHandlerOptions
from rclpy.timer import Timer, TimerInfo
from std_msgs.msg import Float64

from auv_contract import DEPTH_ANSWER_TOPIC, topic_basename
from auv_contract.blas import use_one_blas_thread
from auv_contract.dds import use_dds_profile
from auv_contract.lockstep import NS_PER_S, control_instant
from auv_depth_lqr.authority import LOW, UNKNOWN
from auv_depth_lqr.command_intake import (
    ACCEPTED,
    CLAMPED,
    REFUSED,
    CommandAnswer,
    CommandIntake,
    gid_text,
)
from auv_depth_lqr.controller import PlaneState
from auv_depth_lqr.errors import AuvLqrError, InvalidInputError
from auv_depth_lqr.node_status import (
    answer_status,
    authority_status,
    authority_text,
    control_status,
    status_text,
)
from auv_depth_lqr.parameters import (
    PARAMETERS,
    RELIABILITIES,
    START_ONLY,
    checked_values,
    pilot_from_values,
)
from auv_depth_lqr.pilot import DepthPilot
from auv_depth_lqr.state_input import plane_state_from_odometry
from auv_msgs.msg import ActuatorSetpoint, VehicleState
from auv_sim.errors import AuvSimError
from auv_sim.node_report import write_report
from auv_sim.parameter_descriptor import descriptor

DEFAULT_NAMESPACE = '/auv'
NODE_NAME = 'depth_pilot'
#: Depth of the ``bar_command`` publisher's history (reliable, keep last): 100 s of commands
#: at 10 Hz. A reader that lost a sample (DDS may drop the first one to a reader that has just
#: matched) gets it again from this history at the writer's next heartbeat, seconds of wall
#: time later; a lockstep graph runs many times faster than real time and a recorder paces it
#: only on what it has written, so a shorter history lost the first commands of fast runs.
BAR_HISTORY = 1000

#: The depth-command subscriptions: together they match every publisher (see module docstring);
#: ``latched`` lives only for the first :data:`LATCHED_WINDOW` s.
COMMAND_QOS: dict[str, QoSProfile] = {
    'latched': QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.TRANSIENT_LOCAL),
    'reliable': QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                           durability=DurabilityPolicy.VOLATILE),
    'best_effort': QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT,
                              durability=DurabilityPolicy.VOLATILE),
}
STATE_RELIABILITY = dict(zip(RELIABILITIES, (ReliabilityPolicy.RELIABLE,
                                              ReliabilityPolicy.BEST_EFFORT), strict=True))
_SEEN_COMMANDS = 64  # depth-command samples remembered to apply each once
#: Wall s after start during which a transient-local depth-command subscription takes a
#: command latched before the pilot started (then removed; see the module docstring).
LATCHED_WINDOW = 10.0
_DEPARTURE_SETTLE = 0.5  # wall s after a publisher left before the graph is looked at
_NEAR_INSTANT_NS = 1_000_000  # a state this close to a control instant was meant as one
ANSWER_TOPIC = topic_basename(DEPTH_ANSWER_TOPIC)  # relative: /auv/depth_command_answer
#: The answers: reliable, transient local (a waiting ``auv depth`` that matches late still
#: gets its answer), last 20.
ANSWER_QOS = QoSProfile(depth=20, reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL)
ACK_TIMEOUT = 2.0  # wall s, longest wait at exit for the subscribers' acknowledgements

class DepthPilotNode(Node):
    """Thin ROS wrapper of :class:`DepthPilot` (see module docstring)."""

    def __init__(self, **kwargs: Any) -> None:
        kwargs.setdefault('namespace', DEFAULT_NAMESPACE)
        super().__init__(NODE_NAME, **kwargs)
        # ranges after the check, so that a bad value at start gets the message naming it
        for spec in PARAMETERS.values():
            self.declare_parameter(spec.name, spec.default, descriptor(spec, ranged=False))
        values = checked_values(self._values({}))
        for spec in PARAMETERS.values():
            if spec.range is not None:
                self.set_descriptor(spec.name, descriptor(spec))
        self.realtime_priority: int = values['realtime_priority']
        self.start_subscribers: int = values['start_subscribers']
        self.diagnostics_subscribers: int = values['diagnostics_subscribers']
        self.startup_timeout: float = values['startup_timeout']
        self.report_file = str(values['report_file'])
        self._subscribers_awaited = self.start_subscribers == 0
        self._diagnostics_awaited = self.diagnostics_subscribers == 0
        self.published: dict[str, int] = {}  # topic -> messages published
        self.first_command_time: float | None = None
        """Wall-clock time [s since the epoch] of the first BAR command published."""
        self.pilot = pilot_from_values(values)
        self.command_mode = values['depth_command_mode']
        self.odom_frame = values['odom_frame']
        # a change validated by _on_set, applied by _post_set once ROS has stored it
        self._candidate: tuple[DepthPilot, dict[str, Any]] | None = None
        self.add_on_set_parameters_callback(self._on_set)
        self.add_post_set_parameters_callback(self._post_set)
        # reliable, last BAR_HISTORY: a sample a reader lost is resent from this history
        self.pub = self.create_publisher(ActuatorSetpoint, 'bar_command', BAR_HISTORY)
        self.pub_diagnostics = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        self.pub_answer = self.create_publisher(DiagnosticStatus, ANSWER_TOPIC, ANSWER_QOS)
        self.intake = CommandIntake(_SEEN_COMMANDS)
        self._last_refusal = ''
        self.last_answer: CommandAnswer | None = None
        self._command_warning = ''  # a refusal or loss, until a command is accepted
        self._matched = (0, 0)  # (total, current) publishers of the reliable subscription
        self._near_miss_warned = False
        self.command_subscriptions = {
            name: self.create_subscription(
                Float64, 'depth_command', functools.partial(self._on_depth, name), qos,
                event_callbacks=SubscriptionEventCallbacks(
                    incompatible_qos=functools.partial(self._on_command_incompatible, name),
                    matched=self._on_command_matched if name == 'reliable' else None))
            for name, qos in COMMAND_QOS.items()}
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._latched_end = self.create_timer(LATCHED_WINDOW, self._end_latched_window,
                                              clock=self._steady)
        self._departure_check: Timer | None = None
        state_qos = QoSProfile(depth=50,
                               reliability=STATE_RELIABILITY[values['state_reliability']])
        state_events = SubscriptionEventCallbacks(incompatible_qos=self._on_state_incompatible)
        if values['state_source'] == 'odometry':
            self.state_subscription = self.create_subscription(
                Odometry, 'odom', self._on_odometry, state_qos, event_callbacks=state_events)
        else:
            self.state_subscription = self.create_subscription(
                VehicleState, 'state', self._on_state, state_qos, event_callbacks=state_events)
        self.timer: Timer | None = None
        self._reported = ''
        self._authority_reported = UNKNOWN
        self._envelope_reported = 'clear'
        self._runaway_reported = False
        self._t_command = 0.0
        """Time [s] of the last command computed (what ``/diagnostics`` reports on)."""
        self._configure_timer()
        self.create_timer(values['diagnostics_period'], self._publish_diagnostics)
        self.get_logger().info(
            f'{self.pilot.controller.limits.theta_max * 180 / math.pi:g} deg pitch limit, '
            f'depth envelope [{self.pilot.depth_min:g}, {self.pilot.depth_max:g}] m '
            f'({self.command_mode} outside), state from '
            f'{self.state_subscription.topic_name}'
            + (f' ({self.odom_frame})' if values['state_source'] == 'odometry' else ''))

    # -- parameters --------------------------------------------------------------------------
    def _values(self, changes: dict[str, Any]) -> dict[str, Any]:
        values = {n: self.get_parameter(n).value for n in PARAMETERS}
        values.update(changes)
        return values

    def _on_set(self, params: list[Any]) -> SetParametersResult:
        """Validate a change (nothing is applied here: see :meth:`_post_set`).

        Parameters
        ----------
        params : list of rclpy.parameter.Parameter
            The parameters being set together.

        Returns
        -------
        SetParametersResult
            Refused, with the reason, for a start-only parameter, a value
            :func:`~auv_depth_lqr.parameters.checked_values` or the design refuses, or an
            envelope that excludes the depth command in force.
        """
        self._candidate = None
        fixed = [p.name for p in params if p.name in START_ONLY]
        if fixed:
            return SetParametersResult(successful=False, reason=(
                f'{", ".join(fixed)} applied at start only; restart the node to change it'))
        try:
            values = checked_values(self._values({p.name: p.value for p in params}))
            pilot = pilot_from_values(values)
            z_ref = self.pilot.z_ref
            if z_ref is not None:
                # the command in force must be flyable under the new envelope
                pilot.set_depth_command(z_ref)
        except (AuvLqrError, AuvSimError, ValueError, TypeError) as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        self._candidate = (pilot, values)
        return SetParametersResult(successful=True)

    def _post_set(self, params: list[Any]) -> None:
        """Apply the change :meth:`_on_set` accepted: the redesigned pilot, the command mode,
        the odometry frame; the timer follows at its next tick."""
        del params  # the candidate holds them, checked
        candidate, self._candidate = self._candidate, None
        if candidate is None:
            return
        self.pilot, values = candidate
        self.command_mode = values['depth_command_mode']
        self.odom_frame = values['odom_frame']
        self.get_logger().info('parameters changed: controller redesigned')
        # the timer periods may have changed
        self._pending_timer = True

    def _configure_timer(self) -> None:
        if self.timer is not None:
            self.destroy_timer(self.timer)
            self.timer = None
        self.lockstep = bool(self.get_parameter('lockstep').value)
        self.control_ns = int(round(NS_PER_S / self.pilot.settings.rate_hz))
        if not self.lockstep:
            self.timer = self.create_timer(self.pilot.settings.Ts, self._on_timer)
        self._pending_timer = False

    # -- depth commands ----------------------------------------------------------------------
    def _on_depth(self, subscription: str, msg: Float64, info: Any) -> None:
        gid, seq = _sample_identity(info)
        self.intake.arrived(gid, subscription == 'reliable')
        if not self.intake.first_time(gid, seq):
            return
        newer = self.intake.superseded(gid, seq)
        if newer is not None:
            self.get_logger().info(
                f'depth command {msg.data:g} m (sequence {seq}) of '
                f'{self._publisher_name(gid)} arrived after its sequence {newer}: superseded, '
                'not applied')
            return
        # a latched publisher's late joiner gets only its last sample, by design
        missed = self.intake.missed_before(gid, seq, volatile=subscription != 'latched')
        if missed:
            self._lost(f'{missed} earlier depth command(s) of {self._publisher_name(gid)} did '
                       'not reach the pilot (published before DDS matched the publisher with '
                       'the pilot: wait for the match before publishing, see '
                       'docs/pilot-interfaces.md)')
        clamp = self.command_mode == 'clamp'
        answer: CommandAnswer
        try:
            z = self.pilot.set_depth_command(msg.data, clamp=clamp)
        except InvalidInputError as exc:
            self._last_refusal = str(exc)
            answer = CommandAnswer(msg.data, REFUSED, self.pilot.z_ref, str(exc),
                                   gid_text(gid), seq or 0)
            self.get_logger().warning(f'rejected: {exc}')
        else:
            if z != msg.data:
                answer = CommandAnswer(
                    msg.data, CLAMPED, z, f'outside the envelope [{self.pilot.depth_min:g}, '
                    f'{self.pilot.depth_max:g}] m', gid_text(gid), seq or 0)
                self.get_logger().warning(
                    f'depth command {msg.data:g} m outside the envelope '
                    f'[{self.pilot.depth_min:g}, {self.pilot.depth_max:g}] m: clamped to '
                    f'{z:g} m')
            else:
                answer = CommandAnswer(msg.data, ACCEPTED, z, '', gid_text(gid), seq or 0)
                self.get_logger().info(f'depth command {z:g} m accepted')
        self._answer(answer)

    def _answer(self, answer: CommandAnswer) -> None:
        """Publish the answer to a command (answer topic, and /diagnostics at once)."""
        self.last_answer = answer
        if answer.result == REFUSED:
            self._command_warning = answer.text()
        elif answer.result == ACCEPTED:
            self._command_warning = ''
        self._count(self.pub_answer)
        self.pub_answer.publish(answer_status(answer, self.get_fully_qualified_name(),
                                              self.get_namespace()))
        self._publish_diagnostics()

    def _lost(self, text: str) -> None:
        """A depth command that did not arrive: a warning, and WARN on /diagnostics."""
        self.get_logger().warning(text)
        self._command_warning = text
        self._publish_diagnostics()

    def _publisher_name(self, gid: bytes | None) -> str:
        topic = self.command_subscriptions['reliable'].topic_name
        for i in self.get_publishers_info_by_topic(topic):
            if bytes(i.endpoint_gid) == gid:
                return f'publisher {i.node_namespace.rstrip("/")}/{i.node_name}'
        return 'a publisher'

    def _on_command_matched(self, info: QoSSubscriptionMatchedInfo) -> None:
        # the status is coalesced: a publisher that matched and left between two events shows
        # as total + 1, current + 0; the graph lists a departed publisher a little later
        self._matched = (info.total_count, info.current_count)
        if info.total_count > info.current_count and self._departure_check is None:
            self._departure_check = self.create_timer(_DEPARTURE_SETTLE, self._check_departures,
                                                      clock=self._steady)

    def _check_departures(self) -> None:
        if self._departure_check is not None:
            self.destroy_timer(self._departure_check)
            self._departure_check = None
        topic = self.command_subscriptions['reliable'].topic_name
        present = {bytes(i.endpoint_gid) for i in self.get_publishers_info_by_topic(topic)}
        silent = self.intake.silent_departures(*self._matched, present)
        if silent:
            self._lost(f'{silent} publisher(s) of {topic} left without a depth command reaching '
                       'the pilot: if it published, the command was lost (published before '
                       'DDS matched it with the pilot; wait for the match before publishing, '
                       'see docs/pilot-interfaces.md)')

    def _end_latched_window(self) -> None:
        """End of the start-up window: the transient-local subscription goes (see module
        docstring)."""
        self.destroy_timer(self._latched_end)
        latched = self.command_subscriptions.pop('latched', None)
        if latched is not None:
            self.destroy_subscription(latched)

    def _on_command_incompatible(self, name: str, info: QoSRequestedIncompatibleQoSInfo,
                                 ) -> None:
        policy = _policy_name(info.last_policy_kind)
        subscription = self.command_subscriptions.get(name)
        if subscription is None:
            return
        topic = subscription.topic_name
        lost = []
        for pub in self.get_publishers_info_by_topic(topic):
            if all(qos_check_compatible(pub.qos_profile, qos)[0] == QoSCompatibility.ERROR
                   for qos in COMMAND_QOS.values()):
                lost.append(f'{pub.node_namespace.rstrip("/")}/{pub.node_name} '
                            f'({_qos_text(pub.qos_profile)})')
        if lost:
            self.get_logger().warning(
                f'{topic}: publisher(s) {", ".join(lost)} incompatible with every depth-command '
                f'subscription (last policy: {policy}): their commands do not arrive')
        elif name == 'latched':
            self.get_logger().info(
                f'{topic}: a volatile publisher does not match the start-up subscription for '
                f'latched commands ({policy}; it goes {LATCHED_WINDOW:g} s after start); its '
                'commands arrive through the reliable subscription once DDS has matched it '
                'with the pilot')

    def _on_state_incompatible(self, info: QoSRequestedIncompatibleQoSInfo) -> None:
        policy = _policy_name(info.last_policy_kind)
        topic = self.state_subscription.topic_name
        hint = (' (a best-effort publisher: set state_reliability:=best_effort)'
                if policy == 'RELIABILITY' else '')
        self.get_logger().warning(
            f'{topic}: a publisher with incompatible QoS ({policy}){hint}: its state does '
            'not arrive')

    # -- state -------------------------------------------------------------------------------
    def _now(self) -> float:
        return self.get_clock().now().nanoseconds / NS_PER_S

    def _on_state(self, msg: VehicleState) -> None:
        self._take_state(PlaneState(z=msg.z, theta=msg.theta, w=msg.w, q=msg.q, u=msg.u),
                         msg.header.stamp)

    def _on_odometry(self, msg: Odometry) -> None:
        pose, twist = msg.pose.pose, msg.twist.twist
        try:
            state = plane_state_from_odometry(
                (pose.position.x, pose.position.y, pose.position.z),
                (pose.orientation.x, pose.orientation.y, pose.orientation.z,
                 pose.orientation.w),
                (twist.linear.x, twist.linear.y, twist.linear.z),
                (twist.angular.x, twist.angular.y, twist.angular.z), self.odom_frame)
        except InvalidInputError as exc:
            self.get_logger().warning(f'rejected: {exc}')
            return
        self._take_state(state, msg.header.stamp)

    def _take_state(self, s: PlaneState, stamp: Any) -> None:
        try:
            self.pilot.on_state(self._now(), z=s.z, theta=s.theta, w=s.w, q=s.q, u=s.u,
                                stamp=stamp.sec + stamp.nanosec / NS_PER_S)
        except InvalidInputError as exc:
            self.get_logger().warning(f'rejected: {exc}')
            return
        if self._pending_timer and self.lockstep:
            self._configure_timer()
        if not self.lockstep and self.first_command_time is None:
            # the first command answers at once (after publish_delay from its arrival)
            self._publish(stamp, self._now(),
                          self._wall_out_ns(self.get_clock().now().nanoseconds))
        if self.lockstep:
            stamp_ns = stamp.sec * NS_PER_S + stamp.nanosec
            if control_instant(stamp_ns, self.control_ns) is not None:
                self._publish(stamp, self._now())
            elif not self._near_miss_warned and abs(
                    stamp_ns - round(stamp_ns / self.control_ns) * self.control_ns) \
                    < _NEAR_INSTANT_NS:
                self._near_miss_warned = True
                self.get_logger().warning(
                    f'lockstep: state stamped {stamp_ns} ns is near a control instant but more '
                    'than 1 us off it: not answered (stamp control instants as integer '
                    'nanoseconds, k * period)')

    # -- output ------------------------------------------------------------------------------
    def _on_timer(self, info: TimerInfo) -> None:
        if self._pending_timer:
            self._configure_timer()
        due = info.expected_call_time
        self._publish(due.to_msg(), self._now(), self._wall_out_ns(due.nanoseconds))

    def _wall_out_ns(self, due_ns: int) -> int | None:
        """The system-clock instant [ns] a command due at ``due_ns`` goes out, after
        ``publish_delay``; None on simulated time (``/clock``), where it goes out at once."""
        clock = self.get_clock()  # ROS time: on the system clock unless /clock drives it
        if isinstance(clock, ROSClock) and clock.ros_time_is_active:
            return None
        return due_ns + int(self.pilot.settings.publish_delay * NS_PER_S)

    def _publish(self, stamp: Any, t: float, out_ns: int | None = None) -> None:
        """Compute the command for ``t`` [s] and publish it stamped ``stamp``; with ``out_ns``
        [ns, system clock], not before that instant."""
        bar, status = self.pilot.command(t)
        self._t_command = t
        changed = status != self._reported
        if changed:
            if status == 'ok':
                self.get_logger().info(status_text(self.pilot, status))
            else:
                self.get_logger().warning(status_text(self.pilot, status))
            self._reported = status
        authority = self.pilot.authority
        if authority.level != self._authority_reported and authority.level != UNKNOWN:
            text = f'plane authority {authority.level}: {authority_text(self.pilot)}'
            if authority.level == LOW:
                self.get_logger().warning(text)
            elif self._authority_reported == LOW:
                self.get_logger().info(text)
            self._authority_reported = authority.level
            changed = True
        envelope = self.pilot.envelope_state(t)
        if envelope != self._envelope_reported:
            if envelope == 'given way':
                self.get_logger().warning(self.pilot.envelope_warning(t))
            elif self._envelope_reported == 'given way':
                self.get_logger().info('pitch limit no longer held: depth control as asked')
            self._envelope_reported = envelope
            changed = True
        runaway = self.pilot.runaway_monitor.state is not None
        if runaway != self._runaway_reported:
            if runaway:
                self.get_logger().error(self.pilot.runaway_warning())
            else:
                self.get_logger().info('depth runaway over: the vehicle is coming back to its '
                                       'command, or the plane has left its stop')
            self._runaway_reported = runaway
            changed = True
        out = ActuatorSetpoint()
        out.header.stamp = stamp
        out.header.frame_id = 'bar'
        out.value = float(bar)
        if not self._subscribers_awaited:
            self._await_subscribers()
        if out_ns is not None:
            wait = out_ns - time.time_ns()
            if wait > 0:
                time.sleep(wait / NS_PER_S)
        self._count(self.pub)
        self.pub.publish(out)
        if self.first_command_time is None:
            self.first_command_time = time.time()
        if changed:
            self._publish_diagnostics()

    def _count(self, publisher: Any) -> None:
        topic = publisher.topic_name
        self.published[topic] = self.published.get(topic, 0) + 1

    def _await_subscribers(self) -> None:
        """Before the first command: wait until ``bar_command`` has ``start_subscribers``
        matched subscriptions (DDS matches each subscription on its own; a command published
        before is lost to it)."""
        self._subscribers_awaited = True
        self._await_matched(self.pub, self.start_subscribers)

    def _await_matched(self, publisher: Any, wanted: int) -> None:
        """Wait, at most ``startup_timeout`` wall seconds, until ``publisher`` has ``wanted``
        matched subscriptions; then publish anyway, with a warning."""
        deadline = time.monotonic() + self.startup_timeout
        while publisher.get_subscription_count() < wanted:
            if time.monotonic() >= deadline:
                self.get_logger().warning(
                    f'{publisher.get_subscription_count()} of {wanted} {publisher.topic_name} '
                    f'subscribers after {self.startup_timeout:g} s; publishing anyway')
                return
            time.sleep(0.005)

    def _publish_diagnostics(self) -> None:
        """The pilot's DiagnosticStatus (depth control) and its plane authority on
        ``/diagnostics`` (ROS convention; :mod:`auv_depth_lqr.node_status`)."""
        if not self._diagnostics_awaited:
            # before the first status: the subscribers of the graph (a recorder) matched
            self._diagnostics_awaited = True
            self._await_matched(self.pub_diagnostics, self.diagnostics_subscribers)
        name, namespace = self.get_fully_qualified_name(), self.get_namespace()
        array = DiagnosticArray()
        array.header.stamp = self.get_clock().now().to_msg()
        array.status = [control_status(self.pilot, name, namespace, self._t_command,
                                       self._command_warning, self._last_refusal,
                                       self.last_answer),
                        authority_status(self.pilot, name, namespace)]
        self._count(self.pub_diagnostics)
        self.pub_diagnostics.publish(array)

    def wait_for_acknowledgements(self, timeout: float = ACK_TIMEOUT) -> list[str]:
        """Wait (``timeout`` wall s in all) until every reliable subscriber acknowledged what
        the node published; returns the topics still unacknowledged."""
        end = time.monotonic() + timeout
        late = []
        for pub in (self.pub, self.pub_diagnostics, self.pub_answer):
            left = max(0.0, end - time.monotonic())
            if not pub.wait_for_all_acked(Duration(nanoseconds=int(left * NS_PER_S))):
                late.append(pub.topic_name)
        return late

    def report(self) -> dict[str, Any]:
        """What the node published (``report_file``), and when its first command went out
        (``first_command_time``, wall clock [s since the epoch]; None before any)."""
        return {'node': self.get_fully_qualified_name(), 'published': dict(self.published),
                'first_command_time': self.first_command_time}


def _sample_identity(info: Any) -> tuple[bytes | None, int | None]:
    """(publisher GID, publication sequence number) of a sample from its message info, each
    None when the middleware does not give it."""
    if not isinstance(info, dict):
        return None, None
    gid = info.get('publisher_gid')
    gid_bytes = bytes(gid['data']) if isinstance(gid, dict) and 'data' in gid else None
    seq = info.get('publication_sequence_number')
    return gid_bytes, seq if isinstance(seq, int) else None


def _policy_name(kind: int) -> str:
    """Name of a QoS policy kind (``DURABILITY``, ``RELIABILITY``, ...)."""
    try:
        return QoSPolicyKind(kind).name
    except ValueError:
        return f'policy {kind}'


def _qos_text(qos: QoSProfile) -> str:
    return f'{qos.reliability.name.lower()}, {qos.durability.name.lower()}'


def apply_realtime_priority(priority: int) -> str | None:
    """Move every thread of this process to ``SCHED_FIFO`` at ``priority`` (1-99); ``None``
    when done, else why not (e.g. "Operation not permitted": no CAP_SYS_NICE / rtprio)."""
    try:
        param = os.sched_param(priority)
        for task in os.listdir('/proc/self/task'):
            os.sched_setscheduler(int(task), os.SCHED_FIFO, param)
    except (OSError, AttributeError) as exc:
        return getattr(exc, 'strerror', None) or str(exc)
    return None


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``auv pilot`` options; ROS parameters go after ``--ros-args -p name:=value``."""
    parser.add_argument('--ros-args', dest='ros_args', nargs=argparse.REMAINDER, default=None,
                        help='ROS arguments, e.g. --ros-args -p rate:=10.0 -p lockstep:=true '
                             '-r __ns:=/auv1')


def run(args: argparse.Namespace) -> int:
    """Run the node until SIGINT/SIGTERM; 1 with a one-line error on bad parameters."""
    ros_args = getattr(args, 'ros_args', None)
    return main(['depth_pilot', *(['--ros-args', *ros_args] if ros_args else [])])


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv if argv is None else argv
    use_dds_profile()  # before the first participant (auv_contract.dds)
    use_one_blas_thread()  # small matrices: one BLAS thread (auv_contract.blas)
    rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
    stop: list[int] = []
    previous = {sig: signal.signal(sig, lambda signum, _frame: stop.append(signum))
                for sig in (signal.SIGINT, signal.SIGTERM)}
    node = None
    try:
        node = DepthPilotNode()
        if node.realtime_priority > 0:
            applied = apply_realtime_priority(node.realtime_priority)
            if applied is None:
                node.get_logger().info(f'threads on SCHED_FIFO {node.realtime_priority}')
            else:
                node.get_logger().warning(f'realtime_priority {node.realtime_priority} not '
                                          f'applied ({applied}): normal scheduling')
        # Everything built so far (rclpy, numpy, the design) is long-lived: keep it out of the
        # cyclic collector, whose full passes over it would otherwise pause a control step.
        gc.collect()
        gc.freeze()
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        while not stop:
            executor.spin_once(timeout_sec=0.1)
        late = node.wait_for_acknowledgements()
        if late:
            node.get_logger().warning(f'not acknowledged within {ACK_TIMEOUT:g} s by every '
                                      f'subscriber: {", ".join(late)}')
    except (AuvLqrError, AuvSimError, rclpy.exceptions.ParameterException) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 1
    except rclpy.executors.ExternalShutdownException:
        pass
    finally:
        if node is not None:
            write_report(node.report_file, node.report())
            node.destroy_node()
        if rclpy.ok():
            rclpy.try_shutdown()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    return 0


if __name__ == '__main__':
    sys.exit(main())
