"""Replay a bag on its topics (``auv play``, ``ros2 run auv_bringup player``).

Messages are published as the serialized CDR bytes stored in the bag (no deserialization), at
their original spacing in log time divided by ``--rate``. With ``--clock`` the time base of the
messages is published on ``/clock`` (rosgraph_msgs/Clock) at ``HZ`` wall hertz, so nodes on
simulated time follow the bag: the stamp of the latest stamped message replayed (a header
stamp, or a recorded ``/clock`` value; simulated time for a bag of the simulated graph), never
going back, from the first stamped message's stamp on; the log time (receive time) only for a
bag without any stamped message, which is said. A ``/clock`` topic stored in the bag is then
not replayed. ``--wait-for-subscribers`` waits for a subscriber on every topic that has
messages to replay (and ``/clock``). The whole bag is read before the first message goes out,
so a damaged bag is an error before anything is published.

No message is lost to a slow subscriber: the publishers are reliable, and every half
``--qos-depth`` messages on a topic the replay waits (at most :data:`ACK_TIMEOUT`) until its
subscribers have acknowledged them, before its keep-last history could overwrite one they
have not received; a subscriber that falls behind (a loaded machine) slows the replay down
instead. At the end the replay waits for every subscriber's acknowledgement of the last
messages. A topic not acknowledged within :data:`ACK_TIMEOUT` is an error naming it (exit 1).
``/clock`` is a latest-value stream and is not waited for.
"""
from __future__ import annotations

import argparse
import math
import signal
import sys
import time
from types import FrameType
from typing import Any

from auv_bringup.cli import CliError, standalone
from auv_bringup.record_node import message_class
from auv_bringup.topics import header_stamp

