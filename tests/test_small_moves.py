"""Short depth changes, and a depth hold on a noisy depth sensor.

A short depth change from rest (``GovernorSettings.short_swings``: one the speed-up's jerk
would fly in four plane swings) follows a critically damped fourth-order filter of the
command, its speed, acceleration, jerk and snap proportional to its length. Planned as a
time-optimal manoeuvre instead, its jerk and snap were at their limits whatever its length:
a 1 cm change moved the A18M's plane 15 deg and overshot by 9 cm; the reference started at a
noisy depth reading 1 mm off the command, or a 5-10 cm change, put the small AUV's plane at
its stop, which its 20 deg/s servo could not take back before the vehicle pitched past
40 deg.

Oracle (a hand estimate): moving 1 cm in a few seconds takes a vertical speed under 1 cm/s,
a pitch of a fraction of a degree at 1.5 m/s, so a plane within a tenth of its travel of
trim; moving 10 cm in ten seconds takes a few centimetres per second, a pitch of a few
degrees; a filter of the command never passes it; the measured depth's 2 cm of white noise
(``SensorNoise.realistic``) moves the reference not at all.
"""
from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest

from auv_depth_lqr.closed_loop import run_closed_loop
from auv_depth_lqr.pilot import DepthPilot, PilotSettings
from auv_gap import synth
from auv_ident.vehicle_init import estimate
from auv_sim.model import STATE_NAMES
from auv_sim.params import VehicleParams, load_vehicle
from auv_sim.trim import VerticalPlane

ROOT = pathlib.Path(__file__).resolve().parents[1]
THETA = STATE_NAMES.index('theta')


def small_auv() -> VehicleParams:
    """A 1.4 m, 0.15 m, 20 kg vehicle as ``auv vehicle-init`` estimates it, trimmed neutral:
    open-loop unstable, with a twentieth of the REMUS 100 file's quadratic pitch damping."""
    params, _ = estimate(1.4, 0.15, 20.0, load_vehicle(ROOT / 'config' / 'remus100.yaml'),
                         'small_auv')
    return params.replace(B=params.W)


def vehicle(name: str) -> VehicleParams:
    return small_auv() if name == 'small_auv' else load_vehicle(ROOT / 'config' / f'{name}.yaml')


@pytest.mark.parametrize('name', ['small_auv', 'remus100', 'a18m', 'npsauv2'])
def test_a_one_centimetre_change_barely_moves_the_plane(name: str) -> None:
    params = vehicle(name)
    z0, z1, u0 = 5.0, 5.01, 1.5
    trim = VerticalPlane(params).trim(u0, z=z0)
    run = run_closed_loop(params, [(0.0, z1)], 30.0, z0=z0, u0=u0,
                          pilot=DepthPilot.for_vehicle(params, PilotSettings()))
    z = run.record.x[:, 2]
    theta = run.record.x[:, THETA]
    assert np.max(np.abs(run.bar - trim.bar)) <= 0.1 * params.bar_max
    assert np.max(np.abs(theta - trim.theta)) <= math.radians(1.0)
    assert np.max(z) <= z1 + 0.002                   # no overshoot beyond 2 mm
    assert abs(z[-1] - z1) <= 0.002


@pytest.mark.parametrize('seed', [0, 1, 2])
def test_small_auv_holds_depth_on_a_noisy_depth_sensor(seed: int) -> None:
    params = small_auv()
    thrust = VerticalPlane(params).trim(1.5, z=2.0).thrust
    scenario = synth.Scenario(duration=60.0, z0=2.0, u0=1.5, depth=((0.0, 2.0),),
                              thrust=((0.0, thrust),), doublets=())
    log = synth.simulate(params, None, scenario, seed=seed)
    assert np.max(np.abs(log.true_state[:, THETA])) <= math.radians(3.0)
    assert np.max(np.abs(log.true_state[:, 2] - 2.0)) <= 0.1


@pytest.mark.parametrize('name', ['small_auv', 'remus100', 'a18m', 'npsauv2'])
@pytest.mark.parametrize('dz', [0.05, 0.1, -0.1])
def test_a_short_change_keeps_the_pitch_within_a_few_degrees(name: str, dz: float) -> None:
    params = vehicle(name)
    z0, u0 = 5.0, 1.5
    trim = VerticalPlane(params).trim(u0, z=z0)
    run = run_closed_loop(params, [(0.0, z0 + dz)], 40.0, z0=z0, u0=u0,
                          pilot=DepthPilot.for_vehicle(params, PilotSettings()))
    theta = run.record.x[:, THETA]
    z = run.record.x[:, 2]
    assert np.max(np.abs(theta - trim.theta)) <= math.radians(5.0)
    assert np.max(np.sign(dz) * (z - (z0 + dz))) <= 0.01     # no overshoot beyond 1 cm
    assert abs(z[-1] - (z0 + dz)) <= 0.005
