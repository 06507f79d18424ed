"""Record topics to an MCAP bag (``auv record``, ``ros2 run auv_bringup recorder``).

Subscriptions are raw: the CDR bytes are written as received, never deserialized. Topics of
the project have known types and are subscribed at once, ``state`` last; other topics are
subscribed when their type shows up in the graph. A reliable, volatile DDS reader gets only
what is published after it has matched the writer itself: with ``--await-publishers TOPIC``
the recorder subscribes to ``state`` only once those topics have a matched publisher, so a
simulator that waits for its ``state`` subscribers (``auv launch``) starts when the recorder
will get the first messages of those topics as well.
SIGINT and SIGTERM stop the recording cleanly: spinning stops, the messages already received
by DDS are drained, and the bag is closed with its summary and ``metadata.yaml``.

Namespace: the recorder node runs in ``/auv`` (``-r __ns:=/auv1`` moves it with a vehicle's
graph); relative topic names resolve in it, absolute ones are taken as they are.

Progress: every ``PROGRESS_EVERY`` ``state`` messages written, and ``PROGRESS_PERIOD``
wall seconds after the last report when states were written since, the recorder publishes on
``recorder/progress`` (``builtin_interfaces/Time``) the stamp up to which it has written the
stamped streams of the graph (:data:`PACED_TOPICS`: the simulator's ``state``, ``odom``,
``hydrodynamic_forces`` and ``/clock``, the pilot's ``bar_command``): the oldest of their last
written stamps. It reports nothing while a stream with a matched publisher has delivered
nothing yet (its first message may be on its way again: DDS can lose the first sample to a
reader that has just matched and repairs it at the writer's next heartbeat); streams without a
publisher do not count. A simulator running as fast as possible paces itself on it (see
:mod:`auv_sim.node`), and at its ``stop_time`` waits for it, so a recorder short of CPU slows
the run instead of losing samples of any of them.
"""
from __future__ import annotations

import argparse
import functools
import gc
import importlib
import math
import signal
import sys
import time
from collections.abc import Callable, Sequence
from types import FrameType
from typing import Any

from auv_bringup.cli import CliError, standalone
from auv_bringup.topics import (
    DEFAULT_TOPICS,
    KNOWN_TOPICS,
    NAMESPACE,
    PACED_TOPICS,
    header_stamp,
    known_types,
    topic_basename,
)

__all__ = ['DEFAULT_TOPICS', 'KNOWN_TOPICS', 'NAMESPACE', 'PACED_TOPICS', 'Recorder',
           'header_stamp', 'known_types', 'message_class']

