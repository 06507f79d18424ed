"""The simulator node in its own process, over DDS: commands in, state as the offline model says.

The test process plays the depth pilot's side of the lockstep protocol (see auv_sim.node): it
answers every state stamped at a control instant with a BAR command carrying that stamp. The
run is then deterministic, so the node's states must equal an offline Simulator driven with the
same commands at the same instants, exactly. Two of the answers are invalid (NaN, beyond the
plane limit): the node must log their rejection and keep the last valid command, which the
exact comparison checks.
"""
from __future__ import annotations

import math
import pathlib
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pytest
import rclpy
from nav_msgs.msg import Odometry
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock

from auv_msgs.msg import ActuatorSetpoint, HydrodynamicForces, VehicleState
from auv_sim import frames
from auv_sim.node import stamp_from_ns, stamp_to_ns
from auv_sim.sim_settings import SimSettings, build_setup

ROOT = pathlib.Path(__file__).resolve().parents[1]
CONTROL_PERIOD = 0.1      # s
T_END = 12.0              # s of simulated time compared
NS = 1_000_000_000
QOS = QoSProfile(depth=200, reliability=ReliabilityPolicy.RELIABLE)


def bar_schedule(t: float, trim_bar: float) -> float:
    """The BAR command [rad] the test answers at control instant t [s] (two invalid ones)."""
    if abs(t - 2.0) < 1e-9:
        return math.nan                  # rejected: not finite
    if abs(t - 3.0) < 1e-9:
        return 1.0                       # rejected: beyond bar_max = 0.4363 rad
    if t < 1.0 - 1e-9:
        return trim_bar
    if t < 6.0 - 1e-9:
        return trim_bar + 0.15           # planes trailing edge down -> nose down, dives
    return trim_bar - 0.10


def offline(settings: SimSettings, t_end: float) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """Measured state (15) and wrenches (4 x 6) at every publish instant [ns], offline."""
    setup = build_setup(settings)
    sim = setup.simulator()
    trim_bar = float(setup.x0[12])
    out: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    lo, hi = sim.limits('bar')
    while sim.t <= t_end + 1e-9:
        k = sim.k
        out[setup.stamp_ns(k)] = (sim.measured_state(), sim.wrenches())
        if k % setup.steps_per_control == 0:
            value = bar_schedule(k * setup.dt, trim_bar)
            if math.isfinite(value) and lo <= value <= hi:   # what the node keeps
                sim.command('bar', value)
        sim.step(setup.steps_per_publish)
    return out


@pytest.fixture
def rclpy_context(ros_env: dict[str, str]) -> Iterator[tuple[Context, dict[str, str]]]:
    context = Context()
    rclpy.init(context=context, domain_id=int(ros_env['ROS_DOMAIN_ID']),
               signal_handler_options=SignalHandlerOptions.NO)
    try:
        yield context, ros_env
    finally:
        context.try_shutdown()


def probe(context: Context, name: str) -> tuple[Node, SingleThreadedExecutor]:
    """The test's own node ``name`` in ``context`` and an executor spinning it."""
    node = Node(name, context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    return node, executor


def start_node(env: dict[str, str], args: list[str], log: pathlib.Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, '-m', 'auv_sim.node', *args], cwd=ROOT, env=env,
                            stdout=subprocess.DEVNULL, stderr=log.open('w'))


def answer_until_exit(proc: subprocess.Popen, log: pathlib.Path, node: Node,
                      executor: SingleThreadedExecutor, bar_pub: Any, pending: list[int],
                      stamp_of: Callable[[int], Any], value: float, timeout: float) -> list[int]:
    """Play the pilot's side of lockstep until the simulator exits: answer each control
    instant in ``pending`` [ns] (filled by a state subscription) with a BAR command of
    ``value`` [rad] stamped ``stamp_of(instant)``; returns the stamps sent [ns]. Ends the
    simulator if it is still running at ``timeout`` (wall s), and ``node``."""
    answered = []
    deadline = time.monotonic() + timeout
    try:
        while proc.poll() is None:
            assert time.monotonic() < deadline, log.read_text()
            executor.spin_once(timeout_sec=0.01)
            if pending and bar_pub.get_subscription_count() > 0:
                for ns in pending:
                    msg = ActuatorSetpoint()
                    msg.header.stamp = stamp_of(ns)
                    msg.value = value
                    bar_pub.publish(msg)
                    answered.append(stamp_to_ns(msg.header.stamp))
                pending.clear()
    finally:
        if proc.poll() is None:
            proc.terminate()
            proc.wait(10)
        executor.shutdown(timeout_sec=0.0)
        node.destroy_node()
    return answered


