"""Hand-worked oracles of the simulator's effects of the registry that the gap catalogue
also implements: sensor scale and latency, a current sheared with depth and drifting in time,
a thrust error, added-mass and plane-effectiveness factors, and the registry itself."""
from __future__ import annotations

import numpy as np
import pytest
from conftest import A18M

from auv_sim.environment import (
    EFFECT_FIELDS,
    Environment,
    Sensors,
    declare_effect,
    parse_environment,
    undeclare_effect,
)
from auv_sim.errors import ParameterError
from auv_sim.model import current_ned, wrenches
from auv_sim.params import load_vehicle, mass_matrix
from auv_sim.simulator import Simulator


def test_depth_scale_reads_two_per_cent_more_of_a_constant_depth() -> None:
    env = parse_environment({'effects': {'depth_sensor_scale': {'scale': 1.02}}})
    sensors = env.sensors()
    x = np.zeros(15)
    x[2], x[4] = 50.0, 0.1
    for k in range(5):
        y = sensors.measure(0.1 * k, x)
        assert y[2] == pytest.approx(51.0, abs=1e-12)   # 1.02 x 50 m
        assert y[4] == 0.1


def test_latency_shifts_a_ramp_by_exactly_its_delay() -> None:
    sensors = Sensors(latency=(0.3, 0.12))
    dt = 0.02
    for k in range(200):
        t = k * dt
        x = np.zeros(12)
        x[2] = 40.0 + 0.5 * t          # depth ramp 0.5 m/s
        x[4] = -0.2 + 0.01 * t         # pitch ramp 0.01 rad/s
        x[6] = 2.0
        y = sensors.measure(t, x)
        assert y[6] == 2.0
        if t >= 0.3:
            assert y[2] == pytest.approx(40.0 + 0.5 * (t - 0.3), abs=1e-9)
        else:  # before the first sample the depth is taken as it was then
            assert y[2] == pytest.approx(40.0, abs=1e-12)
        if t >= 0.12:
            assert y[4] == pytest.approx(-0.2 + 0.01 * (t - 0.12), abs=1e-12)


def test_scale_latency_and_bias_compose() -> None:
    sensors = Sensors(scale=(0.98, 1.0), latency=(0.5, 0.0), bias=(0.3, 0.0))
    for k in range(101):
        t = 0.01 * k
        y = sensors.measure(t, np.array([0.0, 0.0, 10.0 + 2.0 * t] + [0.0] * 9))
    assert y[2] == pytest.approx(0.98 * (10.0 + 2.0 * 0.5) + 0.3, abs=1e-9)
    with pytest.raises(ParameterError, match='went back'):
        sensors.measure(0.5, np.zeros(12))


def test_simulator_measures_through_the_sensor_model(tmp_path) -> None:  # type: ignore
    vehicle = load_vehicle(A18M)
    env = parse_environment({'effects': {'pitch_sensor_scale': {'scale': 1.1},
                                         'depth_sensor_bias': {'bias': 0.5}}})
    x0 = np.zeros(15)
    x0[2], x0[4], x0[6] = 30.0, 0.05, 2.0
    sim = Simulator(vehicle, env, x0=x0)
    y = sim.measured_state()
    assert y[2] == pytest.approx(30.5, abs=1e-12)
    assert y[4] == pytest.approx(0.055, abs=1e-12)


def test_current_shear_and_drift_by_hand() -> None:
    env = parse_environment({'effects': {'current': {'north': 0.1},
                                         'current_shear': {'north': 0.002, 'east': -0.001},
                                         'current_drift': {'north': 1e-4, 'east': 2e-4}}})
    vn, ve, vd, gn, ge, gd, tn, te, td = current_ned(500.0, 80.0, env.env_vector(),
                                                     env.profile())
    assert vn == pytest.approx(0.1 + 0.002 * 80.0 + 1e-4 * 500.0, abs=1e-15)   # 0.31 m/s
    assert ve == pytest.approx(-0.001 * 80.0 + 2e-4 * 500.0, abs=1e-15)        # 0.02 m/s
    assert vd == 0.0
    assert (gn, ge, gd) == (0.002, -0.001, 0.0)
    assert (tn, te, td) == (1e-4, 2e-4, 0.0)


def test_thrust_error_scales_the_propeller_force() -> None:
    vehicle = load_vehicle(A18M)
    env = parse_environment({'effects': {'thrust_error': {'gain': 1.2}}})
    x = np.zeros(15)
    x[6], x[14] = 2.0, 80.0
    out = np.empty((4, 6))
    wrenches(0.0, x, vehicle.as_array(), env.env_vector(), env.profile(), out)
    assert out[3, 0] == pytest.approx(96.0, abs=1e-12)   # 1.2 x 80 N


def test_factor_effects_change_the_vehicle() -> None:
    vehicle = load_vehicle(A18M)
    env = parse_environment({'effects': {'added_mass': {'Zwdot': 1.3},
                                         'plane_effectiveness': {'gain': 0.7},
                                         'coefficients': {'CZuw': 1.25, 'CZbar': 2.0}}})
    real = env.apply_to(vehicle)
    assert real.Zwdot == pytest.approx(1.3 * vehicle.Zwdot)
    assert real.Mqdot == vehicle.Mqdot
    assert real.CZuw == pytest.approx(1.25 * vehicle.CZuw)
    assert real.CZbar == pytest.approx(0.7 * 2.0 * vehicle.CZbar)
    assert real.CMbar == pytest.approx(0.7 * vehicle.CMbar)
    # heave entry of M = m - Zwdot (Fossen's sign: Zwdot < 0)
    assert mass_matrix(real)[2, 2] == pytest.approx(vehicle.m - 1.3 * vehicle.Zwdot)


