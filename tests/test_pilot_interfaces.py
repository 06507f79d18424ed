"""The depth pilot's interfaces to a real vehicle, over DDS with the pilot in its own process:
commands from publishers of any QoS, the depth envelope, /diagnostics and the recovery mode,
state from nav_msgs/Odometry, remapping."""
from __future__ import annotations

import math
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64

from auv_msgs.msg import ActuatorSetpoint, VehicleState
from auv_sim.frames import state_to_odometry

LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
BEST_EFFORT = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
#: Deadline of every wait [s]: a safety net, not a timing check. Each awaited event comes well
#: within a second on an idle machine; on a 2-core machine at load 20 a node's start-up alone
#: can take tens of seconds.
DEADLINE_S = 120.0
#: The pilot node's last start-up line (logged once its subscriptions and timers exist).
READY_LINE = 'deg pitch limit, depth envelope'
#: A user's script: a default-QoS publisher, one command once a subscriber matches.
USER_SCRIPT = '''
import time
import rclpy
from rclpy.duration import Duration
from std_msgs.msg import Float64
rclpy.init()
node = rclpy.create_node('user_script')
pub = node.create_publisher(Float64, '/auv/depth_command', 10)
end = time.monotonic() + 30.0
while pub.get_subscription_count() < 1:
    assert time.monotonic() < end, 'no subscriber'
    time.sleep(0.05)
pub.publish(Float64(data=12.0))
assert pub.wait_for_all_acked(Duration(seconds=10.0))
node.destroy_node()
rclpy.shutdown()
'''


class PilotProcess:
    """A pilot node process whose output lines are collected as they come."""

    def __init__(self, env: dict[str, str], *ros_args: str) -> None:
        self.proc = subprocess.Popen([sys.executable, '-m', 'auv_depth_lqr.node', '--ros-args',
                                      *ros_args], env=env, stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT, text=True)
        self.lines: list[str] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def wait_ready(self, timeout: float = DEADLINE_S) -> None:
        """Wait for the node's start-up line; fail with its output if it exits or is late."""
        end = time.monotonic() + timeout
        while self.count(READY_LINE) == 0:
            if self.proc.poll() is not None:
                self._reader.join(5)
                pytest.fail(f'the pilot exited ({self.proc.returncode}): {self.output}')
            if time.monotonic() > end:
                pytest.fail(f'the pilot did not start within {timeout} s: {self.output}')
            time.sleep(0.05)

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.append(line)

    @property
    def output(self) -> str:
        return ''.join(self.lines)

    def count(self, text: str) -> int:
        return sum(text in line for line in list(self.lines))

    def stop(self) -> None:
        self.proc.terminate()
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(5)
        self._reader.join(5)


@pytest.fixture
def probe(ros_env) -> Iterator[Node]:  # type: ignore[no-untyped-def]
    rclpy.init()
    node = rclpy.create_node('interfaces_probe')
    try:
        yield node
    finally:
        node.destroy_node()
        rclpy.shutdown()


def spin_until(node: Node, done: Callable[[], bool], timeout: float, what: str,
               every: Callable[[], None] | None = None) -> None:
    """Spin ``node`` until ``done()`` (calling ``every()`` each 0.05 s), at most ``timeout``
    s; fail naming ``what``."""
    end = time.monotonic() + timeout
    next_call = time.monotonic()
    while not done():
        if time.monotonic() > end:
            pytest.fail(f'{what} not within {timeout} s')
        if every is not None and time.monotonic() >= next_call:
            every()
            next_call = time.monotonic() + 0.05
        rclpy.spin_once(node, timeout_sec=0.01)


def level_state(theta: float = 0.00689) -> VehicleState:
    """The A18M near trim at 20 m, 2 m/s (NED/FRD); with the trim pitch its depth rate is
    what its kinematics give (0 m/s)."""
    msg = VehicleState()
    msg.z, msg.u, msg.theta = 20.0, 2.0, theta
    msg.w = 2.0 * math.tan(theta)  # z_dot = -u sin(theta) + w cos(theta) = 0
    return msg


