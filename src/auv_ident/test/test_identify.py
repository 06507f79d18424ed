"""Identification core on arrays: exact recovery, identifiability errors, Nelder-Mead
equivalence, the consistent derivative filter, the actuator reconstruction and the standard
errors of forces from motion (sensor-noise propagation, flat-top lag window)."""
from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest
from scipy.signal import savgol_filter

from auv_ident.errors import IdentificationError, NotIdentifiableError
from auv_ident.identify import (
    EQUATIONS,
    ForceRecord,
    build_system,
    fit_equation,
    flat_top_lag,
    identify,
    nelder_mead,
    regressor_columns,
    sensor_noise_meat,
    solve,
)
from auv_ident.motion import actuator_positions, consistent_kernel, noise_sigma, reconstruct
from auv_sim.environment import Environment
from auv_sim.missions import load_mission, run_mission
from auv_sim.model import (
    HYDRO_AXIS,
    HYDRO_TERMS,
    actuator_steps,
    hydro_basis_series,
    rk4_steps,
    wrench_series,
)
from auv_sim.params import VehicleParams, load_vehicle
from auv_sim.simulator import Record

A18M = pathlib.Path(__file__).resolve().parents[3] / 'config' / 'a18m.yaml'
DT = 0.02


@pytest.fixture(scope='module')
def base() -> VehicleParams:
    return load_vehicle(A18M)


def synthetic(base: VehicleParams, n: int = 20000, pitch: bool = True, yaw: bool = True,
              noise: float = 0.0, seed: int = 0, collinear: bool = False) -> ForceRecord:
    """Velocities with independent excitation; forces from the model's own hydrodynamic row."""
    t = DT * np.arange(n)
    nu = np.zeros((n, 6))
    nu[:, 0] = 2.0 + 0.6 * np.sin(2 * np.pi * t / 300.0)
    nu[:, 2] = 0.03 * np.sin(2 * np.pi * t / 23.0) + 0.01
    nu[:, 4] = (0.02 * np.sin(2 * np.pi * t / 9.0) if not collinear else 0.5 * nu[:, 2]) * pitch
    nu[:, 1] = 0.03 * np.sin(2 * np.pi * t / 17.0) * yaw
    nu[:, 5] = 0.02 * np.sin(2 * np.pi * t / 7.0 + 1.0) * yaw
    X = np.zeros((n, 15))
    X[:, 6:12] = nu
    env = Environment()
    tau = wrench_series(t, X, base.as_array(), env.env_vector(), env.profile())[:, 0, :].copy()
    if noise:
        tau += noise * np.random.default_rng(seed).standard_normal(tau.shape)
    return ForceRecord('synthetic', t, nu, tau)


def test_least_squares_recovers_the_model_coefficients_exactly(base: VehicleParams) -> None:
    result = identify([synthetic(base)], base, fit_offsets=True)
    for name, c in result.coefficients.items():
        assert c.value == pytest.approx(base.values[name], rel=1e-9), name
    assert result.fits['heave'].r2 == pytest.approx(1.0, abs=1e-12)
    assert result.params.CZuq == pytest.approx(base.CZuq, rel=1e-9)


def test_no_pitch_excitation_names_the_coefficient_and_the_manoeuvre(base: VehicleParams) -> None:
    with pytest.raises(NotIdentifiableError,
                       match=r'^CZuq: pitch rate q never varies by more than 0 deg/s .*'
                             r'fly the pitch mission \(plane doublets\)$'):
        identify([synthetic(base, pitch=False)], base, equations=['heave'])


def test_no_yaw_excitation_is_an_error(base: VehicleParams) -> None:
    with pytest.raises(NotIdentifiableError, match=r'^CYuv: sway velocity v .*yaw'):
        identify([synthetic(base, yaw=False)], base, equations=['sway'])


def test_collinear_regressors_are_not_identifiable(base: VehicleParams) -> None:
    with pytest.raises(NotIdentifiableError, match=r'CZuw and CZuq cannot be told apart'):
        identify([synthetic(base, collinear=True)], base, equations=['heave'])


def test_out_of_order_stamps_are_an_error(base: VehicleParams) -> None:
    rec = synthetic(base, n=2000)
    t = rec.t.copy()
    t[100], t[101] = t[101], t[100]
    with pytest.raises(IdentificationError, match=r'time stamps out of order at sample 101'):
        identify([ForceRecord('x', t, rec.nu, rec.tau)], base)


