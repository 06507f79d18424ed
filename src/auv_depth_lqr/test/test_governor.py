"""Tests of the reference governor and the feed-forward series (pure, on the stand-in model)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from standin import linearize

from auv_depth_lqr.controller import (
    DepthController,
    GainSchedule,
    GovernorSettings,
    Limits,
    PlaneState,
    _constant_jerk,
    _stopping_distance,
)
from auv_depth_lqr.errors import DesignError

TS = 0.1  # s


@pytest.fixture(scope='module')
def schedule() -> GainSchedule:
    return GainSchedule.design(linearize, (1.0, 1.5, 2.0, 2.5, 3.0), Ts=TS)


def simulate_stop(v: float, a: float, a_brake: float, jerk: float, landing: float,
                  v_land: float, dt: float = 1e-4) -> float:
    """The stop of :func:`_stopping_distance` integrated in small steps [m] (the oracle)."""
    z, a_end = 0.0, v_land / landing
    phase = 'ramp'
    while True:
        if phase == 'ramp':
            j = -jerk
            if a <= -a_brake:
                a, phase = -a_brake, 'hold'
                continue
            if v - (a * a - a_end * a_end) / (2.0 * jerk) <= v_land and a < -a_end:
                phase = 'release'
                continue
        elif phase == 'hold':
            j = 0.0
            if v - (a * a - a_end * a_end) / (2.0 * jerk) <= v_land:
                phase = 'release'
                continue
        else:
            j = jerk if a < -a_end else 0.0
            if v <= v_land:
                return z + v * landing
        dz, v, a = _constant_jerk(v, a, j, dt)
        z += dz


@pytest.mark.parametrize(('v', 'a'), [(0.78, 0.0), (0.5, -0.05), (0.37, -0.07), (0.2, 0.0),
                                      (0.6, 0.03)])
def test_stopping_distance_matches_the_integrated_stop(v: float, a: float) -> None:
    expected = simulate_stop(v, a, 0.0766, 0.0265, 3.0, 0.05)
    assert _stopping_distance(v, a, 0.0766, 0.0265, 3.0, 0.05) == pytest.approx(expected,
                                                                                abs=2e-4)


def test_stopping_distance_rest_to_rest_oracle() -> None:
    """Trapezoidal stop from (v, 0): v^2 / (2 A) + v A / (2 J) (classic S-curve)."""
    v, A, J = 0.8, 0.08, 0.02
    assert _stopping_distance(v, 0.0, A, J) == pytest.approx(v * v / (2 * A) + v * A / (2 * J))
    assert _stopping_distance(-v, 0.0, A, J) == pytest.approx(-_stopping_distance(v, 0.0, A, J))


@pytest.mark.parametrize('u0', [1.0, 2.0, 3.0])
def test_feedforward_series_is_a_trajectory_of_the_linear_model(
    schedule: GainSchedule, u0: float
) -> None:
    """For v(t) a cubic, X_ref(t) and BAR_ff(t) from the series satisfy dX/dt = A dX + B dBAR."""
    _, _, A, B = linearize(u0)
    F = schedule.at(u0).F
    c = np.array([0.1, -0.05, 0.02, -0.004])  # v(t) = sum c_k t^k [m/s]

    def derivs(t: float) -> np.ndarray:
        return np.array([
            sum(c[k] * t**k for k in range(4)),
            sum(k * c[k] * t**(k - 1) for k in range(1, 4)),
            sum(k * (k - 1) * c[k] * t**(k - 2) for k in range(2, 4)),
            6.0 * c[3],
        ])

    for t in (0.0, 0.7, 2.3):
        d = derivs(t)
        x = d @ F[:, :3]
        bar = d @ F[:, 3]
        d_next = np.array([d[1], d[2], d[3], 0.0])
        x_dot = d_next @ F[:, :3]
        rhs = A[np.ix_([0, 1, 3], [0, 1, 3])] @ x + B[[0, 1, 3], 0] * bar
        np.testing.assert_allclose(x_dot, rhs, atol=1e-12)
        z_dot = A[2, [0, 1, 3]] @ x + B[2, 0] * bar
        assert z_dot == pytest.approx(d[0], abs=1e-12)


def reference(schedule: GainSchedule, z0: float, z1: float, u0: float, seconds: float,
              governor: GovernorSettings | None = None) -> np.ndarray:
    """The governed reference (t, z_r, v_r) of a controller whose vehicle follows it exactly."""
    ctrl = DepthController(schedule, Limits(), TS, governor)
    rows, z = [], z0
    for k in range(int(seconds / TS)):
        ctrl.step(PlaneState(z=z, theta=0.0, w=0.0, q=0.0, u=u0), z1)
        z_r, v_r = ctrl.governed_reference  # type: ignore[misc]
        rows.append((k * TS, z_r, v_r))
        z = z_r
    return np.array(rows)


@pytest.mark.parametrize(('z0', 'z1', 'u0'), [(40.0, 10.0, 2.0), (10.0, 40.0, 2.0),
                                              (20.0, 21.0, 2.0), (23.0, 20.0, 1.5),
                                              (20.0, 20.3, 3.0), (10.0, 40.0, 1.0)])
def test_reference_never_overshoots_and_respects_the_climb_bound(
    schedule: GainSchedule, z0: float, z1: float, u0: float
) -> None:
    ref = reference(schedule, z0, z1, u0, 150.0)
    direction = math.copysign(1.0, z1 - z0)
    assert np.max(direction * (ref[:, 1] - z1)) <= 1e-9
    assert ref[-1, 1] == z1 and ref[-1, 2] == 0.0
    lo, hi = GainSchedule.vertical_speed_bounds(schedule.at(u0), u0, Limits(),
                                                GovernorSettings().margin)
    assert np.all(ref[:, 2] >= lo - 1e-9) and np.all(ref[:, 2] <= hi + 1e-9)


def test_reference_feedforward_stays_within_the_bar_budget(schedule: GainSchedule) -> None:
    governor, limits = GovernorSettings(), Limits()
    ctrl = DepthController(schedule, limits, TS, governor)
    op = schedule.at(2.0)
    z, worst = 40.0, 0.0
    for _ in range(1200):
        ctrl.step(PlaneState(z=z, theta=0.0, w=0.0, q=0.0, u=2.0), 10.0)
        _, bar_ff = ctrl.feedforward(op, 2.0, ctrl._v_r, ctrl._a_r, ctrl._j_r)
        worst = max(worst, abs(bar_ff))
        z = ctrl.governed_reference[0]  # type: ignore[index]
    assert worst <= governor.bar_margin * limits.bar_max + 1e-5  # rad; exact to O(Ts^2)


def test_reference_waits_for_a_vehicle_that_lags(schedule: GainSchedule) -> None:
    """A vehicle stuck at 40 m: the reference leads it by at most max_lag."""
    governor = GovernorSettings()
    ctrl = DepthController(schedule, Limits(), TS, governor)
    for _ in range(300):
        ctrl.step(PlaneState(z=40.0, theta=0.0069, w=0.0138, q=0.0, u=2.0), 10.0)
        z_r = ctrl.governed_reference[0]  # type: ignore[index]
        assert 40.0 - z_r <= governor.max_lag + 1e-9


def test_pitch_protection_caps_the_depth_feedback(schedule: GainSchedule) -> None:
    """Far below a reference held at rest, the pitch demand is capped at pitch_guard *
    theta_max: at that pitch, with no rate, the command is the trim BAR again."""
    limits, governor = Limits(), GovernorSettings()
    ctrl = DepthController(schedule, limits, TS, governor)
    op = schedule.at(2.0)
    theta_cap = governor.pitch_guard * limits.theta_max
    ctrl.step(PlaneState(z=20.0, theta=op.theta_e, w=op.w_e, q=0.0, u=2.0), 20.0)
    ctrl._bar_prev = None  # isolate the feedback law from the rate limit
    bar = ctrl.step(PlaneState(z=30.0, theta=theta_cap, w=op.w_e, q=0.0, u=2.0), 20.0)
    # The reference waited (max_lag) so z - z_r is max_lag, far beyond the cap.
    assert bar == pytest.approx(op.bar_e, abs=1e-9)


@pytest.mark.parametrize('kwargs', [{'bar_margin': 1.2}, {'landing_distance': 0.0},
                                    {'jerk_bar_share': -0.1}, {'max_lag': math.nan}])
def test_new_governor_settings_are_validated(kwargs: dict[str, float]) -> None:
    with pytest.raises(DesignError, match='GovernorSettings.'):
        GovernorSettings(**kwargs)
