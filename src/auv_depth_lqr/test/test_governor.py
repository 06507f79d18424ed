"""Tests of the reference governor and the feed-forward series (pure, on the stand-in model)."""
from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np
import pytest
from standin import linearize

from auv_depth_lqr.controller import DepthController, PlaneState
from auv_depth_lqr.errors import DesignError
from auv_depth_lqr.governor import GovernorSettings
from auv_depth_lqr.limits import Limits
from auv_depth_lqr.schedule import GainSchedule
from auv_depth_lqr.stop import Brake, stop_distance

TS = 0.1  # s


@pytest.fixture(scope='module')
def schedule() -> GainSchedule:
    return GainSchedule.design(linearize, (1.0, 1.5, 2.0, 2.5, 3.0), Ts=TS)


def _fine_sample(state: np.ndarray, u: float, b: np.ndarray, n: int = 40) -> np.ndarray:
    """One sample of the third-order series model b0 V + b1 A + b2 J + b3 J' = U, RK4 in n
    steps; state (P, V, A, J)."""
    def f(x: np.ndarray) -> np.ndarray:
        return np.array([x[1], x[2], x[3], (u - b[0] * x[1] - b[1] * x[2] - b[2] * x[3]) / b[3]])
    h = TS / n
    for _ in range(n):
        k1 = f(state)
        k2 = f(state + 0.5 * h * k1)
        k3 = f(state + 0.5 * h * k2)
        k4 = f(state + h * k3)
        state = state + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    return state


def oracle_stop(v: float, a: float, j: float, u: float, brake: Brake, b: np.ndarray) -> float:
    """The stop of :func:`stop_distance` by brute force: every switch sample tried, each
    sample integrated finely; the switch interpolated the same way."""
    a_end = -brake.v_land / brake.landing

    def toward(x: float, target: float) -> float:
        return float(np.clip(target, x - brake.du, x + brake.du))

    def release(state: np.ndarray, uu: float) -> tuple[float, float]:
        """Sample by sample until the speed reaches 0 or the acceleration a_end; the end is
        located within the sample by linear interpolation of (P, V) on V or on A."""
        path = [state]
        while path[-1][2] < a_end and path[-1][1] > 0.0:
            uu = toward(uu, brake.u_release)
            path.append(_fine_sample(path[-1], uu, b))
        if len(path) == 1:
            return float(state[0]), float(state[1])
        x0, x1 = path[-2], path[-1]
        if x1[1] <= 0.0:
            f = x0[1] / (x0[1] - x1[1])
            return float(x0[0] + f * (x1[0] - x0[0])), 0.0
        f = (a_end - x0[2]) / (x1[2] - x0[2])
        return float(x0[0] + f * (x1[0] - x0[0])), float(x0[1] + f * (x1[1] - x0[1]))

    state, outcomes = np.array([0.0, v, a, j]), []
    while True:
        p_r, v_r = release(state.copy(), u)
        outcomes.append((p_r + max(min(v_r, brake.v_land), 0.0) * brake.landing, v_r))
        if v_r <= brake.v_land:
            break
        u = toward(u, brake.u_brake)
        state = _fine_sample(state, u, b)
    if len(outcomes) == 1:
        return outcomes[0][0]
    (d0, v0), (d1, v1) = outcomes[-2], outcomes[-1]
    return d0 + (v0 - brake.v_land) / (v0 - v1) * (d1 - d0)


@pytest.mark.parametrize(('v', 'a', 'j'), [(0.78, 0.0, 0.0), (0.5, -0.05, -0.01),
                                           (0.37, -0.07, 0.02), (0.2, 0.0, 0.0),
                                           (0.6, 0.03, 0.01)])
def test_stop_distance_matches_the_finely_integrated_stop(
    schedule: GainSchedule, v: float, a: float, j: float
) -> None:
    """Climb at 2 m/s: the sampled stop (exact one-sample maps, bisection over the switch)
    equals the brute-force stop integrated in 40 RK4 steps per sample."""
    ctrl = DepthController(schedule, Limits(), TS)
    op = schedule.at(2.0)
    landing = ctrl.governor.approach_length / 2.0  # s, as for a command flown at 2 m/s
    _, _, brake = ctrl.reference.limits_toward(op, 2.0, -1.0, landing)
    b = op.F[:, 3]
    u = b[0] * v + b[1] * a + b[2] * j
    expected = oracle_stop(v, a, j, u, brake, b)
    assert stop_distance(v, a, j, u, brake) == pytest.approx(expected, abs=1e-6)


