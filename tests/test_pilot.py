"""The depth pilot's logic and the offline closed loop on the nonlinear A18M model."""
from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import A18M

from auv_depth_lqr.bound import settling_bound
from auv_depth_lqr.closed_loop import run_closed_loop
from auv_depth_lqr.errors import InvalidInputError
from auv_depth_lqr.metrics import step_metrics
from auv_depth_lqr.pilot import DepthPilot, PilotSettings
from auv_sim.environment import Environment
from auv_sim.params import load_vehicle


@pytest.fixture(scope='module')
def params():  # type: ignore[no-untyped-def]
    return load_vehicle(A18M)


@pytest.fixture(scope='module')
def pilot_factory(params):  # type: ignore[no-untyped-def]
    return lambda: DepthPilot.for_vehicle(params, PilotSettings())


def test_bad_depth_commands_are_rejected_and_last_kept(pilot_factory) -> None:
    pilot = pilot_factory()
    pilot.set_depth_command(12.0)
    for bad, match in ((math.nan, 'not finite'), (math.inf, 'not finite'),
                       (-5.0, r'outside the depth envelope \[0, 300\] m'),
                       (1e4, 'outside the depth envelope'), ('x', 'not a number')):
        with pytest.raises(InvalidInputError, match=match):
            pilot.set_depth_command(bad)
        assert pilot.z_ref == 12.0


def test_holds_first_measured_depth_before_any_command(pilot_factory) -> None:
    pilot = pilot_factory()
    pilot.on_state(0.0, z=33.0, theta=0.0, w=0.0, q=0.0, u=2.0)
    bar, status = pilot.command(0.0)
    assert status == 'ok' and pilot.z_ref == 33.0 and math.isfinite(bar)


def test_stale_state_gives_safe_bar_then_recovers(pilot_factory) -> None:
    pilot = pilot_factory()
    safe = pilot.settings.safe_bar
    bar, status = pilot.command(0.0)
    assert status == 'no_state' and bar == pytest.approx(safe)
    pilot.on_state(0.0, z=20.0, theta=0.0, w=0.0, q=0.0, u=2.0)
    assert pilot.command(0.1)[1] == 'ok'
    # no state for 2 s: the plane goes to the safe angle at no more than its rate limit
    slew = pilot.controller.limits.bar_rate_max * pilot.settings.Ts
    bars, last = [], pilot.command(0.2)[0]
    for k in range(3, 40):
        bar, status = pilot.command(0.1 * k)
        if 0.1 * k > 0.5 + 1e-9:
            assert status == 'stale'
            assert abs(bar - last) <= slew + 1e-12
        bars.append(bar)
        last = bar
    assert bars[-1] == pytest.approx(safe)
    pilot.on_state(4.0, z=20.0, theta=0.0, w=0.0, q=0.0, u=2.0)
    bar, status = pilot.command(4.0)
    assert status == 'ok' and abs(bar - bars[-1]) <= slew + 1e-12


def test_non_finite_state_is_ignored(pilot_factory) -> None:
    pilot = pilot_factory()
    with pytest.raises(InvalidInputError, match='non-finite'):
        pilot.on_state(0.0, z=math.nan, theta=0.0, w=0.0, q=0.0, u=2.0)
    assert pilot.command(0.0)[1] == 'no_state'


THETA_MAX = math.radians(25.0)  # rad, the benchmark's pitch limit (PilotSettings default)


def closed_loop_metrics(params, z0: float, z1: float, u0: float,  # type: ignore[no-untyped-def]
                        current: dict[str, float] | None = None,
                        water_speed: float | None = None):
    """Fly z0 -> z1 [m] at u0 [m/s] for 150 s; (run, step metrics)."""
    environment = None if current is None else Environment(effects={'current': current})
    run = run_closed_loop(params, [(0.0, z1)], 150.0, z0=z0, u0=u0, environment=environment,
                          settings=PilotSettings(water_speed=water_speed))
    rec = run.record
    m = step_metrics(rec.t, rec.x[:, 2], rec.x[:, 4], rec.x[:, 10], rec.x[:, 12], z1,
                     bar_max=params.bar_max, u0=u0, theta_max=THETA_MAX)
    return run, m


