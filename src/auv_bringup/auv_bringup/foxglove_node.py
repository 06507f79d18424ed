"""Serve the live topics on a Foxglove WebSocket (``auv foxglove``, ``auv launch --foxglove``).

Each topic of the graph (:data:`auv_bringup.topics.KNOWN_TOPICS` by default) is
subscribed raw over DDS and its CDR bytes are forwarded unchanged to a Foxglove channel of the
same name, with the message's ``ros2msg`` definition as schema (``cdr`` encoding): Foxglove
decodes and plots every field as a ROS 2 tool would.

For the 3D panel the vehicle's pose is also served with Foxglove's own schemas (protobuf):
``/auv/pose`` (``foxglove.PoseInFrame``, frame ``odom``) and ``/auv/tf``
(``foxglove.FrameTransform``, ``odom`` -> ``base_link``), both taken from ``/auv/odom``, that is
in ENU (world) / FLU (body) as REP 103 has it: z is up, so z = -depth (the NED z of
``/auv/state``). ``/auv/hull`` (``foxglove.SceneUpdate``) draws the hull in ``base_link``: a
cylinder of the vehicle file's ``L_ref`` [m] and ``diameter`` [m] along the body x axis, sent
with the pose at most once a wall second (a client that connects later gets it within 1 s).
An odometry sample whose position or orientation is not finite, or whose quaternion is far from
unit norm, gives no pose (it is logged, throttled, and the node goes on); its raw message is
still forwarded.

Log time of every message sent (the timestamp Foxglove places it at): its header stamp [ns] when
it has one (simulated time with ``/clock``, else wall time); for messages without a header, the
latest header or ``/clock`` stamp seen (so a depth command sits at the graph's current time);
before any, the DDS receive time.

Quality of service: the streams (:data:`STREAM_TOPICS`: state, odometry, forces, clock) are
subscribed best effort, keep last 10: they match reliable and best-effort publishers and never
make a publisher resend, so a viewer cannot slow a run, and a sample lost on the way is lost to
the viewer only. Commands are sent once or at a low rate and must not be lost: the commands,
``/diagnostics`` and the other topics are subscribed reliable and volatile, keep last 10
(volatile, as the depth pilot's lasting subscriptions: a transient-local one would make every
volatile publisher of a script warn of incompatible durability; a depth command published
before the bridge started is therefore not shown). A reliable subscription does not match a
best-effort publisher: when one appears on a topic, the bridge follows it best effort. The
node prints one line ``foxglove: serving N topics on ws://HOST:PORT`` on stderr once its
subscriptions exist and the server listens (with ``--port 0`` the port the system chose).
SIGINT/SIGTERM stop it (exit 0).
"""
from __future__ import annotations

import argparse
import errno
import functools
import math
import signal
import socket
import sys
import time
from types import FrameType
from typing import Any, NamedTuple

from auv_bringup.cli import CliError, standalone
from auv_bringup.errors import BridgeError
from auv_bringup.record_node import message_class
from auv_bringup.topics import KNOWN_TOPICS, NAMESPACE, header_stamp, known_types
from auv_contract import config_path

DEFAULT_PORT = 8765  # Foxglove's default WebSocket port
DEFAULT_HOST = '127.0.0.1'
ODOM_TOPIC = '/auv/odom'
CLOCK_TOPIC = '/clock'
POSE_TOPIC = '/auv/pose'
TF_TOPIC = '/auv/tf'
HULL_TOPIC = '/auv/hull'
HULL_PERIOD = 1.0  # wall s between two hull updates
HULL_COLOR = (0.95, 0.75, 0.1, 0.8)  # RGBA, a yellow hull
QUATERNION_NORM_TOLERANCE = 1e-3  # |1 - |q|| above which an orientation is rejected
#: Topics subscribed best effort (high-rate streams; see the module docstring).
STREAM_TOPICS = frozenset({'/auv/state', '/auv/odom', '/auv/hydrodynamic_forces', CLOCK_TOPIC})
GRAPH_POLL = 0.5  # s between looks at the graph (new topic types, best-effort publishers)
WARN_PERIOD = 5.0  # s between two warnings about bad messages on one topic
SPIN_SLICE = 0.1  # s, longest wait of the spin loop (a stop is seen this promptly)
NS = 1_000_000_000