def test_stop_distance_is_longer_from_faster_and_mirrored_away() -> None:
    """More speed, longer stop; a motion away from the target gives a negative distance."""
    b = np.array([0.134, 5.28, 8.07, 5.87])  # A18M series at 2 m/s [rad per m s^(k-1)]
    brake = Brake.build(b, -0.47, 0.0, 0.028, 3.5, 0.043, TS)
    d = [stop_distance(v, 0.0, 0.0, b[0] * v, brake) for v in (0.2, 0.4, 0.6, 0.8)]
    assert all(x < y for x, y in itertools.pairwise(d))
    assert stop_distance(-0.4, 0.0, 0.0, -b[0] * 0.4, brake) < 0.0


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


#: Some of the governor's tests fly idealised vehicles (one that follows the reference exactly
#: at zero pitch, one jumped to a pitch cap) that are not trajectories of the model: the
#: disturbance estimate would read the difference as a disturbance and move the trim, so it
#: is off there; tests/test_controller_disturbance.py tests it on the simulator.
IDEAL = GovernorSettings(disturbance_estimate=False)


def reference(schedule: GainSchedule, z0: float, z1: float, u0: float, seconds: float,
              governor: GovernorSettings = IDEAL) -> np.ndarray:
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
    ref = reference(schedule, z0, z1, u0, 200.0)  # the landing takes 8 s per e-fold at 1 m/s
    direction = math.copysign(1.0, z1 - z0)
    assert np.max(direction * (ref[:, 1] - z1)) <= 1e-9
    assert ref[-1, 1] == z1 and ref[-1, 2] == 0.0
    lo, hi = GainSchedule.vertical_speed_bounds(schedule.at(u0), u0, Limits(),
                                                GovernorSettings().margin)
    assert np.all(ref[:, 2] >= lo - 1e-9) and np.all(ref[:, 2] <= hi + 1e-9)


def test_the_stop_is_known_from_its_first_braking_sample_to_rest(schedule: GainSchedule
                                                                  ) -> None:
    """40 -> 10 m at 2 m/s on a vehicle that follows the reference exactly:
    ``ReferenceGovernor.stopping`` is false through the speed-up and the climb, true from
    the stop's first sample on (the speed only falls from there) until the reference is at
    rest on the command, and false again then and after a new command."""
    ctrl = DepthController(schedule, Limits(), TS, IDEAL)
    z, flags, speeds = 40.0, [], []
    for _ in range(1500):
        ctrl.step(PlaneState(z=z, theta=0.0, w=0.0, q=0.0, u=2.0), 10.0)
        flags.append(ctrl.reference.stopping)
        z, v = ctrl.governed_reference  # type: ignore[misc]
        speeds.append(v)
    first, rest = flags.index(True), speeds.index(0.0, 1)
    assert z == 10.0 and not flags[-1]
    assert not any(flags[:first]) and all(flags[first:rest])
    assert abs(speeds[first - 1]) > 0.9 * max(abs(v) for v in speeds)  # from the climb
    assert all(abs(b) <= abs(a) + 1e-12 for a, b in itertools.pairwise(speeds[first:]))
    ctrl.step(PlaneState(z=z, theta=0.0, w=0.0, q=0.0, u=2.0), 20.0)
    assert not ctrl.reference.stopping


def test_reference_feedforward_stays_within_the_bar_budget(schedule: GainSchedule) -> None:
    governor, limits = IDEAL, Limits()
    ctrl = DepthController(schedule, limits, TS, governor)
    op = schedule.at(2.0)
    z, worst = 40.0, 0.0
    for _ in range(1200):
        ctrl.step(PlaneState(z=z, theta=0.0, w=0.0, q=0.0, u=2.0), 10.0)
        ref = ctrl.reference.reference
        assert ref is not None
        _, bar_ff = ctrl.feedforward(op, 2.0, ref.v, ref.a, ref.j, ref.s)
        worst = max(worst, abs(bar_ff))
        z = ctrl.governed_reference[0]  # type: ignore[index]
    assert worst <= governor.bar_margin * limits.bar_max + 1e-5  # rad; exact to O(Ts^2)


def test_reference_waits_for_a_vehicle_that_lags(schedule: GainSchedule) -> None:
    """A vehicle climbing at only 0.05 m/s: the reference leads it by at most max_lag."""
    governor = GovernorSettings()
    ctrl = DepthController(schedule, Limits(), TS, governor)
    z = 40.0
    for _ in range(300):
        ctrl.step(PlaneState(z=z, theta=0.0069, w=0.0138, q=0.0, u=2.0), 10.0)
        z_r = ctrl.governed_reference[0]  # type: ignore[index]
        assert z - z_r <= governor.max_lag + 1e-9
        z -= 0.05 * TS


