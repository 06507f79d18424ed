"""Envelope fallback: the monitor on hand-made trajectories, the recovery law, and the pilot
flying out of a pitch upset on the simulated vehicle."""
from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import A18M

from auv_depth_lqr.errors import DesignError
from auv_depth_lqr.pilot import DepthPilot, PilotSettings
from auv_depth_lqr.recovery import (
    NORMAL,
    RECOVERY,
    EnvelopeMonitor,
    RecoverySettings,
    recovery_bar,
)
from auv_sim.params import load_vehicle
from auv_sim.simulator import Simulator
from auv_sim.trim import VerticalPlane

DEG = math.pi / 180


def test_pitch_beyond_limit_plus_margin_starts_recovery_and_hysteresis_resumes() -> None:
    monitor = EnvelopeMonitor(25 * DEG, RecoverySettings(pitch_margin=5 * DEG,
                                                         resume_time=3.0))
    # u = w = 0: a constant depth agrees with the kinematics at any pitch
    pitch = [0.0] * 10 + [28.0, 29.9, 30.1, 33.0, 27.0, 24.0, 24.0, 26.0] + [20.0] * 40
    verdicts = [monitor.update(0.1 * k, 20.0, deg * DEG, 0.0, 0.0)
                for k, deg in enumerate(pitch)]
    modes = [v.mode for v in verdicts]
    # 28 and 29.9 deg are inside limit + margin; 30.1 deg (index 12) is not
    assert modes[:12] == [NORMAL] * 12
    assert modes[12] == RECOVERY and verdicts[12].changed
    assert 'pitch 30.1 deg beyond 30.0 deg' in verdicts[12].reason
    # back below 25 deg at index 15 (t = 1.5 s), out again at 17 (26 deg): the clock restarts
    # at index 18 (t = 1.8 s); 3 s later (index 48) control resumes, not before
    assert modes[13:48] == [RECOVERY] * 35
    assert modes[48] == NORMAL and verdicts[48].changed and 'resumed' in verdicts[48].reason


def test_unexplained_depth_rate_starts_recovery_and_is_measured_exactly() -> None:
    settings = RecoverySettings(rate_residual_max=0.3, rate_window=2.0, resume_time=3.0)
    monitor = EnvelopeMonitor(25 * DEG, settings)
    u, theta = 2.0, -10 * DEG  # nose down 10 deg, w = 0: the kinematics dive 2 sin(10 deg)
    z_dot_kin = -u * math.sin(theta)
    # the vehicle sinks 0.5 m/s faster than its velocities explain (a downwelling)
    verdicts = [monitor.update(0.1 * k, 10.0 + (z_dot_kin + 0.5) * 0.1 * k, theta, 0.0, u)
                for k in range(31)]
    assert all(v.residual is None for v in verdicts[:10])  # less than half a window
    assert verdicts[10].residual == pytest.approx(0.5, abs=1e-12)
    assert verdicts[9].mode == NORMAL and verdicts[10].mode == RECOVERY
    assert 'depth rate +0.50 m/s' in verdicts[10].reason
    assert verdicts[30].residual == pytest.approx(0.5, abs=1e-12)


def test_depth_rate_the_kinematics_explain_never_starts_recovery() -> None:
    monitor = EnvelopeMonitor(25 * DEG)
    # a 20 deg nose-down dive at 2 m/s with 0.1 m/s heave, depth from the exact kinematics
    u, w, theta = 2.0, 0.1, -20 * DEG
    z_dot = -u * math.sin(theta) + w * math.cos(theta)
    residuals = [monitor.update(0.02 * k, 5.0 + z_dot * 0.02 * k, theta, w, u).residual
                 for k in range(500)]
    assert monitor.mode == NORMAL
    assert max(abs(r) for r in residuals if r is not None) < 1e-9


def test_recovery_law_levels_at_trim_and_is_plane_limited() -> None:
    # hand-worked: BAR = BAR_e - g (k_w (w - w_e) + k_q q + k_theta (theta - theta_e))
    bar = recovery_bar(k_w=0.2, k_q=1.5, k_theta=-2.0, w_e=0.01, theta_e=0.02, bar_e=-0.05,
                       w=0.11, q=0.1, theta=0.12, gain=0.5, bar_limit=0.3)
    assert bar == pytest.approx(-0.05 - 0.5 * (0.2 * 0.1 + 1.5 * 0.1 - 2.0 * 0.1), abs=1e-15)
    assert recovery_bar(0.0, 0.0, -10.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.2) == 0.2
    assert recovery_bar(0.0, 0.0, -10.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0, 1.0, 0.2) == -0.2


@pytest.mark.parametrize(('name', 'value'), [('pitch_margin', 0.0), ('gain', 1.5),
                                             ('bar_fraction', 0.0), ('resume_time', math.nan)])
def test_bad_recovery_settings_are_refused(name: str, value: float) -> None:
    with pytest.raises(DesignError, match=name):
        RecoverySettings(**{name: value})


def fly_upset(theta0: float, recovery: RecoverySettings, duration: float = 60.0
              ) -> tuple[np.ndarray, list[str], list[float]]:
    """The A18M trimmed at 30 m, 2 m/s, then pitched to ``theta0`` [rad]; the pilot holds
    30 m. Returns the pitch every control step [rad], the pilot's statuses and BARs."""
    params = load_vehicle(A18M)
    settings = PilotSettings(recovery=recovery)
    pilot = DepthPilot.for_vehicle(params, settings)
    x0 = VerticalPlane(params).trim(2.0, z=30.0).state()
    x0[4] = theta0
    sim = Simulator(params, x0=x0)
    pilot.set_depth_command(30.0)
    steps = int(round(settings.Ts / sim.dt))
    pitch, statuses, bars = [], [], []
    for _ in range(int(duration / settings.Ts)):
        x = sim.measured_state()
        pilot.on_state(sim.t, z=x[2], theta=x[4], w=x[8], q=x[10], u=x[6])
        bar, status = pilot.command(sim.t)
        sim.command('bar', bar)
        pitch.append(x[4])
        statuses.append(status)
        bars.append(bar)
        sim.step(steps)
    return np.array(pitch), statuses, bars


@pytest.mark.parametrize('theta0_deg', [-45.0, 40.0])
def test_pilot_recovers_from_a_pitch_upset_and_resumes_depth_control(theta0_deg: float
                                                                       ) -> None:
    pitch, statuses, _ = fly_upset(theta0_deg * DEG, RecoverySettings())
    assert statuses[0] == 'recovery'
    first_ok = statuses.index('ok')
    # back inside the pitch limit for the resume time (3 s) before resuming, within 20 s
    assert np.all(np.abs(pitch[first_ok - 30:first_ok]) <= 25 * DEG)
    assert first_ok * 0.1 <= 20.0
    # no new excursion once resumed; the recovery itself only ever reduced the upset
    assert 'recovery' not in statuses[first_ok:]
    assert np.max(np.abs(pitch[first_ok:])) <= 25.5 * DEG
    assert np.max(np.abs(pitch)) <= abs(theta0_deg) * DEG + 1e-9


def test_recovery_plane_fraction_is_respected() -> None:
    params = load_vehicle(A18M)
    _, statuses, bars = fly_upset(-45 * DEG, RecoverySettings(bar_fraction=0.5))
    first_ok = statuses.index('ok')
    assert max(abs(b) for b in bars[:first_ok]) == pytest.approx(0.5 * params.bar_max,
                                                                 abs=1e-12)
