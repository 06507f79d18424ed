"""A mission flown through the node graph in lockstep: its commands act at their simulated
instants, so the graph's bag equals the offline run (``auv_sim.missions.run_mission``), and in
its own namespace."""
from __future__ import annotations

import pathlib

import numpy as np
import yaml
from conftest import A18M

from auv_bag import bag_topics, read_arrays
from auv_bringup.launch import mission_config, run_graph
from auv_sim.missions import load_mission, run_mission
from auv_sim.params import load_vehicle

FIELDS = ('x', 'y', 'z', 'phi', 'theta', 'psi', 'u', 'v', 'w', 'p', 'q', 'r')
#: A short mission on every channel: a BAR doublet, a rudder step, a thrust step (rad, N).
MISSION = {'mission': 'short', 'duration': 20.0, 'initial': {'z': 30.0, 'u': 2.0},
           'events': [[0.0, 'bar', 'trim'], [0.0, 'thrust', 'trim'], [3.0, 'bar', -0.15],
                      [6.0, 'bar', 'trim'], [8.0, 'helm', 0.1], [11.0, 'helm', 0.0],
                      [13.0, 'thrust', 60.0], [16.0, 'bar', 0.05]]}


def test_mission_through_the_graph_equals_the_offline_run(tmp_path: pathlib.Path,
                                                          ros_env: dict[str, str]) -> None:
    path = tmp_path / 'short.yaml'
    path.write_text(yaml.safe_dump(MISSION))
    bag = tmp_path / 'bag'
    cfg = mission_config(str(path), vehicle=str(A18M), real_time_factor=0.0, record=str(bag),
                         log_dir=str(tmp_path / 'logs'), namespace='auvm')
    codes = run_graph(cfg, duration=300.0, env=ros_env)
    assert codes['simulator'] == 0 and codes['mission'] == 0, codes
    assert all(t.startswith('/auvm/') for t in bag_topics(bag)), bag_topics(bag)
    topics = ['/auvm/state', '/auvm/bar_command', '/auvm/helm_command', '/auvm/thrust_command']
    arrays = read_arrays(bag, topics)
    state = arrays['/auvm/state']
    offline = run_mission(load_vehicle(A18M), load_mission(path))
    assert len(state) == len(offline.t) == 20 * 50 + 1
    np.testing.assert_array_equal(np.round(state['t'], 9), np.round(offline.t, 9))
    graph = np.stack([state[k] for k in FIELDS], axis=1)
    assert np.max(np.abs(graph - offline.measured[:, :12])) <= 1e-9
    # every control instant answered on the three channels, each event from its instant on
    for topic in topics[1:]:
        assert len(arrays[topic]) == 20 * 10 + 1
        np.testing.assert_allclose(arrays[topic]['t'], np.arange(201) * 0.1, atol=1e-9)
    helm = arrays['/auvm/helm_command']
    by_t = dict(zip(np.round(helm['t'], 3), helm['value']))
    assert by_t[7.9] == 0.0 and by_t[8.0] == 0.1 and by_t[10.9] == 0.1 and by_t[11.0] == 0.0
    bar = dict(zip(np.round(arrays['/auvm/bar_command']['t'], 3),
                   arrays['/auvm/bar_command']['value']))
    assert bar[2.9] != -0.15 and bar[3.0] == -0.15 and bar[5.9] == -0.15 and bar[16.0] == 0.05
    thrust = dict(zip(np.round(arrays['/auvm/thrust_command']['t'], 3),
                      arrays['/auvm/thrust_command']['value']))
    assert thrust[12.9] != 60.0 and thrust[13.0] == 60.0