def test_reference_goes_on_for_a_stalled_vehicle(schedule: GainSchedule) -> None:
    """A vehicle held at 10.6 m (a steady disturbance), commanded to 10 m: once its depth
    rate has settled below stall_speed the reference no longer waits (max_lag 0.5 m) but
    reaches the command at rest, and the integrator runs (0.6 m beyond integrate_within)."""
    governor = GovernorSettings()
    ctrl = DepthController(schedule, Limits(), TS, governor)
    for _ in range(600):
        ctrl.step(PlaneState(z=10.6, theta=0.0069, w=0.0138, q=0.0, u=2.0), 10.0)
    assert ctrl.governed_reference == (10.0, 0.0)
    assert ctrl.integrator > 0.0
GUARD_ONLY = dataclasses.replace(IDEAL, pitch_envelope=False)
"""The depth loop's pitch guard without the envelope selector behind it (which would act on
the jump of the pitch rate between these tests' two samples)."""


def test_pitch_protection_caps_the_depth_feedback(schedule: GainSchedule) -> None:
    """Far below a reference held at rest, the pitch demand is capped at pitch_guard *
    theta_max: at that pitch, with no rate, the command is the trim BAR again."""
    # a plane rate limit that cannot bind (2 bar_max per sample) isolates the feedback law
    limits, governor = Limits(bar_rate_max=2.0 * Limits().bar_max / TS), GUARD_ONLY
    ctrl = DepthController(schedule, limits, TS, governor)
    op = schedule.at(2.0)
    theta_cap = governor.pitch_guard * limits.theta_max
    ctrl.step(PlaneState(z=20.0, theta=op.theta_e, w=op.w_e, q=0.0, u=2.0), 20.0)
    bar = ctrl.step(PlaneState(z=30.0, theta=theta_cap, w=op.w_e, q=0.0, u=2.0), 20.0)
    # The reference waited (max_lag) so z - z_r is max_lag, far beyond the cap.
    assert bar == pytest.approx(op.bar_e, abs=1e-9)


def test_pitch_protection_leads_a_rotation_towards_the_limit(schedule: GainSchedule) -> None:
    """Rotating nose-up at q towards the cap, the guard's cap moves in by q times the plane's
    reaction time (pitch_anticipation * bar_max / bar_rate_max): at the pitch cap - lead q
    the attitude loop sees no pitch error, so the command is bar_e - K_q q (by hand from
    BAR = BAR_ff - K (X - X_ref) with the reference at the trim); rotating away, the cap
    stays where it was."""
    limits = Limits(bar_rate_max=2.0 * Limits().bar_max / TS)
    op = schedule.at(2.0)
    theta_cap = IDEAL.pitch_guard * limits.theta_max
    lead = IDEAL.pitch_anticipation * limits.bar_max / limits.bar_rate_max
    k_q = float(op.K[1])
    for q, theta in ((0.03, theta_cap - lead * 0.03), (-0.03, theta_cap)):
        ctrl = DepthController(schedule, limits, TS, GUARD_ONLY)
        ctrl.step(PlaneState(z=20.0, theta=op.theta_e, w=op.w_e, q=0.0, u=2.0), 20.0)
        bar = ctrl.step(PlaneState(z=30.0, theta=theta, w=op.w_e, q=q, u=2.0), 20.0)
        assert bar == pytest.approx(op.bar_e - k_q * q, abs=1e-9)
    # Without the lead, the same rotation at the same pitch would be commanded further up.
    ctrl = DepthController(schedule, limits, TS,
                           dataclasses.replace(GUARD_ONLY, pitch_anticipation=0.0))
    ctrl.step(PlaneState(z=20.0, theta=op.theta_e, w=op.w_e, q=0.0, u=2.0), 20.0)
    bar = ctrl.step(PlaneState(z=30.0, theta=theta_cap - lead * 0.03, w=op.w_e, q=0.03,
                               u=2.0), 20.0)
    k_theta = float(op.K[3])
    assert bar == pytest.approx(op.bar_e - k_q * 0.03 + k_theta * lead * 0.03, abs=1e-9)


@pytest.mark.parametrize('kwargs', [{'bar_margin': 1.2}, {'landing_distance': 0.0},
                                    {'approach_length': -1.0}, {'jerk_bar_share': -0.1},
                                    {'max_lag': math.nan}, {'pitch_anticipation': -0.5},
                                    {'surge_length': -1.0}, {'surge_horizon': 0.0}])
def test_new_governor_settings_are_validated(kwargs: dict[str, float]) -> None:
    with pytest.raises(DesignError, match=r'GovernorSettings\.'):
        GovernorSettings(**kwargs)