@pytest.mark.parametrize('equation', list(EQUATIONS))
def test_bounded_nelder_mead_finds_the_least_squares_solution(base: VehicleParams,
                                                              equation: str) -> None:
    system = build_system([synthetic(base, noise=5.0, seed=3)], EQUATIONS[equation], base, True)
    theta, _ = solve(system)
    start = [0.5 * base.values[n] for n in system.names]  # a poor start, as a prior would be
    nm = nelder_mead(system, start, {n: (-100.0, 100.0) for n in system.names})
    np.testing.assert_allclose(nm, theta, rtol=1e-6)
    assert system.sum_of_squares(nm) <= system.sum_of_squares(theta) * (1 + 1e-12)


def test_active_bound_agrees_with_nelder_mead(base: VehicleParams) -> None:
    system = build_system([synthetic(base, noise=5.0)], EQUATIONS['heave'], base, False)
    bounds = {'CZuw': (-10.0, -3.2)}  # excludes the true -3.105
    theta, at_bound = solve(system, bounds)
    assert theta[0] == pytest.approx(-3.2, abs=1e-12) and at_bound.tolist() == [True, False]
    nm = nelder_mead(system, [-5.0, -1.0], bounds)
    np.testing.assert_allclose(nm, theta, rtol=1e-6)


def test_autocorrelated_residuals_widen_the_interval(base: VehicleParams) -> None:
    rec = synthetic(base)
    rng = np.random.default_rng(5)
    e = np.zeros(len(rec.t))
    white = rng.standard_normal(len(rec.t))
    for k in range(1, len(e)):  # AR(1), correlation time about 100 samples
        e[k] = 0.98 * e[k - 1] + white[k]
    tau = rec.tau.copy()
    tau[:, 2] += 3.0 * e
    system = build_system([ForceRecord('ar1', rec.t, rec.nu, tau)], EQUATIONS['heave'], base)
    iid = fit_equation(system, base, errors='iid')
    hac = fit_equation(system, base, errors='hac')
    ess = fit_equation(system, base, errors='ess')
    assert hac.coefficients[0].std_error > 4 * iid.coefficients[0].std_error
    assert ess.n_effective < len(rec.t) / 20


def test_savgol_derivative_is_the_consistent_kernel_of_the_derivative() -> None:
    """SG slope = parabolic-weighted mean of increments; the kernel maps nu_dot the same way."""
    t = DT * np.arange(400)
    x = np.sin(0.7 * t) + 0.3 * np.cos(2.3 * t)
    xdot = 0.7 * np.cos(0.7 * t) - 0.69 * np.sin(2.3 * t)
    window = 51
    k = consistent_kernel(window)
    assert k.sum() == pytest.approx(1.0, abs=1e-15) and np.allclose(k, k[::-1])
    sg = savgol_filter(x, window, 2, deriv=1, delta=DT)
    filt = np.convolve(xdot, k, mode='same')
    m = window // 2
    np.testing.assert_allclose(sg[m:-m], filt[m:-m], atol=2e-4)  # trapezoid rule at 50 Hz


def pitch_mission(base: VehicleParams) -> tuple[Record, dict[str, tuple[np.ndarray, np.ndarray]]]:
    """The pitch mission flown by the simulator and its command changes (stamps [s],
    set-points) per actuator, as a log holds them."""
    rec = run_mission(base, load_mission('pitch'))
    cmds = {}
    for j, ch in enumerate(('bar', 'helm', 'thrust')):
        change = np.flatnonzero(np.diff(rec.cmd[:, j], prepend=np.nan) != 0)
        cmds[ch] = (rec.t[change], rec.cmd[change, j])
    return rec, cmds


def test_actuators_are_reconstructed_exactly_from_the_commands(base: VehicleParams) -> None:
    rec, cmds = pitch_mission(base)
    pos = actuator_positions(rec.t, cmds, base)
    np.testing.assert_allclose(pos, rec.x[:, 12:15], rtol=0, atol=1e-12)


def test_forces_from_motion_match_the_filtered_true_forces(base: VehicleParams) -> None:
    rec, cmds = pitch_mission(base)
    fr = reconstruct(rec.t, rec.x[:, :12], cmds, base)
    true = np.column_stack([np.convolve(rec.wrench[:, 0, j], fr.kernel, mode='same')
                            for j in range(6)])
    ok = np.isfinite(fr.tau[:, 0])
    for axis, scale in ((2, 30.0), (4, 30.0), (0, 60.0)):
        err = np.max(np.abs(fr.tau[ok, axis] - true[ok, axis]))
        assert err < 0.01 * scale, (axis, err)
    assert not math.isfinite(fr.tau[0, 0])


def _pitch_log(base: VehicleParams, noise: np.ndarray | None, seed: int = 0
               ) -> tuple[np.ndarray, np.ndarray, dict[str, tuple[np.ndarray, np.ndarray]]]:
    rec, cmds = pitch_mission(base)
    state = rec.x[:, :12].copy()
    if noise is not None:
        state += np.random.default_rng(seed).standard_normal(state.shape) * noise
    return rec.t, state, cmds