# Measured on config/a18m.yaml (bench/bench_closed_loop.py): settling 1.45-1.51 T_kin without
# current; overshoot <= 0.005 m; peak pitch <= 24.6 deg; RMS pitch rate after settling
# <= 0.047 deg/s.
@pytest.mark.parametrize(('z0', 'z1', 'u0', 'current', 'settle_bound'), [
    (40.0, 10.0, 2.0, None, 1.6),
    (10.0, 40.0, 2.0, None, 1.6),
    (40.0, 10.0, 1.5, None, 1.6),
    (40.0, 10.0, 2.5, None, 1.6),
    pytest.param(40.0, 10.0, 2.0, {'north': 0.3}, 1.7, marks=pytest.mark.xfail(
        strict=True, reason=(
        'measured: a 0.3 m/s following current, the pilot not told its water speed (its model '
        'at 2.3 m/s over ground, 2.0 m/s through the water): the disturbance estimate takes '
        'the model error of the wrong speed for an offset; 61.7 s = 1.74 T_kin (1.30x the '
        'time-optimal bound; 2.5 % past the 1.7 line), overshoot 0.41 m (twice the 0.2 m '
        'line: the clear failure; 1.57 T_kin, no overshoot without the estimate); told its '
        'water speed the case is still water'))),
])
def test_closed_loop_depth_change_settles(
    params, z0: float, z1: float, u0: float,  # type: ignore[no-untyped-def]
    current: dict[str, float] | None, settle_bound: float,
) -> None:
    run, m = closed_loop_metrics(params, z0, z1, u0, current)
    assert m.settling_time <= settle_bound * m.kinematic_bound, m
    assert m.overshoot < 0.2, m
    assert math.degrees(m.rms_q_settled) < 0.05, m
    assert m.peak_pitch <= THETA_MAX + 1e-6, m
    assert np.all(np.abs(run.bar) <= params.bar_max + 1e-12)
    assert np.all(np.abs(np.diff(run.bar)) <= params.bar_rate * 0.1 + 1e-12)


@pytest.mark.parametrize(('z0', 'z1'), [(20.0, 21.0), (21.0, 20.0), (20.0, 23.0),
                                        (23.0, 20.0), (20.0, 25.0), (25.0, 20.0)])
def test_small_steps_do_not_overshoot(
    params, z0: float, z1: float,  # type: ignore[no-untyped-def]
) -> None:
    _, m = closed_loop_metrics(params, z0, z1, 2.0)
    assert m.overshoot < 0.2, m
    assert m.peak_pitch <= THETA_MAX + 1e-6, m
    assert m.settling_time < 30.0, m


@pytest.mark.parametrize(('z0', 'z1', 'u0'), [(40.0, 10.0, 1.75), (40.0, 10.0, 1.83),
                                              (40.0, 10.0, 2.37), (10.0, 40.0, 1.63),
                                              (10.0, 40.0, 1.5)])
def test_between_and_beside_the_bench_speeds_the_pilot_keeps_its_targets(
    params, z0: float, z1: float, u0: float,  # type: ignore[no-untyped-def]
) -> None:
    """Speeds off the benchmark's: the schedule between its grid speeds keeps the attitude
    quiet (RMS q 0.027-0.036 deg/s; on a 0.5 m/s scheduling grid, 1.83 m/s gave 0.20 deg/s)
    and the pitch within its limit (24.4-24.8 deg). Settling: measured 1.45-1.50 T_kin, 0.3-3.4
    % under the benchmark's 1.5 T_kin target (``bench/bench_closed_loop.py`` reports it at
    the benchmark's speeds): a 1.5 line here would decide on a few samples of a 70 s flight,
    so the line is the 1.6 T_kin of the test above, 6-9 % over every flight."""
    _, m = closed_loop_metrics(params, z0, z1, u0)
    assert m.settling_time <= 1.6 * m.kinematic_bound, m
    assert m.overshoot < 0.2, m
    assert math.degrees(m.rms_q_settled) < 0.05, m
    assert m.peak_pitch <= THETA_MAX, m


