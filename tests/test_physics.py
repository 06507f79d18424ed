"""Physics oracles of the pure vehicle model (auv_sim): analytic answers, not regression values.

Every oracle is computed here independently of the model code (a drag balance solved with
brentq, a pendulum period, a current added as a Galilean shift), except the report figures,
which are the published numbers the A18M file was calibrated to.
"""
from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest
import yaml
from scipy.optimize import brentq

from auv_sim import frames
from auv_sim.environment import Environment
from auv_sim.errors import DivergenceError, ParameterError
from auv_sim.model import rk4_batch, rk4_batch_parallel
from auv_sim.params import VehicleParams, load_vehicle
from auv_sim.simulator import CommandError, Simulator, initial_state, step_batch
from auv_sim.trim import VerticalPlane

ROOT = pathlib.Path(__file__).resolve().parents[1]
A18M_PATH = ROOT / 'config' / 'a18m.yaml'


@pytest.fixture(scope='module')
def a18m() -> VehicleParams:
    return load_vehicle(A18M_PATH)


def neutral(p: VehicleParams, **changes: float) -> VehicleParams:
    """A copy with B = W and no zero-incidence lift/moment (CZ0 = CM0 = 0)."""
    return p.replace(B=p.W, CZ0=0.0, CM0=0.0, **changes)


# ----- rest, surge balance, pitch pendulum -----------------------------------------------------

def test_neutral_vehicle_at_rest_stays_at_rest(a18m: VehicleParams) -> None:
    x0 = initial_state(z=25.0)
    sim = Simulator(a18m.replace(B=a18m.W), x0=x0)
    for _ in range(60):
        sim.advance(1.0)
        assert np.max(np.abs(sim.x - x0)) <= 1e-9, sim.x - x0
    assert sim.t == pytest.approx(60.0)


def drag_balance_speed(p: VehicleParams, thrust: float) -> float:
    """u [m/s] with T = Ksh 1/2 rho S C_XF(Re) u^2, C_XF = 0.075 / (log10 Re - 2)^2 (ITTC-57)."""
    def residual(u: float) -> float:
        re = u * p.L_ref / p.nu_water
        cxf = 0.075 / (math.log10(re) - 2.0) ** 2
        return p.Ksh * 0.5 * p.rho * p.S_ref * cxf * u * u - thrust
    return brentq(residual, 0.05, 20.0, xtol=1e-14, rtol=1e-14)


@pytest.mark.parametrize('thrust', [20.0, 55.0, 150.0])
def test_steady_surge_speed_is_the_drag_balance(a18m: VehicleParams, thrust: float) -> None:
    p = neutral(a18m)
    u_expected = drag_balance_speed(p, thrust)
    sim = Simulator(p, x0=initial_state(z=30.0, u=u_expected * 0.8, thrust=thrust))
    sim.command('thrust', thrust)
    sim.advance(300.0)           # surge time constant (m - Xudot) / (dD/du) ~ 12 s at 2 m/s
    assert sim.x[6] == pytest.approx(u_expected, rel=1e-3)
    assert sim.x[6] == pytest.approx(u_expected, rel=1e-6)   # what it actually achieves
    # level flight: only the small pitch transient while u accelerates (the CG sits below the
    # body origin, so surge acceleration couples into pitch through M_RB) moves it (cm to dm)
    assert abs(sim.x[4]) < 1e-4 and abs(sim.x[2] - 30.0) < 0.5


