"""The time-optimal settling bound (auv_depth_lqr.bound) on the nonlinear A18M vertical plane.

The bound's plan is checked on its own: simulated again, it must keep every limit and stay in
the band from its grid time on; one grid step earlier no start reaches the band (a plan
shifted one step earlier, one with a step cut from its middle, a smooth depth path); and the
pilot flying the same change on the same model can only be slower. The other vehicles and
the perturbation of the last digits: tests/test_settling_bound_vehicles.py.
"""
from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest

from auv_depth_lqr.bound import TOLERANCE, BoundProblem, PlaneModel, feasible, settling_bound
from auv_depth_lqr.closed_loop import run_closed_loop
from auv_depth_lqr.errors import DesignError
from auv_depth_lqr.metrics import step_metrics
from auv_depth_lqr.pilot import PilotSettings
from auv_sim.params import load_vehicle

VEHICLE = pathlib.Path(__file__).resolve().parents[1] / 'config' / 'a18m.yaml'
THETA_MAX = math.radians(25.0)  # rad
STEP, HOLD = 0.5, 10.0          # s
Z0, Z1, U0 = 20.0, 25.0, 2.0    # m, m, m/s


@pytest.fixture(scope='module')
def params():  # type: ignore[no-untyped-def]
    return load_vehicle(VEHICLE)


@pytest.fixture(scope='module')
def bound(params):  # type: ignore[no-untyped-def]
    return settling_bound(params, Z0, Z1, U0, THETA_MAX, step=STEP, hold=HOLD)


def test_the_plan_keeps_every_limit_and_settles_when_claimed(params, bound) -> None:  # type: ignore[no-untyped-def]
    model = PlaneModel(params, U0, STEP)
    states = model.simulate(bound.states[0], bound.bar)
    np.testing.assert_allclose(states, bound.states, atol=1e-12)
    assert np.max(np.abs(bound.bar)) <= params.bar_max + 1e-12
    trim_bar = model.plane.trim(U0).bar
    steps = np.diff(np.r_[trim_bar, bound.bar])
    assert np.max(np.abs(steps)) <= params.bar_rate * STEP + 1e-9
    assert np.max(np.abs(states[:, 3])) <= THETA_MAX + TOLERANCE
    settled = bound.t >= bound.grid_time - 1e-9
    assert np.max(np.abs(states[settled, 2] - Z1)) <= 0.1
    assert np.max(np.abs(states[settled, 2] - Z1)) == pytest.approx(bound.band_reached)
    assert bound.grid_time - STEP < bound.settling_time <= bound.grid_time
    assert bound.settling_time > bound.kinematic_bound  # 5 m at 2 m/s: 5.9 s kinematic


def test_one_step_earlier_no_start_reaches_the_band(params, bound) -> None:  # type: ignore[no-untyped-def]
    problem = BoundProblem.build(params, Z0, Z1, U0, THETA_MAX, params.bar_max,
                                 params.bar_rate, 0.1, STEP, HOLD)
    n = int(round(bound.grid_time / STEP)) - 1
    N = n + problem.n_hold
    # the plan one step earlier: its first step dropped, or one cut from its middle
    shifted = (bound.bar[1:N + 1], bound.states[1:N + 2])
    mid = n // 2
    cut = (np.r_[bound.bar[:mid], bound.bar[mid + 1:]][:N],
           np.vstack([bound.states[:mid + 1], bound.states[mid + 2:]])[:N + 1])
    # a smooth depth path reaching the target at the earlier time, at the limit's pitch
    s = np.clip(np.arange(N + 1) / n, 0.0, 1.0)
    z = Z0 + (Z1 - Z0) * (10 * s**3 - 15 * s**4 + 6 * s**5)
    theta = problem.start[3] + np.arcsin(np.clip(-np.gradient(z, STEP) / U0,
                                                 -math.sin(THETA_MAX), math.sin(THETA_MAX)))
    path = (np.full(N, problem.bar_trim),
            np.column_stack([np.full(N + 1, problem.start[0]), np.gradient(theta, STEP), z,
                             theta]))
    for plan, reference in (shifted, cut, path):
        ok, found = feasible(problem, n, plan, reference, converge=True)
        assert not ok
        assert found.reached > 0.1 or found.violation > TOLERANCE


def test_the_pilot_cannot_beat_the_bound(params, bound) -> None:  # type: ignore[no-untyped-def]
    run = run_closed_loop(params, [(0.0, Z1)], 60.0, z0=Z0, u0=U0,
                          settings=PilotSettings(theta_max=THETA_MAX))
    rec = run.record
    m = step_metrics(rec.t, rec.x[:, 2], rec.x[:, 4], rec.x[:, 10], rec.x[:, 12], Z1,
                     bar_max=params.bar_max, u0=U0, theta_max=THETA_MAX)
    assert math.isfinite(m.settling_time)
    assert m.settling_time >= bound.settling_time - STEP


def test_a_small_change_is_bounded_by_the_dynamics_not_the_climb(params) -> None:  # type: ignore[no-untyped-def]
    """1 m: pitching up and back takes longer than four times the kinematic climb time; the
    bound exists, and the pilot on the same model is not faster."""
    z1 = Z0 + 1.0
    bound = settling_bound(params, Z0, z1, U0, THETA_MAX, step=STEP, hold=HOLD)
    assert bound.settling_time > 4.0 * 1.0 / (U0 * math.sin(THETA_MAX))
    run = run_closed_loop(params, [(0.0, z1)], 40.0, z0=Z0, u0=U0,
                          settings=PilotSettings(theta_max=THETA_MAX))
    rec = run.record
    m = step_metrics(rec.t, rec.x[:, 2], rec.x[:, 4], rec.x[:, 10], rec.x[:, 12], z1,
                     bar_max=params.bar_max, u0=U0, theta_max=THETA_MAX)
    assert bound.settling_time - STEP <= m.settling_time < math.inf


@pytest.mark.parametrize(('kwargs', 'match'), [
    ({'u0': 0.0}, 'u0 > 0'),
    ({'theta_max': 2.0}, 'theta_max'),
    ({'z1': 20.05}, 'already within the band'),
    ({'band': math.nan}, 'band must be finite'),
])
def test_bad_arguments_are_named(params, kwargs, match) -> None:  # type: ignore[no-untyped-def]
    args = {'z0': Z0, 'z1': Z1, 'u0': U0, 'theta_max': THETA_MAX} | kwargs
    with pytest.raises(DesignError, match=match):
        settling_bound(params, **args)