def test_registry_declares_every_simulated_effect_and_plug_ins() -> None:
    assert {'current_shear', 'current_drift', 'added_mass', 'depth_sensor_scale',
            'depth_sensor_latency', 'pitch_sensor_scale',
            'pitch_sensor_latency'} <= set(EFFECT_FIELDS)
    assert EFFECT_FIELDS['current_shear']['north'] == ('1/s', 0.0)
    with pytest.raises(ParameterError, match='must be >= 0'):
        parse_environment({'effects': {'depth_sensor_latency': {'latency': -0.1}}})
    declare_effect('test_plugin', {'gain': ('-', 1.0)})
    try:
        with pytest.raises(ParameterError, match='declared already'):
            declare_effect('test_plugin', {'gain': ('-', 1.0)})
        with pytest.raises(ParameterError, match='does not implement'):
            parse_environment({'effects': {'test_plugin': {'gain': 2.0}}})
    finally:
        undeclare_effect('test_plugin')
    assert 'test_plugin' not in EFFECT_FIELDS
    assert Environment().sensors().measure(0.0, np.arange(12.0))[2] == 2.0


def _wrench(effects: dict[str, dict[str, float]], x: np.ndarray, t: float = 0.0) -> np.ndarray:
    vehicle = load_vehicle(A18M)
    env = parse_environment({'effects': effects})
    out = np.empty((4, 6))
    wrenches(t, x, vehicle.as_array(), env.env_vector(), env.profile(), out)
    return out


def test_thrust_line_below_the_origin_pitches_the_nose_up_by_z_times_thrust() -> None:
    # force (T, 0, 0) at r = (0, 0, zt) body FRD: moment r x F = (0, zt T, 0)
    x = np.zeros(15)
    x[6], x[14] = 2.0, 80.0
    base = _wrench({}, x)
    out = _wrench({'thrust_moment': {'zt': 0.03}}, x)
    assert out[3, 4] - base[3, 4] == pytest.approx(0.03 * 80.0, abs=1e-12)   # 2.4 N m
    assert out[3, 0] == base[3, 0] == 80.0
    # with a thrust error the moment follows the force actually delivered
    out = _wrench({'thrust_moment': {'zt': -0.02}, 'thrust_error': {'gain': 1.25}}, x)
    assert out[3, 4] - base[3, 4] == pytest.approx(-0.02 * 100.0, abs=1e-12)


def test_plane_stall_saturates_the_lift_angle_as_a_tanh() -> None:
    vehicle = load_vehicle(A18M)
    x = np.zeros(15)
    x[6] = 2.0
    x[12] = np.radians(20.0)
    a = np.radians(10.0)
    free = _wrench({}, x)
    stalled = _wrench({'plane_stall': {'angle': a}}, x)
    # lift 1/2 rho S u^2 CZbar bar with bar -> a tanh(bar / a) = 0.1745 tanh(2) = 0.1683 rad
    q = 0.5 * vehicle.rho * vehicle.S_ref * 2.0 * 2.0
    assert stalled[3, 2] == pytest.approx(q * vehicle.CZbar * a * np.tanh(2.0), rel=1e-12)
    assert stalled[3, 2] / free[3, 2] == pytest.approx(0.1683 / 0.3491, abs=2e-4)
    x[12] = np.radians(0.5)   # small angles: within 0.1 % of the linear lift
    assert _wrench({'plane_stall': {'angle': a}}, x)[3, 4] == pytest.approx(
        _wrench({}, x)[3, 4], rel=1e-3)
    with pytest.raises(ParameterError, match=r'plane_stall\.angle must be >= 0'):
        parse_environment({'effects': {'plane_stall': {'angle': -0.1}}})


def test_buoyancy_drift_adds_rate_times_time_to_the_buoyancy() -> None:
    x = np.zeros(15)
    x[2] = 30.0
    at0 = _wrench({'buoyancy_drift': {'rate': -0.01}}, x, t=0.0)
    at600 = _wrench({'buoyancy_drift': {'rate': -0.01}}, x, t=600.0)
    # level: heave restoring force W - B; 600 s at -0.01 N/s loses 6 N of buoyancy
    assert at600[2, 2] - at0[2, 2] == pytest.approx(6.0, abs=1e-9)
    assert at0[2, 2] == pytest.approx(_wrench({}, x)[2, 2], abs=1e-12)


def test_depth_sensor_drift_adds_a_bias_growing_from_zero() -> None:
    sensors = parse_environment({'effects': {'depth_sensor_drift': {'rate': 1e-4}}}).sensors()
    x = np.zeros(15)
    x[2], x[4] = 40.0, 0.05
    for t in (0.0, 100.0, 3600.0):
        y = sensors.measure(t, x)
        assert y[2] == pytest.approx(40.0 + 1e-4 * t, abs=1e-12)   # 0.36 m after an hour
        assert y[4] == 0.05
