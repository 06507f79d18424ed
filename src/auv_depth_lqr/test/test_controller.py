"""Tests of the depth controller on the speed-scaled report model (test stand-in).

The closed loops are continuous plants under zero-order hold at Ts = 0.1 s (see standin.py).
The real check against the nonlinear vehicle model is a cross-package test.
"""
from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
import pytest
from standin import Run, linearize, settling_time, simulate

from auv_depth_lqr.controller import DepthController, PlaneState
from auv_depth_lqr.errors import DesignError, InvalidInputError, NotControllableError
from auv_depth_lqr.governor import GovernorSettings
from auv_depth_lqr.limits import THETA_MAX_DEFAULT, Limits
from auv_depth_lqr.lqr import lqrd
from auv_depth_lqr.schedule import GainSchedule, OperatingPoint
from auv_depth_lqr.summary import design_summary
from auv_depth_lqr.weights import DEFAULT_WEIGHTS, PRESETS, preset

TS = 0.1                                   # s
SPEEDS = (1.0, 1.5, 2.0, 2.5, 3.0)         # m/s; the stand-in cannot trim at 0.5 m/s
THETA_MAX = math.radians(25.0)             # rad


@pytest.fixture(scope='module')
def schedule() -> GainSchedule:
    return GainSchedule.design(linearize, SPEEDS, Ts=TS)


def kinematic_bound(dz: float, u0: float) -> float:
    """T_kin = |dz| / (u0 sin(theta_max)) [s]."""
    return abs(dz) / (u0 * math.sin(THETA_MAX))


def overshoot(run: Run, z0: float, z_ref: float) -> float:
    """Largest excursion beyond z_ref in the direction of travel [m]."""
    return float(z_ref - run.z.min()) if z_ref < z0 else float(run.z.max() - z_ref)


def assert_limits(run: Run, limits: Limits) -> None:
    assert np.max(np.abs(run.bar)) <= limits.bar_max + 1e-12
    assert np.max(np.abs(np.diff(run.bar))) <= limits.bar_rate_max * TS + 1e-12


# -- weights and presets -----------------------------------------------------------------------
def test_presets_hold_the_report_tunings() -> None:
    assert preset('report_4_4').Q == (1e-6, 1.0, 100.0, 10.0, 0.1)
    assert preset('report_4_4').R == 1e9
    assert preset('report_5').Q == (1e8, 1e8, 350.0, 450.0, 1e-5)
    assert preset('report_5').R == 1e8
    assert PRESETS['default'] is DEFAULT_WEIGHTS
    Q, R = DEFAULT_WEIGHTS.matrices()
    assert Q.shape == (5, 5) and R.shape == (1, 1)


def test_unknown_preset_is_named() -> None:
    with pytest.raises(DesignError, match=r"unknown weight preset 'best'; known presets: "
                                          r'default, report_4_4, report_5'):
        preset('best')


def test_theta_max_default_is_25_deg() -> None:
    assert pytest.approx(0.436, abs=5e-4) == THETA_MAX_DEFAULT
    assert Limits().theta_max == THETA_MAX_DEFAULT


@pytest.mark.parametrize('u0', SPEEDS)
def test_default_weights_give_well_damped_poles(u0: float) -> None:
    """'Depth without pitch oscillation': every closed-loop pole has zeta >= 0.7."""
    summary = design_summary(linearize, u0, Ts=TS)
    assert summary['min_damping'] >= 0.7
    assert all(abs(complex(p['re'], p['im'])) < 1.0 for p in summary['poles_discrete'])


# -- gain schedule -----------------------------------------------------------------------------
def test_schedule_at_grid_speed_is_the_lqrd_design(schedule: GainSchedule) -> None:
    x_e, bar_e, A, B = linearize(2.0)
    op = schedule.at(2.0)
    np.testing.assert_allclose(op.K, lqrd(A, B, *DEFAULT_WEIGHTS.matrices(), TS).K[0],
                               rtol=1e-12)
    assert (op.theta_e, op.w_e, op.bar_e) == pytest.approx((x_e[3], x_e[0], bar_e))


def test_schedule_interpolates_linearly_and_clamps(schedule: GainSchedule) -> None:
    low, high, mid = schedule.at(2.0), schedule.at(2.5), schedule.at(2.25)
    np.testing.assert_allclose(mid.K, 0.5 * (low.K + high.K), rtol=1e-12)
    assert mid.theta_e == pytest.approx(0.5 * (low.theta_e + high.theta_e))
    assert mid.bar_e == pytest.approx(0.5 * (low.bar_e + high.bar_e))
    np.testing.assert_array_equal(schedule.at(10.0).K, schedule.at(3.0).K)
    np.testing.assert_array_equal(schedule.at(0.0).K, schedule.at(1.0).K)
    assert schedule.at(10.0).u0 == 3.0