def test_commands_from_latched_default_and_best_effort_publishers(ros_env, probe) -> None:
    # a latched command sent before the pilot starts reaches it (late joiner)
    latched = probe.create_publisher(Float64, '/auv/depth_command', LATCHED)
    latched.publish(Float64(data=22.0))
    pilot = PilotProcess(ros_env, '-p', 'state_timeout:=5.0')
    try:
        spin_until(probe, lambda: pilot.count('depth command 22 m accepted') > 0, DEADLINE_S,
                   'the latched command')
        # a plain script: default QoS (reliable, volatile, keep last 10), as a new user writes
        plain = probe.create_publisher(Float64, '/auv/depth_command', 10)
        spin_until(probe, lambda: plain.get_subscription_count() >= 1, DEADLINE_S, 'matching')
        plain.publish(Float64(data=15.0))
        spin_until(probe, lambda: pilot.count('depth command 15 m accepted') > 0, DEADLINE_S,
                   'the default-QoS command')
        # the same from a user's script in its own process
        script = subprocess.run([sys.executable, '-c', USER_SCRIPT], env=ros_env,
                                capture_output=True, text=True, timeout=60)
        assert script.returncode == 0, script.stderr
        spin_until(probe, lambda: pilot.count('depth command 12 m accepted') > 0, DEADLINE_S,
                   "the user script's command")
        # a best-effort publisher (sent again until it arrives: best effort may drop)
        quick = probe.create_publisher(Float64, '/auv/depth_command', BEST_EFFORT)
        spin_until(probe, lambda: pilot.count('depth command 18 m accepted') > 0, DEADLINE_S,
                   'the best-effort command', every=lambda: quick.publish(Float64(data=18.0)))
        # a best-effort state publisher does not match the reliable state subscription:
        # a warning says so and how to fix it
        state = probe.create_publisher(VehicleState, '/auv/state', BEST_EFFORT)
        spin_until(probe, lambda: pilot.count('state_reliability:=best_effort') > 0, DEADLINE_S,
                   'the state QoS warning', every=lambda: state.publish(level_state()))
        time.sleep(0.5)
        assert pilot.proc.poll() is None
    finally:
        pilot.stop()
    # each sample applied once although it arrives on two (default QoS) or three (latched)
    # of the pilot's subscriptions
    assert pilot.count('depth command 22 m accepted') == 1, pilot.output
    assert pilot.count('depth command 15 m accepted') == 1, pilot.output
    assert pilot.count('incompatible with every depth-command subscription') == 0
    # the false claim of earlier versions ("another subscription of the pilot receives its
    # commands", also for a command lost before the match) is gone
    assert pilot.count('another subscription of the pilot receives') == 0


def diagnostics_of(statuses: list[DiagnosticStatus]) -> dict[str, str]:
    return {kv.key: kv.value for kv in statuses[-1].values} if statuses else {}


def set_remote_parameter(node: Node, client: Any, name: str, value: object
                         ) -> tuple[bool, str]:
    """Set one parameter through a SetParameters ``client`` (deadline DEADLINE_S); returns
    (successful, reason)."""
    from rclpy.parameter import Parameter

    request = client.srv_type.Request()
    request.parameters = [Parameter(name, value=value).to_parameter_msg()]
    future = client.call_async(request)
    rclpy.spin_until_future_complete(node, future, timeout_sec=DEADLINE_S)
    assert future.done(), f'set_parameters {name} timed out'
    result = future.result().results[0]
    return result.successful, result.reason


