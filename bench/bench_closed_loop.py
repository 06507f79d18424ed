"""Closed-loop depth changes of the LQR pilot on the nonlinear A18M model: settling, overshoot,
pitch, pitch rate.

Each case flies the offline closed loop (:func:`auv_depth_lqr.closed_loop.run_closed_loop`:
the 6-DOF simulator at its RK4 step, the pilot at 10 Hz, lockstep) for 150 s from a trim at
the start depth, and reports, from :func:`auv_depth_lqr.metrics.step_metrics`:

* ``settling_time`` [s]: time after the command from which the depth stays within +-0.1 m;
* ``settling_over_kinematic_bound``: that time over ``T_kin = |dz| / (u0 sin(theta_max))``
  (35.5 s for 30 m at 2 m/s and theta_max = 25 deg; it scales with 1 / u0);
* ``overshoot`` [m], ``peak_pitch_deg`` (largest ``|theta|``), ``rms_q_settled_deg_s`` (RMS
  pitch rate over the whole remainder after the settling instant);
* ``time_optimal_bound_s``: the shortest settling time any pilot can reach on the vehicle's
  nonlinear vertical-plane model within the same BAR angle/rate and pitch limits
  (:func:`auv_depth_lqr.bound.settling_bound`; a horizontal current does not change it), and
  ``settling_over_time_optimal_bound``;
* ``null`` settling figures when the depth never stays within the band before the end;
* ``pass`` against the targets: settling <= 1.5 T_kin, overshoot < 0.2 m, RMS q after
  settling < 0.05 deg/s, peak pitch <= 25 deg (BAR limit 25 deg, theta_max 25 deg).

Cases: 40 -> 10 m at 2 m/s; the same with a 0.3 m/s current (following: north, the vehicle
heads north; head: south; cross: east), the vehicle starting trimmed in the water and the pilot
told its speed through the water (``PilotSettings.water_speed``, as from its propeller
setting), and once more in the head current with the pilot on its speed over ground; at
u0 = 1.5, 2.5 and 1.83 m/s (gain scheduling, on and between grid speeds); 10 -> 40 m at
2 m/s. Every case runs with the pilot's
default weights and with the report's section-5
tuning (``report_5``), same governor. Simulated time is exact, so the figures are
deterministic; the wall time per run is reported for information. Run as a script to write
``bench/results/closed_loop.json``.
"""
from __future__ import annotations

import json
import math
import pathlib
import platform
import time
from typing import Any

from timing import save_figures

from auv_depth_lqr.bound import settling_bound
from auv_depth_lqr.closed_loop import run_closed_loop
from auv_depth_lqr.errors import AuvLqrError
from auv_depth_lqr.metrics import step_metrics
from auv_depth_lqr.pilot import PilotSettings
from auv_sim.environment import Environment
from auv_sim.params import load_vehicle

VEHICLE = pathlib.Path(__file__).resolve().parents[1] / 'config' / 'a18m.yaml'
DURATION = 150.0                    # s
THETA_MAX = math.radians(25.0)      # rad
TARGETS = {'settling_over_kinematic_bound': 1.5, 'overshoot_m': 0.2,
           'rms_q_settled_deg_s': 0.05, 'peak_pitch_deg': 25.0}

# name -> (z0 [m], z1 [m], u0 [m/s], current NED [m/s] or None, pilot told its water speed)
CASES: dict[str, tuple[float, float, float, dict[str, float] | None, bool]] = {
    'climb_40_10_u2': (40.0, 10.0, 2.0, None, False),
    'climb_40_10_u2_current_following_0.3': (40.0, 10.0, 2.0, {'north': 0.3}, True),
    'climb_40_10_u2_current_head_0.3': (40.0, 10.0, 2.0, {'north': -0.3}, True),
    'climb_40_10_u2_current_cross_0.3': (40.0, 10.0, 2.0, {'east': 0.3}, True),
    'climb_40_10_u2_current_head_0.3_ground_speed': (40.0, 10.0, 2.0, {'north': -0.3}, False),
    'climb_40_10_u1.5': (40.0, 10.0, 1.5, None, False),
    'climb_40_10_u2.5': (40.0, 10.0, 2.5, None, False),
    'climb_40_10_u1.83': (40.0, 10.0, 1.83, None, False),
    'dive_10_40_u2': (10.0, 40.0, 2.0, None, False),
}
#: cases flown for information, outside the targets: the pilot scheduled on its speed over
#: ground in a head current (it should be told its water speed)
INFORMATION = {'climb_40_10_u2_current_head_0.3_ground_speed'}