def test_steady_climb_feed_forward_is_consistent(schedule: GainSchedule) -> None:
    """The feed-forward climb at v satisfies w_dot = q_dot = 0 and z_dot = v on the model."""
    _x_e, _bar_e, A, B = linearize(2.0)
    op = schedule.at(2.0)
    v = -0.5
    dx = np.array([op.dw_dv * v, 0.0, 0.0, op.dtheta_dv * v, 0.0])
    x_dot = A @ dx + B[:, 0] * op.dbar_dv * v
    np.testing.assert_allclose(x_dot[:3], [0.0, 0.0, v], atol=1e-12)
    assert op.dtheta_dv < 0.0  # a climb (v < 0) needs nose up


@pytest.mark.parametrize(('speeds', 'match'), [
    ((), 'strictly increasing'),
    ((2.0, 1.0), 'strictly increasing'),
    ((1.0, 1.0), 'strictly increasing'),
    ((0.0, 1.0), r'speed must be finite and > 0, got 0.0'),
    ((1.0, math.nan), r'speed must be finite and > 0, got nan'),
])
def test_schedule_rejects_bad_grids(speeds: tuple[float, ...], match: str) -> None:
    with pytest.raises(DesignError, match=match):
        GainSchedule.design(linearize, speeds, Ts=TS)


def test_schedule_names_the_uncontrollable_speed() -> None:
    def no_bar_at_3(u0: float) -> Any:
        x_e, bar_e, A, B = linearize(u0)
        return x_e, bar_e, A, B * (0.0 if u0 == 3.0 else 1.0)

    with pytest.raises(NotControllableError, match=r'at u0=3 m/s: .*rank 0 of 5'):
        GainSchedule.design(no_bar_at_3, (2.0, 3.0), Ts=TS)


def test_schedule_rejects_bad_linearization() -> None:
    with pytest.raises(DesignError, match=r'linearize\(2\) returned A of shape \(4, 4\)'):
        GainSchedule.design(lambda u0: (np.zeros(5), 0.0, np.eye(4), np.ones(5)), (2.0,))
    with pytest.raises(DesignError, match=r'must return \(x_e, u_e, A, B\)'):
        GainSchedule.design(lambda u0: None, (2.0,))  # type: ignore[arg-type,return-value]


def test_report_presets_design_on_the_schedule() -> None:
    """The report's weights run through the same path (for reproduction runs)."""
    sched = GainSchedule.design(linearize, (2.0,), *preset('report_5').matrices(), Ts=TS)
    assert sched.K.shape == (1, 5)


# -- controller construction and inputs --------------------------------------------------------
def test_sample_period_must_match_the_design(schedule: GainSchedule) -> None:
    with pytest.raises(DesignError, match=r'Ts=0.2 s differs .* \(0.1 s\)'):
        DepthController(schedule, Limits(), 0.2)


def test_grid_speed_that_cannot_trim_within_limits_is_refused() -> None:
    """At 0.5 m/s the stand-in needs BAR_e = -1.34 rad: beyond 25 deg."""
    sched = GainSchedule.design(linearize, (0.5, 2.0), Ts=TS)
    with pytest.raises(DesignError, match=r'trim at u0=0.5 m/s .* remove this speed'):
        DepthController(sched, Limits(), TS)


@pytest.mark.parametrize('kwargs', [{'bar_max': 0.0}, {'bar_rate_max': -1.0},
                                    {'theta_max': math.nan}, {'theta_max': 2.0}])
def test_limits_are_validated(kwargs: dict[str, float]) -> None:
    with pytest.raises(DesignError, match=r'Limits\.'):
        Limits(**kwargs)


@pytest.mark.parametrize('kwargs', [{'margin': 1.5}, {'accel_max': 0.0},
                                    {'approach_length': math.inf}])
def test_governor_settings_are_validated(kwargs: dict[str, float]) -> None:
    with pytest.raises(DesignError, match=r'GovernorSettings\.'):
        GovernorSettings(**kwargs)


