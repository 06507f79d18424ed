"""The pilot on plants that are not its design model (gap-catalogue effects, coefficients).

The pilot is designed on the vehicle file; the simulated plant differs by one effect of the
sim-to-real catalogue (auv_sim.environment) at a realistic size (currents: the pilot on its
speed over ground, the speed loop holding it), or by hydrodynamic
coefficients off by +-30 %. Criteria (the robustness goals of the depth pilot): settled
within 2x the time-optimal bound of the design model, no tumbling (|theta| < 35 deg), the
pitch limit not exceeded by more than 2 deg, and the integral action removing the offset
(depth within 1 cm of the command over the last 20 s of 200 s). The plant starts in its
own trim (for the environment effects: the design model's); the vehicle's speed loop (2 s)
holds the surge speed.
"""
from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest

from auv_depth_lqr.bound import settling_bound
from auv_depth_lqr.closed_loop import MODEL_ERRORS, model_error_plant, run_closed_loop
from auv_depth_lqr.metrics import step_metrics
from auv_depth_lqr.pilot import DepthPilot, PilotSettings
from auv_sim.params import VehicleParams, load_vehicle

ROOT = pathlib.Path(__file__).resolve().parents[1]
THETA_MAX = math.radians(25.0)
#: vehicle -> (u0 [m/s], z0, z1 [m])
CASES = {'a18m': (2.0, 40.0, 10.0), 'remus100': (1.5, 20.0, 10.0)}


#: Measured failures (strict xfails: they run and must fail), see docs/vehicles.md. Each
#: fails by a clear margin, on a bound that is the same on every machine to hundredths of a
#: second (tests/test_settling_bound_vehicles.py): with +1 % buoyancy the REMUS settles after
#: 54.2 s, 2.86x its 18.95 s bound (it would pass only at 37.9 s); in the following current
#: after 66.2 s, 3.5x; the weak fins leave it 1.14 m short of the command after 200 s (line
#: 0.01 m). The head current (39.4 s before the pitch envelope selector, line 37.9 s) now
#: settles after 35.7 s and passes.
KNOWN = {
    ('remus100', 'buoyancy+1%'): 'with the weights derived from the vehicle (Bryson on its '
                                 'Froude scales) the plane saturates holding the trim '
                                 'against 7 + 3 N of buoyancy: settled after 54.2 s, 2.9x '
                                 'the 18.95 s bound',
    ('remus100', 'current_following_0.3'): 'the pilot schedules and the speed loop holds the '
                                           'speed over ground: 1.2 m/s through the water, '
                                           'settled after 66.2 s, 3.5x the bound',
    ('remus100', 'fins*0.7'): 'with 30 % less fin lift the plane saturates holding the trim '
                              'against the 7 N of positive buoyancy: 1.14 m short of the '
                              'command after 200 s',
}


@pytest.fixture(scope='module', params=sorted(CASES))
def vehicle(request: pytest.FixtureRequest) -> tuple[str, VehicleParams, float]:
    name = request.param
    design = load_vehicle(ROOT / 'config' / f'{name}.yaml')
    u0, z0, z1 = CASES[name]
    return name, design, settling_bound(design, z0, z1, u0, THETA_MAX).settling_time


@pytest.mark.parametrize('effect', MODEL_ERRORS)
def test_pilot_off_its_design_model(vehicle: tuple[str, VehicleParams, float],
                                   effect: str, request: pytest.FixtureRequest) -> None:
    name, design, bound = vehicle
    if (name, effect) in KNOWN:
        request.applymarker(pytest.mark.xfail(strict=True, reason=KNOWN[(name, effect)]))
    u0, z0, z1 = CASES[name]
    real, environment = model_error_plant(design, effect)
    settings = PilotSettings()
    pilot = DepthPilot.for_vehicle(design, settings)
    run = run_closed_loop(real, [(0.0, z1)], 200.0, z0=z0, u0=u0, environment=environment,
                          settings=settings, pilot=pilot, speed_time_constant=2.0)
    rec = run.record
    theta = np.abs(rec.x[:, 4])
    m = step_metrics(rec.t, rec.x[:, 2], rec.x[:, 4], rec.x[:, 10], rec.x[:, 12], z1,
                     bar_max=design.bar_max, u0=u0, theta_max=THETA_MAX)
    assert np.max(theta) < math.radians(35.0), m
    assert np.max(theta) <= THETA_MAX + math.radians(2.0), m
    assert m.settling_time <= 2.0 * bound, (m, bound)
    last = rec.t > rec.t[-1] - 20.0
    assert np.max(np.abs(rec.x[last, 2] - z1)) < 0.01, m
