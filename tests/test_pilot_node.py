"""The depth-pilot node in its own process, over DDS: fixed rate, bad input, stale state."""
from __future__ import annotations

import itertools
import math
import subprocess
import sys
import time

import pytest
import rclpy
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64

from auv_depth_lqr.pilot import SAFE_BAR_DEFAULT
from auv_msgs.msg import ActuatorSetpoint, VehicleState


@pytest.fixture
def pilot_process(ros_env):  # type: ignore[no-untyped-def]
    proc = subprocess.Popen([sys.executable, '-m', 'auv_depth_lqr.node', '--ros-args',
                             '-p', 'state_timeout:=0.5'], env=ros_env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    yield proc, ros_env
    proc.terminate()
    try:
        proc.wait(10)
    except subprocess.TimeoutExpired:
        proc.kill()


def test_pilot_node_rate_bad_commands_and_stale_state(pilot_process) -> None:
    proc, _ = pilot_process
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
        deadline = time.monotonic() + 20
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
        assert bars[-1][1] == pytest.approx(SAFE_BAR_DEFAULT, abs=1e-9)
        # state returns: control resumes
        bars.clear()
        spin_for(2.0)
        assert bars[-1][1] != pytest.approx(SAFE_BAR_DEFAULT, abs=1e-6)
    finally:
        node.destroy_node()
        rclpy.shutdown()
    proc.terminate()
    out, _ = proc.communicate(timeout=10)
    assert 'depth command 25 m accepted' in out
    assert out.count('rejected: depth command') == 4, out
    assert 'not finite' in out and 'outside the vehicle envelope' in out
    assert 'publishing safe BAR' in out
    assert 'depth control active' in out
