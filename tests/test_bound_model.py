"""The settling bound's vertical plane is the simulator's model and RK4 (auv_depth_lqr.bound).

Checked against a second formulation and a second integrator: the surge-held right-hand
side of :mod:`auv_sim.model` against the textbook vertical-plane reduction
``M_wq [w_dot, q_dot] = [Z, M]`` of :class:`auv_sim.trim.VerticalPlane`, the RK4 steps against
scipy's adaptive RK45 at a tight tolerance, and the complex-step Jacobians against central
differences.
"""
from __future__ import annotations

import pathlib

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from auv_depth_lqr.bound import PlaneModel
from auv_sim.environment import Environment
from auv_sim.model import NX, surge_held_dynamics
from auv_sim.params import VehicleParams, load_vehicle
from auv_sim.trim import VerticalPlane

CONFIG = pathlib.Path(__file__).resolve().parents[1] / 'config'
U0, STEP = 2.0, 0.2  # m/s, s


@pytest.fixture(scope='module', params=['a18m', 'remus100'])
def params(request: pytest.FixtureRequest) -> VehicleParams:
    return load_vehicle(CONFIG / f'{request.param}.yaml')


def test_surge_held_rates_are_the_vertical_plane_reduction(params: VehicleParams) -> None:
    plane = VerticalPlane(params)
    calm = Environment()
    P = plane.params.as_array()
    rng = np.random.default_rng(3)
    for _ in range(20):
        w, q, z, theta = rng.uniform([-0.3, -0.1, 0.0, -0.5], [0.3, 0.1, 80.0, 0.5])
        bar = rng.uniform(-params.bar_max, params.bar_max)
        x = np.zeros(NX)
        x[2], x[4], x[6], x[8], x[10], x[12] = z, theta, U0, w, q, bar
        cmd = np.array([bar, 0.0, 0.0])
        xdot = np.empty(NX)
        surge_held_dynamics(0.0, x, cmd, P, calm.env_vector(), calm.profile(), xdot,
                            np.empty((4, 6)))
        reduced = plane.rates(np.array([w, q, z, theta, 0.0]), bar, U0).real
        scale = np.abs(reduced[:4]) + 1e-9
        assert abs(xdot[6]) < 1e-12                            # surge held
        assert np.max(np.abs(xdot[[7, 9, 11]])) < 1e-12        # no sway, roll or yaw
        assert xdot[12] == 0.0                                 # the plane rests at its command
        got = xdot[[8, 10, 2, 4]]
        assert np.max(np.abs(got - reduced[:4]) / scale) < 1e-9


def _final_state_error(params: VehicleParams, step: float) -> tuple[np.ndarray, float]:
    """Error (4,) of the RK4 steps of ``step`` [s] against RK45 (rtol 1e-11) at the end of
    30 s of plane steps of half the plane's range for 6 s each, and the depth moved [m]."""
    model = PlaneModel(params, U0, step)
    trim = model.plane.trim(U0)
    t = np.arange(int(round(30.0 / step))) * step
    plane = 0.5 * params.bar_max * np.sign(np.sin(2 * np.pi * (t + 1e-9) / 12.0))
    bars = np.clip(trim.bar + plane, -params.bar_max, params.bar_max)
    X0 = np.array([trim.w, 0.0, 30.0, trim.theta])
    ours = model.simulate(X0, bars)[-1]
    X = X0
    for b in bars:
        X = solve_ivp(lambda _t, y, b=b: model.plane.rates(np.r_[y, 0.0], b, U0).real[:4],
                      (0.0, step), X, method='RK45', rtol=1e-11, atol=1e-12).y[:, -1]
    return np.abs(ours - X), abs(float(X[2]) - 30.0)


def test_rk4_steps_converge_to_an_adaptive_integrator_at_fourth_order(
        params: VehicleParams) -> None:
    coarse, moved = _final_state_error(params, 0.1)
    fine, _ = _final_state_error(params, 0.05)
    assert moved > 1.0                        # the plane steps move the vehicle [m]
    assert fine[2] < 1e-4                     # depth [m]
    assert fine[2] < coarse[2] / 8.0          # halving the step: ~1/16 for RK4


def test_complex_step_jacobians_match_central_differences(params: VehicleParams) -> None:
    model = PlaneModel(params, U0, STEP)
    X = np.array([0.05, 0.02, 20.0, 0.3])
    bar = 0.1
    A, B = model.jacobians(X, bar)
    h = 1e-6
    for j in range(4):
        e = np.zeros(4)
        e[j] = h
        fd = (model.step(X + e, bar).real - model.step(X - e, bar).real) / (2 * h)
        np.testing.assert_allclose(A[:, j], fd, rtol=1e-6, atol=1e-8)
    fd = (model.step(X, bar + h).real - model.step(X, bar - h).real) / (2 * h)
    np.testing.assert_allclose(B, fd, rtol=1e-6, atol=1e-8)
