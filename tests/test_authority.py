"""The pilot's plane-authority measure (auv_depth_lqr.authority): hand-worked windows, and in
closed loop the plane the pilot holds depth with against the plant's own nonlinear trim (a
second computation: auv_sim.trim on the true vehicle in its water)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import ROOT

from auv_depth_lqr.authority import LOW, OK, UNKNOWN, AuthorityMonitor
from auv_depth_lqr.closed_loop import model_error_plant, run_closed_loop
from auv_depth_lqr.errors import DesignError
from auv_depth_lqr.pilot import DepthPilot, PilotSettings
from auv_depth_lqr.tuning import derive_tuning
from auv_sim.params import load_vehicle
from auv_sim.trim import VerticalPlane

DEG = math.pi / 180.0


def feed(monitor: AuthorityMonitor, samples: list[tuple[float, float, bool]]):  # type: ignore
    out = None
    for t, bar, holding in samples:
        out = monitor.update(t, bar, holding)
    return out


def test_hold_plane_is_the_time_weighted_mean_once_half_the_window_is_covered() -> None:
    # 0.4 rad travel, 10 s window, low beyond 80 %: -0.2 rad every second while holding
    m = AuthorityMonitor(0.4, 10.0, 0.8)
    a = feed(m, [(float(t), -0.2, True) for t in range(5)])
    assert a.level == UNKNOWN and a.hold_time == pytest.approx(4.0)   # 4 s < 5 s
    a = m.update(5.0, -0.2, True)
    assert a.level == OK and a.hold_time == pytest.approx(5.0)
    assert a.hold_bar == pytest.approx(-0.2) and a.share == pytest.approx(0.5)
    assert a.saturated == 0.0
    # irregular samples weigh by how long each held: 4 s at -0.1, then 1 s at -0.3
    m = AuthorityMonitor(0.4, 10.0, 0.8)
    a = feed(m, [(0.0, -0.1, True), (4.0, -0.3, True), (5.0, -0.3, True)])
    assert a.hold_bar == pytest.approx((4 * -0.1 + 1 * -0.3) / 5.0)


def test_a_trim_beyond_the_share_is_low_and_the_window_forgets() -> None:
    m = AuthorityMonitor(0.4, 10.0, 0.8)
    a = feed(m, [(float(t), -0.35, True) for t in range(11)])
    assert a.level == LOW and a.share == pytest.approx(0.875)
    assert 'more than 80 %' in a.message(0.8, 0.5) and '-20.1 deg' in a.message(0.8, 0.5)
    # at t = 20 s the window [10, 20] s holds the last old sample (t = 10 s, held 1 s) and
    # nine new ones
    a = feed(m, [(float(t), -0.1, True) for t in range(11, 21)])
    assert a.level == OK and a.hold_time == pytest.approx(10.0)
    assert a.hold_bar == pytest.approx((-0.35 + 9 * -0.1) / 10.0)


def test_a_plane_at_its_stop_while_holding_is_low_and_in_a_manoeuvre_not_judged() -> None:
    m = AuthorityMonitor(0.4, 10.0, 0.8)
    # holding: 6 s at the stop, 4 s at 0.1 rad (mean 0.28 rad, 70 % of the travel)
    a = feed(m, [(float(t), 0.4 if t < 6 else 0.1, True) for t in range(11)])
    assert a.level == LOW and a.saturated == pytest.approx(0.6)
    assert a.share == pytest.approx(0.7) and a.at_stop == pytest.approx(0.6)
    assert 'at its stop 60 % of the time: the vehicle answers its plane less' \
        in a.message(0.8, 0.5)
    # 4 s at the stop of 10: ok
    m = AuthorityMonitor(0.4, 10.0, 0.8)
    a = feed(m, [(float(t), -0.4 if t < 4 else 0.1, True) for t in range(11)])
    assert a.level == OK and a.saturated == pytest.approx(0.4)
    # a manoeuvre (reference moving) at the stop all along: not judged, the stop is said
    m = AuthorityMonitor(0.4, 10.0, 0.8)
    a = feed(m, [(float(t), 0.4, False) for t in range(11)])
    assert a.level == UNKNOWN and math.isnan(a.hold_bar) and a.hold_time == 0.0
    assert a.at_stop == pytest.approx(1.0)
    assert 'plane at its stop 100 % of the window' in a.message(0.8, 0.5)


def test_bad_samples_are_ignored_and_bad_settings_refused() -> None:
    m = AuthorityMonitor(0.4, 10.0, 0.8)
    m.update(1.0, -0.2, True)
    before = m.update(2.0, -0.2, True)
    assert m.update(2.0, -0.4, True) == before           # the last sample's time
    assert m.update(3.0, math.nan, True) == before       # not finite
    a = m.update(0.5, -0.3, True)                        # the clock set back: a new window
    assert a.hold_time == 0.0 and a.level == UNKNOWN
    a = m.update(1.5, -0.3, True)
    assert a.hold_time == pytest.approx(1.0) and a.hold_bar == pytest.approx(-0.3)
    m.reset()
    assert m.authority.level == UNKNOWN and m.authority.hold_time == 0.0
    for kwargs, name in (({'bar_max': 0.0}, 'bar_max'), ({'window': math.nan}, 'window'),
                         ({'share_max': 1.5}, 'share_max'),
                         ({'saturated_max': 0.0}, 'saturated_max')):
        args = {'bar_max': 0.4, 'window': 10.0, 'share_max': 0.8, **kwargs}
        with pytest.raises(DesignError, match=name):
            AuthorityMonitor(**args)


def test_window_is_froude_scaled_from_the_vehicle_file() -> None:
    """20 s on the A18M (L = 4.6 m); sqrt(L/g) scaling to another hull (hand-worked)."""
    a18m = load_vehicle(ROOT / 'config' / 'a18m.yaml')
    remus = load_vehicle(ROOT / 'config' / 'remus100.yaml')
    assert derive_tuning(a18m, 25.0 * DEG).authority_window == pytest.approx(20.0, rel=1e-3)
    expected = 20.0 * math.sqrt(float(remus.L_ref) / 4.6)
    assert DepthPilot.for_vehicle(remus).authority_monitor.window == pytest.approx(expected,
                                                                                rel=1e-3)


#: (vehicle, plant error, speed [m/s], z0 -> z1 [m], level at the end)
CASES = [
    ('a18m', None, 2.0, 40.0, 10.0, OK),
    ('a18m', 'buoyancy+1%', 2.0, 40.0, 10.0, OK),
    ('remus100', None, 1.5, 20.0, 10.0, OK),
    ('remus100', 'buoyancy+1%', 1.5, 20.0, 10.0, LOW),
]


@pytest.mark.parametrize(('name', 'error', 'u0', 'z0', 'z1', 'level'), CASES)
def test_hold_plane_is_the_plants_own_trim(name: str, error: str | None, u0: float, z0: float,
                                          z1: float, level: str) -> None:
    """After a depth change and a hold, the plane the pilot holds depth with is the true
    plant's level trim at the speed it flies (auv_sim.trim on the plant), whatever the design
    model says; its share of the travel sets the verdict."""
    design = load_vehicle(ROOT / 'config' / f'{name}.yaml')
    real, environment = (design, None) if error is None else model_error_plant(design, error)
    settings = PilotSettings()
    pilot = DepthPilot.for_vehicle(design, settings)
    run = run_closed_loop(real, [(0.0, z1)], 120.0, z0=z0, u0=u0, environment=environment,
                          settings=settings, pilot=pilot, speed_time_constant=2.0)
    a = pilot.authority
    window = run.record.t >= run.record.t[-1] - pilot.authority_monitor.window
    u = float(np.mean(run.record.x[window, 6]))
    trim = VerticalPlane(real, environment).trim(u, z1)
    assert a.level == level, a
    assert a.hold_time == pytest.approx(pilot.authority_monitor.window, rel=0.02)
    assert a.hold_bar == pytest.approx(trim.bar, abs=0.05 * DEG), (math.degrees(a.hold_bar),
                                                                  math.degrees(trim.bar))
    assert a.share == pytest.approx(abs(trim.bar) / design.bar_max, abs=0.01)
    assert a.saturated == 0.0


def test_weak_fins_never_hold_depth_and_the_plane_is_said_at_its_stop() -> None:
    """REMUS 100 with 30 % less fin lift: its trim takes 13.0 of the 13.6 deg travel
    (auv_sim.trim), the vehicle porpoises about the command with the plane at its stop and
    the reference never comes to rest: not judged, the stop said."""
    design = load_vehicle(ROOT / 'config' / 'remus100.yaml')
    real, environment = model_error_plant(design, 'fins*0.7')
    trim = VerticalPlane(real, environment).trim(1.5, 10.0)
    assert abs(trim.bar) / design.bar_max > 0.9
    settings = PilotSettings()
    pilot = DepthPilot.for_vehicle(design, settings)
    run_closed_loop(real, [(0.0, 10.0)], 120.0, z0=20.0, u0=1.5, environment=environment,
                    settings=settings, pilot=pilot, speed_time_constant=2.0)
    a = pilot.authority
    assert a.level == UNKNOWN and a.hold_time < 0.5 * pilot.authority_monitor.window, a
    assert a.at_stop > 0.5, a
    assert f'plane at its stop {100 * a.at_stop:.0f} % of the window' in a.message(0.8, 0.5)


def test_running_sums_equal_a_direct_sum_over_the_window() -> None:
    """Irregular samples, some at the stop, holding or not, over ten windows: the monitor's
    running sums against the sums written out over the samples of each window."""
    rng = np.random.default_rng(7)
    m = AuthorityMonitor(0.4, 10.0, 0.8)
    times = np.cumsum(rng.uniform(0.05, 0.5, 400))
    bars = np.clip(rng.normal(-0.2, 0.2, times.size), -0.4, 0.4)
    holds = rng.uniform(size=times.size) < 0.7
    for k, (t, bar, hold) in enumerate(zip(times, bars, holds)):
        a = m.update(float(t), float(bar), bool(hold))
        inside = [i for i in range(k) if times[i] >= t - 10.0]
        dur = {i: min(times[i + 1] - times[i], 10.0) for i in inside}
        held = [i for i in inside if holds[i]]
        hold_time = sum(dur[i] for i in held)
        assert a.hold_time == pytest.approx(hold_time, abs=1e-9)
        if hold_time > 0.0:
            assert a.hold_bar == pytest.approx(sum(bars[i] * dur[i] for i in held) / hold_time,
                                               abs=1e-9)
            assert a.saturated == pytest.approx(
                sum(dur[i] for i in held if abs(bars[i]) >= 0.4) / hold_time, abs=1e-9)
        covered = sum(dur.values())
        if covered > 0.0:
            assert a.at_stop == pytest.approx(
                sum(dur[i] for i in inside if abs(bars[i]) >= 0.4) / covered, abs=1e-9)
