"""Two simulated vehicles in one ROS graph: ``auv launch --namespace`` for each, at once, in
one DDS domain; each flies its own depth change on its own topics and simulated clock."""
from __future__ import annotations

import pathlib
import subprocess
import sys

import numpy as np
from conftest import A18M

from auv_bag import bag_topics, read_arrays

STOP = 60.0  # s of simulated time


def test_two_namespaced_vehicles_fly_to_different_depths(tmp_path: pathlib.Path,
                                                         ros_env) -> None:
    targets = {'auv1': 30.0, 'auv2': 50.0}
    procs = {}
    for ns, depth in targets.items():
        procs[ns] = subprocess.Popen(
            [sys.executable, '-m', 'auv_bringup.cli', 'launch', '--namespace', ns,
             '--vehicle', str(A18M), '--lockstep', '--real-time-factor', '0',
             '--initial-depth', '40', '--stop-time', str(STOP), '--depth', str(depth),
             '--record', str(tmp_path / ns), '--log-dir', str(tmp_path / f'{ns}_logs'),
             '--duration', '400'], env=ros_env, stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT, text=True)
    outputs = {}
    try:
        for ns, proc in procs.items():
            outputs[ns], _ = proc.communicate(timeout=450)
    finally:
        for proc in procs.values():
            if proc.poll() is None:
                proc.kill()
    for ns, proc in procs.items():
        assert proc.returncode == 0, (ns, outputs[ns])
    for ns, depth in targets.items():
        bag = tmp_path / ns
        topics = bag_topics(bag)
        # only this vehicle's topics (and its own clock) are in its bag
        assert f'/{ns}/state' in topics and f'/{ns}/clock' in topics, topics
        assert all(t.startswith(f'/{ns}/') for t in topics), topics
        arrays = read_arrays(bag, [f'/{ns}/state', f'/{ns}/bar_command', f'/{ns}/odom',
                                   f'/{ns}/hydrodynamic_forces'])
        state, bar = arrays[f'/{ns}/state'], arrays[f'/{ns}/bar_command']
        # lockstep on its own clock: every state and every control instant exactly once, and
        # every sample of the other streams the recorder paces the simulator on
        assert len(state) == int(STOP) * 50 + 1 and len(bar) == int(STOP) * 10 + 1
        assert len(arrays[f'/{ns}/odom']) == len(arrays[f'/{ns}/hydrodynamic_forces']) \
            == int(STOP) * 50 + 1
        np.testing.assert_allclose(np.diff(state['t']), 0.02, atol=1e-9)
        assert abs(state['z'][-1] - depth) < 0.1, (ns, state['z'][-1])
        pilot_log = (tmp_path / f'{ns}_logs' / 'pilot.log').read_text()
        assert f'depth command {depth:g} m accepted' in pilot_log
        assert f'state from /{ns}/state' in pilot_log


def test_pilot_on_the_simulators_odometry_flies_the_offline_run(tmp_path: pathlib.Path,
                                                                 ros_env) -> None:
    """The lockstep graph with the pilot on /auv/odom (nav_msgs/Odometry, ENU/FLU) instead of
    /auv/state: the BAR commands are those of the offline run on the NED/FRD state."""
    from auv_bringup.launch import GraphConfig, run_graph
    from auv_depth_lqr.closed_loop import run_closed_loop
    from auv_sim.params import load_vehicle

    bag = tmp_path / 'bag'
    cfg = GraphConfig(vehicle=str(A18M), lockstep=True, real_time_factor=0.0,
                      initial_depth=40.0, stop_time=30.0, record=str(bag),
                      log_dir=str(tmp_path / 'logs'), depth_command=10.0,
                      pilot_state='odometry')
    codes = run_graph(cfg, duration=240.0, env=ros_env)
    assert codes['simulator'] == 0, codes
    assert 'state from /auv/odom (enu_flu)' in (tmp_path / 'logs' / 'pilot.log').read_text()
    # the simulator waits for the recorder on /auv/state, not for the pilot, which is on odom
    assert 'fewer than' not in (tmp_path / 'logs' / 'simulator.log').read_text()
    bar = read_arrays(bag, ['/auv/bar_command'])['/auv/bar_command']
    offline = run_closed_loop(load_vehicle(A18M), [(0.0, 10.0)], 30.0, z0=40.0)
    assert len(bar) == 301
    assert np.max(np.abs(bar['value'][:len(offline.bar)] - offline.bar)) <= 1e-9