def test_lockstep_bar_commands_move_depth_and_pitch_as_offline(
        rclpy_context: tuple[Context, dict[str, str]], tmp_path: pathlib.Path) -> None:
    context, env = rclpy_context
    settings = SimSettings(lockstep=True, real_time_factor=0.0, control_period=CONTROL_PERIOD,
                           lockstep_timeout=10.0, lockstep_startup_timeout=30.0)
    trim_bar = float(build_setup(settings).x0[12])
    log = tmp_path / 'node.log'
    proc = start_node(env, ['--lockstep', '--real-time-factor', '0', '--control-period',
                            str(CONTROL_PERIOD), '--lockstep-timeout', '10',
                            '--lockstep-startup-timeout', '30'], log)
    node, executor = probe(context, 'sim_node_test')
    states: dict[int, VehicleState] = {}
    odoms: dict[int, Odometry] = {}
    forces: dict[int, HydrodynamicForces] = {}
    clocks: list[int] = []
    pending: list[int] = []
    ctrl_ns = round(CONTROL_PERIOD * NS)

    def on_state(msg: VehicleState) -> None:
        ns = stamp_to_ns(msg.header.stamp)
        states[ns] = msg
        if ns % ctrl_ns == 0:
            pending.append(ns)

    node.create_subscription(VehicleState, '/auv/state', on_state, QOS)
    node.create_subscription(Odometry, '/auv/odom',
                             lambda m: odoms.__setitem__(stamp_to_ns(m.header.stamp), m), QOS)
    node.create_subscription(HydrodynamicForces, '/auv/hydrodynamic_forces',
                             lambda m: forces.__setitem__(stamp_to_ns(m.header.stamp), m), QOS)
    node.create_subscription(Clock, '/clock', lambda m: clocks.append(stamp_to_ns(m.clock)),
                             QOS)
    bar_pub = node.create_publisher(ActuatorSetpoint, '/auv/bar_command', QOS)
    end_ns = round(T_END * NS)
    try:
        deadline = time.monotonic() + 40.0
        while max(states, default=-1) < end_ns:
            assert time.monotonic() < deadline, f'no state beyond {max(states, default=-1)} ns'
            assert proc.poll() is None, log.read_text()
            executor.spin_once(timeout_sec=0.05)
            if pending and bar_pub.get_subscription_count() > 0:
                for ns in pending:
                    msg = ActuatorSetpoint()
                    msg.header.stamp = stamp_from_ns(ns)
                    msg.value = bar_schedule(ns / NS, trim_bar)
                    bar_pub.publish(msg)
                pending.clear()
        for _ in range(20):   # the forces and odometry of the last instants
            executor.spin_once(timeout_sec=0.01)
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            returncode = proc.wait(timeout=15.0)
        except subprocess.TimeoutExpired:
            proc.kill()
            raise
        executor.shutdown(timeout_sec=0.0)
        node.destroy_node()
    assert returncode == 0, log.read_text()

    expected = offline(settings, T_END)
    stamps = sorted(ns for ns in expected if ns <= end_ns)
    assert set(stamps) <= set(states), 'a state of the lockstep run is missing'
    got = np.array([[getattr(states[ns], f) for f in
                     ('x', 'y', 'z', 'phi', 'theta', 'psi', 'u', 'v', 'w', 'p', 'q', 'r')]
                    for ns in stamps])
    want = np.array([expected[ns][0][:12] for ns in stamps])
    np.testing.assert_array_equal(got, want)          # bit for bit: same inputs, same numbers
    z, theta = got[:, 2], got[:, 4]
    assert z.max() - z[0] > 0.5, 'BAR step did not change the depth'
    assert theta.min() < theta[0] - 0.05, 'BAR step did not pitch the nose down'

    # forces: same stamps as the state, the offline breakdown
    for ns in stamps[::25]:
        f = forces[ns]
        rows = [f.hydrodynamic, f.coriolis, f.restoring, f.actuators]
        got_w = [[w.force.x, w.force.y, w.force.z, w.torque.x, w.torque.y, w.torque.z]
                 for w in rows]
        np.testing.assert_array_equal(got_w, expected[ns][1])
    # odometry: the same state in ENU/FLU
    for ns in stamps[::25]:
        o = odoms[ns]
        assert (o.header.frame_id, o.child_frame_id) == ('odom', 'base_link')
        back = frames.odometry_to_state(frames.Odometry(
            position=np.array([o.pose.pose.position.x, o.pose.pose.position.y,
                               o.pose.pose.position.z]),
            orientation=np.array([o.pose.pose.orientation.x, o.pose.pose.orientation.y,
                                  o.pose.pose.orientation.z, o.pose.pose.orientation.w]),
            linear=np.array([o.twist.twist.linear.x, o.twist.twist.linear.y,
                             o.twist.twist.linear.z]),
            angular=np.array([o.twist.twist.angular.x, o.twist.twist.angular.y,
                              o.twist.twist.angular.z])))
        np.testing.assert_allclose(back, expected[ns][0][:12], atol=1e-9)
    assert clocks and set(clocks) <= set(states)       # /clock on simulated time

    text = log.read_text()
    rejected = [line for line in text.splitlines() if 'rejected bar command' in line]
    assert len(rejected) == 2, text
    assert 'nan' in rejected[0] and 'not finite' in rejected[0]
    assert 'outside' in rejected[1]