def _finite(value: float, digits: int) -> float | None:
    """``value`` rounded, or ``None`` (JSON null) when it is not finite (never settled)."""
    return round(value, digits) if math.isfinite(value) else None


_BOUNDS: dict[tuple[float, float, float], float] = {}


def optimal_bound(params: Any, z0: float, z1: float, u0: float) -> float:
    """Time-optimal settling bound [s] of a change, computed once per (z0, z1, u0)."""
    key = (z0, z1, u0)
    if key not in _BOUNDS:
        _BOUNDS[key] = settling_bound(params, z0, z1, u0, THETA_MAX).settling_time
    return _BOUNDS[key]


def fly(params: Any, z0: float, z1: float, u0: float, current: dict[str, float] | None,
        water: bool, weights: str) -> dict[str, Any]:
    """One closed-loop run; its figures and pass/fail against :data:`TARGETS`."""
    environment = None if current is None else Environment(effects={'current': current})
    t0 = time.perf_counter()
    try:
        run = run_closed_loop(params, [(0.0, z1)], DURATION, z0=z0, u0=u0,
                              environment=environment,
                              settings=PilotSettings(weights=weights, theta_max=THETA_MAX,
                                                     water_speed=u0 if water else None))
    except AuvLqrError as exc:
        return {'error': str(exc), 'pass': False}
    wall = time.perf_counter() - t0
    rec = run.record
    m = step_metrics(rec.t, rec.x[:, 2], rec.x[:, 4], rec.x[:, 10], rec.x[:, 12], z1,
                     bar_max=params.bar_max, u0=u0, theta_max=THETA_MAX)
    ratio = m.settling_time / m.kinematic_bound
    bound = optimal_bound(params, z0, z1, u0)
    figures = {
        'z0_m': z0, 'z1_m': z1, 'u0_m_s': u0, 'current_ned_m_s': current,
        'pilot_water_speed_m_s': u0 if water else None,
        'settling_time_s': _finite(m.settling_time, 2),
        'kinematic_bound_s': round(m.kinematic_bound, 2),
        'settling_over_kinematic_bound': _finite(ratio, 3),
        'time_optimal_bound_s': round(bound, 2),
        'settling_over_time_optimal_bound': _finite(m.settling_time / bound, 3),
        'overshoot_m': round(m.overshoot, 4),
        'peak_pitch_deg': round(math.degrees(m.peak_pitch), 2),
        'rms_q_settled_deg_s': _finite(math.degrees(m.rms_q_settled), 4),
        'bar_saturation_time_s': round(m.bar_saturation_time, 2),
        'wall_s': round(wall, 2),
    }
    checks = {
        'settling': bool(ratio <= TARGETS['settling_over_kinematic_bound']),
        'overshoot': bool(m.overshoot < TARGETS['overshoot_m']),
        'rms_q': bool(math.degrees(m.rms_q_settled) < TARGETS['rms_q_settled_deg_s']),
        'peak_pitch': bool(math.degrees(m.peak_pitch) <= TARGETS['peak_pitch_deg'] + 1e-9),
    }
    figures['checks'] = checks
    figures['pass'] = all(checks.values())
    return figures


def run() -> dict[str, Any]:
    """All cases with the default weights and with ``report_5``; returns the figures."""
    params = load_vehicle(VEHICLE)
    results: dict[str, Any] = {}
    for weights in ('default', 'report_5'):
        results[weights] = {name: fly(params, *case, weights=weights)
                            for name, case in CASES.items()}
    return {
        'vehicle': VEHICLE.name,
        'duration_s': DURATION,
        'theta_max_deg': math.degrees(THETA_MAX),
        'bar_max_deg': round(math.degrees(params.bar_max), 2),
        'bar_rate_deg_s': round(math.degrees(params.bar_rate), 2),
        'targets': TARGETS,
        'results': results,
        'information_cases': sorted(INFORMATION),
        'all_pass_default': all(r['pass'] for name, r in results['default'].items()
                                if name not in INFORMATION),
        'python': platform.python_version(),
        'machine': platform.machine(),
    }


if __name__ == '__main__':
    figures = run()
    save_figures('closed_loop', figures)
    print(json.dumps(figures, indent=2))
