"""The reference governor on an open-loop-unstable vehicle (REMUS 100) and on a stable one.

Oracle: the governed reference itself, flown by a vehicle that follows it exactly (the state
handed to the controller is the reference's own depth and vertical speed): it must reach the
commanded depth, never pass it, and keep its acceleration within the governor's limit (plus
one sample of jerk), where the held-plane stop of the series model ran away (8.8 m/s,
6.9 m/s^2 before the kinematic stop).
"""
from __future__ import annotations

import math
import pathlib

import pytest

from auv_depth_lqr.controller import PlaneState
from auv_depth_lqr.pilot import PilotSettings, build_controller
from auv_sim.params import load_vehicle

ROOT = pathlib.Path(__file__).resolve().parents[1]


@pytest.mark.parametrize(('name', 'kinematic'), [('remus100', True), ('a18m', False),
                                                 ('npsauv2', False)])
def test_stop_model_follows_open_loop_stability(name: str, kinematic: bool) -> None:
    params = load_vehicle(ROOT / 'config' / f'{name}.yaml')
    ctrl = build_controller(params, PilotSettings(speeds=(1.3, 1.5, 2.0)))
    assert ctrl.kinematic_stop is kinematic


@pytest.mark.parametrize(('z0', 'z1'), [(20.0, 10.0), (10.0, 30.0)])
def test_reference_of_unstable_vehicle_stops_on_target(z0: float, z1: float) -> None:
    params = load_vehicle(ROOT / 'config' / 'remus100.yaml')
    ctrl = build_controller(params, PilotSettings(speeds=(1.3, 1.5, 2.0)))
    u, z, v = 1.5, z0, 0.0
    travel = math.copysign(1.0, z1 - z0)
    a_lim = ctrl.governor.accel_max + 2.0 * ctrl.governor.accel_max / ctrl.governor.jerk_time \
        * ctrl.Ts
    peak_a = 0.0
    for _ in range(1200):
        theta = -math.asin(max(-1.0, min(1.0, v / u)))
        ctrl.step(PlaneState(z=z, theta=theta, w=0.0, q=0.0, u=u), z1)
        ref = ctrl.governed_reference
        assert ref is not None
        z, v = ref
        peak_a = max(peak_a, abs(ctrl.reference.reference.a))  # type: ignore[union-attr]
        assert travel * (z - z1) <= 1e-9          # never passes the target
    assert z == pytest.approx(z1, abs=1e-3) and abs(v) < 1e-3
    assert peak_a <= a_lim
