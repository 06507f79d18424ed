"""A third vehicle class: the NPS AUV II (5.3 m, 5443 kg; Healey and Lienard 1993).

The vehicle file config/npsauv2.yaml is derived from the prime (rho/2 L^k) derivatives that
Fossen's MSS toolbox gives for it (CRAFT/AUV/models/npsauv.m). Oracles, typed in here from
that source independently of the file's nondimensional values: the dimensional linear
derivatives, the strip-theory cross-flow integrals (by numerical quadrature of npsauv.m's
strip sum), Healey and Lienard's linearised vertical-plane equations, and the time-optimal
settling bound of the vehicle's own model for the pilot.
"""
from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest
from scipy.integrate import quad
from test_remus100 import wrench_derivatives

from auv_depth_lqr.bound import settling_bound
from auv_depth_lqr.closed_loop import run_closed_loop
from auv_depth_lqr.metrics import step_metrics
from auv_depth_lqr.pilot import PilotSettings
from auv_sim.params import VehicleParams, load_vehicle
from auv_sim.trim import VerticalPlane

ROOT = pathlib.Path(__file__).resolve().parents[1]
RHO, L, W, ZG, IY = 1025.0, 5.3, 53400.0, 0.061, 13587.0     # npsauv.m
R2, R3, R4, R5 = (0.5 * RHO * L**k for k in (2, 3, 4, 5))
PRIME = {'Zw': -0.30, 'Zq': -0.14, 'Muw': 0.10, 'Muq': -0.068, 'Zds': -0.073,
         'Mds': -0.041, 'Yv': -0.10, 'Yr': 0.03, 'Nv': -7.4e-3, 'Nr': -0.016, 'Ydr': 0.027,
         'Ndr': -0.013, 'Zwdot': -0.24, 'Zqdot': -6.8e-3, 'Mqdot': -0.017}
CDY, CDZ, HX, BX = 0.5, 0.6, 0.53, 0.53
THETA_MAX = math.radians(25.0)


@pytest.fixture(scope='module')
def nps() -> VehicleParams:
    return load_vehicle(ROOT / 'config' / 'npsauv2.yaml')


@pytest.mark.parametrize('u', [1.5, 2.0])
def test_forces_equal_the_published_derivatives(nps: VehicleParams, u: float) -> None:
    got = wrench_derivatives(nps, u)
    p = PRIME
    expected = {'Zuw': R2 * p['Zw'], 'Zuq': R3 * p['Zq'], 'Muw': R3 * p['Muw'],
                'Muq': R4 * p['Muq'], 'Zuuds': R2 * p['Zds'], 'Muuds': R3 * p['Mds'],
                'Yuv': R2 * p['Yv'], 'Yur': R3 * p['Yr'], 'Nuv': R3 * p['Nv'],
                'Nur': R4 * p['Nr'], 'Yuudr': R2 * p['Ydr'], 'Nuudr': R3 * p['Ndr']}
    for name, value in expected.items():
        assert got[name] == pytest.approx(value, rel=1e-9), name


def test_crossflow_is_the_strip_integral(nps: VehicleParams) -> None:
    """npsauv.m's strip sum, as an integral over the hull, for pure heave / pitch rate."""
    zww = -0.5 * RHO * CDZ * BX * quad(lambda x: 1.0, -L / 2, L / 2)[0]
    mqq = -0.5 * RHO * CDZ * BX * quad(lambda x: abs(x) ** 3, -L / 2, L / 2)[0]
    yvv = -0.5 * RHO * CDY * HX * L
    nrr = -0.5 * RHO * CDY * HX * quad(lambda x: abs(x) ** 3, -L / 2, L / 2)[0]
    assert (nps.Zww, nps.Mqq, nps.Yvv, nps.Nrr) == pytest.approx((zww, mqq, yvv, nrr),
                                                                 rel=1e-12)
    assert nps.Mww == nps.Zqq == 0.0       # fore-aft symmetric strips


@pytest.mark.parametrize('u0', [1.0, 1.5, 2.5])
def test_open_loop_vertical_plane_is_healey_and_stable(nps: VehicleParams, u0: float) -> None:
    """Neutral vehicle: trim at zero pitch and plane; (w, q, theta) Jacobian equals the
    linearised equations (m - Zwdot) w' - Zqdot q' = Zw u w + (Zq + m) u q,
    (Iy - Mqdot) q' - Mwdot w' = Muw u w + Muq u q - zg W theta; stable, unlike the REMUS."""
    plane = VerticalPlane(nps)
    trim = plane.trim(u0, z=30.0)
    assert abs(trim.theta) < 1e-12 and abs(trim.bar) < 1e-12
    A, _ = plane.linearize(trim)
    m = W / 9.81
    zwd, zqd, mqd = R3 * PRIME['Zwdot'], R4 * PRIME['Zqdot'], R5 * PRIME['Mqdot']
    mass = np.array([[m - zwd, -zqd], [-zqd, IY - mqd]])
    forces = np.array([[R2 * PRIME['Zw'] * u0, (R3 * PRIME['Zq'] + m) * u0, 0.0],
                       [R3 * PRIME['Muw'] * u0, R4 * PRIME['Muq'] * u0, -ZG * W]])
    expected = np.zeros((3, 3))
    expected[:2] = np.linalg.solve(mass, forces)
    expected[2, 1] = 1.0
    np.testing.assert_allclose(A[np.ix_([0, 1, 3], [0, 1, 3])], expected, rtol=1e-9,
                               atol=1e-12)
    assert max(np.linalg.eigvals(expected).real) < 0.0


@pytest.mark.parametrize(('z0', 'z1'), [(20.0, 10.0), (10.0, 30.0), (5.0, 40.0)])
def test_pilot_flies_depth_changes(nps: VehicleParams, z0: float, z1: float) -> None:
    """Default pilot settings, 1.5 m/s, the vehicle's speed loop (2 s): settled within 1.5x
    the time-optimal bound, pitch and plane within limits. Measured: 28.1 / 23.29 s,
    45.3 / 40.13 s, 71.1 / 65.39 s (ratios 1.21, 1.13, 1.09: 19 % or more under the line);
    peak pitch 24.5 deg; no overshoot."""
    run = run_closed_loop(nps, [(0.0, z1)], 150.0, z0=z0, u0=1.5, settings=PilotSettings(),
                          speed_time_constant=2.0)
    rec = run.record
    m = step_metrics(rec.t, rec.x[:, 2], rec.x[:, 4], rec.x[:, 10], rec.x[:, 12], z1,
                     bar_max=nps.bar_max, u0=1.5, theta_max=THETA_MAX)
    assert np.max(np.abs(rec.x[:, 4])) <= THETA_MAX + 1e-6, m
    assert np.max(np.abs(rec.x[:, 12])) <= nps.bar_max + 1e-9
    bound = settling_bound(nps, z0, z1, 1.5, THETA_MAX).settling_time
    assert m.settling_time <= 1.5 * bound, (m, bound)
