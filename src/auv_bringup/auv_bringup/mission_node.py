"""``auv mission NAME``: fly a scripted open-loop mission (report section 2) through the graph.

Publishes the mission's commands (``/auv/bar_command``, ``/auv/helm_command`` [rad],
``/auv/thrust_command`` [N], stamped on simulated time) as simulated time passes: each
``/auv/state`` message (NED/FRD, stamped on simulated time) releases the events due at or
before its stamp, so the mission follows the simulator at any real-time factor. ``trim``
values are resolved from the vehicle file at the mission's initial speed and depth (the
simulator should start trimmed there: ``auv launch --mission NAME`` does). Exits 0 once the
mission's duration has passed in simulated time.
"""
from __future__ import annotations

import argparse
import sys
import time

from auv_contract import CHANNELS, config_path
from auv_sim.missions import events_array, load_mission
from auv_sim.params import load_vehicle

NS_PER_S = 1_000_000_000


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('mission', help='surge, pitch, yaw or a mission file')
    parser.add_argument('--vehicle', default=str(config_path('a18m.yaml')),
                        help='vehicle file (default: config/a18m.yaml)')
    parser.add_argument('--timeout', type=float, default=30.0,
                        help='wall seconds to wait for the first state')


def run(args: argparse.Namespace) -> int:
    mission = load_mission(args.mission)
    events = events_array(mission, load_vehicle(args.vehicle))

    import rclpy
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    from auv_msgs.msg import ActuatorSetpoint, VehicleState

    rclpy.init()
    node = rclpy.create_node('auv_mission')
    qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    pubs = {ch: node.create_publisher(ActuatorSetpoint, f'/auv/{ch}_command', qos)
            for ch in CHANNELS}
    state = {'next': 0, 'done': False, 'seen': False}

    def on_state(msg: VehicleState) -> None:
        state['seen'] = True
        stamp_ns = msg.header.stamp.sec * NS_PER_S + msg.header.stamp.nanosec
        while state['next'] < len(events) and \
                round(events[state['next'], 0] * NS_PER_S) <= stamp_ns:
            _t, channel, value = events[state['next']]
            out = ActuatorSetpoint()
            out.header.stamp = msg.header.stamp
            out.header.frame_id = CHANNELS[int(channel)]
            out.value = float(value)
            pubs[CHANNELS[int(channel)]].publish(out)
            state['next'] += 1
        if stamp_ns >= round(mission.duration * NS_PER_S):
            state['done'] = True

    node.create_subscription(VehicleState, '/auv/state', on_state, 100)
    deadline = time.monotonic() + args.timeout
    try:
        while not state['done']:
            rclpy.spin_once(node, timeout_sec=0.05)
            if not state['seen'] and time.monotonic() > deadline:
                print(f'error: no /auv/state within {args.timeout:g} s', file=sys.stderr)
                return 1
    except KeyboardInterrupt:
        # the simulator stopped first (auv launch stops the graph): fine once all is sent
        if state['next'] < len(events):
            print(f'mission {mission.name} interrupted after {state["next"]} of '
                  f'{len(events)} commands', file=sys.stderr)
            return 130
    finally:
        node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    print(f'mission {mission.name}: all {state["next"]} commands published', file=sys.stderr)
    return 0
