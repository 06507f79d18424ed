"""Depth commands that never vanish and never lie, over DDS with the pilot in its own process:
``auv depth`` waits for the pilot's answer (exit 1 on a refusal), the refusal is WARN on
``/diagnostics`` and recorded, the recorder gets ``auv depth``'s command, the example script
commands depth the right way, a command lost before the match is said, and a default-QoS
script gets no incompatible-durability warning."""
from __future__ import annotations

import pathlib
import signal
import subprocess
import sys
import time

import pytest
from test_pilot_interfaces import DEADLINE_S, PilotProcess

from auv_bag import read_messages

ROOT = pathlib.Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / 'examples' / 'depth_command.py'
#: A user's script as a new user writes it: default QoS, publish right after create_publisher
#: (before DDS has matched the pilot); it then stays until DDS has matched its publisher with the
#: pilot's two subscriptions (so the pilot sees it) and, with a second argument, publishes that
#: value once more before it leaves.
HASTY_SCRIPT = '''
import sys, time
import rclpy
from rclpy.duration import Duration
from std_msgs.msg import Float64
rclpy.init()
node = rclpy.create_node('hasty_script')
pub = node.create_publisher(Float64, '/auv/depth_command', 10)
for value in sys.argv[1].split(','):
    pub.publish(Float64(data=float(value)))
end = time.monotonic() + 60.0
while pub.get_subscription_count() < 2:
    assert time.monotonic() < end, 'no pilot'
    time.sleep(0.05)
time.sleep(1.0)
if len(sys.argv) > 2:
    pub.publish(Float64(data=float(sys.argv[2])))
    assert pub.wait_for_all_acked(Duration(seconds=10.0))
node.destroy_node()
rclpy.shutdown()
'''
#: The same script done right but with default QoS: it waits for the pilot's match.
PATIENT_SCRIPT = '''
import time
import rclpy
from std_msgs.msg import Float64
from rclpy.duration import Duration
rclpy.init()
node = rclpy.create_node('patient_script')
pub = node.create_publisher(Float64, '/auv/depth_command', 10)
end = time.monotonic() + 60.0
while pub.get_subscription_count() < 2:   # the pilot's reliable and best-effort subscriptions
    assert time.monotonic() < end, 'no pilot'
    time.sleep(0.05)
pub.publish(Float64(data=16.0))
assert pub.wait_for_all_acked(Duration(seconds=10.0))
node.destroy_node()
rclpy.shutdown()
'''


def auv(env: dict[str, str], *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, '-m', 'auv_bringup.cli', *args], env=env,
                          capture_output=True, text=True, timeout=2 * DEADLINE_S)


@pytest.fixture
def pilot(ros_env: dict[str, str]):  # type: ignore[no-untyped-def]
    proc = PilotProcess(ros_env, '-p', 'state_timeout:=5.0')
    proc.wait_ready()
    try:
        yield proc
    finally:
        proc.stop()


def wait_for(pilot: PilotProcess, text: str) -> None:
    end = time.monotonic() + DEADLINE_S
    while pilot.count(text) == 0:
        assert time.monotonic() < end, f'no {text!r} within {DEADLINE_S} s: {pilot.output}'
        time.sleep(0.05)


def test_auv_depth_waits_for_the_answer_and_the_recorder_gets_it_all(
        ros_env: dict[str, str], pilot: PilotProcess, tmp_path: pathlib.Path) -> None:
    bag = tmp_path / 'bag'
    recorder = subprocess.Popen([sys.executable, '-m', 'auv_bringup.cli', 'record', '--out',
                                 str(bag), '--topics', 'depth_command', '/diagnostics'],
                                env=ros_env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                text=True)
    try:
        # two subscriber nodes: the pilot and the recorder, each matched before the publish
        ok = auv(ros_env, 'depth', '12', '--min-subscribers', '2', '--timeout', str(DEADLINE_S))
        assert ok.returncode == 0, ok.stderr
        assert ok.stderr == 'depth command 12 m accepted by /auv/depth_pilot\n'
        refused = auv(ros_env, 'depth', '-5', '--min-subscribers', '2', '--timeout',
                      str(DEADLINE_S))
        assert refused.returncode == 1
        assert refused.stderr.count('\n') == 1, refused.stderr
        assert refused.stderr.startswith('error: /auv/depth_pilot: depth command -5 m refused: '
                                         'depth command -5 m is outside the depth envelope '
                                         '[0, 300] m; kept 12.0 m'), refused.stderr
        time.sleep(2.5)  # a periodic status (1 s) with the refusal on its way to the recorder
    finally:
        recorder.send_signal(signal.SIGTERM)
        assert recorder.wait(60) == 0, recorder.stderr.read() if recorder.stderr else ''
    commands = [m.msg.data for m in read_messages(bag, ['/auv/depth_command'])]
    assert commands == [12.0, -5.0]
    statuses = [s for m in read_messages(bag, ['/diagnostics']) for s in m.msg.status
                if s.name == '/auv/depth_pilot: depth control']
    refusal = [s for s in statuses if 'depth command -5 m refused' in s.message]
    assert refusal, [s.message for s in statuses]
    values = {kv.key: kv.value for kv in refusal[0].values}
    assert refusal[0].level == 1  # WARN
    assert values['last_command_result'] == 'refused'
    assert values['last_command_value_m'] == '-5'
    assert values['depth_command_m'] == '12.000'  # the command in force is kept
    # not told its water speed (the default), it says it schedules on the speed over ground
    assert values['speed_basis'] == 'over ground'
    assert values['current_along_heading_mps'] == 'unknown'


