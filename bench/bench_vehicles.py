"""The depth pilot on other vehicles and off its design model: settling over the bound.

Part 1 (``vehicles``): the REMUS 100 (config/remus100.yaml, Prestero 2001; open-loop unstable
in pitch/heave) and the NPS AUV II (config/npsauv2.yaml, Healey and Lienard 1993; 5.3 m,
5443 kg) fly 20 -> 10 m, 10 -> 30 m and 5 -> 40 m at 1.5 m/s with the pilot's default
settings designed from each vehicle file; the vehicle's speed loop holds the surge speed
(:func:`auv_depth_lqr.closed_loop.run_closed_loop`, ``speed_time_constant`` 2 s). Reported per
case: settling time (+-0.1 m), the time-optimal bound of the vehicle's own model
(:func:`auv_depth_lqr.bound.settling_bound`) and their ratio (target <= 1.5), overshoot, peak
pitch (limit 25 deg), plane saturation time. ``bounds``: each bound with the grid time its
plan settles at, the bands reached there and one grid step earlier, the solver's starts and
its wall time.

Part 2 (``model_error``): the A18M 40 -> 10 m at 2 m/s and the REMUS 20 -> 10 m at 1.5 m/s,
the pilot designed on the vehicle file and the plant changed by one of
:data:`auv_depth_lqr.closed_loop.MODEL_ERRORS`; 200 s. Reported: settling over the bound
(goal <= 2), peak pitch (no tumble: < 35 deg; limit + 2 deg), the depth error over the last
20 s (integral action: < 0.01 m).

Run as a script to write ``bench/results/vehicles.json`` (about 8 min on one core).
"""
from __future__ import annotations

import json
import math
import os
import pathlib
import platform
import time
from typing import Any

import numpy as np
from timing import save_figures

from auv_depth_lqr.bound import settling_bound
from auv_depth_lqr.closed_loop import MODEL_ERRORS, model_error_plant, run_closed_loop
from auv_depth_lqr.errors import AuvLqrError
from auv_depth_lqr.metrics import step_metrics
from auv_depth_lqr.pilot import DepthPilot, PilotSettings
from auv_sim.errors import AuvSimError
from auv_sim.params import VehicleParams, load_vehicle

CONFIG = pathlib.Path(__file__).resolve().parents[1] / 'config'
THETA_MAX = math.radians(25.0)
SPEED_TAU = 2.0                                         # s, the vehicle's speed loop
CHANGES = ((20.0, 10.0), (10.0, 30.0), (5.0, 40.0))     # m, at 1.5 m/s
ERROR_CASES = {'a18m': (40.0, 10.0, 2.0), 'remus100': (20.0, 10.0, 1.5)}


def _finite(value: float, digits: int) -> float | None:
    return round(value, digits) if math.isfinite(value) else None


def fly(design: VehicleParams, z0: float, z1: float, u0: float, bound: float,
        error: str | None = None, duration: float = 150.0) -> dict[str, Any]:
    """One closed-loop run of the pilot designed on ``design``; the plant has ``error``."""
    real, environment = (design, None) if error is None else model_error_plant(design, error)
    settings = PilotSettings()
    t0 = time.perf_counter()
    try:
        run = run_closed_loop(real, [(0.0, z1)], duration, z0=z0, u0=u0,
                              environment=environment, settings=settings,
                              pilot=DepthPilot.for_vehicle(design, settings),
                              speed_time_constant=SPEED_TAU)
    except (AuvLqrError, AuvSimError) as exc:
        return {'error': str(exc)}
    rec = run.record
    m = step_metrics(rec.t, rec.x[:, 2], rec.x[:, 4], rec.x[:, 10], rec.x[:, 12], z1,
                     bar_max=design.bar_max, u0=u0, theta_max=THETA_MAX)
    last = rec.t > rec.t[-1] - 20.0
    return {
        'settling_time_s': _finite(m.settling_time, 2),
        'time_optimal_bound_s': round(bound, 2),
        'settling_over_time_optimal_bound': _finite(m.settling_time / bound, 3),
        'overshoot_m': round(m.overshoot, 3),
        'peak_pitch_deg': round(math.degrees(float(np.max(np.abs(rec.x[:, 4])))), 2),
        'bar_saturation_time_s': round(m.bar_saturation_time, 2),
        'final_depth_error_m': round(float(np.max(np.abs(rec.x[last, 2] - z1))), 4),
        'wall_s': round(time.perf_counter() - t0, 2),
    }


def bound_figures(params: VehicleParams, z0: float, z1: float, u0: float
                  ) -> tuple[float, dict[str, Any]]:
    """The time-optimal bound [s] and how it was found: the first grid time a plan settles
    at, the bands reached there and one step earlier [m], SLP starts, wall time [s]."""
    t0 = time.perf_counter()
    bound = settling_bound(params, z0, z1, u0, THETA_MAX)
    return bound.settling_time, {
        'time_optimal_bound_s': round(bound.settling_time, 3),
        'grid_time_s': round(bound.grid_time, 3),
        'band_reached_m': round(bound.band_reached, 4),
        'earlier_band_m': round(bound.earlier_band, 4),
        'solver_starts': bound.solves, 'wall_s': round(time.perf_counter() - t0, 1)}


def run() -> dict[str, Any]:
    """Both parts; returns the figures."""
    load_start = os.getloadavg()[0]
    bounds: dict[str, Any] = {}
    vehicles: dict[str, Any] = {}
    for name in ('remus100', 'npsauv2'):
        params = load_vehicle(CONFIG / f'{name}.yaml')
        vehicles[name] = {}
        for z0, z1 in CHANGES:
            key = f'{z0:g}->{z1:g}m'
            bound, bounds[f'{name} {key} at 1.5 m/s'] = bound_figures(params, z0, z1, 1.5)
            vehicles[name][key] = fly(params, z0, z1, 1.5, bound)
    errors: dict[str, Any] = {}
    for name, (z0, z1, u0) in ERROR_CASES.items():
        params = load_vehicle(CONFIG / f'{name}.yaml')
        bound, figures = bound_figures(params, z0, z1, u0)
        bounds.setdefault(f'{name} {z0:g}->{z1:g}m at {u0:g} m/s', figures)  # once computed
        errors[f'{name} {z0:g}->{z1:g}m at {u0:g} m/s'] = {
            'none': fly(params, z0, z1, u0, bound, None, duration=200.0),
            **{error: fly(params, z0, z1, u0, bound, error, duration=200.0)
               for error in MODEL_ERRORS}}
    return {'speed_u0_m_s': 1.5, 'theta_max_deg': 25.0, 'speed_loop_s': SPEED_TAU,
            'vehicles': vehicles, 'model_error': errors, 'bounds': bounds,
            'machine': {'python': platform.python_version(), 'cpus': os.cpu_count(),
                        'load_average_1min_start': round(load_start, 2),
                        'load_average_1min_end': round(os.getloadavg()[0], 2)}}


if __name__ == '__main__':
    figures = run()
    save_figures('vehicles', figures)
    print(json.dumps(figures, indent=2))