@pytest.mark.parametrize('ros_args, needle', [
    (['-p', 'vehicle_file:=/nonexistent/vehicle.yaml'], 'vehicle_file'),
    (['-p', 'publish_rate:=-5.0'], 'publish_rate'),
])
def test_bad_parameter_exits_with_one_line_error(ros_env: dict[str, str], ros_args: list[str],
                                                 needle: str) -> None:
    proc = subprocess.run([sys.executable, '-m', 'auv_sim.node', '--ros-args', *ros_args],
                          cwd=ROOT, env=ros_env, capture_output=True, text=True, timeout=60,
                          check=False)
    assert proc.returncode == 1
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith('error: ') and needle in lines[0], \
        proc.stderr


def sim_rate(executor: SingleThreadedExecutor, clocks: list[tuple[float, int]],
             duration: float) -> float:
    """Simulated seconds per wall second seen on /clock over ``duration`` wall seconds."""
    clocks.clear()
    end = time.monotonic() + duration
    while time.monotonic() < end:
        executor.spin_once(timeout_sec=0.02)
    assert len(clocks) > 10
    (w0, s0), (w1, s1) = clocks[0], clocks[-1]
    return (s1 - s0) / NS / (w1 - w0)


def test_real_time_pacing_and_parameter_changes(
        rclpy_context: tuple[Context, dict[str, str]], tmp_path: pathlib.Path) -> None:
    from rcl_interfaces.srv import DescribeParameters, GetParameters, SetParameters
    from rclpy.parameter import Parameter, parameter_value_to_python

    context, env = rclpy_context
    log = tmp_path / 'node.log'
    proc = start_node(env, ['--real-time-factor', '1'], log)
    node, executor = probe(context, 'sim_param_test')
    clocks: list[tuple[float, int]] = []
    node.create_subscription(Clock, '/clock',
                             lambda m: clocks.append((time.monotonic(), stamp_to_ns(m.clock))),
                             QOS)
    client = node.create_client(SetParameters, '/auv/simulator/set_parameters')
    describe = node.create_client(DescribeParameters, '/auv/simulator/describe_parameters')
    get = node.create_client(GetParameters, '/auv/simulator/get_parameters')

    def call(service: Any, request: Any) -> Any:
        future = service.call_async(request)
        executor.spin_until_future_complete(future, timeout_sec=10.0)
        assert future.done(), f'{service.srv_name} timed out'
        return future.result()

    def set_parameter(name: str, value: object) -> tuple[bool, str]:
        request = SetParameters.Request()
        request.parameters = [Parameter(name, value=value).to_parameter_msg()]
        result = call(client, request).results[0]
        return result.successful, result.reason

    def value(name: str) -> object:
        answer = call(get, GetParameters.Request(names=[name]))
        return parameter_value_to_python(answer.values[0])

    try:
        for service in (client, describe, get):
            assert service.wait_for_service(timeout_sec=30.0), log.read_text()
        rate_d, pitch_d = call(describe, DescribeParameters.Request(
            names=['publish_rate', 'initial_pitch'])).descriptors
        assert '[Hz' in rate_d.description and 'in (0, inf)' in rate_d.additional_constraints
        assert [(r.from_value, r.to_value) for r in rate_d.floating_point_range] \
            == [(0.0, math.inf)]
        assert '[rad]' in pitch_d.description
        assert 'applied at start only' in pitch_d.additional_constraints
        assert [(r.from_value, r.to_value) for r in pitch_d.floating_point_range] \
            == [(-math.pi / 2, math.pi / 2)]
        deadline = time.monotonic() + 30.0
        while not clocks:
            assert time.monotonic() < deadline and proc.poll() is None, log.read_text()
            executor.spin_once(timeout_sec=0.05)
        # margins that hold on a busy 2-core machine; factors 1 and 4 stay far apart
        assert sim_rate(executor, clocks, 3.0) == pytest.approx(1.0, rel=0.25)

        ok, reason = set_parameter('publish_rate', -1.0)     # ROS, on the declared range
        assert not ok and 'publish_rate' in reason and 'out of range' in reason
        ok, reason = set_parameter('publish_rate', 0.0)      # the node: the open bound
        assert not ok and 'publish_rate' in reason and '> 0' in reason
        ok, reason = set_parameter('publish_rate', 30.0)     # not a whole number of steps
        assert not ok and 'whole multiple' in reason
        assert value('publish_rate') == 50.0
        assert 'parameters changed' not in log.read_text()
        ok, reason = set_parameter('publish_rate', 25.0)
        assert ok, reason
        assert value('publish_rate') == 25.0
        ok, reason = set_parameter('vehicle_file', 'config/other.yaml')
        assert not ok and 'cannot change while the simulator runs' in reason
        ok, reason = set_parameter('real_time_factor', 4.0)
        assert ok, reason
        assert sim_rate(executor, clocks, 3.0) == pytest.approx(4.0, rel=0.25)
        assert proc.poll() is None
    finally:
        proc.send_signal(signal.SIGTERM)
        try:
            returncode = proc.wait(timeout=15.0)
        except subprocess.TimeoutExpired:
            proc.kill()
            raise
        executor.shutdown(timeout_sec=0.0)
        node.destroy_node()
    assert returncode == 0, log.read_text()


