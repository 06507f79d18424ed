"""The depth pilot on a plant that is not its model, through the real node graph.

The simulator node flies a vehicle built from the REMUS 100 file the way a third party's
simulator differs from it (:func:`auv_depth_lqr.closed_loop.foreign_plant`: plane force x0.5,
moment x0.6, no Munk moment, neutrally buoyant, so its level trim needs 9.1 deg less nose-down
plane than the file's), thrust held at its trim value, no speed loop; the pilot node is
started on config/remus100.yaml in lockstep with learning on, and told 10 m from
20 m at once (cold start).

Oracles, independent of the pilot: the plant's own trim (auv_sim.trim on the plant's
parameters) for what the pilot must learn to hold; the time-optimal bound of the plant's own
model (25.6 s for this change, auv_depth_lqr.bound.settling_bound) against which 60 s is
more than twice; the pitch limit 25 deg plus the 1 deg margin.
"""
from __future__ import annotations

import math
import pathlib
import subprocess
import sys

import numpy as np
from conftest import ROOT

from auv_bag import read_arrays
from auv_bringup.launch import GraphConfig, run_graph
from auv_depth_lqr.closed_loop import foreign_plant, run_closed_loop
from auv_depth_lqr.metrics import step_metrics
from auv_depth_lqr.pilot import DepthPilot, PilotSettings
from auv_sim.params import load_vehicle, save_vehicle
from auv_sim.trim import VerticalPlane

REMUS = ROOT / 'config' / 'remus100.yaml'
THETA_MAX = math.radians(25.0)


def test_cold_start_on_a_foreign_plant_through_the_graph(tmp_path: pathlib.Path,
                                                         ros_env) -> None:
    design = load_vehicle(REMUS)
    plant = foreign_plant(design, 1.5)
    plant_file = tmp_path / 'plant.yaml'
    save_vehicle(plant, plant_file)
    bag = tmp_path / 'bag'
    cfg = GraphConfig(vehicle=str(plant_file), pilot_vehicle=str(REMUS), lockstep=True,
                      real_time_factor=0.0, initial_depth=20.0, initial_speed=1.5,
                      stop_time=80.0, record=str(bag), log_dir=str(tmp_path / 'logs'),
                      depth_command=10.0, pilot_learn=True)
    codes = run_graph(cfg, duration=300.0, env=ros_env)
    assert codes['simulator'] == 0, codes
    arrays = read_arrays(bag, ['/auv/state', '/auv/bar_command'])
    s, bar = arrays['/auv/state'], arrays['/auv/bar_command']
    m = step_metrics(s['t'], s['z'], s['theta'], s['q'], np.interp(s['t'], bar['t'],
                     bar['value']), 10.0, bar_max=design.bar_max, u0=1.5)
    assert m.settling_time < 60.0, m
    assert m.peak_pitch <= THETA_MAX + math.radians(1.0), m
    # the same flight offline with the same core gives the same commands (lockstep)
    pilot = DepthPilot.for_vehicle(design, PilotSettings(learn=True))
    offline = run_closed_loop(plant, [(0.0, 10.0)], 80.0, z0=20.0, u0=1.5, pilot=pilot)
    n = len(offline.bar)
    assert np.max(np.abs(bar['value'][:n] - offline.bar)) <= 1e-9
    # what the pilot learned holds the plant's own level trim, not the file's
    own = VerticalPlane(plant).trim(1.5)
    learned = pilot.controller.trimmed(pilot.controller.design.at(1.5))
    file_trim = pilot.controller.design.at(1.5).bar_e
    assert abs(own.bar - file_trim) > math.radians(8.0)
    assert abs(learned.bar_e - own.bar) < 0.25 * abs(own.bar - file_trim)


def test_auv_launch_flies_the_pilot_of_another_file(tmp_path: pathlib.Path, ros_env) -> None:
    """``auv launch --vehicle PLANT --pilot-vehicle FILE``: the simulator flies the plant
    and the pilot is the one built on FILE, command for command the offline core's on the
    same plant (lockstep, 10 s of the REMUS 100 foreign plant's climb)."""
    design = load_vehicle(REMUS)
    plant = foreign_plant(design, 1.5)
    plant_file = tmp_path / 'plant.yaml'
    save_vehicle(plant, plant_file)
    bag = tmp_path / 'bag'
    res = subprocess.run([sys.executable, '-m', 'auv_bringup.cli', 'launch', '--vehicle',
                          str(plant_file), '--pilot-vehicle', str(REMUS), '--lockstep',
                          '--real-time-factor', '0', '--initial-depth', '20',
                          '--initial-speed', '1.5', '--stop-time', '10', '--depth', '10',
                          '--record', str(bag)], env=ros_env, capture_output=True, text=True,
                         timeout=300)
    assert res.returncode == 0, res.stderr
    bar = read_arrays(bag, ['/auv/bar_command'])['/auv/bar_command']
    offline = run_closed_loop(plant, [(0.0, 10.0)], 10.0, z0=20.0, u0=1.5,
                              pilot=DepthPilot.for_vehicle(design, PilotSettings()))
    n = min(len(offline.bar), len(bar['value']))
    assert n >= 90
    assert np.max(np.abs(bar['value'][:n] - offline.bar[:n])) <= 1e-9
    # the pilot on the plant's own file commands otherwise
    own = run_closed_loop(plant, [(0.0, 10.0)], 10.0, z0=20.0, u0=1.5,
                          pilot=DepthPilot.for_vehicle(plant, PilotSettings()))
    assert np.max(np.abs(bar['value'][:n] - own.bar[:n])) > 1e-3