# A vehicle unlike its file's nominal A18M: each pitch and heave derivative, the plane's
# authority, the restoring moment, the buoyancy, the inertia and the servo lag changed by a
# factor of 0.3-3. Measured (40 -> 10 m and 10 -> 40 m at 2 m/s): settling 1.27-1.66 T_kin,
# overshoot <= 0.198 m (the plane's moment doubled, climbing; <= 0.07 m for the others), peak
# pitch <= 25.9 deg (CMuq halved), the pitch rate after settling decaying to 0 (no limit
# cycle). The overshoot line is 0.3 m: the 0.2 m target is the nominal vehicle's
# (``bench/bench_closed_loop.py``), and the doubled plane sits 1 % under it.
VEHICLE_CHANGES = {
    'CMuw': 1.5, 'CMuq': 0.5, 'CMbar': 2.0, 'CZbar': 0.5, 'zg': 3.0, 'Iy': 1.5, 'Mqdot': 2.0,
    'bar_tau': 4.0,
}


@pytest.mark.parametrize('name', sorted(VEHICLE_CHANGES))
@pytest.mark.parametrize(('z0', 'z1'), [(40.0, 10.0), (10.0, 40.0)])
def test_the_pilot_flies_vehicles_unlike_the_nominal_one(
    params, name: str, z0: float, z1: float,  # type: ignore[no-untyped-def]
) -> None:
    vehicle = params.replace(**{name: params.values[name] * VEHICLE_CHANGES[name]})
    run = run_closed_loop(vehicle, [(0.0, z1)], 200.0, z0=z0, u0=2.0)
    rec = run.record
    m = step_metrics(rec.t, rec.x[:, 2], rec.x[:, 4], rec.x[:, 10], rec.x[:, 12], z1,
                     bar_max=vehicle.bar_max, u0=2.0, theta_max=THETA_MAX)
    assert m.settling_time <= 2.0 * m.kinematic_bound, m
    assert m.overshoot < 0.3, m
    assert m.peak_pitch <= math.radians(27.0), m
    last = rec.t >= rec.t[-1] - 20.0
    assert np.max(np.abs(rec.x[last, 2] - z1)) < 0.01
    assert math.degrees(np.sqrt(np.mean(rec.x[last, 10] ** 2))) < 0.01


def test_big_climb_settles_after_the_time_optimal_bound(
    params,  # type: ignore[no-untyped-def]
) -> None:
    """40 -> 10 m at 2 m/s: no faster than the time-optimal bound of the model (47.6 s, the
    shortest settling any BAR sequence within the limits reaches with the surge held at
    2 m/s; this run holds the thrust, the surge stays within 1.98-2.01 m/s), and within
    1.6 T_kin. Measured 51.9 s = 1.46 T_kin = 1.09x the bound: the benchmark's 1.5
    T_kin target (``bench/bench_closed_loop.py``) sits 2.5 % above it, too close for a test's
    verdict, so the test asserts the physical bound below and the line of the test above."""
    _, m = closed_loop_metrics(params, 40.0, 10.0, 2.0)
    bound = settling_bound(params, 40.0, 10.0, 2.0, THETA_MAX)
    assert bound.settling_time - 0.2 <= m.settling_time <= 1.6 * m.kinematic_bound, \
        (m, bound.settling_time)