@pytest.mark.parametrize(('z_ref', 'state', 'match'), [
    (math.nan, PlaneState(20.0, 0.0, 0.0, 0.0, 2.0), r'depth reference z_ref \[m\] must be '
                                                     r'finite, got nan'),
    ('deep', PlaneState(20.0, 0.0, 0.0, 0.0, 2.0), r"z_ref \[m\] must be a number, got 'deep'"),
    (10.0, PlaneState(math.inf, 0.0, 0.0, 0.0, 2.0), r'state.z \[m\] must be finite'),
    (10.0, PlaneState(20.0, 0.0, 0.0, 0.0, math.nan), r'state.u \[m/s\] must be finite'),
])
def test_bad_inputs_raise_and_leave_the_state_alone(
    schedule: GainSchedule, z_ref: Any, state: PlaneState, match: str
) -> None:
    ctrl = DepthController(schedule, Limits(), TS)
    good = PlaneState(20.0, 0.0069, 0.0138, 0.0, 2.0)
    first = ctrl.step(good, 15.0)
    before = (ctrl.integrator, ctrl.governed_reference)
    with pytest.raises(InvalidInputError, match=match):
        ctrl.step(state, z_ref)
    assert (ctrl.integrator, ctrl.governed_reference) == before
    assert isinstance(first, float)


def test_invalid_input_is_a_value_error(schedule: GainSchedule) -> None:
    with pytest.raises(ValueError):
        DepthController(schedule).step(PlaneState(0.0, 0.0, 0.0, 0.0, 2.0), math.nan)


# -- limits and anti-windup --------------------------------------------------------------------
def test_rate_limit_applies_from_the_given_previous_bar(schedule: GainSchedule) -> None:
    limits = Limits()
    ctrl = DepthController(schedule, limits, TS)
    ctrl.reset(bar_previous=0.3)
    bar = ctrl.step(PlaneState(20.0, 0.0, 0.0, 0.0, 2.0), 20.0)
    assert abs(bar - 0.3) <= limits.bar_rate_max * TS + 1e-12


def test_integrator_stays_bounded_when_the_vehicle_cannot_follow(
    schedule: GainSchedule
) -> None:
    """Vehicle stuck 0.3 m off the reference: xi is clamped to its pitch share and stops."""
    limits = Limits()
    ctrl = DepthController(schedule, limits, TS)
    stuck = PlaneState(z=10.3, theta=0.0069, w=0.0138, q=0.0, u=2.0)
    xi = []
    for _ in range(3000):
        ctrl.step(stuck, 10.0)
        xi.append(ctrl.integrator)
    k_xi, k_theta = abs(schedule.at(2.0).K[4]), abs(schedule.at(2.0).K[3])
    assert abs(k_xi * xi[-1]) <= limits.integral_pitch_max * k_theta + 1e-12
    assert xi[-1] == xi[-100]  # not integrating any more


def test_integrator_waits_while_the_reference_moves(schedule: GainSchedule) -> None:
    ctrl = DepthController(schedule, Limits(), TS)
    state = PlaneState(z=40.5, theta=0.0069, w=0.0138, q=0.0, u=2.0)
    for _ in range(200):  # 20 s: the governed reference is climbing at > 0.05 m/s
        ctrl.step(state, 10.0)
    assert abs(ctrl.integrator) < 0.01  # only the first samples, before v_r > 0.05 m/s


# -- closed loop on the stand-in ---------------------------------------------------------------
@pytest.mark.parametrize('exact_kinematics', [True, False])
def test_big_climb_40_to_10_m_at_2_m_s(schedule: GainSchedule, exact_kinematics: bool) -> None:
    """Limits respected, pitch within theta_max, no overshoot, quiet pitch once settled."""
    limits = Limits()
    run = simulate(DepthController(schedule, limits, TS), 2.0, 40.0, 10.0, 180.0,
                   exact_kinematics=exact_kinematics)
    t_settle = settling_time(run.t, run.z, 10.0, 0.1)
    assert_limits(run, limits)
    assert np.max(np.abs(run.theta)) <= THETA_MAX
    assert overshoot(run, 40.0, 10.0) < 0.02
    assert t_settle <= 1.7 * kinematic_bound(30.0, 2.0)          # 58.3 s
    quiet = run.t >= t_settle + 5.0
    assert math.degrees(float(np.sqrt(np.mean(run.q[quiet] ** 2)))) < 0.05
    assert abs(run.z[-1] - 10.0) < 0.01


def test_big_climb_settles_within_1_6_kinematic_bounds(schedule: GainSchedule) -> None:
    """Measured 1.46 T_kin on the stand-in: the 1.5 T_kin target of the A18M benchmark
    (``bench/bench_closed_loop.py``) sits 2.5 % above it, too close for a verdict that must
    not depend on the machine; the line here is 1.6 T_kin, that of the dive below."""
    run = simulate(DepthController(schedule, Limits(), TS), 2.0, 40.0, 10.0, 120.0)
    assert settling_time(run.t, run.z, 10.0, 0.1) <= 1.6 * kinematic_bound(30.0, 2.0)


