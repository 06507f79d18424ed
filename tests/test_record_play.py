"""`auv record` and `auv play` as real processes on Fast DDS (no mocks).

A publisher process streams VehicleState on /auv/state at about 200 Hz with reliable QoS once
the recorder's subscription has matched; SIGTERM then stops the recorder, which must have
written every message it had received. The bag is then replayed to a subscriber process, at
rate 1 and 2, and the timing of what arrives is compared with the bag.
"""
from __future__ import annotations

import json
import os
import pathlib
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from auv_bag import read_arrays, read_messages

N = 500
NS_PER_S = 1_000_000_000
RATE_HZ = 200.0
STATE = '/auv/state'
#: deadlines (wall s) for a listener to be ready and to hear its stream, with room for a busy
#: 2-core machine; a listener ends as soon as it has heard its last expected message
READY_S = 60.0
LISTEN_S = 60.0

PUBLISHER = r'''
import sys, time
import rclpy
from rclpy.duration import Duration
from rclpy.qos import QoSProfile, ReliabilityPolicy
from auv_msgs.msg import VehicleState

n, rate, mark = int(sys.argv[1]), float(sys.argv[2]), int(sys.argv[3])
rclpy.init()
node = rclpy.create_node('test_state_publisher')
pub = node.create_publisher(VehicleState, '/auv/state',
                            QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
deadline = time.monotonic() + 60.0
while pub.get_subscription_count() == 0:
    if time.monotonic() > deadline:
        print('no subscriber', flush=True)
        sys.exit(2)
    time.sleep(0.01)
start = time.monotonic()
for i in range(n):
    msg = VehicleState()
    t = 1000.0 + i / rate
    msg.header.stamp.sec = int(t)
    msg.header.stamp.nanosec = int(round((t - int(t)) * 1e9))
    msg.header.frame_id = 'ned' if i % 2 else 'base_link'
    msg.x, msg.z, msg.theta, msg.r = float(i), 0.5 * i, -0.001 * i, 1.0 / (i + 1)
    pub.publish(msg)
    if i == mark:
        print('mark', flush=True)
    time.sleep(max(0.0, start + (i + 1) / rate - time.monotonic()))
acked = pub.wait_for_all_acked(Duration(seconds=10))
print('acked' if acked else 'not acked', flush=True)
time.sleep(0.5 if mark >= 0 else 0.0)
rclpy.shutdown()
'''

SUBSCRIBER = r'''
import faulthandler, json, sys, time
import rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy
from auv_msgs.msg import VehicleState

n, timeout = int(sys.argv[1]), float(sys.argv[2])
faulthandler.dump_traceback_later(timeout + 20.0, exit=True)  # a hang says where (stderr)
rclpy.init()
node = rclpy.create_node('test_state_subscriber')
got = []
node.create_subscription(VehicleState, '/auv/state',
                         lambda m: got.append((time.monotonic(), m.x, m.z)),
                         QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
print('ready', flush=True)
deadline = time.monotonic() + timeout
while len(got) < n and time.monotonic() < deadline:
    rclpy.spin_once(node, timeout_sec=0.05)
print(json.dumps(got), flush=True)
rclpy.shutdown()
'''


def _auv(*args: str) -> list[str]:
    return [sys.executable, '-m', 'auv_bringup.cli', *args]


def _wait_line(proc: subprocess.Popen[str], want: str, timeout: float) -> str:
    """Next stdout line of ``proc`` equal to ``want`` (with a deadline)."""
    deadline = time.monotonic() + timeout
    assert proc.stdout is not None
    os.set_blocking(proc.stdout.fileno(), False)
    buf = ''
    while time.monotonic() < deadline:
        chunk = proc.stdout.readline()
        if chunk:
            buf += chunk
            if chunk.strip() == want:
                return buf
            continue
        if proc.poll() is not None:
            break
        time.sleep(0.01)
    raise AssertionError(f'no {want!r} from process (got {buf!r}, rc={proc.poll()})')


