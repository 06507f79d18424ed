"""The depth pilot off its design model: causes of the robustness failures, one test each.

* A buoyancy offset: the disturbance estimate of the controller must hold the heave
  acceleration the offset gives (oracle: ``-dB / (m - Zwdot)`` worked by hand from the
  vehicle file) and move the level trim to the plant's own (oracle: the nonlinear trim of the
  vehicle with that buoyancy, solved by ``auv_sim.trim``), so the depth holds with no offset.
* A pilot told its water speed on a vehicle that slows down in a dive: the surge it flies its
  model at is the true one (oracle: the hand-worked ``u - c cos(theta)``), not the setting.
* Settings derived from the vehicle file: the disturbance estimate's time constant scales
  with ``sqrt(L/g)`` (Froude), the safe BAR with the plane travel.
* A plane held at its angle limit: the disturbance estimate holds still there (a plane
  weaker than the model's would read as an offset), and learns off the limit.

Frames and units: NED, z down [m]; pitch nose up [rad]; BAR [rad].
"""
from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest

from auv_depth_lqr.closed_loop import run_closed_loop
from auv_depth_lqr.controller import PlaneState
from auv_depth_lqr.pilot import DepthPilot, PilotSettings
from auv_depth_lqr.tuning import derive_tuning
from auv_sim.environment import Environment
from auv_sim.params import VehicleParams, load_vehicle
from auv_sim.trim import VerticalPlane

ROOT = pathlib.Path(__file__).resolve().parents[1]
THETA_MAX = math.radians(25.0)


@pytest.fixture(scope='module')
def a18m() -> VehicleParams:
    return load_vehicle(ROOT / 'config' / 'a18m.yaml')


@pytest.mark.parametrize('share', [0.01, -0.01])
def test_disturbance_estimate_holds_a_buoyancy_offset(a18m: VehicleParams,
                                                      share: float) -> None:
    """Holding 30 m at 2 m/s with a buoyancy 1 % of the weight off (light, heavy)."""
    d_b = share * a18m.m * a18m.g  # [N], up
    settings = PilotSettings()
    pilot = DepthPilot.for_vehicle(a18m, settings)
    run = run_closed_loop(a18m, [(0.0, 30.0)], 60.0, z0=30.0, u0=2.0,
                          environment=Environment(effects={'buoyancy_offset': {'dB': d_b}}),
                          settings=settings, pilot=pilot)
    controller = pilot.controller
    d_w, _ = controller.disturbance
    # the offset, up, is a heave acceleration -dB / (m - Zwdot) (z down) at level pitch
    assert d_w == pytest.approx(-d_b / (a18m.m - a18m.Zwdot), rel=0.05)
    # the level trim moved by the estimate is the plant's own (nonlinear trim, solved apart)
    own = VerticalPlane(a18m.replace(B=a18m.B + d_b)).trim(2.0)
    nominal = controller.design.at(2.0)
    moved = controller.trimmed(nominal)
    assert abs(own.bar - nominal.bar_e) > math.radians(3.0)  # the offset matters ...
    assert moved.bar_e == pytest.approx(own.bar, abs=0.1 * abs(own.bar - nominal.bar_e))
    assert moved.theta_e == pytest.approx(own.theta, abs=math.radians(0.3))
    # ... and the depth holds: within 2 cm over the last 10 s of a minute
    rec = run.record
    last = rec.t >= rec.t[-1] - 10.0
    assert np.max(np.abs(rec.x[last, 2] - 30.0)) < 0.02


def test_disturbance_estimate_holds_still_with_the_plane_at_its_limit(
        a18m: VehicleParams) -> None:
    """The same unexplained pitch acceleration (the pitch rate ramping by 0.005 rad/s^2, at
    2 m/s, depth on the command) fed to two controllers: one pitched 15 deg nose up, whose
    loop holds the BAR at +bar_max on every sample, keeps its estimate at zero; one at its
    trim pitch, its BAR within the limits, takes the same data for a disturbance."""
    estimates = []
    for pitch in (15.0, 0.0):
        controller = DepthPilot.for_vehicle(a18m).controller
        op = controller.design.at(2.0)
        bars = [controller.step(PlaneState(z=30.0, theta=op.theta_e + math.radians(pitch),
                                           w=op.w_e, q=0.0005 * k, u=2.0), 30.0)
                for k in range(30)]
        share = [abs(b) / controller.limits.bar_max for b in bars]
        estimates.append((controller.disturbance, share))
    (held, at_limit), (learned, within) = estimates
    assert min(at_limit) == 1.0  # the plane at its limit on every sample ...
    assert held == (0.0, 0.0)    # ... and the estimate as it started
    assert max(within) < 0.6     # the plane within its limits on every sample ...
    assert abs(learned[1]) > 5e-3  # ... and the pitch acceleration taken [rad/s^2]


def test_told_its_water_speed_the_pilot_flies_its_true_surge(a18m: VehicleParams) -> None:
    """A 0.3 m/s following current, the pilot told 2 m/s through the water: level, the
    measured 2.3 m/s over ground gives the current; pitched 20 deg down at 1.6 m/s through
    the water (it slowed down in the dive), the pilot flies 1.6 m/s, not the setting."""
    pilot = DepthPilot.for_vehicle(a18m, PilotSettings(water_speed=2.0))
    theta0 = pilot.controller.design.at(2.0).theta_e
    c = 0.3
    pilot.on_state(0.0, z=20.0, theta=theta0, w=c * math.sin(theta0),
                   q=0.0, u=2.0 + c * math.cos(theta0))
    assert pilot.state is not None
    assert pilot.state.u == pytest.approx(2.0, abs=1e-12)
    assert pilot.state.w == pytest.approx(0.0, abs=1e-12)
    theta = math.radians(-20.0)
    u_r, w_r = 1.6, 0.05
    pilot.on_state(0.1, z=20.0, theta=theta, w=w_r + c * math.sin(theta), q=0.0,
                   u=u_r + c * math.cos(theta))
    assert pilot.state.u == pytest.approx(u_r, abs=1e-12)
    assert pilot.state.w == pytest.approx(w_r, abs=1e-12)


def test_settings_scale_with_the_vehicle(a18m: VehicleParams) -> None:
    """The disturbance estimate's time constant is 3 s on the A18M and scales with
    sqrt(L/g); the safe BAR with the plane travel (REMUS 100: L 1.33 m, 13.6 deg fins;
    hand-worked)."""
    remus = load_vehicle(ROOT / 'config' / 'remus100.yaml')
    mine = derive_tuning(a18m, THETA_MAX)
    other = derive_tuning(remus, THETA_MAX)
    assert mine.governor.disturbance_time == pytest.approx(3.0, rel=1e-9)
    assert other.governor.disturbance_time == pytest.approx(3.0 * math.sqrt(remus.L_ref / 4.6),
                                                            rel=1e-9)
    assert mine.safe_bar == pytest.approx(-0.12, rel=1e-9)
    assert abs(other.safe_bar) == pytest.approx(0.12 / 0.4363 * remus.bar_max, rel=1e-9)
