"""The pilot learning its plant on noisy sensors: the vehicle file's own model, learning on
and off, side by side.

The plant is the pilot's own vehicle file (nothing to learn: every parameter's truth is 0),
flown from its level trim at 1.5 m/s with its thrust held, through one depth change and its
hold, the pilot on the measured state plus the simulator's realistic white sensor noise
(:meth:`auv_logs.simlog.SensorNoise.realistic`: 2 cm, 0.1 deg, 1 cm/s, 0.1 deg/s; seeds 0 to
``--seeds`` - 1, :func:`auv_depth_lqr.closed_loop.run_closed_loop` ``sensor_noise``).
Reported per vehicle, change and seed, learning off and on: settling to +-0.1 m [s], the
largest depth error over the last 30 s [m], peak pitch [deg] and, learning, the estimate
(:data:`auv_depth_lqr.learning.PARAMETERS`); per case the range of each over the seeds;
``worst`` the worst of every case (settled flights; ``unsettled`` those not settled within
the 150 s).
No target: it measures how much the sensors' noise moves what is learned
(docs/pilot-design.md, "What does not work").

Run: ``python bench/bench_noisy_learning.py`` writes ``bench/results/noisy_learning.json``
(~3 min on a machine of 2 cores).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import pathlib
import time
from typing import Any

import numpy as np
from timing import save_figures

from auv_depth_lqr.closed_loop import run_closed_loop
from auv_depth_lqr.learning import PARAMETERS
from auv_depth_lqr.metrics import step_metrics
from auv_depth_lqr.pilot import DepthPilot, PilotSettings
from auv_logs.simlog import SensorNoise
from auv_sim.params import load_vehicle

CONFIG = pathlib.Path(__file__).resolve().parents[1] / 'config'
VEHICLES = ('remus100', 'a18m')
CHANGES = ((10.0, 20.0), (20.0, 10.0))   # m
U0 = 1.5                                 # m/s
DURATION = 150.0                         # s
HOLD_WINDOW = 30.0                       # s
THETA_MAX = math.radians(25.0)


def fly(vehicle: str, z0: float, z1: float, seed: int, learn: bool) -> dict[str, Any]:
    """One noisy flight's figures (module docstring)."""
    params = load_vehicle(CONFIG / f'{vehicle}.yaml')
    pilot = DepthPilot.for_vehicle(params, PilotSettings(learn=learn))
    t0 = time.perf_counter()
    run = run_closed_loop(params, [(0.0, z1)], DURATION, z0=z0, u0=U0, pilot=pilot,
                          sensor_noise=SensorNoise.realistic().sigmas(), seed=seed)
    rec = run.record
    m = step_metrics(rec.t, rec.x[:, 2], rec.x[:, 4], rec.x[:, 10], rec.cmd[:, 0], z1, u0=U0,
                     theta_max=THETA_MAX)
    last = rec.t >= rec.t[-1] - HOLD_WINDOW
    out: dict[str, Any] = {
        'settling_time_s': None if math.isnan(m.settling_time) else round(m.settling_time, 2),
        'hold_error_m': round(float(np.max(np.abs(rec.x[last, 2] - z1))), 4),
        'peak_pitch_deg': round(math.degrees(m.peak_pitch), 2),
        'wall_s': round(time.perf_counter() - t0, 2)}
    learner = pilot.controller.learner
    if learner is not None:
        out['learned'] = {k: round(v, 3) for k, v in zip(PARAMETERS, learner.estimate.values)}
    return out


def _range(rows: list[dict[str, Any]], key: str) -> list[float | None]:
    values = [r[key] for r in rows]
    if any(v is None for v in values):
        return [min((v for v in values if v is not None), default=None), None]
    return [min(values), max(values)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seeds', type=int, default=6, help='noise seeds per case')
    args = parser.parse_args()
    cases: dict[str, Any] = {}
    for vehicle in VEHICLES:
        for z0, z1 in CHANGES:
            case: dict[str, Any] = {}
            for label, learn in (('without_learning', False), ('learning', True)):
                rows = [fly(vehicle, z0, z1, seed, learn) for seed in range(args.seeds)]
                case[label] = {
                    'flights': rows,
                    'settling_time_s_range': _range(rows, 'settling_time_s'),
                    'hold_error_m_max': max(r['hold_error_m'] for r in rows),
                    'peak_pitch_deg_max': max(r['peak_pitch_deg'] for r in rows)}
            name = f'{vehicle} {z0:g}->{z1:g}m'
            cases[name] = case
            print(name, json.dumps({k: {kk: vv for kk, vv in v.items() if kk != 'flights'}
                                    for k, v in case.items()}), flush=True)
    worst: dict[str, Any] = {}
    for label in ('without_learning', 'learning'):
        flights = [r for case in cases.values() for r in case[label]['flights']]
        settled = [r['settling_time_s'] for r in flights if r['settling_time_s'] is not None]
        worst[label] = {'settling_s': max(settled, default=None),
                        'unsettled': len(flights) - len(settled),
                        'hold_error_m': max(r['hold_error_m'] for r in flights),
                        'peak_pitch_deg': max(r['peak_pitch_deg'] for r in flights)}
    figures = {'noise': 'SensorNoise.realistic', 'seeds': args.seeds, 'speed_m_s': U0,
               'duration_s': DURATION, 'worst': worst, 'cases': cases,
               'machine': {'cpus': os.cpu_count()}}
    path = save_figures('noisy_learning', figures)
    print(path)


if __name__ == '__main__':
    main()