class Pose(NamedTuple):
    """A rigid-body pose: stamp [ns], frames, position [m] and orientation (x, y, z, w)."""

    stamp_ns: int
    frame_id: str
    child_frame_id: str
    position: tuple[float, float, float]
    orientation: tuple[float, float, float, float]


def pose_from_odometry(msg: Any) -> Pose:
    """The pose of a ``nav_msgs/Odometry`` (ENU world / FLU body, REP 103) message.

    Raises
    ------
    BridgeError
        a position or orientation component is not finite, or the quaternion's norm
        is more than :data:`QUATERNION_NORM_TOLERANCE` from 1.
    """
    p, q = msg.pose.pose.position, msg.pose.pose.orientation
    position = (float(p.x), float(p.y), float(p.z))
    orientation = (float(q.x), float(q.y), float(q.z), float(q.w))
    if not all(math.isfinite(v) for v in position + orientation):
        raise BridgeError(f'odometry pose not finite: position {position}, orientation '
                       f'{orientation}')
    norm = math.sqrt(sum(v * v for v in orientation))
    if abs(norm - 1.0) > QUATERNION_NORM_TOLERANCE:
        raise BridgeError(f'odometry orientation is not a unit quaternion (norm {norm:.6g})')
    stamp = msg.header.stamp
    return Pose(int(stamp.sec) * NS + int(stamp.nanosec), str(msg.header.frame_id),
                str(msg.child_frame_id), position, orientation)