def _record(ros_env: dict[str, str], out: pathlib.Path, mark: int) -> np.ndarray:
    """Record while the publisher streams; SIGTERM the recorder after the 'mark' (mark >= 0)
    or once every message is acknowledged (mark < 0). Returns the recorded state array."""
    rec = subprocess.Popen(_auv('record', '--out', str(out), '--topics', STATE), env=ros_env,
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    pub = subprocess.Popen([sys.executable, '-c', PUBLISHER, str(N), str(RATE_HZ), str(mark)],
                           env=ros_env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                           text=True)
    try:
        _wait_line(pub, 'mark' if mark >= 0 else 'acked', timeout=40)
        rec.send_signal(signal.SIGTERM)
        _, err = rec.communicate(timeout=20)
        assert rec.returncode == 0, err
        if mark >= 0:
            pub.terminate()  # the rest of the stream is not needed
        pub.communicate(timeout=30)
    finally:
        for proc in (rec, pub):
            if proc.poll() is None:
                proc.kill()
                proc.communicate()
    return read_arrays(out, [STATE])[STATE]


def _check_contents(arr: np.ndarray, count: int) -> None:
    i = np.arange(count)
    np.testing.assert_array_equal(arr['x'], i)
    np.testing.assert_array_equal(arr['z'], 0.5 * i)
    np.testing.assert_array_equal(arr['theta'], -0.001 * i)
    np.testing.assert_array_equal(arr['r'], 1.0 / (i + 1))
    np.testing.assert_allclose(arr['t'], 1000.0 + i / RATE_HZ, atol=1e-9)


@pytest.fixture(scope='module')
def recorded(tmp_path_factory: pytest.TempPathFactory) -> pathlib.Path:
    from conftest import ros_domain_id

    env = dict(os.environ, ROS_DOMAIN_ID=str(ros_domain_id()),
               ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST', RMW_IMPLEMENTATION='rmw_fastrtps_cpp',
               PYTHONUNBUFFERED='1')
    out = tmp_path_factory.mktemp('rec') / 'all'
    arr = _record(env, out, mark=-1)
    assert len(arr) == N
    _check_contents(arr, N)
    return out


def test_sigterm_after_stream_keeps_every_message(recorded: pathlib.Path) -> None:
    arr = read_arrays(recorded, [STATE])[STATE]
    assert len(arr) == N
    # Log times are receive times: the stream's spacing, in the same order as the stamps.
    assert np.all(np.diff(arr['t_log']) >= 0)
    span = arr['t_log'][-1] - arr['t_log'][0]
    assert abs(span - (N - 1) / RATE_HZ) < 0.5
    assert (recorded / 'metadata.yaml').is_file()


def test_sigterm_mid_stream_closes_a_whole_bag(ros_env: dict[str, str],
                                               tmp_path: pathlib.Path) -> None:
    arr = _record(ros_env, tmp_path / 'mid', mark=N // 2)
    # Everything received before the stop, as a gap-free prefix of the stream.
    assert N // 2 < len(arr) < N
    _check_contents(arr, len(arr))


def _play(ros_env: dict[str, str], bag: pathlib.Path, rate: float,
          clock_hz: float | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """Play ``bag`` to a /auv/state listener (and a /clock listener with ``clock_hz``):
    arrival times (s, monotonic) with x and z; clock values (ns) or None.

    Both listeners have their subscriptions before the player starts ('ready' handshake), the
    player starts once every replayed topic has matched, and each listener ends on the last
    message it expects (the N-th state; the clock at the bag's last log time)."""
    last_ns = round((1000.0 + (N - 1) / RATE_HZ) * NS_PER_S)  # the last state's stamp
    subs = [subprocess.Popen([sys.executable, '-c', SUBSCRIBER, str(N), str(LISTEN_S)],
                             env=ros_env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             text=True)]
    extra = []
    try:
        _wait_line(subs[0], 'ready', timeout=READY_S)
        if clock_hz is not None:
            subs.append(_listen(ros_env, '/clock', 'rosgraph_msgs.msg.Clock',
                                '(m.clock.sec, m.clock.nanosec)', 100_000, LISTEN_S,
                                last=f'({last_ns // 10**9}, {last_ns % 10**9})'))
            extra = ['--clock', str(clock_hz)]
        play = subprocess.run(_auv('play', str(bag), '--rate', str(rate),
                                   '--wait-for-subscribers', *extra),
                              env=ros_env, capture_output=True, text=True, timeout=90)
        assert play.returncode == 0, play.stderr
        done = [proc.communicate(timeout=LISTEN_S + 30) for proc in subs]
        outs = [out for out, _ in done]
        for (out, err), proc in zip(done, subs):
            assert proc.returncode == 0 and out.strip(), f'listener: {out[-500:]} {err[-3000:]}'
    finally:
        for proc in subs:
            if proc.poll() is None:
                proc.kill()
                proc.communicate()
    got = np.array(json.loads(outs[0].strip().splitlines()[-1]))
    clock = None
    if clock_hz is not None:
        pairs = json.loads(outs[1].strip().splitlines()[-1])
        clock = np.array([sec * 1_000_000_000 + nsec for sec, nsec in pairs])
    return got, clock


@pytest.mark.parametrize('rate', [1.0, 2.0])
def test_play_preserves_timing(recorded: pathlib.Path, ros_env: dict[str, str],
                               rate: float) -> None:
    arr = read_arrays(recorded, [STATE])[STATE]
    clock_hz = 50.0 if rate == 2.0 else None
    got, clock = _play(ros_env, recorded, rate, clock_hz)
    assert len(got) == N
    np.testing.assert_array_equal(got[:, 1], arr['x'])
    np.testing.assert_array_equal(got[:, 2], arr['z'])
    bag_span = arr['t_log'][-1] - arr['t_log'][0]
    play_span = got[-1, 0] - got[0, 0]
    # Margins that hold on a busy 2-core machine (the replay's timing figures on an idle one
    # are measured by bench/bench_replay.py): a player that ignored the log times would be
    # off by up to the whole span (1.25-2.5 s here).
    assert abs(play_span - bag_span / rate) < 0.1 * bag_span / rate + 0.2
    # Message by message: arrival offsets follow the bag's log-time offsets / rate.
    lag = (got[:, 0] - got[0, 0]) - (arr['t_log'] - arr['t_log'][0]) / rate
    assert np.percentile(np.abs(lag), 95) < 0.15
    if clock is not None:
        # /clock on the messages' time base (their header stamps, 1000 s + i / 200 Hz here;
        # not the recording's wall-clock log times): never going back, from the first to the
        # last stamp, each value a stamp of the bag, at about 50 Hz of wall time while the bag
        # plays at rate 2.
        stamps = np.round(arr['t'] * NS_PER_S).astype(np.int64)
        assert np.all(np.diff(clock) >= 0)
        assert clock[0] == stamps[0] and clock[-1] == stamps[-1]
        assert set(clock.tolist()) <= set(stamps.tolist())
        expected = clock_hz * bag_span / rate
        assert abs(len(clock) - expected) < 0.3 * expected + 3


def test_wait_for_subscribers_skips_topics_without_messages(recorded: pathlib.Path,
                                                           ros_env: dict[str, str],
                                                           tmp_path: pathlib.Path) -> None:
    """A bag with a declared topic that holds no message (a recording with no depth command)
    replays once the topics with messages have subscribers: nobody needs to listen to
    ``/auv/depth_command`` here."""
    from auv_bag import BagWriter

    bag = tmp_path / 'with_empty_topic'
    with BagWriter(bag) as out:
        out.add_topic('/auv/depth_command', 'std_msgs/msg/Float64')
        out.add_topic(STATE, 'auv_msgs/msg/VehicleState')
        for m in read_messages(recorded, [STATE], decode=False):
            out.write(STATE, m.data, m.log_time)
    got, _ = _play(ros_env, bag, rate=4.0)
    assert len(got) == N


def test_play_bad_bag_is_one_line_error(ros_env: dict[str, str],
                                        tmp_path: pathlib.Path) -> None:
    bad = tmp_path / 'bad.mcap'
    bad.write_bytes(b'\x89MCAP0\r\n' + b'\x01' * 40)
    res = subprocess.run(_auv('play', str(bad)), env=ros_env, capture_output=True, text=True,
                         timeout=30)
    assert res.returncode == 1
    assert res.stderr.count('\n') == 1 and res.stderr.startswith(f'error: bag {bad} is ')
    res = subprocess.run(_auv('play', str(tmp_path), '--rate', '0'), env=ros_env,
                         capture_output=True, text=True, timeout=30)
    assert res.returncode == 1 and res.stderr == 'error: --rate must be a positive number, ' \
                                                 'got 0.0\n'



def test_record_bad_await_option_is_one_line_error(ros_env: dict[str, str],
                                                   tmp_path: pathlib.Path) -> None:
    res = subprocess.run(_auv('record', '--out', str(tmp_path / 'bag'), '--topics', 'state',
                              '--await-publishers', 'bar_command'),
                         env=ros_env, capture_output=True, text=True, timeout=30)
    assert res.returncode == 1 and res.stderr == ('error: --await-publishers bar_command: not '
                                                  'among the recorded --topics\n')
    assert not (tmp_path / 'bag').exists()

LISTENER = r'''
import faulthandler, importlib, json, sys, time
import rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy

topic, typename, expr, n, timeout = sys.argv[1:6]
faulthandler.dump_traceback_later(float(timeout) + 20.0, exit=True)  # a hang says where
last_value = eval(sys.argv[6]) if len(sys.argv) > 6 else None
module, name = typename.rsplit('.', 1)
cls = getattr(importlib.import_module(module), name)
rclpy.init()
node = rclpy.create_node('test_listener')
got = []
def on_message(m):
    got.append(eval(expr, {'m': m}))
node.create_subscription(cls, topic, on_message,
                         QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
print('ready', flush=True)
deadline = time.monotonic() + float(timeout)
while len(got) < int(n) and time.monotonic() < deadline:
    if got and last_value is not None and got[-1] == last_value:
        break
    rclpy.spin_once(node, timeout_sec=0.05)
print(json.dumps(got), flush=True)
rclpy.shutdown()
'''


def _listen(ros_env: dict[str, str], topic: str, typename: str, expr: str, n: int,
            timeout: float, last: str | None = None) -> subprocess.Popen[str]:
    """A listener process on ``topic`` that is subscribed when this returns; it prints the
    values of ``expr`` once it has ``n`` of them, has heard the value ``last`` (a Python
    literal), or ``timeout`` wall seconds have passed."""
    proc = subprocess.Popen([sys.executable, '-c', LISTENER, topic, typename, expr, str(n),
                             str(timeout), *([last] if last is not None else [])],
                            env=ros_env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    _wait_line(proc, 'ready', timeout=READY_S)
    return proc


def test_depth_command_is_delivered(ros_env: dict[str, str]) -> None:
    res = subprocess.run(_auv('depth', 'nan'), env=ros_env, capture_output=True, text=True,
                         timeout=30)
    assert res.returncode == 1
    assert res.stderr == 'error: depth must be a finite number (m), got nan\n'
    listener = _listen(ros_env, '/auv/depth_command', 'std_msgs.msg.Float64', 'm.data', 1,
                       LISTEN_S)
    try:
        # no depth pilot here: delivered (acknowledged), no answer awaited
        res = subprocess.run(_auv('depth', '12.5', '--no-answer'), env=ros_env,
                             capture_output=True, text=True, timeout=30)
        assert res.returncode == 0, res.stderr
        out, _ = listener.communicate(timeout=LISTEN_S + 30)
    finally:
        if listener.poll() is None:
            listener.kill()
            listener.communicate()
    assert json.loads(out.strip().splitlines()[-1]) == [12.5]


def test_recorder_progress_waits_for_every_stream_with_a_publisher(
        ros_env: dict[str, str], tmp_path: pathlib.Path) -> None:
    """``recorder/progress`` is the oldest of the paced streams' last written stamps, and it
    is not reported while a paced stream with a matched publisher has delivered nothing (its
    first sample may be on its way again): 60 states (more than the 50 after which the
    recorder reports) with a silent ``bar_command`` publisher give no report; one command
    stamped 10.2 s then gives 10.2 s, the older of the two last stamps."""
    import rclpy
    from builtin_interfaces.msg import Time
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rclpy.signals import SignalHandlerOptions

    from auv_msgs.msg import ActuatorSetpoint, VehicleState
    from auv_sim.node import PROGRESS_QOS, stamp_from_ns, stamp_to_ns

    context = Context()
    rclpy.init(context=context, domain_id=int(ros_env['ROS_DOMAIN_ID']),
               signal_handler_options=SignalHandlerOptions.NO)
    bag = tmp_path / 'bag'
    proc = subprocess.Popen(_auv('record', '--out', str(bag), '--topics', 'state', 'bar_command',
                                 '--await-publishers', 'bar_command'),
                            env=ros_env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            text=True)
    reports: list[int] = []
    try:
        node = rclpy.create_node('progress_probe', context=context)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        bar = node.create_publisher(ActuatorSetpoint, '/auv/bar_command', qos)
        state = node.create_publisher(VehicleState, '/auv/state', qos)
        progress = node.create_subscription(Time, '/auv/recorder/progress',
                                            lambda m: reports.append(stamp_to_ns(m)),
                                            PROGRESS_QOS)

        def spin_until(done: object, seconds: float) -> None:
            end = time.monotonic() + seconds
            while not done() and time.monotonic() < end:  # type: ignore[operator]
                assert proc.poll() is None, proc.stderr.read() if proc.stderr else ''
                executor.spin_once(timeout_sec=0.02)

        spin_until(lambda: (state.get_subscription_count() > 0 and bar.get_subscription_count()
                            > 0 and progress.get_publisher_count() > 0), READY_S)
        assert state.get_subscription_count() > 0 and progress.get_publisher_count() > 0
        for i in range(60):
            msg = VehicleState()
            msg.header.stamp = stamp_from_ns(10 * NS_PER_S + i * 10_000_000)
            state.publish(msg)
        spin_until(lambda: False, 1.5)
        assert reports == []
        cmd = ActuatorSetpoint()
        cmd.header.stamp = stamp_from_ns(10 * NS_PER_S + 200_000_000)
        bar.publish(cmd)
        spin_until(lambda: bool(reports), LISTEN_S)
        assert reports == [10 * NS_PER_S + 200_000_000]
    finally:
        context.try_shutdown()
        proc.send_signal(signal.SIGTERM)
        proc.wait(30)
    counts = {t: len(a) for t, a in read_arrays(bag, ['/auv/state', '/auv/bar_command']).items()}
    assert counts == {'/auv/state': 60, '/auv/bar_command': 1}
