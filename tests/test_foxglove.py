"""The Foxglove bridge seen by a real Foxglove WebSocket client, and ``auv launch`` leaving no
orphan node when it is SIGKILLed.

The client (:mod:`foxglove_client`) speaks the Foxglove WebSocket protocol with the
``websockets`` package and decodes each message against the schema the server advertised. The
values are checked against physics and REP 103 (ENU/FLU) worked by hand, not against the
bridge's own code.
"""
from __future__ import annotations

import asyncio
import math
import os
import pathlib
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest
import yaml
from foxglove_client import Decoded, LineReader, receive

ROOT = pathlib.Path(__file__).resolve().parents[1]
A18M = ROOT / 'config' / 'a18m.yaml'
NS = 1_000_000_000
DEPTH = 25.0   # m, NED z of the simulator's trimmed start
SPEED = 1.8    # m/s, body surge of the simulator's trimmed start


# ------------------------------------------------------------------------------------------
# processes

def stop(proc: subprocess.Popen[str], deadline: float = 15.0) -> int:
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
    try:
        return proc.wait(deadline)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(5.0)
        raise AssertionError(f'process {proc.args} did not stop within {deadline} s') from None


@pytest.fixture
def bridge(ros_env: dict[str, str]) -> Iterator[tuple[int, subprocess.Popen[str], LineReader]]:
    """The bridge on a free port; yields (port, process, its stderr lines) once it is ready."""
    proc = subprocess.Popen([sys.executable, '-m', 'auv_bringup.foxglove_node', '--port', '0'],
                            cwd=ROOT, env=ros_env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)
    reader = LineReader(proc.stderr)
    try:
        line = reader.wait_for('foxglove: serving', 60.0)
        # every channel of the graph exists before a client can connect (a channel added while
        # a client subscribes can be refused as unknown): the 9 topics and 3 pose topics
        assert 'serving 12 topics' in line, line
        port = int(line.rsplit(':', 1)[1])
        yield port, proc, reader
    finally:
        code = stop(proc)
    assert code == 0, ''.join(reader.lines)


# ------------------------------------------------------------------------------------------
# the client


# ------------------------------------------------------------------------------------------
# tests


def forward_axis_enu(q: Any) -> tuple[float, float, float]:
    """The body x axis (FLU forward) rotated into the world frame by quaternion q (x, y, z, w)."""
    x, y, z, w = q.x, q.y, q.z, q.w
    return (1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y))


