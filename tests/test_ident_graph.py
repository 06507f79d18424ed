"""Identification round trip through the node graph: the three missions are flown by the
simulator node driven by `auv mission`, recorded by `auv record`, then identified with
`auv ident` from the force topic."""
from __future__ import annotations

import json
import pathlib
import subprocess
import sys

import pytest
from conftest import A18M

from auv_bringup.launch import mission_config, run_graph
from auv_sim.params import load_vehicle

IDENTIFIED = ('Ksh', 'CZuw', 'CZuq', 'CMuw', 'CMuq', 'CYuv', 'CYur', 'CNuv', 'CNur')


@pytest.fixture(scope='module')
def graph_bags(tmp_path_factory: pytest.TempPathFactory) -> list[pathlib.Path]:
    import os

    from conftest import ros_domain_id
    env = dict(os.environ, ROS_DOMAIN_ID=str(ros_domain_id()),
               ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    root = tmp_path_factory.mktemp('graph_missions')
    bags = []
    for mission in ('surge', 'pitch', 'yaw'):
        bag = root / mission
        cfg = mission_config(mission, vehicle=str(A18M), real_time_factor=0.0,
                             record=str(bag), log_dir=str(root / f'{mission}_logs'))
        codes = run_graph(cfg, duration=300.0, env=env)
        assert codes['simulator'] == 0 and codes['mission'] == 0, codes
        bags.append(bag)
    return bags


def test_missions_recorded_through_the_graph_identify_within_half_a_percent(
        graph_bags: list[pathlib.Path], tmp_path: pathlib.Path) -> None:
    out = tmp_path / 'ident'
    res = subprocess.run([sys.executable, '-m', 'auv_bringup.cli', 'ident',
                          *map(str, graph_bags), '--out', str(out), '--source', 'forces',
                          '--no-nelder-mead'], capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    report = json.loads((out / 'report.json').read_text())
    truth = load_vehicle(A18M)
    for name in IDENTIFIED:
        value = report['coefficients'][name]['value']
        assert value == pytest.approx(truth.values[name], rel=0.005), name
    identified = load_vehicle(out / 'vehicle.yaml')
    assert identified.values['CZuw'] == pytest.approx(truth.CZuw, rel=0.005)