SIGMAS = np.array([0.02] * 3 + [math.radians(0.1)] * 3 + [0.01] * 3 + [math.radians(0.1)] * 3)


def test_sensor_noise_levels_are_estimated_from_the_log(base: VehicleParams) -> None:
    _t, state, _ = _pitch_log(base, SIGMAS, seed=4)
    np.testing.assert_allclose(noise_sigma(state), SIGMAS, rtol=0.05)


def test_sensor_noise_propagation_gives_the_variance_of_the_moments(base: VehicleParams) -> None:
    """Var(D'e) over fresh noise draws (D fixed) matches the propagated S, and the noise model
    predicts the residual variance."""
    t, clean, cmds = _pitch_log(base, None)
    t, clean = t[:6000], clean[:6000]
    rng = np.random.default_rng(7)
    eq = EQUATIONS['pitch']
    theta = np.array([base.values[n] for n in eq.coefficients])
    rec = reconstruct(t, clean + rng.standard_normal(clean.shape) * SIGMAS, cmds, base)
    system = build_system([rec], eq, base)
    design = system.A / np.sqrt(np.sum(system.A ** 2, axis=0))
    S, ratio = sensor_noise_meat(system, design, system.b - system.regressors @ theta, theta,
                                 base)
    assert 0.85 < ratio < 1.15
    moments = []
    for _ in range(40):
        noisy = build_system([reconstruct(t, clean + rng.standard_normal(clean.shape) * SIGMAS,
                                          cmds, base)], eq, base)
        assert np.array_equal(noisy.rows, system.rows)
        moments.append(design.T @ (noisy.b - noisy.regressors @ theta))
    empirical = np.cov(np.array(moments).T)
    np.testing.assert_allclose(np.sqrt(np.diag(empirical)), np.sqrt(np.diag(S)), rtol=0.25)


def test_motion_standard_errors_use_the_noise_model_only_when_it_explains_the_residual(
        base: VehicleParams) -> None:
    t, noisy, cmds = _pitch_log(base, SIGMAS, seed=2)
    fit = identify([reconstruct(t, noisy, cmds, base)], base, equations=['pitch']).fits['pitch']
    assert fit.covariance.startswith('sensor-noise propagation') and fit.hac_lags == 0
    # no sensor noise: the residual is the filter's discretisation error, not white noise
    _, clean, _ = _pitch_log(base, None)
    fit = identify([reconstruct(t, clean, cmds, base)], base, equations=['pitch']).fits['pitch']
    assert fit.covariance.startswith('flat-top lag window') and fit.hac_lags >= 100
    assert all(c.std_error > 0 for c in fit.coefficients)


def test_flat_top_lag_covers_the_memory_of_a_moving_average() -> None:
    rng = np.random.default_rng(3)
    white = rng.standard_normal(40000)
    ma = np.convolve(white, np.ones(30), mode='same')  # memory 29 samples
    lag = flat_top_lag(ma[:, None])
    assert 29 <= lag <= 45
    assert flat_top_lag(white[:, None], minimum=50) == 50


def test_regressor_columns_are_the_report_terms_for_unit_coefficients(base: VehicleParams
                                                                      ) -> None:
    # hand-worked from the report's section 2 and Prestero's cross-flow drag
    nu = np.array([[2.0, 0.1, -0.05, 0.1, 0.02, -0.03],
                   [0.5, 0.0, 0.2, 0.0, -0.1, 0.0]])
    qs = 0.5 * base.rho * base.S_ref
    L = base.L_ref
    heave = regressor_columns(EQUATIONS['heave'], nu, base)
    assert list(heave) == ['CZ0', 'CZuw', 'CZuq', 'Zww', 'Zqq']
    np.testing.assert_allclose(heave['CZ0'], [qs * 4.0, qs * 0.25], rtol=1e-14)
    np.testing.assert_allclose(heave['CZuw'], [qs * 2.0 * -0.05, qs * 0.5 * 0.2], rtol=1e-14)
    np.testing.assert_allclose(heave['CZuq'], [qs * L * 2.0 * 0.02, qs * L * 0.5 * -0.1],
                               rtol=1e-14)
    np.testing.assert_allclose(heave['Zww'], [-0.0025, 0.04], rtol=1e-14)
    np.testing.assert_allclose(heave['Zqq'], [0.0004, -0.01], rtol=1e-14)
    yaw = regressor_columns(EQUATIONS['yaw'], nu, base)
    np.testing.assert_allclose(yaw['CNur'], [qs * L * L * 2.0 * -0.03, 0.0], atol=1e-14)
    np.testing.assert_allclose(yaw['Nrr'], [-0.0009, 0.0], atol=1e-18)
    # surge: ITTC-1957 with the Reynolds number held at 1e5 below it
    surge = regressor_columns(EQUATIONS['surge'], nu, base)['Ksh']
    for k, u in enumerate((2.0, 0.5)):
        re = max(u * L / base.nu_water, 1.0e5)
        assert surge[k] == pytest.approx(-qs * 0.075 / (math.log10(re) - 2.0) ** 2 * u * u,
                                         rel=1e-13)


