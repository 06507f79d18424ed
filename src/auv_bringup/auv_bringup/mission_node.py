"""``auv mission NAME``: fly a scripted open-loop mission (report section 2) through the graph.

The mission's commands go out on ``bar_command``, ``helm_command`` [rad] and
``thrust_command`` [N] (``auv_msgs/ActuatorSetpoint``, relative to the node's namespace,
``/auv`` unless remapped with ``--ros-args -r __ns:=/NS``) on simulated time: every ``state``
(NED/FRD) stamped at a control instant ``k * control_period`` (within 1 us,
:func:`auv_contract.lockstep.control_instant`) is answered on the three channels, stamped with
the state's stamp, with the value each holds at that instant: the mission's events due at or
before it applied, ``trim`` resolved from the vehicle file at the mission's initial speed and
depth (the simulator starts trimmed there: ``auv launch --mission NAME`` does). This is the
lockstep protocol of ``docs/lockstep.md`` on the three channels: a simulator with
``lockstep_channels:=bar,helm,thrust`` waits for the answers, so the mission's events act at
their simulated instants at any real-time factor and whatever the load (the graph's bag then
equals ``auv run --mission NAME`` bit for bit). An event between two control instants acts
at the next one (said once at start). Exits 0 once the mission's duration has passed in
simulated time.
"""
from __future__ import annotations

import argparse
import math
import signal
import sys
import time
from types import FrameType
from typing import Any

from auv_bringup.cli import CliError
from auv_contract import CHANNELS, config_path
from auv_contract.lockstep import NS_PER_S, control_instant
from auv_sim.missions import events_array, load_mission
from auv_sim.node_report import write_report
from auv_sim.params import load_vehicle
from auv_sim.trim import cached_trim

NAMESPACE = '/auv'
ACK_TIMEOUT = 2.0  # wall s, longest wait at exit for the subscribers' acknowledgements


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('mission', help='surge, pitch, yaw or a mission file')
    parser.add_argument('--vehicle', default=str(config_path('a18m.yaml')),
                        help='vehicle file (default: config/a18m.yaml)')
    parser.add_argument('--timeout', type=float, default=30.0,
                        help='wall seconds to wait for the first state')
    parser.add_argument('--control-period', type=float, default=0.1, metavar='S',
                        help='simulated seconds between two answers (default: %(default)s)')
    parser.add_argument('--await-subscribers', type=int, default=0, metavar='N',
                        help='before the first answer, wait (--timeout) until every command '
                             'topic has N matched subscribers (simulator, recorder)')
    parser.add_argument('--report-file', default='', metavar='FILE',
                        help='JSON written at exit: messages published per topic')
    parser.add_argument('--ros-args', dest='ros_args', nargs=argparse.REMAINDER, default=None,
                        help='ROS arguments (-r __ns:=/auv1 ...)')


def _check(args: argparse.Namespace) -> None:
    if not (math.isfinite(args.timeout) and args.timeout > 0):
        raise CliError(f'--timeout must be a positive number of seconds, got {args.timeout}')
    if not (math.isfinite(args.control_period) and args.control_period > 0):
        raise CliError(f'--control-period must be a positive number of seconds, got '
                       f'{args.control_period}')
    if args.await_subscribers < 0:
        raise CliError(f'--await-subscribers must be >= 0, got {args.await_subscribers}')


def initial_commands(mission: Any, params: Any) -> list[float]:
    """The commands (bar [rad], helm [rad], thrust [N]) the simulator holds at a trimmed start
    at the mission's initial speed and depth: what a channel answers before its first event."""
    x0 = cached_trim(params, mission.u0, z=mission.z0).state()
    return [float(v) for v in x0[12:15]]


def run(args: argparse.Namespace) -> int:
    _check(args)
    mission = load_mission(args.mission)
    params = load_vehicle(args.vehicle)
    events = events_array(mission, params)
    held = initial_commands(mission, params)
    period_ns = round(args.control_period * NS_PER_S)
    off_grid = [float(t) for t in events[:, 0]
                if control_instant(round(float(t) * NS_PER_S), period_ns) is None]

    import rclpy
    from rclpy.duration import Duration
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rclpy.signals import SignalHandlerOptions

    from auv_msgs.msg import ActuatorSetpoint, VehicleState

    stop: list[int] = []

    def on_signal(signum: int, _frame: FrameType | None) -> None:
        stop.append(signum)

    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    rclpy.init(args=['auv-mission', *(['--ros-args', *args.ros_args] if args.ros_args else [])],
               signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('auv_mission', namespace=NAMESPACE)
    if off_grid:
        node.get_logger().warning(
            f'events at {", ".join(f"{t:g}" for t in off_grid[:5])} s are not on the '
            f'{args.control_period:g} s control grid: each acts at the next control instant')
    qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
    pubs = {ch: node.create_publisher(ActuatorSetpoint, f'{ch}_command', qos)
            for ch in CHANNELS}
    published = dict.fromkeys((p.topic_name for p in pubs.values()), 0)
    state = {'next': 0, 'done': False, 'seen': False, 'awaited': args.await_subscribers == 0}

    def await_subscribers() -> None:
        state['awaited'] = True
        deadline = time.monotonic() + args.timeout
        while any(p.get_subscription_count() < args.await_subscribers for p in pubs.values()):
            if time.monotonic() > deadline:
                node.get_logger().warning(f'fewer than {args.await_subscribers} subscribers '
                                          f'after {args.timeout:g} s; publishing anyway')
                return
            time.sleep(0.005)

    def on_state(msg: VehicleState) -> None:
        state['seen'] = True
        stamp_ns = msg.header.stamp.sec * NS_PER_S + msg.header.stamp.nanosec
        instant = control_instant(stamp_ns, period_ns)
        if instant is None:
            return
        while state['next'] < len(events) and \
                round(events[state['next'], 0] * NS_PER_S) <= instant:
            _t, channel, value = events[state['next']]
            held[int(channel)] = float(value)
            state['next'] += 1
        if not state['awaited']:
            await_subscribers()
        for i, channel in enumerate(CHANNELS):
            out = ActuatorSetpoint()
            out.header.stamp = msg.header.stamp
            out.header.frame_id = channel
            out.value = held[i]
            pubs[channel].publish(out)
            published[pubs[channel].topic_name] += 1
        if instant >= round(mission.duration * NS_PER_S):
            state['done'] = True

    node.create_subscription(VehicleState, 'state', on_state, qos)
    deadline = time.monotonic() + args.timeout
    try:
        while not state['done'] and not stop:
            rclpy.spin_once(node, timeout_sec=0.05)
            if not state['seen'] and time.monotonic() > deadline:
                print(f'error: no {node.resolve_topic_name("state")} within {args.timeout:g} s',
                      file=sys.stderr)
                return 1
        for pub in pubs.values():
            pub.wait_for_all_acked(Duration(seconds=ACK_TIMEOUT))
    finally:
        write_report(args.report_file, {'node': node.get_fully_qualified_name(),
                                        'published': published})
        node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if not state['done']:
        # stopped by a signal (auv launch stops the graph after the simulator's last state)
        print(f'mission {mission.name} stopped after {state["next"]} of {len(events)} events',
              file=sys.stderr)
        return 130 if state['next'] < len(events) else 0
    print(f'mission {mission.name}: all {state["next"]} events flown', file=sys.stderr)
    return 0