def test_depth_envelope_refuses_or_clamps_over_dds(ros_env, probe) -> None:
    from rcl_interfaces.srv import SetParameters

    statuses: list[DiagnosticStatus] = []

    def on_diagnostics(msg: DiagnosticArray) -> None:
        statuses.extend(s for s in msg.status if s.name == '/auv/depth_pilot: depth control')

    probe.create_subscription(DiagnosticArray, '/diagnostics', on_diagnostics, 10)
    client = probe.create_client(SetParameters, '/auv/depth_pilot/set_parameters')
    commands = probe.create_publisher(Float64, '/auv/depth_command', 10)
    # an integer is a valid value of a number parameter
    pilot = PilotProcess(ros_env, '-p', 'depth_min:=5.0', '-p', 'depth_max:=50',
                         '-p', 'diagnostics_period:=0.2')

    def command(z: float, expect: str) -> None:
        before = pilot.count(expect)
        commands.publish(Float64(data=z))
        spin_until(probe, lambda: pilot.count(expect) > before, DEADLINE_S, f'{expect!r} for {z}')

    def set_parameter(name: str, value: object) -> tuple[bool, str]:
        return set_remote_parameter(probe, client, name, value)

    def diagnosed(**expected: str) -> None:
        """Spin until a diagnostics status carries ``expected`` (key: text in its value); one
        published before the pilot handled the last command may still be on its way."""
        def carries() -> bool:
            values = diagnostics_of(statuses)
            return all(text in values.get(key, '') for key, text in expected.items())
        spin_until(probe, carries, DEADLINE_S, f'diagnostics carrying {expected}')

    try:
        spin_until(probe, lambda: commands.get_subscription_count() >= 1, DEADLINE_S, 'matching')
        assert client.wait_for_service(timeout_sec=30.0)
        command(30.0, 'depth command 30 m accepted')
        for bad, needle in ((60.0, 'depth command 60 m is outside the depth envelope [5, 50]'),
                            (3.0, 'depth command 3 m is outside the depth envelope [5, 50]'),
                            (math.nan, 'depth command nan is not finite'),
                            (-math.inf, 'depth command -inf is not finite')):
            command(bad, needle)
        diagnosed(depth_command_m='30.000',
                  last_rejected_command='depth command -inf is not finite; kept 30.0 m')
        assert diagnostics_of(statuses)['depth_command_m'] == '30.000'
        ok, reason = set_parameter('depth_command_mode', 'clamp')
        assert ok, reason
        command(60.0, 'clamped to 50 m')
        diagnosed(depth_command_m='50.000')
        command(math.nan, 'depth command nan is not finite')  # never clamped
        diagnosed(last_rejected_command='depth command nan is not finite; kept 50.0 m')
        assert diagnostics_of(statuses)['depth_command_m'] == '50.000'
        # the envelope may not exclude the command in force, nor exceed the vehicle's
        ok, reason = set_parameter('depth_max', 40.0)
        assert not ok and 'outside the depth envelope [5, 40]' in reason, reason
        ok, reason = set_parameter('depth_max', 400.0)
        assert not ok and 'depth_max = 400.0 m is outside the envelope [0, 300]' in reason, \
            reason
        ok, reason = set_parameter('depth_command_mode', 'round')
        assert not ok and 'depth_command_mode' in reason, reason
        ok, reason = set_parameter('state_source', 'odometry')
        assert not ok and 'at start only' in reason, reason
        assert pilot.proc.poll() is None
    finally:
        pilot.stop()