def test_cross_flow_drag_of_the_vehicle_is_a_fixed_term(base: VehicleParams) -> None:
    crossflow = {'Zww': -120.0, 'Zqq': -0.6, 'Mww': 8.0, 'Mqq': -9.0, 'Yvv': -130.0,
                 'Yrr': 0.6, 'Nvv': -7.0, 'Nrr': -10.0}
    vehicle = base.replace(**crossflow)
    data = synthetic(vehicle)
    result = identify([data], vehicle)
    assert result.fits['heave'].fixed == {'CZ0': vehicle.CZ0, 'Zww': -120.0, 'Zqq': -0.6}
    assert result.fits['yaw'].fixed == {'Nvv': -7.0, 'Nrr': -10.0}
    for name, c in result.coefficients.items():
        assert c.value == pytest.approx(vehicle.values[name], rel=1e-9), name
    # the same data fitted in the structure of a file without the drag: the coefficients
    # absorb it, and the 95 % interval no longer holds the true value
    lo, hi = identify([data], base, structures=False).coefficients['CZuw'].ci95
    assert not lo <= vehicle.CZuw <= hi
    # the structure chosen by held-out prediction fits the quadratic drag: the truth again
    chosen = identify([data], base)
    assert chosen.fits['heave'].structure == 'quadratic'
    assert chosen.coefficients['CZuw'].value == pytest.approx(vehicle.CZuw, rel=1e-4)
    assert chosen.coefficients['Zww'].value == pytest.approx(-120.0, rel=0.01)


def test_actuator_steps_are_the_simulators_actuators_bit_for_bit(base: VehicleParams) -> None:
    P = base.as_array()
    env = Environment()
    rng = np.random.default_rng(3)
    full = np.zeros(15)
    full[6] = 1.8
    full[14] = 20.0
    alone = np.zeros(15)
    alone[12:15] = full[12:15]
    for _ in range(40):
        cmd = np.array([rng.uniform(-0.6, 0.6), rng.uniform(-0.6, 0.6), rng.uniform(-5, 80)])
        k = int(rng.integers(1, 50))
        assert rk4_steps(0.0, full, cmd, P, env.env_vector(), env.profile(), base.dt, k) == -1
        assert actuator_steps(alone, cmd, P, base.dt, k) == -1
        assert np.array_equal(alone[12:15], full[12:15])
    assert np.all(alone[:12] == 0.0)


def test_hydrodynamic_wrench_is_the_term_table_times_the_coefficients(base: VehicleParams
                                                                     ) -> None:
    # the table identification reads (HYDRO_TERMS, HYDRO_AXIS) against the model's kernel,
    # with every coefficient and the environment's cross-flow drag non-zero
    rng = np.random.default_rng(5)
    vehicle = base.replace(**{k: -float(rng.uniform(1.0, 200.0)) for k in (
        'Yvv', 'Zww', 'Mqq', 'Nrr')}, **{k: float(rng.uniform(-5.0, 5.0)) for k in (
            'Yrr', 'Zqq', 'Mww', 'Nvv')})
    extra = {'Zww': -30.0, 'Mqq': -4.0, 'Yvv': -20.0, 'Nrr': -3.0}
    env = Environment(effects={'crossflow_drag': extra})
    n = 200
    X = np.zeros((n, 15))
    X[:, 6] = rng.uniform(-0.5, 3.0, n)
    X[:, 7:12] = rng.uniform(-0.3, 0.3, (n, 5))
    W = wrench_series(np.zeros(n), X, vehicle.as_array(), env.env_vector(), env.profile())
    basis = hydro_basis_series(np.ascontiguousarray(X[:, 6:12]), vehicle.as_array(),
                               np.arange(len(HYDRO_TERMS)))
    expected = np.zeros((n, 6))
    for k, (name, axis) in enumerate(zip(HYDRO_TERMS, HYDRO_AXIS)):
        expected[:, axis] += (vehicle.values[name] + extra.get(name, 0.0)) * basis[:, k]
    np.testing.assert_allclose(W[:, 0], expected, rtol=1e-13, atol=1e-10)
