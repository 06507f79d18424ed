"""The identification node and the offline command, fed the same bag, give the same numbers.

Real processes on Fast DDS: ``auv ident-node`` subscribes; ``auv play`` replays a bag of a
short manoeuvre (thrust steps and plane doublets) once the node's subscriptions have matched;
the test calls the node's ``~/identify`` service (std_srvs/Trigger) from its own rclpy node,
then stops the node with SIGTERM, which writes the outputs once more. The node keys samples by
header stamp, so with no message lost the coefficients equal ``auv ident`` on the bag.
"""
from __future__ import annotations

import json
import os
import pathlib
import signal
import subprocess
import sys
import time

import pytest

from auv_logs.simlog import write_record
from auv_sim.missions import parse_mission, run_mission
from auv_sim.params import load_vehicle

ROOT = pathlib.Path(__file__).resolve().parents[1]
EQUATIONS = ('surge', 'heave', 'pitch')

MANOEUVRE = {
    'mission': 'short pitch', 'duration': 80.0, 'initial': {'z': 40.0, 'u': 2.0},
    'events': [[0.0, 'bar', 'trim'], [0.0, 'thrust', 'trim'], [5.0, 'bar', -0.0237],
               [8.0, 'bar', -0.1437], [11.0, 'bar', 'trim'], [20.0, 'thrust', 110.0],
               [35.0, 'bar', 0.0163], [39.0, 'bar', -0.1837], [43.0, 'bar', 'trim'],
               [50.0, 'thrust', 25.0], [60.0, 'bar', -0.2037], [62.0, 'bar', 0.0363],
               [64.0, 'bar', 'trim']],
}


def auv(*args: str, env: dict[str, str], **kw: object) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, '-m', 'auv_bringup.cli', *args], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            **kw)  # type: ignore[call-overload]


def call_identify(domain_id: int, timeout: float = 60.0) -> dict:  # type: ignore[type-arg]
    import rclpy
    from std_srvs.srv import Trigger

    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=domain_id)
    try:
        node = rclpy.create_node('test_ident_client', context=ctx)
        client = node.create_client(Trigger, '/identifier/identify')
        assert client.wait_for_service(timeout_sec=20.0), 'no ~/identify service'
        future = client.call_async(Trigger.Request())
        deadline = time.monotonic() + timeout
        from rclpy.executors import SingleThreadedExecutor
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        while not future.done() and time.monotonic() < deadline:
            ex.spin_once(timeout_sec=0.1)
        assert future.done(), 'identify service did not answer'
        resp = future.result()
        assert resp.success, resp.message
        return json.loads(resp.message)
    finally:
        rclpy.shutdown(context=ctx)


@pytest.mark.parametrize('options', [[], ['--source', 'motion', '--fit-planes']],
                         ids=['forces', 'motion_planes'])
def test_node_and_offline_command_agree_on_a_replayed_bag(ros_env: dict[str, str],
                                                          tmp_path: pathlib.Path,
                                                          options: list[str]) -> None:
    params = load_vehicle(ROOT / 'config' / 'a18m.yaml')
    bag = tmp_path / 'short_pitch'
    write_record(bag, run_mission(params, parse_mission(MANOEUVRE)), forces=True)

    offline = subprocess.run(
        [sys.executable, '-m', 'auv_bringup.cli', 'ident', str(bag), '--out',
         str(tmp_path / 'offline'), '--equations', *EQUATIONS, *options], env=ros_env,
        capture_output=True, text=True, timeout=120)
    assert offline.returncode == 0, offline.stderr
    expected = json.loads(offline.stdout)['coefficients']
    assert ('CMbar' in expected) == ('--fit-planes' in options)

    node = auv('ident-node', '--out', str(tmp_path / 'node'), '--equations', *EQUATIONS,
               *options, env=ros_env)
    try:
        play = subprocess.run(
            [sys.executable, '-m', 'auv_bringup.cli', 'play', str(bag), '--rate', '8',
             '--wait-for-subscribers', '--wait-timeout', '30'],
            env=ros_env, capture_output=True, text=True, timeout=120)
        assert play.returncode == 0, play.stderr
        answer = call_identify(int(ros_env['ROS_DOMAIN_ID']))
        assert answer['samples']['/auv/state'] == 4001
        for name, c in expected.items():
            assert answer['coefficients'][name]['value'] == pytest.approx(c['value'],
                                                                          rel=1e-12), name
            assert answer['coefficients'][name]['std_error'] == pytest.approx(
                c['std_error'], rel=1e-9), name
    finally:
        node.send_signal(signal.SIGTERM)
        _out, err = node.communicate(timeout=60)
    assert node.returncode == 0, err
    on_shutdown = json.loads((tmp_path / 'node' / 'report.json').read_text())
    for name, c in expected.items():
        assert on_shutdown['coefficients'][name]['value'] == pytest.approx(c['value'],
                                                                           rel=1e-12)
    assert (tmp_path / 'node' / 'vehicle.yaml').exists()
    assert (tmp_path / 'node' / 'fig3_heave.png').exists()


def test_node_rejects_a_bad_parameter(ros_env: dict[str, str], tmp_path: pathlib.Path) -> None:
    proc = auv('ident-node', '--out', str(tmp_path), '--window', '-1', env=ros_env)
    _out, err = proc.communicate(timeout=60)
    assert proc.returncode == 1
    assert [line for line in err.splitlines() if line.startswith('error: ')] == [
        'error: parameter window must be > 0 s, got -1.0']
    assert os.path.exists(tmp_path) and not (tmp_path / 'report.json').exists()