def test_live_state_odometry_and_pose_decode_to_the_simulated_vehicle(
        bridge: tuple[int, subprocess.Popen[str], LineReader], ros_env: dict[str, str],
        tmp_path: pathlib.Path) -> None:
    port, bridge_proc, _ = bridge
    log = tmp_path / 'sim.log'
    sim = subprocess.Popen([sys.executable, '-m', 'auv_sim.node', '--initial-depth', str(DEPTH),
                            '--initial-speed', str(SPEED), '--initial-heading', '0.5',
                            '--real-time-factor', '1'], cwd=ROOT, env=ros_env,
                           stdout=subprocess.DEVNULL, stderr=log.open('w'))
    topics = ['/auv/state', '/auv/odom', '/auv/pose', '/auv/tf', '/auv/hydrodynamic_forces']
    try:
        got = asyncio.run(receive(port, [*topics, '/auv/hull'], lambda d: all(
            len(d.messages[t]) >= 40 for t in topics) and len(d.messages['/auv/hull']) >= 1,
            deadline=90.0))
        assert sim.poll() is None, log.read_text()
        assert bridge_proc.poll() is None
    finally:
        code = stop(sim)
    assert code == 0, log.read_text()

    chans = got.channels
    assert (chans['/auv/state']['encoding'], chans['/auv/state']['schemaEncoding'],
            chans['/auv/state']['schemaName']) == ('cdr', 'ros2msg', 'auv_msgs/msg/VehicleState')
    assert chans['/auv/odom']['schemaName'] == 'nav_msgs/msg/Odometry'
    assert chans['/auv/pose']['schemaName'] == 'foxglove.PoseInFrame'
    assert chans['/auv/tf']['schemaName'] == 'foxglove.FrameTransform'

    # state: stamps on the 50 Hz publish grid, increasing; the timestamp is the header stamp
    states = {}
    previous = -1
    for stamp, msg in got.messages['/auv/state']:
        ns = msg.header.stamp.sec * NS + msg.header.stamp.nanosec
        assert stamp == ns
        assert ns > previous and ns % 20_000_000 == 0, (previous, ns)
        previous = ns
        states[ns] = msg
        # a trimmed start holds depth and speed over the first simulated seconds
        assert abs(msg.z - DEPTH) < 0.5 and abs(msg.u - SPEED) < 0.1, (msg.z, msg.u)
        assert abs(msg.psi - 0.5) < 1e-3 and abs(msg.phi) < 1e-3 and abs(msg.theta) < 0.2
    # odometry (raw CDR) and the Foxglove pose are the same state in ENU/FLU (REP 103):
    # ENU x = NED y (east), ENU y = NED x (north), ENU z = -NED z (up = -depth)
    matched = 0
    for topic in ('/auv/odom', '/auv/pose'):
        for stamp, msg in got.messages[topic]:
            if topic == '/auv/odom':
                ns = msg.header.stamp.sec * NS + msg.header.stamp.nanosec
                p, q = msg.pose.pose.position, msg.pose.pose.orientation
                assert (msg.header.frame_id, msg.child_frame_id) == ('odom', 'base_link')
            else:
                ns = msg.timestamp.seconds * NS + msg.timestamp.nanos
                p, q = msg.pose.position, msg.pose.orientation
                assert msg.frame_id == 'odom'
            assert stamp == ns
            if ns not in states:
                continue        # best effort: a sample of the other topic may be missing
            s = states[ns]
            assert (p.x, p.y, p.z) == pytest.approx((s.y, s.x, -s.z), abs=1e-9)
            assert math.hypot(math.hypot(q.x, q.y), math.hypot(q.z, q.w)) \
                == pytest.approx(1.0, abs=1e-9)
            forward = forward_axis_enu(q)
            c = math.cos(s.theta)
            assert forward == pytest.approx(
                (c * math.sin(s.psi), c * math.cos(s.psi), math.sin(s.theta)), abs=1e-9)
            matched += 1
    assert matched >= 40, 'too few odometry/pose samples share a stamp with a state'
    for stamp, tf in got.messages['/auv/tf']:
        assert (tf.parent_frame_id, tf.child_frame_id) == ('odom', 'base_link')
        assert stamp == tf.timestamp.seconds * NS + tf.timestamp.nanos
        if stamp in states:
            assert tf.translation.z == pytest.approx(-states[stamp].z, abs=1e-9)
    # the hull: a cylinder of the vehicle file's length and diameter along the body x axis
    geometry = yaml.safe_load(A18M.read_text())['geometry']
    for stamp, update in got.messages['/auv/hull']:
        entity, = update.entities
        assert (entity.frame_id, entity.frame_locked) == ('base_link', True)
        assert stamp == entity.timestamp.seconds * NS + entity.timestamp.nanos
        cylinder, = entity.cylinders
        assert (cylinder.size.x, cylinder.size.y, cylinder.size.z) == pytest.approx(
            (geometry['diameter']['value'], geometry['diameter']['value'],
             geometry['L_ref']['value']))
        axis = forward_axis_enu(cylinder.pose.orientation)   # where the local x goes ...
        assert axis == pytest.approx((0.0, 0.0, -1.0), abs=1e-9)  # ... so local z goes to +x
    # forces: the restoring force of a trimmed, level vehicle is nearly vertical, and the
    # stamps are those of the states
    for stamp, f in got.messages['/auv/hydrodynamic_forces']:
        assert stamp == f.header.stamp.sec * NS + f.header.stamp.nanosec
        r = f.restoring.force
        assert abs(r.x) <= abs(r.z) * 0.2 + 1e-6


