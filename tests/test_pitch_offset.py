"""The pitch-sensor offset estimate of the depth pilot (``auv_depth_lqr.attitude``).

Oracles: the offset a synthetic straight run was given (the kinematics worked by hand:
``z_dot = -u sin(theta) + w cos(theta)``), the vertical current over the surge speed, and in
closed loop the pitch-sensor bias the simulator was configured with (``auv_sim`` applies it;
the pilot never reads it).

Frames and units: NED, z down [m]; body FRD; pitch nose up [rad]; time [s].
"""
from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest

from auv_depth_lqr.attitude import PitchOffsetEstimator
from auv_depth_lqr.closed_loop import run_closed_loop
from auv_depth_lqr.errors import DesignError
from auv_depth_lqr.pilot import DepthPilot, PilotSettings
from auv_sim.environment import Environment
from auv_sim.params import load_vehicle

ROOT = pathlib.Path(__file__).resolve().parents[1]
DEG = math.pi / 180.0


def _straight_run(offset: float, vertical_current: float = 0.0, noise: float = 0.0,
                  duration: float = 80.0, ts: float = 0.1, seed: int = 1
                  ) -> PitchOffsetEstimator:
    """A vehicle at 2 m/s whose true pitch sweeps -10..+10 deg slowly, its pitch sensor
    reading ``offset`` [rad] high, in a vertical current [m/s, down]; depth with white noise
    [m]. The depth is integrated by hand from the true kinematics."""
    est = PitchOffsetEstimator(time=20.0, offset_max=3.0 * DEG, gap=0.5)
    rng = np.random.default_rng(seed)
    u, w, z = 2.0, 0.02, 30.0
    n = int(round(duration / ts))
    for k in range(n + 1):
        t = k * ts
        theta = 10.0 * DEG * math.sin(2.0 * math.pi * t / 60.0)
        est.update(t, z + noise * float(rng.standard_normal()), theta + offset, w, u)
        # exact depth rate at the true pitch, midpoint rule over the next sample
        theta_mid = 10.0 * DEG * math.sin(2.0 * math.pi * (t + 0.5 * ts) / 60.0)
        z += ts * (-u * math.sin(theta_mid) + w * math.cos(theta_mid) + vertical_current)
    return est


@pytest.mark.parametrize('offset_deg', [0.5, -0.5, 2.0])
def test_offset_of_a_straight_run_is_found(offset_deg: float) -> None:
    est = _straight_run(offset_deg * DEG, noise=0.05)
    found = est.estimate
    assert found.valid
    assert found.offset == pytest.approx(offset_deg * DEG, abs=0.03 * DEG)


def test_no_offset_gives_none() -> None:
    assert abs(_straight_run(0.0, noise=0.05).estimate.offset) < 0.03 * DEG


def test_vertical_current_is_taken_as_the_flight_path_offset() -> None:
    # a 0.02 m/s downward current at 2 m/s: the corrected pitch holds the depth when it is
    # c_v / u = 0.01 rad higher than the model's (first order in the small angles)
    est = _straight_run(0.0, vertical_current=0.02)
    assert est.estimate.offset == pytest.approx(0.02 / 2.0, rel=0.03)


def test_a_fit_beyond_the_physical_bound_is_not_applied() -> None:
    est = _straight_run(5.0 * DEG)
    found = est.estimate
    assert not found.valid
    assert found.fitted == pytest.approx(5.0 * DEG, abs=0.05 * DEG)
    assert found.offset == 0.0  # nothing valid before: nothing applied


def test_a_gap_restarts_the_fit_and_holds_the_last_offset() -> None:
    est = _straight_run(0.5 * DEG)
    held = est.estimate.offset
    after = est.update(200.0, 30.0, 0.0, 0.0, 2.0)  # 120 s later: a gap
    assert after.offset == held
    assert not after.valid


def test_bad_settings_are_refused() -> None:
    with pytest.raises(DesignError, match='time'):
        PitchOffsetEstimator(time=0.0, offset_max=0.05, gap=0.5)
    with pytest.raises(DesignError, match='pitch_offset_max'):
        PilotSettings(pitch_offset_max=-1.0)


def test_pilot_removes_a_pitch_sensor_bias_in_closed_loop() -> None:
    """A18M, 20 -> 25 m at 2 m/s with its pitch sensor 0.5 deg high: the estimate finds the
    simulator's bias, and the depth arrives without the 0.1 m offset (0.2 m/deg) the LQR
    leaves when it flies the biased pitch, until its slow integrator removes it."""
    a18m = load_vehicle(ROOT / 'config' / 'a18m.yaml')
    bias = 0.5 * DEG
    env = Environment(effects={'pitch_sensor_bias': {'bias': bias}})
    tails = {}
    for estimate in (True, False):
        settings = PilotSettings(pitch_offset=estimate)
        pilot = DepthPilot.for_vehicle(a18m, settings)
        run = run_closed_loop(a18m, [(0.0, 25.0)], 60.0, z0=20.0, u0=2.0, environment=env,
                              settings=settings, pilot=pilot)
        rec = run.record
        arrived = (rec.t >= 30.0) & (rec.t < 40.0)
        tails[estimate] = abs(float(np.mean(rec.x[arrived, 2])) - 25.0)
        if estimate:
            assert pilot.pitch_offset.valid
            assert pilot.pitch_offset.offset == pytest.approx(bias, abs=0.05 * DEG)
    assert tails[False] > 0.06       # the biased pitch costs a depth offset ...
    assert tails[True] < 0.02        # ... which the estimate removes


def test_forgetting_time_is_froude_scaled_from_the_vehicle_file() -> None:
    """20 s on the A18M (L = 4.6 m); sqrt(L/g) scaling to another hull (hand-worked)."""
    from auv_depth_lqr.tuning import derive_tuning
    a18m = load_vehicle(ROOT / 'config' / 'a18m.yaml')
    remus = load_vehicle(ROOT / 'config' / 'remus100.yaml')
    assert derive_tuning(a18m, 25.0 * DEG).pitch_offset_time == pytest.approx(20.0, rel=1e-3)
    expected = 20.0 * math.sqrt(float(remus.L_ref) / 4.6)
    assert derive_tuning(remus, 25.0 * DEG).pitch_offset_time == pytest.approx(expected,
                                                                             rel=1e-3)
    pilot = DepthPilot.for_vehicle(remus)
    assert pilot.settings.pitch_offset_time == pytest.approx(expected, rel=1e-3)
