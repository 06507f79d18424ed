"""The pilot's settings derived from the vehicle file (auv_depth_lqr.tuning), on a vehicle
scaled geometrically.

The A18M scaled by ``k`` in every length, with masses ``k^3``, inertias ``k^5``, times
``sqrt(k)`` and the water's viscosity ``k^1.5`` (equal Reynolds number at the Froude-scaled
speed), is the same vehicle in Froude similarity: flown at ``sqrt(k)`` times the speed through
a ``k`` times larger depth change it must take ``sqrt(k)`` times as long. Oracles: the
settings worked by hand from the rules of :func:`derive_tuning` (heave excursion
``0.1 sqrt(k)`` m/s, ...), and the similarity law for the flights, checked against a flight
of the unscaled A18M in the same test (not a stored figure).
"""
from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest

from auv_depth_lqr.closed_loop import run_closed_loop
from auv_depth_lqr.errors import DesignError
from auv_depth_lqr.metrics import step_metrics
from auv_depth_lqr.pilot import DepthPilot, PilotSettings, build_controller
from auv_depth_lqr.tuning import derive_tuning
from auv_sim.params import SCHEMA, VehicleParams, load_vehicle

ROOT = pathlib.Path(__file__).resolve().parents[1]
THETA_MAX = math.radians(25.0)
# Froude-similarity exponent of k per unit of the vehicle file (mass ~ k^3, length ~ k,
# time ~ k^0.5); the simulator's step is kept (it must divide the pilot's period).
EXPONENT = {'-': 0.0, '1/rad': 0.0, 'rad': 0.0, 'kg/m^3': 0.0, 'm/s^2': 0.0, 'm': 1.0,
            'm^2': 2.0, 'kg': 3.0, 'N': 3.0, 'kg m': 4.0, 'kg m^2': 5.0, 'kg/m': 2.0,
            'm^2/s': 1.5, 's': 0.5, 'rad/s': -0.5}


def scaled(params: VehicleParams, k: float) -> VehicleParams:
    """``params`` scaled geometrically by ``k`` in Froude similarity (see module docstring)."""
    return params.replace(**{name: value * k ** EXPONENT[SCHEMA[name][1]]
                             for name, value in params.values.items() if name != 'dt'})


@pytest.fixture(scope='module')
def a18m() -> VehicleParams:
    return load_vehicle(ROOT / 'config' / 'a18m.yaml')


def test_scaled_vehicle_settings_follow_the_rules(a18m: VehicleParams) -> None:
    """Hand-worked for k = 2 from the A18M's tuned excursions (0.1 m/s, 0.03 rad/s, 0.3 m,
    0.06 rad, 4.5 m s, 0.1 rad plane) and governor (0.2 m/s^2, 8 m, 0.12 m, 0.5 m, 0.2 m)."""
    k = 2.0
    tuning = derive_tuning(scaled(a18m, k), THETA_MAX)
    r2 = math.sqrt(2.0)
    excursions = (0.1 * r2, 0.03 / r2, 0.6, 0.06, 4.5 * 2.0 * r2)
    q_diagonal = [1.0 / e**2 for e in excursions]
    r_bar = 1.0 / 0.1**2
    q_got, r_got = tuning.weights
    assert q_got == pytest.approx(q_diagonal, rel=1e-3)
    assert r_got == pytest.approx(r_bar, rel=1e-3)
    g = tuning.governor
    assert (g.accel_max, g.approach_length, g.landing_distance, g.max_lag,
            g.integrate_within) == pytest.approx((0.2, 16.0, 0.24, 1.0, 0.4), rel=1e-3)
    assert tuning.safe_bar == pytest.approx(-0.12, rel=1e-3)


def test_safe_bar_is_nose_up_and_within_the_plane(a18m: VehicleParams) -> None:
    """The sign follows CMbar (nose-up moment), the size the plane travel: 0.12 rad of the
    A18M's 0.4363 rad travel."""
    flipped = a18m.replace(CMbar=-a18m.CMbar, bar_max=0.2)
    assert derive_tuning(flipped, THETA_MAX).safe_bar == pytest.approx(0.2 * 0.12 / 0.4363)
    pilot = DepthPilot.for_vehicle(a18m, PilotSettings(speeds=(1.5, 2.0, 2.5), bar_max=0.3))
    assert pilot.settings.safe_bar == pytest.approx(-0.3 * 0.12 / 0.4363)


def test_settings_without_safe_bar_need_the_vehicle(a18m: VehicleParams) -> None:
    settings = PilotSettings(speeds=(1.5, 2.0, 2.5))
    with pytest.raises(DesignError, match='safe_bar'):
        DepthPilot(build_controller(a18m, settings), 0.0, 100.0, settings)


def _fly(params: VehicleParams, z0: float, z1: float, u0: float, band: float
         ) -> tuple[float, float, float]:
    """Settling time [s] within ``band`` [m], peak |pitch| [rad], overshoot [m]."""
    run = run_closed_loop(params, [(0.0, z1)], 200.0, z0=z0, u0=u0, settings=PilotSettings())
    rec = run.record
    m = step_metrics(rec.t, rec.x[:, 2], rec.x[:, 4], rec.x[:, 10], rec.x[:, 12], z1,
                     band=band, bar_max=params.bar_max, u0=u0, theta_max=THETA_MAX)
    return m.settling_time, float(np.max(np.abs(rec.x[:, 4]))), m.overshoot


@pytest.mark.parametrize('k', [0.5, 2.0])
def test_scaled_vehicle_flies_in_similarity(a18m: VehicleParams, k: float) -> None:
    """40 -> 10 m at 2 m/s on the A18M; 40k -> 10k m at 2 sqrt(k) m/s on the scaled one:
    the settling time (band 0.1k m) is sqrt(k) times the A18M's within 5 % (the pilot's
    10 Hz sample and 1 s jerk time are not scaled), within 1.5 T_kin, pitch within the limit,
    overshoot below 0.2k m (the bench's 0.2 m target, scaled)."""
    t_ref, _, _ = _fly(a18m, 40.0, 10.0, 2.0, 0.1)
    u = 2.0 * math.sqrt(k)
    t_k, peak, overshoot = _fly(scaled(a18m, k), 40.0 * k, 10.0 * k, u, 0.1 * k)
    assert t_k == pytest.approx(math.sqrt(k) * t_ref, rel=0.05)
    assert t_k <= 1.5 * 30.0 * k / (u * math.sin(THETA_MAX))
    assert peak <= THETA_MAX + math.radians(0.5)
    assert overshoot <= 0.2 * k