def test_a_bad_odometry_gives_no_pose_and_the_bridge_goes_on(
        bridge: tuple[int, subprocess.Popen[str], LineReader]) -> None:
    """Also: a best-effort publisher of a command topic (subscribed reliable) is followed."""
    import rclpy
    from nav_msgs.msg import Odometry
    from rclpy.context import Context
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rclpy.signals import SignalHandlerOptions

    from auv_msgs.msg import ActuatorSetpoint

    port, bridge_proc, reader = bridge
    context = Context()
    rclpy.init(context=context, domain_id=int(os.environ['ROS_DOMAIN_ID']),
               signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('bad_odometry', context=context)
    pub = node.create_publisher(Odometry, '/auv/odom', 10)
    best_effort = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
    bar_pub = node.create_publisher(ActuatorSetpoint, '/auv/bar_command', best_effort)
    subscribed = threading.Event()
    stop_publishing = threading.Event()

    def odometry(sec: int, quaternion_w: float, x: float) -> Odometry:
        msg = Odometry()
        msg.header.stamp.sec = sec
        msg.header.frame_id, msg.child_frame_id = 'odom', 'base_link'
        msg.pose.pose.position.x = x
        msg.pose.pose.orientation.w = quaternion_w
        return msg

    def publish() -> None:
        end = time.monotonic() + 60.0
        while pub.get_subscription_count() < 1 or not subscribed.is_set():
            if time.monotonic() > end or stop_publishing.is_set():
                return
            time.sleep(0.05)
        while not stop_publishing.is_set() and time.monotonic() < end:
            pub.publish(odometry(1, 0.0, 1.0))          # zero quaternion: no orientation
            pub.publish(odometry(2, 1.0, math.nan))     # position not finite
            pub.publish(odometry(3, 1.0, 7.0))          # good
            bar_pub.publish(ActuatorSetpoint(value=0.125))
            time.sleep(0.1)

    publisher = threading.Thread(target=publish, daemon=True)
    publisher.start()
    try:
        got = asyncio.run(receive(
            port, ['/auv/odom', '/auv/pose', '/auv/bar_command'],
            lambda d: {s for s, _ in d.messages['/auv/odom']} >= {1 * NS, 2 * NS, 3 * NS}
            and len(d.messages['/auv/pose']) >= 3 and len(d.messages['/auv/bar_command']) >= 1,
            deadline=60.0, on_subscribed=subscribed.set))
    finally:
        stop_publishing.set()
        publisher.join(5.0)
        node.destroy_node()
        context.try_shutdown()
    poses = got.messages['/auv/pose']
    assert {s for s, _ in poses} == {3 * NS}, 'a pose was served from a bad odometry'
    assert all(m.pose.position.x == 7.0 for _, m in poses)
    assert all(m.value == 0.125 for _, m in got.messages['/auv/bar_command'])
    assert bridge_proc.poll() is None
    reader.wait_for('message skipped', 10.0)


def occupied_port() -> tuple[socket.socket, int]:
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.bind(('127.0.0.1', 0))
    sock.listen(1)
    return sock, sock.getsockname()[1]


@pytest.mark.parametrize('command', [['foxglove', '--port'], ['launch', '--foxglove']])
def test_port_in_use_is_a_one_line_error(ros_env: dict[str, str], command: list[str]) -> None:
    sock, port = occupied_port()
    with sock:
        proc = subprocess.run([sys.executable, '-m', 'auv_bringup.cli', *command, str(port)],
                              cwd=ROOT, env=ros_env, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 1
    assert proc.stderr.strip() == (f'error: Foxglove port {port} on 127.0.0.1 is in use '
                                   '(another server? choose one with --foxglove PORT / --port '
                                   'PORT)'), proc.stderr


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(('127.0.0.1', 0))
        return int(sock.getsockname()[1])


def wait_for_line(path: pathlib.Path, needle: str, proc: subprocess.Popen[str],
                  deadline: float) -> None:
    end = time.monotonic() + deadline
    while not (path.is_file() and needle in path.read_text()):
        assert proc.poll() is None, proc.communicate()[1]
        assert time.monotonic() < end, f'no {needle!r} in {path} within {deadline} s'
        time.sleep(0.1)


def test_launch_foxglove_serves_the_commands_of_the_closed_loop(
        ros_env: dict[str, str], tmp_path: pathlib.Path) -> None:
    port = free_port()
    logs = tmp_path / 'logs'
    launch = subprocess.Popen([sys.executable, '-m', 'auv_bringup.cli', 'launch', '--foxglove',
                               str(port), '--log-dir', str(logs), '--initial-depth', '40'],
                              cwd=ROOT, env=ros_env, stdout=subprocess.DEVNULL,
                              stderr=subprocess.PIPE, text=True)
    depth_cmd: list[subprocess.CompletedProcess[str]] = []

    def command_depth() -> None:
        depth_cmd.append(subprocess.run(
            # two subscriber nodes: the pilot and the bridge
            [sys.executable, '-m', 'auv_bringup.cli', 'depth', '35', '--min-subscribers', '2',
             '--timeout', '30'], cwd=ROOT, env=ros_env, capture_output=True, text=True,
            timeout=60))

    def answered(d: Decoded) -> bool:
        """1 s of the pilot holding 40 m, the command, then 2 s of its answer."""
        if commander.ident is None and len(d.messages['/auv/bar_command']) >= 10:
            commander.start()
        commands = d.messages['/auv/depth_command']
        return bool(commands) and sum(s > commands[0][0] + NS
                                      for s, _ in d.messages['/auv/bar_command']) >= 10

    commander = threading.Thread(target=command_depth, daemon=True)
    topics = ['/auv/state', '/auv/bar_command', '/auv/depth_command']
    try:
        wait_for_line(logs / 'foxglove.log', 'foxglove: serving', launch, 60.0)
        got = asyncio.run(receive(port, topics, answered, deadline=90.0))
    finally:
        launch.send_signal(signal.SIGINT)
        try:
            code = launch.wait(40.0)
        except subprocess.TimeoutExpired:
            launch.kill()
            raise
        if commander.is_alive():
            commander.join(60.0)
    stderr = launch.communicate()[1]
    assert code == 0, stderr
    # the launcher says where to connect, and the layout to load
    assert f'launch: Foxglove at ws://127.0.0.1:{port} (in a browser: https://app.foxglove.dev/' \
        f'?ds=foxglove-websocket&ds.url=ws%3A%2F%2F127.0.0.1%3A{port}; layout ' in stderr, stderr
    assert depth_cmd and depth_cmd[0].returncode == 0, depth_cmd
    assert got.channels['/auv/bar_command']['schemaName'] == 'auv_msgs/msg/ActuatorSetpoint'
    assert got.channels['/auv/depth_command']['schemaName'] == 'std_msgs/msg/Float64'
    (stamp, depth), = got.messages['/auv/depth_command'][:1]
    assert depth.data == 35.0
    # no header: placed at the graph's time (simulated, from 0) when it arrived
    state_stamps = [s for s, _ in got.messages['/auv/state']]
    assert 0 < stamp <= max(state_stamps) + NS
    bar_max = math.radians(25.0)    # the a18m's plane travel (config/a18m.yaml)
    bars = got.messages['/auv/bar_command']
    assert all(abs(m.value) <= bar_max + 1e-12 for _, m in bars)
    assert [s for s, _ in bars] == sorted(s for s, _ in bars)
    assert all(s == m.header.stamp.sec * NS + m.header.stamp.nanosec for s, m in bars)
    # climbing from 40 m to 35 m: the planes pitch the nose up (trailing edge up, BAR < trim)
    before = [m.value for s, m in bars if s < stamp]
    after = [m.value for s, m in bars if s > stamp + NS]
    assert before and after and min(after) < min(before) - 0.01, (before, after)


# ------------------------------------------------------------------------------------------
# auv launch SIGKILLed leaves no orphan


def children(pid: int) -> dict[int, str]:
    """pid -> command line of the live processes whose parent is ``pid`` (Linux /proc)."""
    out = {}
    for entry in pathlib.Path('/proc').iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / 'stat').read_text()
            cmdline = (entry / 'cmdline').read_bytes().replace(b'\0', b' ').decode()
        except OSError:
            continue
        fields = stat.rsplit(')', 1)[1].split()
        if int(fields[1]) == pid and fields[0] != 'Z':
            out[int(entry.name)] = cmdline
    return out


def alive(pid: int) -> bool:
    try:
        stat = pathlib.Path(f'/proc/{pid}/stat').read_text()
    except OSError:
        return False
    return stat.rsplit(')', 1)[1].split()[0] != 'Z'


@pytest.mark.skipif(not sys.platform.startswith('linux'), reason='PR_SET_PDEATHSIG is Linux')
def test_launch_sigkilled_leaves_no_orphan_node(ros_env: dict[str, str],
                                                tmp_path: pathlib.Path) -> None:
    logs = tmp_path / 'logs'
    bag = tmp_path / 'bag'
    launch = subprocess.Popen([sys.executable, '-m', 'auv_bringup.cli', 'launch', '--log-dir',
                               str(logs), '--record', str(bag), '--initial-depth', '30'],
                              cwd=ROOT, env=ros_env, stdout=subprocess.DEVNULL,
                              stderr=subprocess.PIPE, text=True)
    modules = ('auv_bringup.record_node', 'auv_depth_lqr.node', 'auv_sim.node')
    nodes: dict[int, str] = {}
    try:
        end = time.monotonic() + 60.0
        while True:     # ready: the three nodes run their modules and the recorder records
            assert launch.poll() is None, launch.communicate()[1]
            nodes = children(launch.pid)
            recording = (logs / 'recorder.log').is_file() and 'recording' in \
                (logs / 'recorder.log').read_text()
            if recording and all(any(m in c for c in nodes.values()) for m in modules):
                break
            assert time.monotonic() < end, f'graph not up within 60 s: {nodes}'
            time.sleep(0.1)
        launch.kill()
        launch.wait(10.0)
        end = time.monotonic() + 30.0
        while any(alive(pid) for pid in nodes) and time.monotonic() < end:
            time.sleep(0.1)
        left = {pid: cmd for pid, cmd in nodes.items() if alive(pid)}
    finally:
        if launch.poll() is None:
            launch.kill()
            launch.wait(10.0)
        for pid in nodes:
            if alive(pid):
                os.kill(pid, signal.SIGKILL)
    assert not left, f'nodes left running after SIGKILL of auv launch: {left}'
    # the recorder got SIGTERM, not SIGKILL: it closed its bag with its metadata
    assert (bag / 'metadata.yaml').is_file()


def test_the_layout_file_is_the_tools_output_and_names_served_topics() -> None:
    """``config/foxglove/auv_graph_layout.json`` is what ``tools/foxglove_layout.py`` writes,
    and every topic a panel plots is one the bridge serves."""
    import importlib.util
    import json

    from auv_bringup.foxglove_node import HULL_TOPIC, POSE_TOPIC, TF_TOPIC
    from auv_bringup.topics import KNOWN_TOPICS

    spec = importlib.util.spec_from_file_location('foxglove_layout',
                                                  ROOT / 'tools' / 'foxglove_layout.py')
    assert spec is not None and spec.loader is not None
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    text = (ROOT / 'config' / 'foxglove' / 'auv_graph_layout.json').read_text()
    assert text == tool.layout_json()
    served = {t if t.startswith('/') else f'/auv/{t}' for t in KNOWN_TOPICS} | {
        POSE_TOPIC, TF_TOPIC, HULL_TOPIC}
    used: set[str] = set()

    def walk(node: Any) -> None:
        if isinstance(node, dict):
            for key, value in node.items():
                if key == 'topics':
                    used.update(value)
                elif key in ('value', 'topicToRender') and isinstance(value, str):
                    used.add(value.split('.')[0])
                walk(value)
        elif isinstance(node, list):
            for item in node:
                walk(item)
    walk(json.loads(text))
    assert used == {'/auv/pose', '/auv/hull', '/auv/state', '/auv/depth_command',
                    '/auv/bar_command', '/diagnostics'}
    assert used <= served
