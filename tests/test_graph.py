"""The closed loop through the real node graph: simulator, depth pilot and recorder processes."""
from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest
from conftest import A18M

from auv_bag import read_arrays
from auv_bringup.launch import GraphConfig, run_graph
from auv_depth_lqr.closed_loop import run_closed_loop
from auv_depth_lqr.metrics import kinematic_bound, step_metrics
from auv_sim.params import load_vehicle

FIELDS = ('x', 'y', 'z', 'phi', 'theta', 'psi', 'u', 'v', 'w', 'p', 'q', 'r')


def fly(tmp_path: pathlib.Path, env: dict[str, str], z0: float, z1: float,
        stop_time: float) -> dict[str, np.ndarray]:
    bag = tmp_path / 'bag'
    cfg = GraphConfig(vehicle=str(A18M), lockstep=True, real_time_factor=0.0,
                      initial_depth=z0, stop_time=stop_time, record=str(bag),
                      log_dir=str(tmp_path / 'logs'), depth_command=z1)
    codes = run_graph(cfg, duration=240.0, env=env)
    assert codes['simulator'] == 0, codes
    return read_arrays(bag, ['/auv/state', '/auv/bar_command'])


def test_lockstep_graph_run_equals_offline_run(tmp_path: pathlib.Path, ros_env) -> None:
    arrays = fly(tmp_path, ros_env, 40.0, 10.0, stop_time=30.0)
    state, bar = arrays['/auv/state'], arrays['/auv/bar_command']
    assert len(state) == 30 * 50 + 1 and len(bar) == 30 * 10 + 1
    offline = run_closed_loop(load_vehicle(A18M), [(0.0, 10.0)], 30.0, z0=40.0)
    rec = offline.record
    np.testing.assert_array_equal(np.round(rec.t, 9), np.round(state['t'], 9))
    graph = np.stack([state[k] for k in FIELDS], axis=1)
    assert np.max(np.abs(graph - rec.measured[:, :12])) <= 1e-9
    assert np.max(np.abs(bar['value'][:len(offline.bar)] - offline.bar)) <= 1e-9


@pytest.mark.parametrize('z0,z1', [(40.0, 10.0), (10.0, 40.0)])
def test_depth_change_through_the_graph_settles(tmp_path: pathlib.Path, ros_env, z0: float,
                                                z1: float) -> None:
    params = load_vehicle(A18M)
    arrays = fly(tmp_path, ros_env, z0, z1, stop_time=120.0)
    s, bar = arrays['/auv/state'], arrays['/auv/bar_command']
    m = step_metrics(s['t'], s['z'], s['theta'], s['q'], np.interp(s['t'], bar['t'],
                     bar['value']), z1, bar_max=params.bar_max)
    assert m.settling_time <= 1.7 * kinematic_bound(z1 - z0, 2.0, math.radians(25)), m
    assert abs(s['z'][-1] - z1) < 0.1
    assert m.peak_pitch <= math.radians(25.5), m
    assert np.all(np.abs(bar['value']) <= params.bar_max + 1e-12)


def test_the_simulator_waits_for_a_pilot_on_odometry() -> None:
    """A pilot on ``nav_msgs/Odometry`` is an ``odom`` subscriber the simulator waits for
    before t = 0, as a pilot on ``VehicleState`` is a ``state`` one: counted from the graph's
    configuration, beside the recorder and the Foxglove bridge."""
    from auv_bringup.launch import odom_subscribers, state_subscribers
    on_odom = GraphConfig(vehicle=str(A18M), pilot_state='odometry')
    assert (odom_subscribers(on_odom), state_subscribers(on_odom)) == (1, 0)
    recorded = GraphConfig(vehicle=str(A18M), pilot_state='odometry', record='bag')
    assert (odom_subscribers(recorded), state_subscribers(recorded)) == (2, 1)
    on_state = GraphConfig(vehicle=str(A18M), record='bag', foxglove=8765)
    assert (odom_subscribers(on_state), state_subscribers(on_state)) == (2, 3)
    mission = GraphConfig(vehicle=str(A18M), pilot_state='odometry', mission='pitch')
    assert odom_subscribers(mission) == 0


def test_the_pilot_waits_for_every_command_subscriber_of_the_graph() -> None:
    """The pilot's first command goes out once the simulator, the recorder (if it records
    the command) and the Foxglove bridge have matched it: counted from the graph's
    configuration, not from discovery, which is what races."""
    from auv_bringup.launch import bar_subscribers
    base = GraphConfig(vehicle=str(A18M))
    assert bar_subscribers(base) == 1
    assert bar_subscribers(GraphConfig(vehicle=str(A18M), record='bag')) == 2
    assert bar_subscribers(GraphConfig(vehicle=str(A18M), record='bag', foxglove=8765)) == 3
    assert bar_subscribers(GraphConfig(vehicle=str(A18M), record='bag',
                                       topics=('state', 'depth_command'))) == 1
    assert bar_subscribers(GraphConfig(vehicle=str(A18M), record='bag',
                                       topics=('/auv/bar_command',))) == 2
