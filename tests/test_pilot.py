"""The depth pilot's logic and the offline closed loop on the nonlinear A18M model."""
from __future__ import annotations

import math

import numpy as np
import pytest

from auv_depth_lqr.closed_loop import run_closed_loop
from auv_depth_lqr.errors import InvalidInputError
from auv_depth_lqr.metrics import step_metrics
from auv_depth_lqr.pilot import DepthPilot, PilotSettings
from auv_sim.params import load_vehicle
from conftest import A18M


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
                       (-5.0, 'outside the vehicle envelope'),
                       (1e4, 'outside the vehicle envelope'), ('x', 'not a number')):
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


@pytest.mark.parametrize('z0,z1', [(40.0, 10.0), (10.0, 40.0)])
def test_closed_loop_depth_change_settles(params, z0: float, z1: float) -> None:
    run = run_closed_loop(params, [(0.0, z1)], 150.0, z0=z0, u0=2.0)
    rec = run.record
    m = step_metrics(rec.t, rec.x[:, 2], rec.x[:, 4], rec.x[:, 10], rec.x[:, 12], z1,
                     bar_max=params.bar_max)
    assert m.settling_time < 120.0, m
    assert m.peak_pitch <= math.radians(25.0) + 1e-6, m
    assert np.all(np.abs(run.bar) <= params.bar_max + 1e-12)
    assert np.all(np.abs(np.diff(run.bar)) <= params.bar_rate * 0.1 + 1e-12)
