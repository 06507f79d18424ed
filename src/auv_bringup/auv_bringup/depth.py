"""Publish one depth command (``auv depth Z``): std_msgs/Float64 on /auv/depth_command.

The depth is in metres, positive down (NED). The command waits, with a deadline, for a
subscriber (the depth pilot) to match, publishes once and waits briefly for the reliable
delivery to be acknowledged, so that a script can rely on it having arrived. The publisher is
reliable and transient-local (latched), and it stays up ``LATCH_TIME`` after the delivery:
DDS matches a new publisher with each subscriber's process on its own, so the pilot may match
it after another subscriber (a recorder) has already acknowledged (on a 2-core machine, 10 s
after the pilot started, its subscriptions matched after the recorder's and the command was
lost to it); a latched subscription that matches while it is up, such as the pilot's, gets
the command from its history. A pilot that starts while it is up gets it too.
``--namespace auv1`` commands the vehicle in ``/auv1`` (topic ``/auv1/depth_command``).
Whether the pilot accepts the depth (its envelope) is in its log and on ``/diagnostics``.
"""
from __future__ import annotations

import argparse
import math
import sys
import time

from auv_bringup.cli import CliError
from auv_bringup.launch import namespace_path

DEPTH_TOPIC = '/auv/depth_command'
DEPTH_TOPIC_NAME = 'depth_command'  # in the vehicle's namespace
ACK_TIMEOUT = 2.0  # s
#: s the latched publisher stays up after the first delivery (see the module docstring): past
#: Fast DDS's participant announcement period (3 s), after which a subscriber's process that
#: missed the first announcements of the new publisher hears of it
LATCH_TIME = 4.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``auv depth``."""
    parser.add_argument('depth', type=float, metavar='Z',
                        help='commanded depth (m, positive down)')
    parser.add_argument('--topic', default=None,
                        help=f'topic of the command (default: {DEPTH_TOPIC}, or '
                             'NS/depth_command with --namespace)')
    parser.add_argument('--namespace', default='/auv', metavar='NS',
                        help="the vehicle's namespace (default: %(default)s)")
    parser.add_argument('--timeout', type=float, default=5.0, metavar='S',
                        help='deadline for a subscriber to appear (s, default 5)')
    parser.add_argument('--min-subscribers', type=int, default=1, metavar='N',
                        help='wait until at least N subscribers match (default 1)')


def run(args: argparse.Namespace) -> int:
    """Publish the command; exit status 0 once delivered."""
    if not math.isfinite(args.depth):
        raise CliError(f'depth must be a finite number of metres, got {args.depth}')
    if not (math.isfinite(args.timeout) and args.timeout > 0):
        raise CliError(f'--timeout must be a positive number of seconds, got {args.timeout}')
    if args.topic is None:
        args.topic = f'{namespace_path(args.namespace)}/{DEPTH_TOPIC_NAME}'

    import rclpy
    from rclpy.duration import Duration
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from std_msgs.msg import Float64

    rclpy.init()
    try:
        node = rclpy.create_node('auv_depth_command')
        qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
        pub = node.create_publisher(Float64, args.topic, qos)
        deadline = time.monotonic() + args.timeout
        wanted = max(1, args.min_subscribers)
        while pub.get_subscription_count() < wanted:
            if time.monotonic() > deadline:
                raise CliError(f'{pub.get_subscription_count()} of {wanted} subscriber(s) on '
                               f'{args.topic} after {args.timeout:g} s '
                               '(is the depth pilot running?)')
            time.sleep(0.02)
        pub.publish(Float64(data=float(args.depth)))
        if not pub.wait_for_all_acked(Duration(seconds=ACK_TIMEOUT)):
            raise CliError(f'depth command on {args.topic} not acknowledged within '
                           f'{ACK_TIMEOUT:g} s')
        time.sleep(LATCH_TIME)  # late-matching latched subscriptions take it from the history
        pub.wait_for_all_acked(Duration(seconds=ACK_TIMEOUT))
        print(f'depth command {args.depth:g} m published on {args.topic}', file=sys.stderr)
        node.destroy_node()
    finally:
        if rclpy.ok():
            rclpy.shutdown()
    return 0