def check_port_free(host: str, port: int) -> None:
    """Raise :class:`CliError` (one line) if TCP ``host:port`` cannot be bound now.

    Port 0 (the system chooses) is always free.
    """
    if port == 0:
        return
    if not 0 < port < 65536:
        raise CliError(f'Foxglove port must be 0..65535, got {port}')
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        # as a server binds: a connection of an earlier server in TIME_WAIT does not count
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            sock.bind((host, port))
        except OSError as exc:
            if exc.errno == errno.EADDRINUSE:
                raise CliError(f'Foxglove port {port} on {host} is in use (another server? '
                               'choose one with --foxglove PORT / --port PORT)') from None
            raise CliError(f'cannot serve on {host}:{port}: {exc.strerror}') from None


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``auv foxglove``."""
    parser.add_argument('--port', type=int, default=DEFAULT_PORT,
                        help='WebSocket port (default: %(default)s; 0: any free port, printed)')
    parser.add_argument('--host', default=DEFAULT_HOST,
                        help='address to listen on (default: %(default)s; 0.0.0.0 for every '
                             'interface)')
    parser.add_argument('--topics', nargs='+', metavar='TOPIC', default=list(KNOWN_TOPICS),
                        help='topics to serve (default: %(default)s); types other than the '
                             "project's are taken from the graph when they appear")
    parser.add_argument('--no-pose', action='store_true',
                        help=f'do not derive {POSE_TOPIC}, {TF_TOPIC} and {HULL_TOPIC} from '
                             f'{ODOM_TOPIC}')
    parser.add_argument('--vehicle', default=str(config_path('a18m.yaml')),
                        help='vehicle file: the hull drawn in 3D (default: %(default)s)')


class Bridge:
    """Raw DDS subscriptions forwarded to Foxglove channels (see the module docstring)."""

    def __init__(self, node: Any, topics: list[str], pose: bool,
                 hull: tuple[float, float] | None = None) -> None:
        """``hull``: (length, diameter) [m] of the hull drawn in 3D; None: none drawn."""
        import foxglove
        from foxglove.channels import (
            FrameTransformChannel,
            PoseInFrameChannel,
            SceneUpdateChannel,
        )

        from auv_bag import typestore

        self.node = node
        self._foxglove = foxglove
        self._store = typestore()
        self._channels: dict[str, Any] = {}
        #: topic -> (subscription, its type, reliable)
        self._subscriptions: dict[str, tuple[Any, str, bool]] = {}
        self._pending: list[str] = []
        self._last_stamp: int | None = None   # latest header/clock stamp seen [ns]
        self._warned: dict[str, float] = {}
        self.forwarded = 0
        self.rejected = 0
        self._pose = PoseInFrameChannel(POSE_TOPIC) if pose else None
        self._tf = FrameTransformChannel(TF_TOPIC) if pose else None
        self._hull_size = hull
        self._hull = SceneUpdateChannel(HULL_TOPIC) if pose and hull else None
        self._hull_sent = -math.inf  # time.monotonic() of the last hull update
        known = known_types(node)
        for topic in topics:
            name = node.resolve_topic_name(topic)
            msgtype = known.get(name)
            if msgtype is None:
                self._pending.append(name)
            else:
                self._subscribe(name, msgtype, reliable=name not in STREAM_TOPICS)

    @property
    def topic_count(self) -> int:
        """Topics served now (forwarded ones plus the derived pose topics)."""
        derived = (self._pose, self._tf, self._hull)
        return len(self._channels) + sum(c is not None for c in derived)

    def _subscribe(self, topic: str, msgtype: str, reliable: bool) -> None:
        from rclpy.qos import QoSProfile, ReliabilityPolicy

        cls = message_class(msgtype)
        if topic not in self._channels:
            definition, _ = self._store.generate_msgdef(msgtype, ros_version=2)
            schema = self._foxglove.Schema(name=msgtype, encoding='ros2msg',
                                           data=definition.encode())
            self._channels[topic] = self._foxglove.Channel(topic, schema=schema,
                                                           message_encoding='cdr')
        old = self._subscriptions.pop(topic, None)
        if old is not None:
            self.node.destroy_subscription(old[0])
        if not reliable:
            qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
        else:
            qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        with_header = 'header' in cls.get_fields_and_field_types()
        sub = self.node.create_subscription(
            cls, topic, functools.partial(self._on_message, topic, with_header, cls), qos,
            raw=True)
        self._subscriptions[topic] = (sub, msgtype, reliable)

    def _on_message(self, topic: str, with_header: bool, cls: Any, data: bytes,
                    info: dict[str, int]) -> None:
        """Forward one CDR message; never raises (a bad message is logged and skipped)."""
        try:
            stamp = self._stamp(topic, with_header, data, info)
            self._channels[topic].log(bytes(data), log_time=stamp)
            self.forwarded += 1
            if topic == ODOM_TOPIC:
                self._publish_pose(data, cls)
        except Exception as exc:  # a viewer never dies on a message
            self.rejected += 1
            self._warn(topic, f'{topic}: message skipped: {exc}')

    def _stamp(self, topic: str, with_header: bool, data: bytes, info: dict[str, int]) -> int:
        """Log time [ns] of a message (see the module docstring)."""
        stamp = header_stamp(data) if with_header or topic == CLOCK_TOPIC else None
        if stamp is not None and stamp[0] >= 0:
            ns = stamp[0] * NS + stamp[1]
            self._last_stamp = ns if self._last_stamp is None else max(self._last_stamp, ns)
            return ns
        if self._last_stamp is not None:
            return self._last_stamp
        return int(info.get('received_timestamp') or time.time_ns())

    def _publish_pose(self, data: bytes, cls: Any) -> None:
        from foxglove.messages import FrameTransform, PoseInFrame, Quaternion, Timestamp, Vector3
        from foxglove.messages import Pose as FoxglovePose
        from rclpy.serialization import deserialize_message

        if self._pose is None or self._tf is None:
            return
        pose = pose_from_odometry(deserialize_message(data, cls))
        stamp = Timestamp(pose.stamp_ns // NS, pose.stamp_ns % NS)
        position = Vector3(x=pose.position[0], y=pose.position[1], z=pose.position[2])
        qx, qy, qz, qw = pose.orientation
        orientation = Quaternion(x=qx, y=qy, z=qz, w=qw)
        self._pose.log(PoseInFrame(timestamp=stamp, frame_id=pose.frame_id,
                                   pose=FoxglovePose(position=position, orientation=orientation)),
                       log_time=pose.stamp_ns)
        self._tf.log(FrameTransform(timestamp=stamp, parent_frame_id=pose.frame_id,
                                    child_frame_id=pose.child_frame_id, translation=position,
                                    rotation=orientation), log_time=pose.stamp_ns)
        if self._hull is not None and time.monotonic() - self._hull_sent >= HULL_PERIOD:
            self._hull_sent = time.monotonic()
            self._publish_hull(stamp, pose)

    def _publish_hull(self, stamp: Any, pose: Pose) -> None:
        """The hull as a cylinder along the body x axis (a Foxglove cylinder's axis is its
        local z: turned +90 deg about y), centred on the body origin, locked to the body."""
        from foxglove.messages import (
            Color,
            CylinderPrimitive,
            Quaternion,
            SceneEntity,
            SceneUpdate,
            Vector3,
        )
        from foxglove.messages import Pose as FoxglovePose

        if self._hull is None or self._hull_size is None:
            return
        length, diameter = self._hull_size
        half = math.sqrt(0.5)
        r, g, b, a = HULL_COLOR
        cylinder = CylinderPrimitive(
            pose=FoxglovePose(position=Vector3(), orientation=Quaternion(x=0.0, y=half, z=0.0,
                                                                         w=half)),
            size=Vector3(x=diameter, y=diameter, z=length), bottom_scale=1.0, top_scale=1.0,
            color=Color(r=r, g=g, b=b, a=a))
        entity = SceneEntity(timestamp=stamp, frame_id=pose.child_frame_id, id='hull',
                             frame_locked=True, cylinders=[cylinder])
        self._hull.log(SceneUpdate(entities=[entity]), log_time=pose.stamp_ns)

    def _warn(self, topic: str, text: str) -> None:
        now = time.monotonic()
        if now - self._warned.get(topic, -math.inf) >= WARN_PERIOD:
            self._warned[topic] = now
            self.node.get_logger().warning(text)

    def poll_graph(self) -> None:
        """Subscribe requested topics whose type has appeared in the graph; follow
        best-effort publishers on reliable subscriptions best effort."""
        from rclpy.qos import ReliabilityPolicy

        if self._pending:
            types = dict(self.node.get_topic_names_and_types())
            for topic in list(self._pending):
                if types.get(topic):
                    try:
                        self._subscribe(topic, types[topic][0],
                                        reliable=topic not in STREAM_TOPICS)
                    except Exception as exc:  # type not importable or not describable
                        self._warn(topic, f'{topic}: not served: {exc}')
                    self._pending.remove(topic)
        for topic, (_, msgtype, reliable) in list(self._subscriptions.items()):
            if reliable and any(i.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT
                                for i in self.node.get_publishers_info_by_topic(topic)):
                self.node.get_logger().warning(f'{topic}: best-effort publisher, following it '
                                               'best effort')
                self._subscribe(topic, msgtype, reliable=False)


def run(args: argparse.Namespace) -> int:
    """Serve until SIGINT/SIGTERM; returns the exit status."""
    check_port_free(args.host, args.port)
    from auv_sim.params import load_vehicle

    vehicle = load_vehicle(args.vehicle)
    import foxglove
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    stop = {'signal': 0}

    def on_signal(signum: int, _frame: FrameType | None) -> None:
        stop['signal'] = signum

    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    server = None
    try:
        node = rclpy.create_node('auv_foxglove', namespace=NAMESPACE)
        bridge = Bridge(node, list(dict.fromkeys(args.topics)), pose=not args.no_pose,
                        hull=(vehicle.L_ref, vehicle.diameter))
        try:
            server = foxglove.start_server(name='auv', host=args.host, port=args.port)
        except RuntimeError as exc:  # the SDK's FoxgloveError (e.g. the port was taken since)
            raise CliError(f'cannot serve Foxglove WebSocket on {args.host}:{args.port}: '
                           f'{str(exc).splitlines()[0] if str(exc) else type(exc).__name__}'
                           ) from None
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        print(f'foxglove: serving {bridge.topic_count} topics on '
              f'ws://{args.host}:{server.port}', file=sys.stderr, flush=True)
        next_poll = time.monotonic()
        while not stop['signal']:
            executor.spin_once(timeout_sec=SPIN_SLICE)
            if time.monotonic() >= next_poll:
                bridge.poll_graph()
                next_poll = time.monotonic() + GRAPH_POLL
        print(f'foxglove: forwarded {bridge.forwarded} messages, skipped {bridge.rejected}',
              file=sys.stderr, flush=True)
        executor.shutdown()
        node.destroy_node()
    finally:
        if server is not None:
            server.stop()
        if rclpy.ok():
            rclpy.shutdown()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    return 0


def main() -> None:
    """``ros2 run auv_bringup foxglove``."""
    sys.exit(standalone('auv_bringup.foxglove_node', 'foxglove'))


if __name__ == '__main__':
    main()
