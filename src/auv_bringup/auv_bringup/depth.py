"""Command a depth (``auv depth Z``): std_msgs/Float64 on /auv/depth_command, and the answer.

The depth is in metres, positive down (NED). The command waits, with a deadline
(``--timeout``), until the depth pilot and every other subscriber the graph lists on the topic
(a recorder, a viewer) have matched its publisher (reliable, transient local), publishes once,
waits until every subscriber has acknowledged the sample, then waits for the pilot's answer on
``depth_command_answer`` (diagnostic_msgs/DiagnosticStatus, transient local, see
:mod:`auv_depth_lqr.node`), matched to this command by its publisher GID and sequence number:

* accepted: ``depth command Z m accepted by /auv/depth_pilot`` on stderr, exit 0;
* clamped to the envelope (pilot in ``clamp`` mode): said on stderr, exit 0;
* refused (outside the envelope, not finite): ``error: /auv/depth_pilot refused depth
  command Z m: <reason>``, exit 1;
* no answer within ``--timeout``: ``error: ...``, exit 1.

``--min-subscribers N`` waits for N subscriber nodes (e.g. 2: the pilot and a recorder), so a
script knows who got it; ``--no-answer`` publishes to a subscriber that is not the pilot (it
then exits once the sample is acknowledged). ``--namespace auv1`` commands the vehicle in
``/auv1`` (topic ``/auv1/depth_command``). Python scripts do the same with a few lines of
rclpy: ``examples/depth_command.py``.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from typing import Any

from auv_bringup.cli import CliError
from auv_bringup.launch import namespace_path
from auv_bringup.options import check_number
from auv_bringup.topics import DEPTH_ANSWER

DEPTH_TOPIC = '/auv/depth_command'
DEPTH_TOPIC_NAME = 'depth_command'  # in the vehicle's namespace
ACK_TIMEOUT = 5.0  # s for every matched subscriber to acknowledge the sample
POLL = 0.02  # s between two looks at the graph


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``auv depth``."""
    parser.add_argument('depth', type=float, metavar='Z',
                        help='commanded depth (m, positive down)')
    parser.add_argument('--topic', default=None,
                        help=f'topic of the command (default: {DEPTH_TOPIC}, or '
                             'NS/depth_command with --namespace)')
    parser.add_argument('--namespace', default='/auv', metavar='NS',
                        help="the vehicle's namespace (default: %(default)s)")
    parser.add_argument('--timeout', type=float, default=10.0, metavar='S',
                        help='deadline for the subscribers to match, and again for the '
                             "pilot's answer (s, default 10)")
    parser.add_argument('--min-subscribers', type=int, default=1, metavar='N',
                        help='wait until at least N subscriber nodes (the pilot, a recorder, '
                             '...) have matched (default 1)')
    parser.add_argument('--no-answer', action='store_true',
                        help="do not wait for a depth pilot's answer (for a subscriber that "
                             'is not the pilot)')


def _subscriber_nodes(node: Any, topic: str) -> tuple[set[str], int]:
    """Nodes subscribing ``topic`` and their subscriptions' count (a reliable, transient-local
    publisher matches every subscription, whatever its reliability and durability)."""
    infos = node.get_subscriptions_info_by_topic(topic)
    return ({f'{i.node_namespace.rstrip("/")}/{i.node_name}' for i in infos}, len(infos))


def run(args: argparse.Namespace) -> int:
    """Publish the command and wait for its answer; exit status 0 once accepted."""
    check_number('depth', args.depth, unit='m')
    check_number('--timeout', args.timeout, above=0.0, unit='s')
    check_number('--min-subscribers', args.min_subscribers, minimum=1)
    ns = namespace_path(args.namespace)
    if args.topic is None:
        args.topic = f'{ns}/{DEPTH_TOPIC_NAME}'
    answer_topic = f'{ns}/{DEPTH_ANSWER}'

    import rclpy
    from diagnostic_msgs.msg import DiagnosticStatus
    from rclpy.duration import Duration
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from std_msgs.msg import Float64

    rclpy.init()
    try:
        node = rclpy.create_node(f'auv_depth_{os.getpid()}')
        qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
        pub = node.create_publisher(Float64, args.topic, qos)
        answers: list[Any] = []
        if not args.no_answer:
            node.create_subscription(
                DiagnosticStatus, answer_topic, answers.append,
                QoSProfile(depth=20, reliability=ReliabilityPolicy.RELIABLE,
                           durability=DurabilityPolicy.TRANSIENT_LOCAL))
        deadline = time.monotonic() + args.timeout

        def ready() -> tuple[bool, str]:
            nodes, readers = _subscriber_nodes(node, args.topic)
            pilots = {f'{i.node_namespace.rstrip("/")}/{i.node_name}'
                      for i in node.get_publishers_info_by_topic(answer_topic)}
            if len(nodes) < args.min_subscribers:
                return False, f'{len(nodes)} of {args.min_subscribers} subscriber node(s)'
            if not args.no_answer and not pilots & nodes:
                return False, f'no depth pilot answering on {answer_topic}'
            if pub.get_subscription_count() < readers:
                return False, (f'{pub.get_subscription_count()} of {readers} subscriptions '
                               'matched')
            return True, ''
        ok, why = ready()
        while not ok:
            if time.monotonic() > deadline:
                raise CliError(f'{args.topic}: {why} after {args.timeout:g} s (is the depth '
                               'pilot running, in this namespace and ROS domain?)')
            rclpy.spin_once(node, timeout_sec=POLL)
            ok, why = ready()
        pub.publish(Float64(data=float(args.depth)))
        if not pub.wait_for_all_acked(Duration(seconds=ACK_TIMEOUT)):
            raise CliError(f'depth command on {args.topic} not acknowledged within '
                           f'{ACK_TIMEOUT:g} s')
        if args.no_answer:
            print(f'depth command {args.depth:g} m delivered to '
                  f'{pub.get_subscription_count()} subscription(s) on {args.topic}',
                  file=sys.stderr)
            return 0
        gid = next((bytes(i.endpoint_gid).hex() for i in
                    node.get_publishers_info_by_topic(args.topic)
                    if i.node_name == node.get_name()), '')
        answer = _await_answer(node, answers, gid, args.depth,
                               time.monotonic() + args.timeout)
        if answer is None:
            raise CliError(f'no answer from a depth pilot on {answer_topic} within '
                           f'{args.timeout:g} s (the command was delivered to '
                           f'{pub.get_subscription_count()} subscription(s))')
        result = {kv.key: kv.value for kv in answer.values}.get('result')
        pilot = answer.name.split(': ', 1)[0]
        if result == 'refused':
            raise CliError(f'{pilot}: {answer.message}')
        print(f'depth command {args.depth:g} m accepted by {pilot}' if result == 'accepted'
              else f'{pilot}: {answer.message}', file=sys.stderr)
        node.destroy_node()
    finally:
        if rclpy.ok():
            rclpy.shutdown()
    return 0


def _await_answer(node: Any, answers: list[Any], gid: str, depth: float,
                  deadline: float) -> Any:
    """The pilot's answer to this command (its publisher GID and first sequence number; by
    value when the GID is unknown), or None at the deadline."""
    import rclpy

    def mine(status: Any) -> bool:
        values = {kv.key: kv.value for kv in status.values}
        if gid and values.get('publisher'):
            return values.get('publisher') == gid and values.get('sequence') == '1'
        return values.get('value_m') == f'{depth:g}'

    while time.monotonic() < deadline:
        for status in answers:
            if mine(status):
                return status
        rclpy.spin_once(node, timeout_sec=POLL)
    return next((s for s in answers if mine(s)), None)
