"""The depth-pilot node in its own process, over DDS: fixed rate, bad input, stale state."""
from __future__ import annotations

import itertools
import math
import subprocess
import sys
import time
from typing import Any

import pytest
import rclpy
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64
from test_pilot_interfaces import DEADLINE_S, PilotProcess, set_remote_parameter

from auv_msgs.msg import ActuatorSetpoint, VehicleState


@pytest.fixture
def pilot_process(ros_env):  # type: ignore[no-untyped-def]
    pilot = PilotProcess(ros_env, '-p', 'state_timeout:=0.5')
    pilot.wait_ready()
    yield pilot
    pilot.stop()


def test_pilot_node_rate_bad_commands_and_stale_state(pilot_process) -> None:
    proc = pilot_process.proc
    rclpy.init()
    node = rclpy.create_node('pilot_probe')
    bars: list[tuple[float, float]] = []
    phase: list[tuple[int, int]] = []  # (header stamp, receipt) [ns, system clock]

    def on_bar(m: ActuatorSetpoint) -> None:
        bars.append((time.monotonic(), m.value))
        phase.append((m.header.stamp.sec * 10**9 + m.header.stamp.nanosec, time.time_ns()))
    node.create_subscription(ActuatorSetpoint, '/auv/bar_command', on_bar, 50)
    state_pub = node.create_publisher(VehicleState, '/auv/state', 50)
    depth_pub = node.create_publisher(Float64, '/auv/depth_command', QoSProfile(
        depth=1, reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL))

    def spin_for(seconds: float, publish_state: bool = True) -> None:
        end = time.monotonic() + seconds
        next_state = time.monotonic()
        while time.monotonic() < end:
            if publish_state and time.monotonic() >= next_state:
                msg = VehicleState()
                msg.z, msg.u, msg.theta, msg.w = 20.0, 2.0, 0.00689, 0.01377
                state_pub.publish(msg)
                next_state += 0.02
            rclpy.spin_once(node, timeout_sec=0.005)

    try:
        deadline = time.monotonic() + DEADLINE_S
        while not bars and time.monotonic() < deadline:
            spin_for(0.1)
        assert bars, 'the pilot published nothing'
        # fixed rate: ~10 Hz whether or not state arrives
        bars.clear()
        spin_for(2.0)
        periods = [b - a for (a, _), (b, _) in itertools.pairwise(bars)]
        assert 15 <= len(bars) <= 25
        assert abs(sorted(periods)[len(periods) // 2] - 0.1) < 0.02
        # output phase: stamped with the tick's instant (an exact 0.1 s grid), received no
        # earlier than the default publish delay (10 ms) after it
        stamps = [st for st, _ in phase[-len(bars):]]
        assert {b - a for a, b in itertools.pairwise(stamps)} == {100_000_000}
        assert min(rx - st for st, rx in phase[-len(bars):]) >= 10_000_000
        # a valid command, then NaN, inf and out-of-envelope commands: rejected, node alive
        depth_pub.publish(Float64(data=25.0))
        spin_for(1.0)
        for bad in (math.nan, math.inf, -3.0, 5000.0):
            depth_pub.publish(Float64(data=bad))
            spin_for(0.4)
        assert proc.poll() is None
        bars.clear()
        spin_for(1.0)
        assert bars and all(math.isfinite(v) for _, v in bars)
        # the vehicle at 20 m, commanded 25 m: the plane dives (BAR above trim, positive = dive)
        assert bars[-1][1] > -0.08367
        # stale state: the documented safe BAR, still at the fixed rate
        bars.clear()
        spin_for(3.0, publish_state=False)
        assert len(bars) >= 25
        # the safe BAR derived from the vehicle file (no safe_bar parameter given): 0.12/0.4363
        # of the A18M's 0.4363 rad plane travel to the nose-up side (negative: CMbar < 0)
        assert bars[-1][1] == pytest.approx(-0.12, abs=1e-9)
        # state returns: control resumes
        bars.clear()
        spin_for(2.0)
        assert bars[-1][1] != pytest.approx(-0.12, abs=1e-3)
    finally:
        node.destroy_node()
        rclpy.shutdown()
    pilot_process.stop()
    out = pilot_process.output
    assert 'depth command 25 m accepted' in out
    assert out.count('rejected: depth command') == 4, out
    assert 'not finite' in out and 'outside the depth envelope' in out
    assert 'publishing safe BAR' in out
    assert 'depth control active' in out


@pytest.mark.parametrize(('ros_args', 'needle'), [
    (['-p', 'vehicle_file:=/nonexistent/vehicle.yaml'], 'vehicle'),
    (['-p', 'rate:=-5.0'], 'rate'),
    (['-p', 'weights:=no_such_preset'], 'no_such_preset'),
    (['-p', 'theta_max:=0.0'], 'theta_max'),
    (['-p', 'publish_delay:=0.08'], 'publish_delay'),
    (['-p', 'realtime_priority:=150'], 'realtime_priority'),
    (['-p', 'start_subscribers:=-1'], 'start_subscribers'),
    (['-p', 'depth_max:=500.0'], 'depth_max = 500.0 m is outside the envelope [0, 300]'),
    (['-p', 'depth_min:=40.0', '-p', 'depth_max:=20.0'], 'must be below depth_max'),
    (['-p', 'depth_min:=shallow'], 'depth_min'),
    (['-p', 'depth_command_mode:=round'], 'depth_command_mode'),
    (['-p', 'state_source:=gps'], 'state_source'),
    (['-p', 'odom_frame:=enu'], 'odom_frame'),
    (['-p', 'state_reliability:=sometimes'], 'state_reliability'),
    (['-p', 'recovery_gain:=2.0'], 'gain'),
    (['-p', 'recovery_pitch_margin:=-1.0'], 'pitch_margin'),
    (['-p', 'diagnostics_period:=0.0'], 'diagnostics_period'),
])
def test_bad_parameter_at_start_exits_with_one_line_error(ros_env, ros_args: list[str],
                                                          needle: str) -> None:
    proc = subprocess.run([sys.executable, '-m', 'auv_depth_lqr.node', '--ros-args', *ros_args],
                          env=ros_env, capture_output=True, text=True, timeout=60, check=False)
    assert proc.returncode == 1, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith('error: ') and needle in lines[0], \
        proc.stderr


def _stamp_probe(name: str) -> tuple[Any, list[int]]:
    """rclpy initialised and a node ``name`` whose list gets the stamp [ns] of every
    ``/auv/bar_command`` it receives."""
    rclpy.init()
    node = rclpy.create_node(name)
    stamps: list[int] = []
    node.create_subscription(
        ActuatorSetpoint, '/auv/bar_command',
        lambda m: stamps.append(m.header.stamp.sec * 10**9 + m.header.stamp.nanosec), 50)
    return node, stamps


def test_parameter_changes_are_validated_and_applied(pilot_process) -> None:
    from rcl_interfaces.srv import SetParameters

    proc = pilot_process.proc
    node, stamps = _stamp_probe('pilot_param_probe')
    client = node.create_client(SetParameters, '/auv/depth_pilot/set_parameters')

    def set_parameter(name: str, value: object) -> tuple[bool, str]:
        return set_remote_parameter(node, client, name, value)

    def spin_for(seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.01)

    try:
        assert client.wait_for_service(timeout_sec=DEADLINE_S)
        for name, bad, needle in (('rate', 0.0, 'rate_hz'), ('weights', 'bogus', 'bogus'),
                                  ('publish_delay', 0.06, 'publish_delay'),
                                  ('vehicle_file', '/nonexistent.yaml', 'nonexistent'),
                                  ('water_speed', -1.0, 'water_speed'),
                                  ('realtime_priority', 10, 'at start only')):
            ok, reason = set_parameter(name, bad)
            assert not ok and needle in reason, (name, reason)
        assert proc.poll() is None
        # a valid change is applied: 5 Hz, so the stamps step by 0.2 s
        ok, reason = set_parameter('rate', 5.0)
        assert ok, reason
        spin_for(1.0)
        stamps.clear()
        spin_for(2.0)
        steps = {b - a for a, b in itertools.pairwise(stamps)}
        assert steps == {200_000_000}, steps
    finally:
        node.destroy_node()
        rclpy.shutdown()


def test_realtime_priority_moves_the_threads_to_sched_fifo_or_says_why_not(ros_env) -> None:
    """Where the process may (CAP_SYS_NICE or an rtprio limit) every thread of the node runs
    SCHED_FIFO at the priority; where it may not, one warning says so and the node runs."""
    import os
    proc = subprocess.Popen([sys.executable, '-m', 'auv_depth_lqr.node', '--ros-args',
                             '-p', 'realtime_priority:=7'], env=ros_env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        deadline = time.monotonic() + 30.0
        lines: list[str] = []
        while time.monotonic() < deadline:
            line = proc.stdout.readline() if proc.stdout else ''
            lines.append(line)
            if 'SCHED_FIFO' in line or 'not applied' in line:
                break
        text = ''.join(lines)
        if 'threads on SCHED_FIFO 7' in text:
            tasks = os.listdir(f'/proc/{proc.pid}/task')
            assert tasks and all(os.sched_getscheduler(int(t)) == os.SCHED_FIFO
                                 for t in tasks)
            assert all(os.sched_getparam(int(t)).sched_priority == 7 for t in tasks)
        else:
            assert 'realtime_priority 7 not applied' in text, text
        assert proc.poll() is None
    finally:
        proc.terminate()
        proc.wait(10)


def test_auv_pilot_takes_ros_arguments_as_the_docs_show(ros_env) -> None:
    """``auv pilot --ros-args -p depth_min:=2.0`` (docs/pilot-interfaces.md) starts the pilot
    with that envelope; a bad value is one line ``error: ...``, exit 1."""
    auv = [sys.executable, '-m', 'auv_bringup.cli', 'pilot']
    proc = subprocess.Popen([*auv, '--ros-args', '-p', 'depth_min:=2.0', '-p',
                             'depth_max:=80.0', '-p', 'depth_command_mode:=clamp'],
                            env=ros_env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True)
    try:
        assert proc.stdout is not None
        line = ''
        deadline = time.monotonic() + DEADLINE_S
        while 'depth envelope' not in line:
            assert time.monotonic() < deadline and proc.poll() is None, line
            line = proc.stdout.readline()
        assert 'depth envelope [2, 80] m (clamp outside)' in line, line
    finally:
        proc.terminate()
        proc.wait(30)
    assert proc.returncode == 0
    bad = subprocess.run([*auv, '--ros-args', '-p', 'depth_min:=500.0'], env=ros_env,
                         capture_output=True, text=True, timeout=DEADLINE_S)
    assert bad.returncode == 1
    assert bad.stderr.count('\n') == 1 and bad.stderr.startswith('error: '), bad.stderr
    assert 'depth_min' in bad.stderr


def test_first_state_is_answered_at_once(ros_env) -> None:
    """On simulated time with no ``/clock`` yet the timer never fires (ROS time stays 0): the
    one command that comes is the answer to the first state, stamped with its stamp."""
    pilot = PilotProcess(ros_env, '-p', 'use_sim_time:=true')
    pilot.wait_ready()
    node, stamps = _stamp_probe('first_state_probe')
    state_pub = node.create_publisher(VehicleState, '/auv/state', 50)
    try:
        deadline = time.monotonic() + DEADLINE_S
        while state_pub.get_subscription_count() == 0 or node.count_publishers(
                '/auv/bar_command') == 0:
            assert time.monotonic() < deadline, 'the pilot did not match the probe'
            rclpy.spin_once(node, timeout_sec=0.05)
        time.sleep(0.5)  # the pilot's bar_command publisher matches the probe's subscription
        for k in range(25):  # 0.5 s of states stamped 5.00, 5.02, ... s, no /clock
            msg = VehicleState()
            msg.header.stamp.sec, msg.header.stamp.nanosec = 5, 20_000_000 * k
            msg.z, msg.u, msg.theta, msg.w = 20.0, 2.0, 0.00689, 0.01377
            state_pub.publish(msg)
            end = time.monotonic() + 0.02
            while time.monotonic() < end:
                rclpy.spin_once(node, timeout_sec=0.005)
        end = time.monotonic() + 1.0
        while time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.05)
        assert stamps == [5_000_000_000], pilot.output
    finally:
        node.destroy_node()
        rclpy.shutdown()
        pilot.stop()