CLOCK_TOPIC = '/clock'
NS = 1_000_000_000
ACK_TIMEOUT = 30.0  # s, longest wait for the subscribers' acknowledgement of a topic


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``auv play``."""
    parser.add_argument('bag', help='bag directory or .mcap file')
    parser.add_argument('--rate', type=float, default=1.0,
                        help='playback rate factor (2 plays twice as fast; default 1)')
    parser.add_argument('--clock', type=float, nargs='?', const=100.0, default=None,
                        metavar='HZ', help='publish the bag time on /clock at HZ (default 100)')
    parser.add_argument('--topics', nargs='+', metavar='TOPIC', default=None,
                        help='replay only these topics (default: all)')
    parser.add_argument('--loop', action='store_true', help='replay until stopped')
    parser.add_argument('--delay', type=float, default=0.0, metavar='S',
                        help='wait this long before the first message (s)')
    parser.add_argument('--wait-for-subscribers', action='store_true',
                        help='start only when every topic with messages to replay (and /clock '
                             'with --clock) has a subscriber')
    parser.add_argument('--wait-timeout', type=float, default=10.0, metavar='S',
                        help='deadline of --wait-for-subscribers (s)')
    parser.add_argument('--qos-depth', type=int, default=1000, metavar='N',
                        help='keep-last depth of the reliable publishers (messages)')


def _check(args: argparse.Namespace) -> None:
    if not (math.isfinite(args.rate) and args.rate > 0):
        raise CliError(f'--rate must be a positive number, got {args.rate}')
    if args.clock is not None and not (math.isfinite(args.clock) and args.clock > 0):
        raise CliError(f'--clock must be a positive frequency in Hz, got {args.clock}')
    if args.qos_depth < 1:
        raise CliError(f'--qos-depth must be at least 1, got {args.qos_depth}')
    for opt in ('delay', 'wait_timeout'):
        value = getattr(args, opt)
        if not (math.isfinite(value) and value >= 0):
            raise CliError(f'--{opt.replace("_", "-")} must be >= 0 s, got {value}')


def run(args: argparse.Namespace) -> int:
    """Replay the bag once (or until stopped with ``--loop``); returns the exit status."""
    _check(args)
    from auv_bag import bag_topics, read_messages

    present = bag_topics(args.bag)
    topics = list(present) if args.topics is None else list(dict.fromkeys(args.topics))
    if args.clock is not None and CLOCK_TOPIC in topics:
        topics.remove(CLOCK_TOPIC)
    stamped = stamped_topics(args.bag, present)
    messages = [(m.log_time, m.topic, m.data)
                for m in read_messages(args.bag, topics, decode=False)]
    messages.sort(key=lambda m: m[0])  # stable: equal times keep the recording order
    classes = {topic: message_class(present[topic]) for topic in topics}
    base = None
    if args.clock is not None:
        # the bag's own /clock counts for the time base even though it is not replayed
        base = time_base(sorted(((m.log_time, m.topic, m.data) for m in read_messages(
            args.bag, [t for t in present if t in stamped], decode=False)),
            key=lambda m: m[0]), stamped, [m[0] for m in messages])
        if base is None:
            print('play: no stamped message in the bag: /clock follows the log (receive) '
                  'time', file=sys.stderr)

    import rclpy
    from rclpy.duration import Duration
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rclpy.signals import SignalHandlerOptions

    stop = {'signal': 0}

    def on_signal(signum: int, _frame: FrameType | None) -> None:
        stop['signal'] = signum

    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    try:
        node = rclpy.create_node('auv_player')
        qos = QoSProfile(depth=args.qos_depth, reliability=ReliabilityPolicy.RELIABLE)
        pubs = {t: node.create_publisher(cls, t, qos) for t, cls in classes.items()}
        clock_pub = None
        if args.clock is not None:
            from rosgraph_msgs.msg import Clock

            clock_pub = node.create_publisher(Clock, CLOCK_TOPIC, qos)
        if args.wait_for_subscribers:
            with_messages = {m[1] for m in messages}
            waited = {t: p for t, p in pubs.items() if t in with_messages}
            if clock_pub is not None:
                waited[CLOCK_TOPIC] = clock_pub
            _wait_for_subscribers(waited, args.wait_timeout, stop)
        if args.delay:
            _sleep_until(time.monotonic() + args.delay, stop)
        while not stop['signal']:
            _play_once(messages, pubs, clock_pub, args, stop, base)
            if not args.loop:
                break
        if clock_pub is not None:
            clock_pub.wait_for_all_acked(Duration(seconds=1.0))
        late = [t for t, pub in pubs.items() if not acknowledged(pub)]
        node.destroy_node()
        if late:
            raise CliError(f'not acknowledged by every subscriber within {ACK_TIMEOUT:g} s: '
                           f'{", ".join(late)} (messages may be lost)')
    finally:
        if rclpy.ok():
            rclpy.shutdown()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    return 130 if stop['signal'] == signal.SIGINT else 0


def acknowledged(pub: Any, timeout: float = ACK_TIMEOUT) -> bool:
    """Whether every subscriber of the reliable publisher ``pub`` acknowledged all its
    messages within ``timeout`` [s]."""
    from rclpy.duration import Duration

    return bool(pub.wait_for_all_acked(Duration(seconds=timeout)))


MATCH_SETTLE = 0.3  # s after the writers see their readers, for the readers to see the writers


def _wait_for_subscribers(pubs: dict[str, Any], timeout: float, stop: dict[str, int]) -> None:
    """Wait until every publisher has a subscriber, then :data:`MATCH_SETTLE` more: DDS
    discovery is not symmetric, and a sample sent before the reader has matched the writer
    arrives late, by retransmission, and distorts the replayed timing."""
    deadline = time.monotonic() + timeout
    while not stop['signal']:
        missing = [t for t, p in pubs.items() if p.get_subscription_count() == 0]
        if not missing:
            _sleep_until(time.monotonic() + MATCH_SETTLE, stop)
            return
        if time.monotonic() > deadline:
            raise CliError(f'no subscriber on {", ".join(missing)} after {timeout:g} s')
        time.sleep(0.02)


def _sleep_until(t_wall: float, stop: dict[str, int]) -> None:
    while not stop['signal']:
        left = t_wall - time.monotonic()
        if left <= 0:
            return
        time.sleep(min(left, 0.05))


def _clock_message(t_ns: int) -> Any:
    from builtin_interfaces.msg import Time
    from rosgraph_msgs.msg import Clock

    sec, nsec = divmod(int(t_ns), 1_000_000_000)
    return Clock(clock=Time(sec=sec, nanosec=nsec))


def stamped_topics(bag: str, present: dict[str, str]) -> set[str]:
    """Topics of ``bag`` whose messages open with a stamp: a ``std_msgs/Header`` or, as
    ``rosgraph_msgs/Clock``, a ``builtin_interfaces/Time`` (types the project's typestore
    knows; others count as unstamped)."""
    from auv_bag import typestore

    fielddefs = typestore().fielddefs
    out = set()
    for topic, msgtype in present.items():
        fields = fielddefs.get(msgtype, ((), []))[1]
        if fields and fields[0][1][1] in ('std_msgs/msg/Header', 'builtin_interfaces/msg/Time'):
            out.add(topic)
    return out


def time_base(stamped_messages: list[tuple[int, str, bytes]], stamped: set[str],
              log_times: list[int]) -> list[int] | None:
    """The clock value [ns] in force when each replayed message (log times ``log_times``,
    sorted) goes out: the largest stamp among the stamped messages logged up to it, and the
    first stamp before any; None when there is no stamped message."""
    stamps = [(log_ns, header_stamp(data)) for log_ns, topic, data in stamped_messages
              if topic in stamped]
    stamps_ns = [(log_ns, st[0] * NS + st[1]) for log_ns, st in stamps if st is not None]
    if not stamps_ns:
        return None
    out = []
    latest = stamps_ns[0][1]
    j = 0
    for log_ns in log_times:
        while j < len(stamps_ns) and stamps_ns[j][0] <= log_ns:
            latest = max(latest, stamps_ns[j][1])
            j += 1
        out.append(latest)
    return out


def _play_once(messages: list[tuple[int, str, bytes]], pubs: dict[str, Any], clock_pub: Any,
               args: argparse.Namespace, stop: dict[str, int],
               base: list[int] | None = None) -> None:
    """Publish every message at its log time, scaled by the rate; /clock in between, on the
    messages' time base ``base`` (one value per message; None: the log time)."""
    if not messages:
        return
    t0 = messages[0][0]
    start = time.monotonic()
    clock_period = 1.0 / args.clock if clock_pub is not None else math.inf
    next_clock = start

    def clock_now(now: float, i: int) -> int:
        """Clock value before message ``i`` goes out, ``now`` wall s."""
        if base is not None:
            return base[max(0, i - 1)]
        return min(t0 + int((now - start) * args.rate * 1e9), messages[i][0])

    every = max(1, args.qos_depth // 2)
    sent = dict.fromkeys(pubs, 0)
    for i, (log_ns, topic, data) in enumerate(messages):
        target = start + (log_ns - t0) * 1e-9 / args.rate
        while not stop['signal']:
            now = time.monotonic()
            if clock_pub is not None and now >= next_clock:
                clock_pub.publish(_clock_message(clock_now(now, i)))
                next_clock = max(next_clock + clock_period, now)
                continue
            if now >= target:
                break
            time.sleep(max(0.0, min(target, next_clock) - now))
        if stop['signal']:
            return
        pubs[topic].publish(data)
        sent[topic] += 1
        if sent[topic] % every == 0 and not acknowledged(pubs[topic]):
            raise CliError(f'{topic}: the subscribers did not acknowledge the last {every} '
                           f'messages within {ACK_TIMEOUT:g} s; replay stopped before any '
                           'is lost')
    if clock_pub is not None:
        clock_pub.publish(_clock_message(base[-1] if base is not None else messages[-1][0]))


def main() -> None:
    """``ros2 run auv_bringup player``."""
    sys.exit(standalone('auv_bringup.play_node', 'player'))


if __name__ == '__main__':
    main()
