"""The depth-pilot node: ``ros2 run auv_depth_lqr depth_pilot`` / ``auv pilot``.

Subscribes ``/auv/depth_command`` (std_msgs/Float64, metres down; reliable, transient-local so
a command sent before the pilot starts is not lost) and ``/auv/state``
(auv_msgs/VehicleState, NED/FRD); publishes ``/auv/bar_command`` (auv_msgs/ActuatorSetpoint,
rad) at a fixed rate (``rate``, default 10 Hz) from a timer, whether or not new state arrived.
All logic is in :class:`auv_depth_lqr.pilot.DepthPilot`; this module converts messages.

Lockstep (parameter ``lockstep``, with the simulator's ``lockstep``): no timer; each state
whose stamp is a control instant ``k / rate`` gets its BAR command stamped with that same
instant, so the simulator can wait for it (see :mod:`auv_sim.node`).

Parameters (validated at start and on change): ``vehicle_file``, ``rate`` [Hz], ``weights``
(preset name), ``theta_max_deg`` [deg], ``bar_max`` / ``bar_rate`` [rad, rad/s; 0 = vehicle
file], ``state_timeout`` [s], ``safe_bar`` [rad], ``lockstep`` (bool), ``water_speed``
[m/s; 0 = schedule on the measured surge over ground, else the known speed through the water,
see :func:`auv_depth_lqr.pilot.water_relative`], ``publish_delay`` [s],
``realtime_priority`` (0-99, at start only; 0 = normal scheduling).

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
import gc
import math
import os
import pathlib
import sys
import time
from typing import Any

import rclpy
import rclpy.exceptions
import rclpy.executors
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import ROSClock
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.timer import Timer, TimerInfo
from std_msgs.msg import Float64

from auv_depth_lqr.errors import AuvLqrError, DesignError, InvalidInputError
from auv_depth_lqr.pilot import SAFE_BAR_DEFAULT, DepthPilot, PilotSettings
from auv_msgs.msg import ActuatorSetpoint, VehicleState
from auv_sim.errors import AuvSimError
from auv_sim.params import load_vehicle

NS_PER_S = 1_000_000_000


def default_vehicle_file() -> str:
    """``config/a18m.yaml`` of the workspace (``AUV_ROOT``) or of the source tree."""
    root = os.environ.get('AUV_ROOT')
    base = pathlib.Path(root) if root else pathlib.Path(__file__).resolve().parents[3]
    return str(base / 'config' / 'a18m.yaml')


class DepthPilotNode(Node):
    """Thin ROS wrapper of :class:`DepthPilot` (see module docstring)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__('depth_pilot', **kwargs)
        self.declare_parameter('vehicle_file', default_vehicle_file())
        self.declare_parameter('rate', 10.0)
        self.declare_parameter('weights', 'default')
        self.declare_parameter('theta_max_deg', 25.0)
        self.declare_parameter('bar_max', 0.0)
        self.declare_parameter('bar_rate', 0.0)
        self.declare_parameter('state_timeout', 0.5)
        self.declare_parameter('safe_bar', SAFE_BAR_DEFAULT)
        self.declare_parameter('lockstep', False)
        self.declare_parameter('water_speed', 0.0)
        self.declare_parameter('publish_delay', 0.01)
        self.declare_parameter('realtime_priority', 0)
        self.realtime_priority = _priority(self.get_parameter('realtime_priority').value)
        self.pilot = self._build(self._values({}))
        self.add_on_set_parameters_callback(self._on_set)
        # reliable, last 100 (10 s at 10 Hz): a lost sample is resent from this history
        self.pub = self.create_publisher(ActuatorSetpoint, '/auv/bar_command', 100)
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.create_subscription(Float64, '/auv/depth_command', self._on_depth, latched)
        self.create_subscription(VehicleState, '/auv/state', self._on_state, 50)
        self.timer: Timer | None = None
        self._reported = ''
        self._configure_timer()

    # -- parameters --------------------------------------------------------------------------
    def _values(self, changes: dict[str, Any]) -> dict[str, Any]:
        names = ('vehicle_file', 'rate', 'weights', 'theta_max_deg', 'bar_max', 'bar_rate',
                 'state_timeout', 'safe_bar', 'lockstep', 'water_speed', 'publish_delay')
        values = {n: self.get_parameter(n).value for n in names}
        values.update(changes)
        return values

    def _build(self, v: dict[str, Any]) -> DepthPilot:
        params = load_vehicle(v['vehicle_file'])
        settings = PilotSettings(
            rate_hz=float(v['rate']), weights=str(v['weights']),
            theta_max=math.radians(float(v['theta_max_deg'])),
            bar_max=float(v['bar_max']) or None, bar_rate=float(v['bar_rate']) or None,
            state_timeout=float(v['state_timeout']), safe_bar=float(v['safe_bar']),
            water_speed=float(v['water_speed']) or None,
            publish_delay=float(v['publish_delay']))
        return DepthPilot.for_vehicle(params, settings)

    def _on_set(self, params: list[Any]) -> SetParametersResult:
        if any(p.name == 'realtime_priority' for p in params):
            return SetParametersResult(successful=False, reason=(
                'realtime_priority is applied at start only; restart the node to change it'))
        try:
            pilot = self._build(self._values({p.name: p.value for p in params}))
        except (AuvLqrError, AuvSimError, ValueError, TypeError) as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        if self.pilot.z_ref is not None:
            pilot.z_ref = self.pilot.z_ref
        self.pilot = pilot
        self.get_logger().info('parameters changed: controller redesigned')
        # the timer period may have changed
        self._pending_timer = True
        return SetParametersResult(successful=True)

    def _configure_timer(self) -> None:
        if self.timer is not None:
            self.destroy_timer(self.timer)
            self.timer = None
        self.lockstep = bool(self.get_parameter('lockstep').value)
        self.control_ns = int(round(NS_PER_S / self.pilot.settings.rate_hz))
        if not self.lockstep:
            self.timer = self.create_timer(self.pilot.settings.Ts, self._on_timer)
        self._pending_timer = False

    # -- callbacks ---------------------------------------------------------------------------
    def _now(self) -> float:
        return self.get_clock().now().nanoseconds / NS_PER_S

    def _on_depth(self, msg: Float64) -> None:
        try:
            z = self.pilot.set_depth_command(msg.data)
            self.get_logger().info(f'depth command {z:g} m accepted')
        except InvalidInputError as exc:
            self.get_logger().warning(f'rejected: {exc}')

    def _on_state(self, msg: VehicleState) -> None:
        try:
            self.pilot.on_state(self._now(), z=msg.z, theta=msg.theta, w=msg.w, q=msg.q,
                                u=msg.u)
        except InvalidInputError as exc:
            self.get_logger().warning(f'rejected: {exc}')
            return
        if self.lockstep:
            stamp_ns = msg.header.stamp.sec * NS_PER_S + msg.header.stamp.nanosec
            if stamp_ns % self.control_ns == 0:
                self._publish(msg.header.stamp, self._now())

    def _on_timer(self, info: TimerInfo) -> None:
        if self._pending_timer:
            self._configure_timer()
        due = info.expected_call_time
        clock = self.get_clock()  # ROS time: on the system clock unless /clock drives it
        wall = not (isinstance(clock, ROSClock) and clock.ros_time_is_active)
        out_ns = due.nanoseconds + int(self.pilot.settings.publish_delay * NS_PER_S)
        self._publish(due.to_msg(), self._now(), out_ns if wall else None)

    def _publish(self, stamp: Any, t: float, out_ns: int | None = None) -> None:
        """Compute the command for ``t`` [s] and publish it stamped ``stamp``; with ``out_ns``
        [ns, system clock], not before that instant."""
        bar, status = self.pilot.command(t)
        if status != self._reported:
            if status == 'ok':
                self.get_logger().info('state received: depth control active')
            else:
                text = {'stale': f'no state for more than {self.pilot.settings.state_timeout}'
                                 f' s: publishing safe BAR {self.pilot.settings.safe_bar:.3f} rad',
                        'no_state': 'no state yet: publishing safe BAR'}.get(status, status)
                self.get_logger().warning(text)
            self._reported = status
        out = ActuatorSetpoint()
        out.header.stamp = stamp
        out.header.frame_id = 'bar'
        out.value = float(bar)
        if out_ns is not None:
            wait = out_ns - time.time_ns()
            if wait > 0:
                time.sleep(wait / NS_PER_S)
        self.pub.publish(out)


def _priority(value: Any) -> int:
    """``realtime_priority`` checked: an integer 0-99 (DesignError otherwise)."""
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 99:
        raise DesignError(f'parameter realtime_priority = {value!r} must be an integer 0-99 '
                          '(0: normal scheduling)')
    return value


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
    parser.add_argument('ros_args', nargs=argparse.REMAINDER,
                        help='ROS arguments, e.g. --ros-args -p rate:=10.0 -p lockstep:=true')


def run(args: argparse.Namespace) -> int:
    """Run the node until SIGINT/SIGTERM; 1 with a one-line error on bad parameters."""
    return main(['depth_pilot', *getattr(args, 'ros_args', [])])


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv if argv is None else argv
    rclpy.init(args=argv)
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
        rclpy.spin(node)
    except (AuvLqrError, AuvSimError, rclpy.exceptions.ParameterException) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        pass
    except rclpy.executors.ExternalShutdownException:
        pass
    finally:
        if node is not None:
            node.destroy_node()
        if rclpy.ok():
            rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