def test_as_fast_as_possible_the_simulator_keeps_pace_with_a_recorder(
        rclpy_context: tuple[Context, dict[str, str]], tmp_path: pathlib.Path) -> None:
    """A publisher on /auv/recorder/progress holds the run within half the output history
    (500 samples = 10 s at 50 Hz) of the last stamp it reports; without reports for 5 wall s
    the simulator says so and runs on."""
    from builtin_interfaces.msg import Time

    context, env = rclpy_context
    log = tmp_path / 'node.log'
    node, executor = probe(context, 'sim_pacing_test')
    clocks: list[int] = []
    progress = node.create_publisher(Time, '/auv/recorder/progress', 10)
    node.create_subscription(Clock, '/clock', lambda m: clocks.append(stamp_to_ns(m.clock)),
                             QOS)
    for kind, topic in ((VehicleState, '/auv/state'), (Odometry, '/auv/odom'),
                        (HydrodynamicForces, '/auv/hydrodynamic_forces')):
        node.create_subscription(kind, topic, lambda m: None, QOS)
    # the run starts once this probe (its progress publisher first) is matched
    proc = start_node(env, ['--real-time-factor', '0', '--stop-time', '60',
                            '--start-subscribers', '1'], log)

    def spin_for(seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            executor.spin_once(timeout_sec=0.01)

    def spin_until(t_ns: int, timeout: float = 30.0) -> None:
        deadline = time.monotonic() + timeout
        while not clocks or max(clocks) < t_ns:
            assert time.monotonic() < deadline and proc.poll() is None, log.read_text()
            spin_for(0.05)

    try:
        # no report yet: held at 10 s of simulated time (alone it reaches 60 s in ~0.3 wall s)
        spin_until(10 * NS)
        spin_for(1.0)
        assert max(clocks) == 10 * NS, max(clocks) / NS
        progress.publish(Time(sec=25, nanosec=0))
        spin_until(35 * NS)
        spin_for(1.0)
        assert max(clocks) == 35 * NS, max(clocks) / NS
        # no further report: within 5 s the simulator gives up waiting and runs on to its
        # stop time (its last /clock samples may be lost as it exits: its log says where)
        assert proc.wait(30.0) == 0
    finally:
        node.destroy_node()
        if proc.poll() is None:
            proc.terminate()
            proc.wait(10)
    text = log.read_text()
    assert 'recorder pacing: no progress within 5.0 s at t = 35.00 s' in text
    assert 'stopped at t = 60.000 s' in text, text


def test_lockstep_answer_given_while_the_simulator_waits_for_a_recorder_is_taken(
        rclpy_context: tuple[Context, dict[str, str]], tmp_path: pathlib.Path) -> None:
    """Lockstep and recorder pacing at once: a recorder (here a progress publisher that never
    reports) holds the run at 10 s of simulated time, and the pilot's answer to the state of
    t = 10 s arrives while the simulator waits for that recorder. The answer is taken: no
    command is ignored, none is waited for in vain, and the run goes on to its stop time once
    the simulator stops waiting for the recorder."""
    from builtin_interfaces.msg import Time

    context, env = rclpy_context
    log = tmp_path / 'node.log'
    node, executor = probe(context, 'sim_lockstep_pacing_test')
    node.create_publisher(Time, '/auv/recorder/progress', 10)
    ctrl_ns = round(CONTROL_PERIOD * NS)
    pending: list[int] = []

    def on_state(msg: VehicleState) -> None:
        ns = stamp_to_ns(msg.header.stamp)
        if ns % ctrl_ns == 0:
            pending.append(ns)

    node.create_subscription(VehicleState, '/auv/state', on_state, QOS)
    for kind, topic in ((Odometry, '/auv/odom'),
                        (HydrodynamicForces, '/auv/hydrodynamic_forces')):
        node.create_subscription(kind, topic, lambda m: None, QOS)
    bar_pub = node.create_publisher(ActuatorSetpoint, '/auv/bar_command', QOS)
    trim_bar = float(build_setup(SimSettings()).x0[12])
    proc = start_node(env, ['--lockstep', '--real-time-factor', '0', '--control-period',
                            str(CONTROL_PERIOD), '--lockstep-timeout', '10',
                            '--lockstep-startup-timeout', '30', '--stop-time', '12',
                            '--start-subscribers', '1'], log)
    answered = answer_until_exit(proc, log, node, executor, bar_pub, pending, stamp_from_ns,
                                 trim_bar, 60.0)
    text = log.read_text()
    assert proc.returncode == 0, text
    assert 10 * NS in answered
    assert 'recorder pacing: no progress within 5.0 s at t = 10.00 s' in text, text
    assert 'ignored bar command' not in text and 'no bar command stamped' not in text, text
    assert 'stopped at t = 12.000 s' in text, text


def test_lockstep_takes_answers_stamped_in_floating_point_and_reports(
        rclpy_context: tuple[Context, dict[str, str]], tmp_path: pathlib.Path) -> None:
    """A controller that stamps its answers in floating point on the 50 Hz grid,
    ``Time(seconds=j * 0.02)``, is a nanosecond off some instants (4.1 s is 4099999999 ns):
    each answer still releases the simulator at its instant. The report written at exit counts
    what was published and no missed instant."""
    import json

    from rclpy.time import Time

    context, env = rclpy_context
    log = tmp_path / 'node.log'
    report = tmp_path / 'report.json'
    node, executor = probe(context, 'sim_float_stamps_test')
    pending: list[int] = []

    def on_state(msg: VehicleState) -> None:
        ns = stamp_to_ns(msg.header.stamp)
        if ns % round(CONTROL_PERIOD * NS) == 0:
            pending.append(ns)

    node.create_subscription(VehicleState, '/auv/state', on_state, QOS)
    bar_pub = node.create_publisher(ActuatorSetpoint, '/auv/bar_command', QOS)
    trim_bar = float(build_setup(SimSettings()).x0[12])
    proc = start_node(env, ['--lockstep', '--real-time-factor', '0', '--control-period',
                            str(CONTROL_PERIOD), '--lockstep-timeout', '30',
                            '--lockstep-startup-timeout', '60', '--stop-time', '9',
                            '--report-file', str(report)], log)
    # the instant k * 0.1 s stamped as the 50 Hz sample 5 k, in floating point
    answered = answer_until_exit(
        proc, log, node, executor, bar_pub, pending,
        lambda ns: Time(seconds=5 * round(ns / (CONTROL_PERIOD * NS)) * 0.02).to_msg(),
        trim_bar, 120.0)
    text = log.read_text()
    assert proc.returncode == 0, text
    early = [ns for ns in answered if ns % round(CONTROL_PERIOD * NS)]  # a nanosecond off
    assert early and all(ns % round(CONTROL_PERIOD * NS) == round(CONTROL_PERIOD * NS) - 1
                         for ns in early), early
    assert len(answered) == 91  # 0 .. 9 s every 0.1 s
    assert 'ignored bar command' not in text and 'no bar command stamped' not in text, text
    got = json.loads(report.read_text())
    assert got['lockstep_missed'] == 0 and got['t_end'] == pytest.approx(9.0)
    # 50 Hz for 9 s and the last instant, each stream once
    assert got['published'] == {'/auv/state': 451, '/auv/odom': 451,
                                '/auv/hydrodynamic_forces': 451, '/clock': 451}


def test_lockstep_waits_for_a_controller_on_odom_besides_the_recorder(
        rclpy_context: tuple[Context, dict[str, str]], tmp_path: pathlib.Path) -> None:
    """A controller on ``odom`` that subscribes after a recorder has: with
    ``start_odom_subscribers`` 2 the simulator starts only once both are matched, so the
    controller gets the state of t = 0 and answers every instant (the race a lockstep graph
    with its pilot on odometry lost one run in many: the recorder alone released the start,
    the pilot never saw t = 0 and the simulator waited for its answer in vain)."""
    import json

    context, env = rclpy_context
    log = tmp_path / 'node.log'
    report = tmp_path / 'report.json'
    node, executor = probe(context, 'sim_odom_controller_test')
    first_state: list[float] = []
    node.create_subscription(  # the recorder's odom, there from the start
        Odometry, '/auv/odom',
        lambda m: first_state.append(time.monotonic()) if not first_state else None, QOS)
    bar_pub = node.create_publisher(ActuatorSetpoint, '/auv/bar_command', QOS)
    pending: list[int] = []
    seen: list[int] = []

    def on_odom(msg: Odometry) -> None:
        ns = stamp_to_ns(msg.header.stamp)
        seen.append(ns)
        if ns % round(CONTROL_PERIOD * NS) == 0:
            pending.append(ns)

    trim_bar = float(build_setup(SimSettings()).x0[12])
    proc = start_node(env, ['--lockstep', '--real-time-factor', '0', '--control-period',
                            str(CONTROL_PERIOD), '--lockstep-timeout', '30',
                            '--lockstep-startup-timeout', '60', '--stop-time', '2',
                            '--start-odom-subscribers', '2', '--report-file', str(report)],
                     log)
    late = time.monotonic() + 3.0  # the controller subscribes 3 wall s after the recorder
    while time.monotonic() < late:
        executor.spin_once(timeout_sec=0.05)
    subscribed = time.monotonic()
    node.create_subscription(Odometry, '/auv/odom', on_odom, QOS)
    answered = answer_until_exit(proc, log, node, executor, bar_pub, pending, stamp_from_ns,
                                 trim_bar, 120.0)
    text = log.read_text()
    assert proc.returncode == 0, text
    assert first_state and first_state[0] > subscribed, (first_state, subscribed)
    assert seen[0] == 0 and len(answered) == 21, (seen[:3], len(answered))  # 0 .. 2 s
    assert json.loads(report.read_text())['lockstep_missed'] == 0


def test_another_simulator_on_the_namespace_is_refused(
        rclpy_context: tuple[Context, dict[str, str]], tmp_path: pathlib.Path) -> None:
    """A node already publishing /auv/state (another graph's simulator): the simulator ends
    with one line naming it, exit status 1, before it publishes anything."""
    context, env = rclpy_context
    node, executor = probe(context, 'other_simulator')
    node.create_publisher(VehicleState, '/auv/state', QOS)
    clocks: list[int] = []
    node.create_subscription(Clock, '/clock', lambda m: clocks.append(1), QOS)
    log = tmp_path / 'node.log'
    proc = start_node(env, ['--real-time-factor', '1', '--start-subscribers', '1'], log)
    try:
        deadline = time.monotonic() + 120.0
        while proc.poll() is None:
            assert time.monotonic() < deadline, log.read_text()
            executor.spin_once(timeout_sec=0.05)
    finally:
        if proc.poll() is None:
            proc.terminate()
            proc.wait(10)
        node.destroy_node()
    text = log.read_text()
    assert proc.returncode == 1, text
    errors = [line for line in text.splitlines() if line.startswith('error: ')]
    # the other node named once discovery has its name, else "another node"
    assert len(errors) == 1 and errors[0].endswith(
        ' publishes /auv/state already: another graph runs on namespace /auv (stop it, or give '
        'this one its own namespace)'), text
    assert errors[0].split()[1] in ('/other_simulator', 'another'), errors
    assert clocks == []
