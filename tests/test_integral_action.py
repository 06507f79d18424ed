"""Integral action removes a steady offset: a vertical current the design model does not know.

A vertical current of +-0.1 m/s (down / up, auv_sim.environment ``current``) needs the
vehicle to climb or dive through the water at 0.1 m/s to hold its depth: a steady pitch
offset of a few degrees that only the integrator can supply. Goal (issue: worst steady-state
depth error < 0.1 m): the depth over the last 20 s of a 200 s run within 0.01 m of the
command, pitch within the limit + 2 deg. Independent oracle: the command itself.
"""
from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest

from auv_depth_lqr.closed_loop import run_closed_loop
from auv_depth_lqr.pilot import DepthPilot, PilotSettings
from auv_sim.environment import Environment
from auv_sim.params import load_vehicle

ROOT = pathlib.Path(__file__).resolve().parents[1]
THETA_MAX = math.radians(25.0)
#: vehicle -> (u0 [m/s], z0, z1 [m])
CASES = {'a18m': (2.0, 40.0, 10.0), 'remus100': (1.5, 20.0, 10.0),
         'npsauv2': (1.5, 20.0, 10.0)}


@pytest.mark.parametrize('down', [0.1, -0.1])
@pytest.mark.parametrize('name', sorted(CASES))
def test_vertical_current_leaves_no_offset(name: str, down: float) -> None:
    params = load_vehicle(ROOT / 'config' / f'{name}.yaml')
    u0, z0, z1 = CASES[name]
    settings = PilotSettings()
    run = run_closed_loop(params, [(0.0, z1)], 200.0, z0=z0, u0=u0,
                          environment=Environment(effects={'current': {'down': down}}),
                          settings=settings, pilot=DepthPilot.for_vehicle(params, settings),
                          speed_time_constant=2.0)
    rec = run.record
    last = rec.t > rec.t[-1] - 20.0
    assert np.max(np.abs(rec.x[last, 2] - z1)) < 0.01
    assert np.max(np.abs(rec.x[:, 4])) <= THETA_MAX + math.radians(2.0)