def test_auv_depth_started_before_the_pilot_is_delivered_and_answered(
        ros_env: dict[str, str]) -> None:
    depth = subprocess.Popen([sys.executable, '-m', 'auv_bringup.cli', 'depth', '21',
                              '--timeout', str(DEADLINE_S)], env=ros_env,
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    time.sleep(1.0)
    pilot = PilotProcess(ros_env)
    try:
        _, err = depth.communicate(timeout=2 * DEADLINE_S + 30)
        assert depth.returncode == 0, err
        assert err == 'depth command 21 m accepted by /auv/depth_pilot\n'
        wait_for(pilot, 'depth command 21 m accepted')
    finally:
        pilot.stop()
    assert pilot.count('depth command 21 m accepted') == 1


def test_the_example_script_commands_depth_the_right_way(ros_env: dict[str, str],
                                                        pilot: PilotProcess) -> None:
    ok = subprocess.run([sys.executable, str(EXAMPLE), '15.5'], env=ros_env,
                        capture_output=True, text=True, timeout=2 * DEADLINE_S)
    assert ok.returncode == 0, ok.stderr
    assert ok.stdout == 'depth command 15.5 m accepted\n'
    wait_for(pilot, 'depth command 15.5 m accepted')
    refused = subprocess.run([sys.executable, str(EXAMPLE), '400'], env=ros_env,
                             capture_output=True, text=True, timeout=2 * DEADLINE_S)
    assert refused.returncode == 1
    assert refused.stdout.startswith('depth command 400 m refused: depth command 400 m is '
                                     'outside the depth envelope [0, 300] m'), refused.stdout


def test_commands_lost_before_the_match_are_said_and_default_qos_gets_no_warning(
        ros_env: dict[str, str], pilot: PilotProcess) -> None:
    """Never silent: each command a script publishes before DDS matched it with the pilot is
    either delivered (DDS matched in time) or counted as lost in a warning; the count is
    exact when a later command of the same publisher arrives (its sequence number). The
    pilot's subscriptions deliver independently, so an earlier command can arrive after a
    later one (logged as superseded, not applied)."""
    import re

    from auv_depth_lqr.node import LATCHED_WINDOW

    # after the start-up window the pilot has no transient-local subscription left
    time.sleep(LATCHED_WINDOW + 1.0)

    def script(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run([sys.executable, '-c', HASTY_SCRIPT, *args], env=ros_env,
                              capture_output=True, text=True, timeout=2 * DEADLINE_S)

    # two commands right after create_publisher, a third after the match
    first = script('14,14.5', '15')
    assert first.returncode == 0, first.stderr
    wait_for(pilot, 'depth command 15 m accepted')
    values = ('14', '14.5')
    applied = sum(pilot.count(f'depth command {v} m accepted') for v in values)
    superseded = sum(pilot.count(f'depth command {v} m (sequence') for v in values)
    missed = sum(int(n) for n in re.findall(r'(\d+) earlier depth command', pilot.output))
    assert applied + superseded <= 2, pilot.output  # each arrival acts or is said once
    assert applied + superseded + missed >= 2, pilot.output  # what never arrived is counted
    # one command right after create_publisher, then the script leaves: delivered, or its
    # departure without a command said
    second = script('13')
    assert second.returncode == 0, second.stderr
    end = time.monotonic() + DEADLINE_S
    said = ('left without a depth command reaching the pilot', 'depth command 13 m accepted')
    while not any(pilot.count(text) for text in said):
        assert time.monotonic() < end, f'the command 13 m vanished silently: {pilot.output}'
        time.sleep(0.1)
    # a default-QoS (volatile) publisher matches every subscription the pilot has now: no
    # incompatible-durability warning in the script's output
    patient = subprocess.run([sys.executable, '-c', PATIENT_SCRIPT], env=ros_env,
                             capture_output=True, text=True, timeout=2 * DEADLINE_S)
    assert patient.returncode == 0, patient.stderr
    wait_for(pilot, 'depth command 16 m accepted')
    assert 'incompatible' not in patient.stderr + first.stderr + second.stderr, patient.stderr
    assert pilot.count('another subscription of the pilot receives') == 0