DRAIN_QUIET = 0.3  # s without a new message that ends the drain after a stop
DRAIN_MAX = 3.0  # s, longest drain after a stop
GRAPH_POLL = 0.5  # s between looks at the graph for topics of unknown type
DRAIN_BATCH = 100  # most messages taken per callback beyond the one the executor took
PROGRESS_EVERY = 50  # /auv/state messages written between two progress reports
PROGRESS_PERIOD = 0.05  # wall s after which states written since the last report are reported


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``auv record``."""
    parser.add_argument('--out', metavar='DIR', default=None,
                        help='bag directory to create (default: out/bags/rosbag2_<date-time>)')
    parser.add_argument('--topics', nargs='+', metavar='TOPIC', default=DEFAULT_TOPICS,
                        help='topics to record, relative ones in the namespace (/auv unless '
                             '--ros-args -r __ns:=/NS) (default: %(default)s)')
    parser.add_argument('--duration', type=float, metavar='S', default=None,
                        help='stop after this many seconds (wall clock; default: until '
                             'SIGINT/SIGTERM)')
    parser.add_argument('--qos-depth', type=int, metavar='N', default=1000,
                        help='keep-last depth of the reliable subscriptions (messages)')
    parser.add_argument('--compression', choices=['zstd', 'lz4', 'none'], default='zstd',
                        help='chunk compression (default: zstd, as rosbag2)')
    parser.add_argument('--flush-interval', type=float, metavar='S', default=1.0,
                        help='longest time a received message waits in memory (s)')
    parser.add_argument('--await-publishers', nargs='+', metavar='TOPIC', default=[],
                        help='subscribe to state only once these recorded topics have a '
                             'matched publisher (at most --await-timeout): a simulator that '
                             'waits for the recorder on state then starts only when the '
                             'recorder will get the first messages of these topics too')
    parser.add_argument('--await-timeout', type=float, metavar='S', default=30.0,
                        help='longest wait for --await-publishers (s, wall clock)')


def message_class(msgtype: str) -> Any:
    """The rclpy message class of ``pkg/msg/Type``.

    Raises
    ------
    CliError
        the package's Python messages are not importable.
    """
    parts = msgtype.split('/')
    if len(parts) == 2:
        parts = [parts[0], 'msg', parts[1]]
    try:
        return getattr(importlib.import_module(f'{parts[0]}.{parts[1]}'), parts[2])
    except (ImportError, AttributeError, IndexError):
        raise CliError(f'message type {msgtype} is not available to Python (is the '
                       'workspace built and sourced?)') from None


def _default_out() -> str:
    return time.strftime('out/bags/rosbag2_%Y_%m_%d-%H_%M_%S')


class Recorder:
    """Raw subscriptions feeding a :class:`auv_bag.BagWriter`."""

    def __init__(self, node: Any, writer: Any, topics: list[str], qos_depth: int,
                 await_publishers: Sequence[str] = (), await_timeout: float = 30.0,
                 stopped: Callable[[], bool] = lambda: False) -> None:
        from builtin_interfaces.msg import Time
        from rclpy.qos import QoSProfile, ReliabilityPolicy

        from auv_sim.node import PROGRESS_QOS, PROGRESS_TOPIC

        self.node = node
        self._stopped = stopped
        self.lost: dict[str, int] = {}  # topic -> samples DDS reported lost to a subscription
        self._time = Time
        self._progress = node.create_publisher(Time, PROGRESS_TOPIC, PROGRESS_QOS)
        self._state_topic = node.resolve_topic_name('state')
        known = known_types(node)
        self._unreported = 0  # /auv/state messages written since the last progress report
        self._paced = {node.resolve_topic_name(t) for t in PACED_TOPICS}
        self._last_paced: dict[str, bytes] = {}  # paced topic -> its last message written
        self._dirty = False  # a paced message written since the last progress report
        self._reported_at = 0.0  # time.monotonic() of the last report
        self.writer = writer
        self.count = 0
        self.late = 0  # messages received after the stop, not written
        self.stop_ns: int | None = None  # receive time (ns, system clock) of the stop
        self.last_message = time.monotonic()
        self.pending: list[str] = []
        self._last_ns: dict[str, int] = {}
        self._reliable = QoSProfile(depth=qos_depth, reliability=ReliabilityPolicy.RELIABLE)
        self._best_effort = QoSProfile(depth=qos_depth,
                                       reliability=ReliabilityPolicy.BEST_EFFORT)
        self.subscriptions: dict[str, tuple[Any, bool]] = {}  # topic -> (sub, reliable)
        names = [node.resolve_topic_name(topic) for topic in topics]
        # state last: a simulator that waits for its subscribers starts once it is matched
        for name in sorted(names, key=lambda n: n == self._state_topic):
            if name == self._state_topic:
                self._await_publishers(await_publishers, await_timeout)
            msgtype = known.get(name)
            if msgtype is None:
                self.pending.append(name)
            else:
                self._subscribe(name, msgtype, reliable=True)

    def _await_publishers(self, topics: Sequence[str], timeout: float) -> None:
        """Wait (at most ``timeout`` wall seconds) until the subscriptions of ``topics`` have
        a matched publisher: a reliable, volatile reader gets only what is published after it
        has matched the writer itself, whatever the writer knows."""
        subs = [self.subscriptions[n][0] for n in map(self.node.resolve_topic_name, topics)
                if n in self.subscriptions]
        deadline = time.monotonic() + timeout
        while any(sub.get_publisher_count() < 1 for sub in subs) and not self._stopped():
            if time.monotonic() >= deadline:
                missing = [sub.topic_name for sub in subs if sub.get_publisher_count() < 1]
                self.node.get_logger().warning(
                    f'no publisher on {", ".join(missing)} after {timeout:g} s; recording '
                    'anyway')
                return
            time.sleep(0.005)

    def _subscribe(self, topic: str, msgtype: str, reliable: bool) -> None:
        from rclpy.event_handler import SubscriptionEventCallbacks

        from auv_bag import qos_profiles_yaml

        cls = message_class(msgtype)
        old = self.subscriptions.pop(topic, None)
        if old is not None:
            self.node.destroy_subscription(old[0])
        self.writer.add_topic(topic, msgtype, qos_profiles_yaml(
            'reliable' if reliable else 'best_effort', 'volatile', self._reliable.depth))
        sub = self.node.create_subscription(
            cls, topic, functools.partial(self._on_message, topic),
            self._reliable if reliable else self._best_effort, raw=True,
            event_callbacks=SubscriptionEventCallbacks(
                message_lost=functools.partial(self._on_lost, topic)))
        self.subscriptions[topic] = (sub, reliable)

    def _on_message(self, topic: str, data: bytes, info: dict[str, int]) -> None:
        """Write the message, then the others already queued on its subscription (see
        :meth:`_write`). The executor takes one message per wait of its wait set, which in
        rclpy costs far more than the take itself; taking the rest of a burst here, with the
        same call the executor makes, keeps a recorder up with a lockstep run many times
        faster than real time."""
        self._write(topic, data, info)
        sub = self.subscriptions[topic][0]
        for _ in range(DRAIN_BATCH):
            with sub.handle:
                taken = sub.handle.take_message(sub.msg_type, sub.raw)
            if taken is None:
                return
            self._write(topic, taken[0], taken[1])

    def _on_lost(self, topic: str, info: Any) -> None:
        """DDS says samples of ``topic`` were lost to this subscription: said, never silent."""
        self.lost[topic] = int(info.total_count)
        self.node.get_logger().error(f'{topic}: {info.total_count_change} message(s) lost on '
                                     f'the way to the recorder ({info.total_count} in all)')

    def report_progress(self) -> None:
        """Report the paced messages written since the last report if that is
        ``PROGRESS_PERIOD`` ago (called from the spin loop)."""
        if self._dirty and time.monotonic() - self._reported_at >= PROGRESS_PERIOD:
            self._report()

    def _report(self) -> None:
        """Publish the oldest of the paced topics' last written stamps (see the module
        docstring); nothing, and again next period, while a paced stream with a publisher has
        delivered nothing."""
        self._unreported = 0
        self._reported_at = time.monotonic()
        if any(topic not in self._last_paced and sub.get_publisher_count() > 0
               for topic, (sub, _) in self.subscriptions.items() if topic in self._paced):
            return
        self._dirty = False
        stamps = [st for st in map(header_stamp, self._last_paced.values()) if st is not None]
        if stamps:
            sec, nanosec = min(stamps)
            self._progress.publish(self._time(sec=sec, nanosec=nanosec))

    def _write(self, topic: str, data: bytes, info: dict[str, int]) -> None:
        """Write one message; its log time is its DDS receive time (ns, system clock), held
        non-decreasing per topic: a reliable reader delivers in publication order, but samples
        repaired by retransmission carry a later receive time than the ones queued behind them,
        and the bag's log-time order must be its delivery order. Its publish time is the DDS
        source timestamp (ns, the publisher's system clock at ``publish``), as rosbag2 records
        it: the publisher's own timing, without the delivery delay."""
        received = info.get('received_timestamp') or time.time_ns()
        if self.stop_ns is not None and received > self.stop_ns:
            self.late += 1
            return
        received = max(received, self._last_ns.get(topic, 0))
        self._last_ns[topic] = received
        self.writer.write(topic, data, received, info.get('source_timestamp') or received)
        self.count += 1
        if topic in self._paced:
            self._last_paced[topic] = data
            self._dirty = True
        if topic == self._state_topic:
            self._unreported += 1
            if self._unreported >= PROGRESS_EVERY:
                self._report()
        self.last_message = time.monotonic()

    def poll_graph(self) -> None:
        """Subscribe topics whose type appeared; follow best-effort publishers."""
        from rclpy.qos import ReliabilityPolicy

        if self.pending:
            types = dict(self.node.get_topic_names_and_types())
            for topic in list(self.pending):
                if types.get(topic):
                    self._subscribe(topic, types[topic][0], reliable=True)
                    self.pending.remove(topic)
        for topic, (_, reliable) in list(self.subscriptions.items()):
            if not reliable:
                continue
            infos = self.node.get_publishers_info_by_topic(topic)
            if any(i.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT for i in infos):
                # A reliable subscription would not match a best-effort publisher.
                self.node.get_logger().warning(f'{topic}: best-effort publisher, '
                                               'recording best effort')
                self._subscribe(topic, self.writer.topics[topic], reliable=False)


def run(args: argparse.Namespace) -> int:
    """Record until SIGINT/SIGTERM or ``--duration``; returns the exit status."""
    if args.duration is not None and not (math.isfinite(args.duration) and args.duration > 0):
        raise CliError(f'--duration must be a positive number of seconds, got {args.duration}')
    if args.qos_depth < 1:
        raise CliError(f'--qos-depth must be at least 1, got {args.qos_depth}')
    if not (math.isfinite(args.await_timeout) and args.await_timeout > 0):
        raise CliError(f'--await-timeout must be > 0 s, got {args.await_timeout}')
    recorded = {topic_basename(t) for t in args.topics}
    unrecorded = sorted(t for t in args.await_publishers if topic_basename(t) not in recorded)
    if unrecorded:
        raise CliError(f'--await-publishers {" ".join(unrecorded)}: not among the recorded '
                       '--topics')
    if not (math.isfinite(args.flush_interval) and args.flush_interval >= 0):
        raise CliError(f'--flush-interval must be >= 0 s, got {args.flush_interval}')
    out = args.out or _default_out()

    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    from auv_bag import BagWriter

    stop = {'signal': 0}

    def on_signal(signum: int, _frame: FrameType | None) -> None:
        stop['signal'] = signum

    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    writer = None
    try:
        node = rclpy.create_node('auv_recorder', namespace=NAMESPACE)
        writer = BagWriter(out, compression=args.compression,
                           flush_interval=args.flush_interval)
        recorder = Recorder(node, writer, list(dict.fromkeys(args.topics)), args.qos_depth,
                            args.await_publishers, args.await_timeout,
                            stopped=lambda: bool(stop['signal']))
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        print(f'recording {len(args.topics)} topics to {out}', file=sys.stderr, flush=True)
        gc.collect()
        gc.freeze()  # long-lived set-up objects out of the cyclic collector's full passes
        t_end = None if args.duration is None else time.monotonic() + args.duration
        next_poll = time.monotonic()
        while not stop['signal'] and (t_end is None or time.monotonic() < t_end):
            executor.spin_once(timeout_sec=PROGRESS_PERIOD)
            recorder.report_progress()
            if time.monotonic() >= next_poll:
                recorder.poll_graph()
                next_poll = time.monotonic() + GRAPH_POLL
        # Drain what DDS had received before the stop, until quiet (bounded).
        recorder.stop_ns = time.time_ns()
        drain_end = time.monotonic() + DRAIN_MAX
        quiet_from = time.monotonic()
        while time.monotonic() < drain_end:
            before = recorder.count
            executor.spin_once(timeout_sec=0.02)
            if recorder.count != before:
                quiet_from = time.monotonic()
            elif time.monotonic() - quiet_from > DRAIN_QUIET:
                break
        writer.close()
        print(f'recorded {recorder.count} messages to {out}'
              + (f'; lost on the way: {recorder.lost}' if recorder.lost else ''),
              file=sys.stderr, flush=True)
        executor.shutdown()
        node.destroy_node()
    finally:
        if writer is not None:
            writer.close()
        if rclpy.ok():
            rclpy.shutdown()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    return 0  # a stop by signal is the normal end of a recording


def main() -> None:
    """``ros2 run auv_bringup recorder``."""
    sys.exit(standalone('auv_bringup.record_node', 'recorder'))


if __name__ == '__main__':
    main()