def test_recovery_mode_on_diagnostics_and_back(ros_env, probe) -> None:
    statuses: list[DiagnosticStatus] = []
    authority: list[DiagnosticStatus] = []

    def on_diagnostics(msg: DiagnosticArray) -> None:
        statuses.extend(s for s in msg.status if s.name == '/auv/depth_pilot: depth control')
        authority.extend(s for s in msg.status if s.name == '/auv/depth_pilot: plane authority')

    probe.create_subscription(DiagnosticArray, '/diagnostics', on_diagnostics, 10)
    state = probe.create_publisher(VehicleState, '/auv/state', 50)
    pilot = PilotProcess(ros_env, '-p', 'recovery_resume_time:=1.0')
    pitch = [0.00689]
    try:
        spin_until(probe, lambda: state.get_subscription_count() >= 1, DEADLINE_S, 'matching')
        spin_until(probe, lambda: bool(statuses) and statuses[-1].level == DiagnosticStatus.OK,
                   DEADLINE_S, 'OK diagnostics in level flight',
                   every=lambda: state.publish(level_state(pitch[0])))
        # 40 deg nose up: beyond the 25 deg limit plus the 5 deg margin
        pitch[0] = math.radians(40.0)
        spin_until(probe, lambda: statuses[-1].level == DiagnosticStatus.WARN, DEADLINE_S,
                   'WARN diagnostics', every=lambda: state.publish(level_state(pitch[0])))
        # the plane authority goes with every depth-control status: the A18M's 25 deg travel,
        # its window derived from the hull (20 s); not judged after a few seconds of holding
        assert len(authority) == len(statuses), (len(authority), len(statuses))
        plane = diagnostics_of(authority)
        assert plane['bar_max_deg'] == '25.00' and plane['window_s'] == '20.0', plane
        assert plane['level'] == 'unknown' and authority[-1].level == DiagnosticStatus.OK
        assert 'not judged' in authority[-1].message
        warn = diagnostics_of(statuses)
        assert warn['mode'] == 'recovery' and warn['status'] == 'recovery'
        assert 'pitch 40.0 deg beyond 30.0 deg' in warn['reason']
        assert 'envelope left' in statuses[-1].message
        assert float(warn['pitch_deg']) == pytest.approx(40.0, abs=0.01)
        # level again: after the residual window (2 s) and the resume time (1 s), OK again
        pitch[0] = 0.00689
        spin_until(probe, lambda: statuses[-1].level == DiagnosticStatus.OK, DEADLINE_S,
                   'OK diagnostics after recovery',
                   every=lambda: state.publish(level_state(pitch[0])))
        back = diagnostics_of(statuses)
        assert back['mode'] == 'normal' and 'resumed' in back['reason']
    finally:
        pilot.stop()
    assert 'envelope left (pitch 40.0 deg' in pilot.output
    assert 'depth control resumed' in pilot.output


def test_odometry_input_gives_the_vehicle_state_commands_on_remapped_topics(
        ros_env, probe) -> None:
    """Two lockstep pilots: one on VehicleState in /vs, one on Odometry (ENU/FLU) with its
    topics remapped onto a vehicle's (/nav/odometry in, /fins/bar out); the same hand-made
    state sequence, stamped at the control instants, gives the same BAR commands (the pitch
    envelope selector off, as in ``tests/test_state_input.py``, and learning off: the
    hand-made sequence is no vehicle's motion, and the learned model would be nothing's)."""
    common = ['-p', 'lockstep:=true', '-p', 'recovery:=false', '-p', 'state_timeout:=5.0',
              '-p', 'pitch_envelope:=false', '-p', 'learn:=false']
    by_state = PilotProcess(ros_env, *common, '-r', '__ns:=/vs')
    by_odom = PilotProcess(ros_env, *common, '-p', 'state_source:=odometry',
                           '-r', 'odom:=/nav/odometry', '-r', 'bar_command:=/fins/bar')
    bars: dict[str, dict[int, float]] = {'state': {}, 'odom': {}}

    def keep(which: str) -> Callable[[ActuatorSetpoint], None]:
        def on_bar(m: ActuatorSetpoint) -> None:
            bars[which][m.header.stamp.sec * 10**9 + m.header.stamp.nanosec] = m.value
        return on_bar

    probe.create_subscription(ActuatorSetpoint, '/vs/bar_command', keep('state'), 100)
    probe.create_subscription(ActuatorSetpoint, '/fins/bar', keep('odom'), 100)
    state_pub = probe.create_publisher(VehicleState, '/vs/state', 100)
    odom_pub = probe.create_publisher(Odometry, '/nav/odometry', 100)
    commands = [probe.create_publisher(Float64, topic, LATCHED)
                for topic in ('/vs/depth_command', '/auv/depth_command')]
    try:
        for c in commands:
            c.publish(Float64(data=30.0))
        spin_until(probe, lambda: by_state.count('depth command 30 m accepted') == 1
                   and by_odom.count('depth command 30 m accepted') == 1
                   and state_pub.get_subscription_count() >= 1
                   and odom_pub.get_subscription_count() >= 1, DEADLINE_S, 'both pilots ready')
        assert 'state from /nav/odometry (enu_flu)' in by_odom.output
        for k in range(80):
            t = 0.1 * k
            theta = -0.15 * math.sin(0.2 * t)
            x = [2.0 * t, 0.1 * t, 20.0 + 0.3 * t - 0.01 * t * t, 0.02, theta, 0.4,
                 2.0 - 0.002 * t, 0.01, 0.05 * math.cos(0.3 * t), 0.0,
                 -0.03 * math.cos(0.2 * t), 0.0]
            stamp_ns = k * 100_000_000
            msg = VehicleState()
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 10**9)
            (msg.x, msg.y, msg.z, msg.phi, msg.theta, msg.psi,
             msg.u, msg.v, msg.w, msg.p, msg.q, msg.r) = x
            odom = Odometry()
            odom.header.stamp = msg.header.stamp
            o = state_to_odometry(x)
            pose, twist = odom.pose.pose, odom.twist.twist
            pose.position.x, pose.position.y, pose.position.z = map(float, o.position)
            (pose.orientation.x, pose.orientation.y, pose.orientation.z,
             pose.orientation.w) = map(float, o.orientation)
            twist.linear.x, twist.linear.y, twist.linear.z = map(float, o.linear)
            twist.angular.x, twist.angular.y, twist.angular.z = map(float, o.angular)
            state_pub.publish(msg)
            odom_pub.publish(odom)
            spin_until(probe, lambda s=stamp_ns: s in bars['state'] and s in bars['odom'],
                       DEADLINE_S, f'both answers to the state at {t:.1f} s')
    finally:
        by_state.stop()
        by_odom.stop()
    assert sorted(bars['state']) == sorted(bars['odom'])
    values = [bars['state'][s] for s in sorted(bars['state'])]
    assert len(values) == 80 and len(set(values)) > 40  # the pilot acted on the sequence
    assert max(abs(bars['state'][s] - bars['odom'][s]) for s in bars['state']) <= 1e-9


