"""The identification node reads a real vehicle's original log through a map at start and
gives the numbers ``auv ident --map`` gives offline (real processes on Fast DDS: the node, and
a test client calling its ``~/identify`` service; the service's availability is the
readiness handshake)."""
from __future__ import annotations

import json
import pathlib
import signal
import subprocess
import sys

import pytest

from auv_logs import synth
from auv_sim.missions import parse_mission, run_mission
from auv_sim.params import load_vehicle

ROOT = pathlib.Path(__file__).resolve().parents[1]
MAP = ROOT / 'config' / 'maps' / 'ros2_custom_fins.yaml'
EQUATIONS = ('heave', 'pitch')



def test_node_reads_original_logs_through_a_map(ros_env: dict[str, str],
                                                tmp_path: pathlib.Path) -> None:
    from test_ident_node import MANOEUVRE, call_identify

    rec = run_mission(load_vehicle(ROOT / 'config' / 'a18m.yaml'), parse_mission(MANOEUVRE))
    log = tmp_path / 'lab_bag'
    synth.write_ros2(log, rec, custom_fins=True, every=2)
    offline = subprocess.run(
        [sys.executable, '-m', 'auv_bringup.cli', 'ident', str(log), '--map', str(MAP),
         '--out', str(tmp_path / 'offline'), '--equations', *EQUATIONS, '--no-nelder-mead'],
        env=ros_env, capture_output=True, text=True, timeout=300)
    assert offline.returncode == 0, offline.stderr
    expected = json.loads(offline.stdout)['coefficients']
    node = subprocess.Popen(
        [sys.executable, '-m', 'auv_bringup.cli', 'ident-node', '--map', str(MAP), '--logs',
         str(log), '--out', str(tmp_path / 'node'), '--equations', *EQUATIONS], env=ros_env,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        answer = call_identify(int(ros_env['ROS_DOMAIN_ID']))
        assert answer['samples']['/auv/state'] == len(rec.t[::2])
        for name, c in expected.items():
            assert answer['coefficients'][name]['value'] == pytest.approx(c['value'],
                                                                          rel=1e-12), name
    finally:
        node.send_signal(signal.SIGTERM)
        _out, err = node.communicate(timeout=120)
    assert node.returncode == 0, err