def test_big_dive_10_to_40_m_at_2_m_s(schedule: GainSchedule) -> None:
    limits = Limits()
    run = simulate(DepthController(schedule, limits, TS), 2.0, 10.0, 40.0, 120.0)
    assert_limits(run, limits)
    assert np.max(np.abs(run.theta)) <= THETA_MAX
    assert overshoot(run, 10.0, 40.0) < 0.02
    assert settling_time(run.t, run.z, 40.0, 0.1) <= 1.6 * kinematic_bound(30.0, 2.0)


@pytest.mark.parametrize('u0', [1.5, 2.25, 3.0])
def test_big_climb_at_other_speeds(schedule: GainSchedule, u0: float) -> None:
    """Gain scheduling: between and at grid speeds the same goals hold (2.25 is off-grid)."""
    limits = Limits()
    run = simulate(DepthController(schedule, limits, TS), u0, 40.0, 10.0, 150.0)
    assert_limits(run, limits)
    assert np.max(np.abs(run.theta)) <= THETA_MAX
    assert overshoot(run, 40.0, 10.0) < 0.1
    assert settling_time(run.t, run.z, 10.0, 0.1) <= 2.2 * kinematic_bound(30.0, u0)


@pytest.mark.parametrize(('z0', 'z_ref'), [(20.0, 21.0), (21.0, 20.0)])
def test_small_steps(schedule: GainSchedule, z0: float, z_ref: float) -> None:
    limits = Limits()
    run = simulate(DepthController(schedule, limits, TS), 2.0, z0, z_ref, 40.0)
    assert_limits(run, limits)
    assert overshoot(run, z0, z_ref) < 0.1
    assert settling_time(run.t, run.z, z_ref, 0.1) < 12.0


def test_medium_step_overshoot(schedule: GainSchedule) -> None:
    run = simulate(DepthController(schedule, Limits(), TS), 2.0, 20.0, 23.0, 60.0)
    assert overshoot(run, 20.0, 23.0) < 0.2


def test_integral_action_removes_a_trim_error() -> None:
    """Design trim BAR off by 2 deg: the integrator brings the depth error to zero."""
    def wrong_trim(u0: float) -> Any:
        x_e, bar_e, A, B = linearize(u0)
        return x_e, bar_e + math.radians(2.0), A, B

    sched = GainSchedule.design(wrong_trim, SPEEDS, Ts=TS)
    run = simulate(DepthController(sched, Limits(), TS), 2.0, 40.0, 10.0, 240.0)
    assert abs(run.z[-1] - 10.0) < 1e-3
    assert overshoot(run, 40.0, 10.0) < 0.1


def test_holding_depth_at_trim_is_quiet(schedule: GainSchedule) -> None:
    run = simulate(DepthController(schedule, Limits(), TS), 2.0, 20.0, 20.0, 30.0)
    assert np.max(np.abs(run.z - 20.0)) < 1e-6


# -- design summary ----------------------------------------------------------------------------
def test_design_summary_is_json_and_consistent() -> None:
    summary = design_summary(linearize, 2.0, Ts=TS)
    text = json.dumps(summary, allow_nan=False)
    back = json.loads(text)
    x_e, bar_e, A, B = linearize(2.0)
    K = lqrd(A, B, *DEFAULT_WEIGHTS.matrices(), TS).K
    np.testing.assert_allclose(back['K'], K)
    np.testing.assert_allclose(back['A'], A)
    assert back['trim'] == pytest.approx({'w': x_e[0], 'q': 0.0, 'theta': x_e[3],
                                          'bar': bar_e})
    assert back['controllability']['rank'] == 5
    assert back['states'] == ['w', 'q', 'z', 'theta', 'xi']
    assert len(back['poles_continuous']) == len(back['poles_discrete']) == 5


def test_design_summary_with_report_weights() -> None:
    summary = design_summary(linearize, 2.0, *preset('report_4_4').matrices(), Ts=TS)
    assert np.shape(summary['K']) == (1, 5)


def test_design_summary_rejects_a_bad_speed() -> None:
    with pytest.raises(DesignError, match=r'u0 must be finite and > 0 m/s, got -1'):
        design_summary(linearize, -1.0)


def test_rows_at_scales_with_the_speed() -> None:
    """At twice the design speed the heave and pitch terms double, the plane's quadruple and
    the hydrostatic column stays (hand-worked)."""
    P = np.array([[1.0, 2.0, 3.0, 4.0], [5.0, 6.0, 7.0, 8.0]])
    op = OperatingPoint(u0=1.5, K=np.zeros(5), w_e=0.0, theta_e=0.0, bar_e=0.0, dw_dv=0.0,
                        dtheta_dv=0.0, dbar_dv=0.0, F=np.zeros((4, 4)), P=P)
    assert op.rows_at(3.0) == pytest.approx(
        np.array([[2.0, 4.0, 3.0, 16.0], [10.0, 12.0, 7.0, 32.0]]), abs=1e-12)