def zero_crossings(t: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Times [s] where y crosses zero, linearly interpolated."""
    i = np.nonzero(np.signbit(y[:-1]) != np.signbit(y[1:]))[0]
    return t[i] - y[i] * (t[i + 1] - t[i]) / (y[i + 1] - y[i])


def test_small_pitch_free_decay_has_the_pendulum_period(a18m: VehicleParams) -> None:
    p = a18m.replace(B=a18m.W)     # u = 0: every hydrodynamic coefficient term vanishes
    period = 2.0 * math.pi * math.sqrt((p.Iy - p.Mqdot) / (p.zg * p.W - p.zb * p.B))
    sim = Simulator(p, x0=initial_state(z=20.0, theta=0.02))
    n = round(4.5 * period / sim.dt)
    t = np.empty(n)
    theta = np.empty(n)
    for i in range(n):
        t[i], theta[i] = sim.t, sim.x[4]
        sim.step(1)
    crossings = zero_crossings(t, theta)
    assert len(crossings) >= 8
    measured = 2.0 * float(np.mean(np.diff(crossings)))
    assert measured == pytest.approx(period, rel=0.01)
    # undamped and not growing: the amplitude stays 0.02 rad to 1e-4 (second-order terms)
    last = np.abs(theta[t > t[-1] - period])
    assert np.max(np.abs(theta)) <= 0.02 * (1 + 1e-4) and last.max() >= 0.02 * (1 - 1e-4)


# ----- trim and Jacobian against the report ----------------------------------------------------

def test_trim_and_jacobian_match_the_report(a18m: VehicleParams) -> None:
    vp = VerticalPlane(a18m)
    full = vp.trim(2.0, z=40.0, kinematics='full')
    assert full.w == pytest.approx(0.01377, rel=0.02)
    assert full.theta == pytest.approx(0.00689, rel=0.02)
    assert full.bar == pytest.approx(-0.08367, rel=0.02)
    w_only = vp.trim(2.0, z=40.0, kinematics='w')
    assert w_only.theta == pytest.approx(-0.19917, rel=0.02)
    assert w_only.bar == pytest.approx(-0.03048, rel=0.02)
    A, B = vp.linearize(full)
    for (i, j), value in {(0, 0): -0.4375, (0, 1): -0.6383, (1, 0): 0.2385, (1, 1): -1.1326,
                          (1, 3): -0.0391}.items():
        assert A[i, j] == pytest.approx(value, rel=0.02), (i, j)
    assert B[0, 0] == pytest.approx(-0.1136, rel=0.02)
    assert B[1, 0] == pytest.approx(-0.0888, rel=0.02)


def test_trim_is_an_equilibrium_of_the_simulator(a18m: VehicleParams) -> None:
    trim = VerticalPlane(a18m).trim(2.0, z=40.0)
    sim = Simulator(a18m, x0=trim.state())
    sim.advance(30.0)
    np.testing.assert_allclose(sim.x[[2, 4, 6, 8, 10]],
                               [40.0, trim.theta, 2.0, trim.w, 0.0], atol=1e-8)


# ----- divergence, commands ---------------------------------------------------------------------

def test_non_finite_state_stops_the_run_naming_time_and_state(a18m: VehicleParams) -> None:
    p = a18m.replace(CZuw=1.0e9)              # absurd positive heave "damping"
    x0 = initial_state(z=40.0, u=2.0)
    x0[8] = 0.01
    sim = Simulator(p, x0=x0)
    with pytest.raises(DivergenceError, match=r'non-finite at t = \d+\.\d+ s.*w=') as info:
        sim.advance(10.0)
    assert np.all(np.isfinite(sim.x))          # the last finite state is kept
    assert f't = {sim.t:.3f} s' in str(info.value)


def test_command_is_zero_order_hold_from_the_next_step(a18m: VehicleParams) -> None:
    x0 = VerticalPlane(a18m).trim(2.0, z=40.0).state()
    a = Simulator(a18m, x0=x0)
    a.step(7)
    a.command('bar', 0.1)
    assert a.cmd[0] == 0.1
    a.step(1)
    assert a.x[12] != x0[12]                   # the plane moves within the first step
    a.step(92)
    b = Simulator(a18m, x0=x0)                 # same command, steps taken one at a time
    b.step(7)
    b.command('bar', 0.1)
    for _ in range(93):
        b.step(1)
    np.testing.assert_array_equal(a.x, b.x)


@pytest.mark.parametrize('delay, delay_steps', [(0.05, 5), (0.033, 4)])
def test_transport_delay_acts_at_the_first_step_after_it(a18m: VehicleParams, delay: float,
                                                          delay_steps: int) -> None:
    x0 = VerticalPlane(a18m).trim(2.0, z=40.0).state()
    delayed = Simulator(a18m, Environment(effects={'actuator_delay': {'bar': delay}}), x0=x0)
    delayed.command('bar', 0.2)
    assert delayed.cmd[0] == x0[12]            # not yet
    delayed.step(delay_steps - 1)
    assert delayed.cmd[0] == x0[12] and delayed.x[12] == x0[12]
    delayed.step(1)
    assert delayed.cmd[0] == 0.2
    delayed.step(200)
    late = Simulator(a18m, x0=x0)              # no delay, commanded delay_steps later
    late.step(delay_steps)
    late.command('bar', 0.2)
    late.step(200)
    np.testing.assert_array_equal(delayed.x, late.x)


@pytest.mark.parametrize('channel, value, match', [
    ('bar', math.nan, 'not finite'), ('bar', math.inf, 'not finite'),
    ('bar', 0.5, 'outside'), ('helm', -0.44, 'outside'), ('thrust', 251.0, 'outside'),
    ('thrust', -61.0, 'outside'), ('rudder', 0.0, 'unknown'),
])
def test_bad_command_is_rejected_and_the_last_valid_one_kept(
        a18m: VehicleParams, channel: str, value: float, match: str) -> None:
    sim = Simulator(a18m, x0=initial_state(z=10.0, u=2.0))
    sim.command('bar', 0.1)
    sim.command('helm', -0.1)
    sim.command('thrust', 40.0)
    before = sim.cmd.copy()
    with pytest.raises(CommandError, match=match):
        sim.command(channel, value)
    np.testing.assert_array_equal(sim.cmd, before)


# ----- parameter files --------------------------------------------------------------------------

def write_variant(tmp_path: pathlib.Path, edit) -> pathlib.Path:  # type: ignore[no-untyped-def]
    doc = yaml.safe_load(A18M_PATH.read_text())
    edit(doc)
    path = tmp_path / 'variant.yaml'
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


@pytest.mark.parametrize('edit, match', [
    (lambda d: d['mass'].pop('Iy'), r'missing parameter mass\.Iy'),
    (lambda d: d['hydrodynamics']['Ksh'].update(value=-48.0), r'hydrodynamics\.Ksh .*> 0'),
    (lambda d: d['added_mass']['Zwdot'].update(value=680.0), r'added_mass\.Zwdot .*<= 0'),
    (lambda d: d['mass']['m'].update(value=float('nan')), r'mass\.m = nan is not finite'),
    (lambda d: d['mass']['m'].update(value=float('inf')), r'mass\.m = inf is not finite'),
    (lambda d: d['hydrodynamics'].update(CZfoo={'value': 1.0}),
     r'unknown parameter hydrodynamics\.CZfoo'),
    (lambda d: d['mass']['Iy'].update(value='heavy'), r'mass\.Iy .*not a number'),
    (lambda d: d['geometry']['L_ref'].update(unit='ft'), r'geometry\.L_ref is in .ft.'),
])
def test_parameter_file_errors_name_key_and_file(tmp_path: pathlib.Path, edit,  # type: ignore[no-untyped-def]
                                                 match: str) -> None:
    path = write_variant(tmp_path, edit)
    with pytest.raises(ParameterError, match=match) as info:
        load_vehicle(path)
    assert str(path) in str(info.value)


def test_malformed_yaml_names_file_and_line(tmp_path: pathlib.Path) -> None:
    path = tmp_path / 'broken.yaml'
    path.write_text('vehicle: X\nmass:\n  m: {value: 620.0\n  B: 1\n')
    with pytest.raises(ParameterError, match=r'malformed YAML at line \d+') as info:
        load_vehicle(path)
    assert str(path) in str(info.value)


def test_missing_file(tmp_path: pathlib.Path) -> None:
    with pytest.raises(ParameterError, match=r'cannot read vehicle file .*nope\.yaml'):
        load_vehicle(tmp_path / 'nope.yaml')


# ----- environment: current ---------------------------------------------------------------------

def body_to_ned(x: np.ndarray, v_body: np.ndarray) -> np.ndarray:
    """Body FRD vector -> NED, through the quaternion of the Euler angles (not the model)."""
    return frames.rotate(frames.euler_to_quaternion(x[3], x[4], x[5]), v_body)


def ned_to_body(x: np.ndarray, v_ned: np.ndarray) -> np.ndarray:
    q = frames.euler_to_quaternion(x[3], x[4], x[5])
    return frames.rotate(frames.quaternion_conjugate(q), v_ned)


@pytest.mark.parametrize('bar_step', [0.0, 0.1])
def test_constant_current_carries_the_vehicle_without_changing_its_water_speed(
        a18m: VehicleParams, bar_step: float) -> None:
    v_c = np.array([0.3, -0.2, 0.0])            # NED [m/s]
    trim = VerticalPlane(a18m).trim(2.0, z=60.0)
    calm = Simulator(a18m, x0=trim.state())
    x0 = trim.state()
    x0[6:9] += ned_to_body(x0, v_c)             # same water-relative motion, over ground + v_c
    drift = Simulator(a18m, Environment(effects={'current': {'north': 0.3, 'east': -0.2}}),
                      x0=x0)
    for sim in (calm, drift):
        sim.command('bar', trim.bar + bar_step)  # 0: steady trimmed flight; 0.1: a manoeuvre
    for _ in range(40):
        calm.advance(1.0)
        drift.advance(1.0)
        nu_r = drift.x[6:9] - ned_to_body(drift.x, v_c)
        np.testing.assert_allclose(nu_r, calm.x[6:9], atol=1e-7)      # water-relative speed
        np.testing.assert_allclose(drift.x[3:6], calm.x[3:6], atol=1e-7)
        np.testing.assert_allclose(drift.x[0:3] - calm.x[0:3], v_c * drift.t, atol=1e-6)
    ground = body_to_ned(drift.x, drift.x[6:9])
    np.testing.assert_allclose(ground - body_to_ned(calm.x, calm.x[6:9]), v_c, atol=1e-7)
    if bar_step:
        assert abs(calm.x[2] - 60.0) > 1.0        # it did manoeuvre


# ----- batch ------------------------------------------------------------------------------------

def test_batch_equals_single_runs_exactly(a18m: VehicleParams) -> None:
    rng = np.random.default_rng(11)
    n = 16
    trim = VerticalPlane(a18m).trim(2.0, z=40.0)
    X = np.tile(trim.state(), (n, 1))
    X[:, 2] += rng.uniform(-5.0, 5.0, n)
    X[:, 4] += rng.uniform(-0.05, 0.05, n)
    X[:, 6] += rng.uniform(-0.5, 0.5, n)
    CMD = np.column_stack([rng.uniform(-0.3, 0.3, n), rng.uniform(-0.2, 0.2, n),
                           rng.uniform(20.0, 120.0, n)])
    env = Environment(effects={'current': {'north': 0.2}})
    singles = []
    for i in range(n):
        sim = Simulator(a18m, env, x0=X[i])
        sim.command('bar', CMD[i, 0])
        sim.command('helm', CMD[i, 1])
        sim.command('thrust', CMD[i, 2])
        sim.step(500)
        singles.append(sim.x)
    Xb = X.copy()
    status = step_batch(a18m, Xb, CMD, 500, environment=env)
    assert np.all(status == -1)
    np.testing.assert_array_equal(Xb, np.array(singles))


def test_parallel_batch_equals_serial_batch(a18m: VehicleParams) -> None:
    trim = VerticalPlane(a18m).trim(2.0, z=40.0)
    n = 64
    X = np.tile(trim.state(), (n, 1))
    X[:, 12] = np.linspace(-0.3, 0.3, n)
    CMD = np.tile(X[0, 12:15], (n, 1))
    CMD[:, 0] = np.linspace(0.3, -0.3, n)
    env = Environment()
    P, E, prof = a18m.as_array(), env.env_vector(), env.profile()
    Xs, Xp = X.copy(), X.copy()
    s1 = rk4_batch(0.0, Xs, CMD, P, E, prof, a18m.dt, 300)
    s2 = rk4_batch_parallel(0.0, Xp, CMD, P, E, prof, a18m.dt, 300)
    np.testing.assert_array_equal(s1, s2)
    np.testing.assert_array_equal(Xs, Xp)


def test_a_trimmed_start_in_a_current_has_no_surge_transient(a18m: VehicleParams) -> None:
    """Trim.state(environment): the trim's velocities through the water plus the current;
    with the trim's BAR and thrust held, the velocities over ground stay put."""
    env = Environment(effects={'current': {'north': -0.3, 'east': 0.1}})
    psi = 0.4
    trim = VerticalPlane(a18m).trim(2.0, z=30.0)
    x0 = trim.state(env, psi=psi)
    # the current along the heading, seen along the body x axis of a vehicle pitched theta
    c_body_u = (-0.3 * math.cos(psi) + 0.1 * math.sin(psi)) * math.cos(trim.theta)
    assert x0[6] == pytest.approx(2.0 + c_body_u, abs=1e-12)
    sim = Simulator(a18m, env, x0=x0)
    sim.step(int(round(20.0 / sim.dt)))
    assert np.max(np.abs(sim.x[6:12] - x0[6:12])) < 1e-6