@pytest.mark.parametrize('current', [{'north': 0.3}, {'north': -0.3}, {'east': 0.3}])
def test_told_its_water_speed_the_pilot_flies_a_current_as_still_water(
    params, current: dict[str, float],  # type: ignore[no-untyped-def]
) -> None:
    """A uniform horizontal current does not change the vertical-plane physics through the
    water; told its speed through the water, the pilot settles as in still water (1.46 T_kin,
    the same time to the sample; on its speed over ground a head current gave 1.64 T_kin and
    0.29 deg/s RMS q). The settling line is the 1.6 T_kin of the still-water test (the 1.5
    T_kin target, 2.4 % above the flight, is the benchmark's)."""
    _, still = closed_loop_metrics(params, 40.0, 10.0, 2.0, None, water_speed=2.0)
    _run, m = closed_loop_metrics(params, 40.0, 10.0, 2.0, current, water_speed=2.0)
    assert m.settling_time <= 1.6 * m.kinematic_bound, m
    assert abs(m.settling_time - still.settling_time) <= 0.2, (m, still)
    assert math.degrees(m.rms_q_settled) < 0.05, m
    assert m.peak_pitch <= THETA_MAX + 1e-6, m


def test_water_relative_velocities_undo_a_horizontal_current() -> None:
    """Oracle: body velocities over ground built from known water-relative ones and a
    current along the heading; the function gets the water-relative ones back."""
    from auv_depth_lqr.pilot import water_relative
    for theta, c in ((0.3, 0.25), (-0.4, -0.3), (0.0, 0.5)):
        u_r, w_r = 1.9, 0.03
        u, w = u_r + c * math.cos(theta), w_r + c * math.sin(theta)
        assert water_relative(u, w, theta, u_r) == pytest.approx((u_r, w_r), abs=1e-12)


def test_the_pilot_says_which_speed_it_schedules_on() -> None:
    """Hand-worked: told 1.5 m/s through the water, a level state measuring 1.8 m/s over
    ground is a 0.3 m/s following current, and the pilot flies from 1.5 m/s; not told, it
    flies from the 1.8 m/s over ground and says it cannot know the current."""
    params = load_vehicle(A18M)
    told = DepthPilot.for_vehicle(params, PilotSettings(water_speed=1.5))
    assert told.speed_diagnostics()['scheduled_speed_mps'] == 'none'
    told.on_state(0.0, 10.0, 0.0, 0.0, 0.0, 1.8)
    values = told.speed_diagnostics()
    assert values['speed_basis'] == 'through the water (told 1.500 m/s)'
    assert values['current_along_heading_mps'] == '+0.300'
    assert values['scheduled_speed_mps'] == '1.500'
    ground = DepthPilot.for_vehicle(params)
    ground.on_state(0.0, 10.0, 0.0, 0.0, 0.0, 1.8)
    values = ground.speed_diagnostics()
    assert values['speed_basis'] == 'over ground'
    assert values['current_along_heading_mps'] == 'unknown'
    assert values['scheduled_speed_mps'] == '1.800'
    assert 'water_speed' in values['speed_basis_note']


def test_bad_water_speed_is_refused() -> None:
    from auv_depth_lqr.errors import DesignError
    for bad in (0.0, -1.0, math.nan):
        with pytest.raises(DesignError, match='water_speed'):
            PilotSettings(water_speed=bad)


def test_bad_publish_delay_is_refused() -> None:
    from auv_depth_lqr.errors import DesignError
    for bad in (-0.001, 0.05, math.nan, math.inf):
        with pytest.raises(DesignError, match='publish_delay'):
            PilotSettings(publish_delay=bad)
    assert PilotSettings(publish_delay=0.0).publish_delay == 0.0


def test_a_vehicle_the_controller_loses_never_gets_a_non_finite_command() -> None:
    """On the REMUS 100 file (open-loop unstable in pitch, 3.6 deg of nose-up fin left at
    trim) the controller's planning can fail; the pilot then sends its safe fin angle, and
    every command stays finite and within the fin's angle and rate limits."""
    import pathlib
    remus = load_vehicle(pathlib.Path(A18M).parent / 'remus100.yaml')
    settings = PilotSettings(speeds=(1.3, 1.5, 2.0, 2.5))
    run = run_closed_loop(remus, [(0.0, 10.0)], 60.0, z0=20.0, u0=2.0, settings=settings)
    assert np.all(np.isfinite(run.bar))
    assert np.max(np.abs(run.bar)) <= remus.bar_max + 1e-12
    assert np.max(np.abs(np.diff(run.bar))) <= remus.bar_rate * settings.Ts + 1e-12