def test_lockstep_answers_states_stamped_in_floating_point(ros_env, probe) -> None:
    """A simulator that stamps ``Time(seconds=k * 0.02)`` is a nanosecond off some control
    instants (rclpy truncates 4.1e9 - 5e-7 to 4099999999 ns): the lockstep pilot answers every
    state within 1 us of an instant, with the state's own stamp, and no other state; a state
    5 us off an instant gets no answer and one warning."""
    from rclpy.time import Time

    pilot = PilotProcess(ros_env, '-p', 'lockstep:=true', '-p', 'state_timeout:=5.0')
    answers: dict[int, float] = {}
    probe.create_subscription(
        ActuatorSetpoint, '/auv/bar_command',
        lambda m: answers.__setitem__(m.header.stamp.sec * 10**9 + m.header.stamp.nanosec,
                                      m.value), 200)
    state_pub = probe.create_publisher(VehicleState, '/auv/state', 200)
    stamps = [Time(seconds=k * 0.02).nanoseconds for k in range(500)]  # 10 s at 50 Hz
    instants = [ns for k, ns in enumerate(stamps) if k % 5 == 0]
    # the case of the report: instants that float stamps miss by a nanosecond
    off = [ns for ns in instants if ns % 100_000_000]
    assert 4_099_999_999 in off and all(abs(ns % 100_000_000 - 50_000_000) > 49_999_000
                                        for ns in off), off
    try:
        pilot.wait_ready()
        spin_until(probe, lambda: state_pub.get_subscription_count() >= 1, DEADLINE_S,
                   'the state subscription')
        for ns in stamps:
            msg = level_state()
            msg.header.stamp = Time(nanoseconds=ns).to_msg()
            state_pub.publish(msg)
            if ns in instants:
                spin_until(probe, lambda s=ns: s in answers, DEADLINE_S,
                           f'the answer to the state at {ns} ns')
        near = 10 * 10**9 + 5_000  # 5 us after the instant of 10 s
        msg = level_state()
        msg.header.stamp = Time(nanoseconds=near).to_msg()
        state_pub.publish(msg)
        spin_until(probe, lambda: pilot.count('is near a control instant') > 0, DEADLINE_S,
                   'the near-miss warning')
        end = time.monotonic() + 1.0  # an answer, if one were sent, arrives meanwhile
        while time.monotonic() < end:
            rclpy.spin_once(probe, timeout_sec=0.05)
    finally:
        pilot.stop()
    assert sorted(answers) == instants
    assert near not in answers
    assert pilot.count('is near a control instant') == 1
