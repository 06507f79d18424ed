"""The surge speed a held-thrust vehicle is heading for (auv_depth_lqr.surge): the surge time
constant from the vehicle file's trims against the simulator's own thrust-step response, the
filtered trend against a ramp worked by hand, and the stop it plans."""
from __future__ import annotations

import dataclasses
import math
import pathlib

import numpy as np
import pytest

from auv_depth_lqr.controller import DepthController, PlaneState
from auv_depth_lqr.pilot import PilotSettings, build_controller, trimmable_speeds
from auv_depth_lqr.surge import SurgeTrend, surge_length
from auv_sim.params import VehicleParams, load_vehicle
from auv_sim.simulator import Simulator
from auv_sim.trim import VerticalPlane

CONFIG = pathlib.Path(__file__).resolve().parents[1] / 'config'


@pytest.fixture(scope='module')
def a18m() -> VehicleParams:
    return load_vehicle(CONFIG / 'a18m.yaml')


@pytest.mark.parametrize('name', ['a18m.yaml', 'npsauv2.yaml'])
def test_surge_length_is_the_simulated_thrust_step_response(name: str) -> None:
    """Second method: the level-trimmed vehicle at 2 m/s, its thrust stepped by +2 %, in the
    simulator (6-DOF RK4): the surge speed reaches 63.2 % of its change after the time
    constant surge_length / u (within 3 %; the step is small, so the drag is linear in it)."""
    params = load_vehicle(CONFIG / name)
    length = surge_length(params, trimmable_speeds(params, PilotSettings().speeds))
    trim = VerticalPlane(params).trim(2.0)
    sim = Simulator(params, x0=trim.state())
    thrust = 1.02 * trim.thrust
    sim.command('thrust', thrust)
    t, u = [0.0], [float(sim.x[6])]
    while sim.t < 8.0 * length / 2.0:
        sim.advance(0.1)
        t.append(sim.t)
        u.append(float(sim.x[6]))
    u_end = u[-1]
    rise = np.interp(u[0] + (1.0 - math.exp(-1.0)) * (u_end - u[0]), u, t)
    assert u_end > u[0]
    assert rise == pytest.approx(length / 2.0, rel=0.03)


def test_the_trend_of_a_ramp_is_its_slope() -> None:
    """By hand: each first-order low-pass of a ramp of slope a lags it by a * time in steady
    state (discrete: a Ts (1 - alpha) / alpha = a time), so (u1 - u2) / time = a exactly, and
    the speed it heads for is u + (surge_length / u) a."""
    trend = SurgeTrend(surge_length=26.0, time=1.0, ts=0.1)
    a = -0.02
    for k in range(600):
        u = 2.0 + a * 0.1 * k
        heading = trend.update(u)
    assert trend.rate == pytest.approx(a, abs=1e-9)
    assert heading == pytest.approx(u + 26.0 / u * a, abs=1e-9)
    off = SurgeTrend(surge_length=0.0, time=1.0, ts=0.1)
    for k in range(50):
        assert off.update(2.0 - 0.002 * k) == 2.0 - 0.002 * k


def test_a_slowing_vehicle_gets_an_earlier_stop(a18m: VehicleParams) -> None:
    """A vehicle commanded 10 -> 20 m whose depth follows the reference exactly but whose
    surge speed falls at 0.02 m/s^2 to 1.6 m/s (a held propeller in a positively buoyant
    dive): planned at the speed it is heading for, the reference brakes earlier than the one
    planned at the measured speed (surge_length 0): 20 s in, it is shallower and slower, and
    neither passes the command. (The disturbance estimate is off: the state fed here is
    not a dynamic one.)"""
    base = build_controller(a18m, PilotSettings())
    assert base.governor.surge_length == pytest.approx(
        surge_length(a18m, base.design.speeds), rel=1e-12)
    at_20s = {}
    for length in (base.governor.surge_length, 0.0):
        governor = dataclasses.replace(base.governor, surge_length=length,
                                       disturbance_estimate=False)
        ctrl = DepthController(base.design, base.limits, base.Ts, governor)
        z = 10.0
        for k in range(601):
            u = max(2.0 - 0.002 * k, 1.6)
            ctrl.step(PlaneState(z=z, theta=0.0, w=0.0, q=0.0, u=u), 20.0)
            ref = ctrl.governed_reference
            assert ref is not None and ref[0] <= 20.0 + 1e-9
            z = ref[0]
            if k == 200:
                at_20s[length] = ref
        assert z == pytest.approx(20.0, abs=0.03)
    predicted, measured = at_20s[base.governor.surge_length], at_20s[0.0]
    assert predicted[0] < measured[0] - 0.05 and predicted[1] < measured[1] - 0.01
