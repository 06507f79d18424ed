"""The depth pilot on plants that are not its model, from a cold start, thrust held.

Plants (:func:`auv_depth_lqr.closed_loop.foreign_plant`): from each vehicle file (REMUS 100,
A18M, NPS AUV II) a vehicle whose plane gives half the force and 60 % of the moment, which has
no moment in ``u w`` (no Munk moment), is neutrally buoyant and whose level trim at 1.5 m/s
needs 9 deg more plane than the file's. The pilot is built on the vehicle file; the plant
starts in its own level trim at 1.5 m/s with its thrust held at its trim value (no speed
loop) and the command is given at once (cold start: nothing learned yet).

Reported per plant and depth change (20 -> 10, 10 -> 30, 5 -> 40 m): settling to +-0.1 m over
the plant's own time-optimal bound (:func:`auv_depth_lqr.bound.settling_bound` on the plant's
parameters; goal <= 1.3; where it finds no plan, the bound is ``null`` and its
:class:`~auv_depth_lqr.errors.DesignError` text is kept as ``bound_error``), peak pitch over
the 25 deg limit (goal <= 1 deg), overshoot; side by side the same pilot with learning
(``PilotSettings(learn=True)``) and without (the default).
Then ``sequence``: ten alternating 20 <-> 10 m changes in one flight from the cold start,
the first against the tenth (the first as good as the tenth) and against the ninth (the
last change the same way as the first), with learning and (under ``without_learning``)
without. Then ``held_thrust``:
the vehicle files themselves (with and without learning) with the thrust held at the trim value
(no speed loop), with 1 % more buoyancy than weight and with 30 % less fin lift, peak pitch
over the limit (goal <= 1 deg). Every flight also gives the times at which the pilot began
to report a depth runaway (``runaway_reported_s``, :mod:`auv_depth_lqr.runaway`). Then
``noisy``: the plants' changes again with the pilot reading the realistic sensor noise
(``SensorNoise.realistic``: 2 cm, 0.1 deg, 1 cm/s, 0.1 deg/s; seeds 0 and 1), with learning
and without, settling over the bound.

Run: ``python bench/bench_foreign_plants.py`` writes ``bench/results/foreign_plants.json``
(3.5-5.5 min on a machine of 2 cores, longer when it is loaded); ``--quick`` flies the
REMUS 100 only.
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

from auv_depth_lqr.bound import settling_bound
from auv_depth_lqr.closed_loop import foreign_plant, model_error_plant, run_closed_loop
from auv_depth_lqr.errors import DesignError
from auv_depth_lqr.metrics import step_metrics
from auv_depth_lqr.pilot import DepthPilot, PilotSettings
from auv_logs.simlog import SensorNoise
from auv_sim.params import VehicleParams, load_vehicle

CONFIG = pathlib.Path(__file__).resolve().parents[1] / 'config'
THETA_MAX = math.radians(25.0)
U0 = 1.5                                                 # m/s
CHANGES = ((20.0, 10.0), (10.0, 30.0), (5.0, 40.0))     # m
VEHICLES = ('remus100', 'a18m', 'npsauv2')
RATIO_GOAL = 1.3
PITCH_MARGIN_DEG = 1.0
SEQUENCE = (20.0, 10.0)                                  # m, alternated
SEQUENCE_LEG = 90.0                                      # s per change
NOISE_SEEDS = (0, 1)


def _metrics(run: Any, z1: float, t0: float = 0.0, t1: float = math.inf) -> dict[str, float]:
    rec = run.record
    keep = (rec.t >= t0 - 1e-9) & (rec.t <= t1 + 1e-9)
    m = step_metrics(rec.t[keep], rec.x[keep, 2], rec.x[keep, 4], rec.x[keep, 10],
                     rec.cmd[keep, 0], z1, t_command=t0, u0=U0, theta_max=THETA_MAX)
    return {'settling_time_s': round(m.settling_time, 2) if math.isfinite(m.settling_time)
            else None,
            'peak_pitch_deg': round(math.degrees(m.peak_pitch), 2),
            'over_limit_deg': round(max(math.degrees(m.peak_pitch - THETA_MAX), 0.0), 2),
            'overshoot_m': round(m.overshoot, 3),
            'min_surge_mps': round(float(np.min(rec.x[keep, 6])), 3)}


def listen_for_runaway(pilot: DepthPilot) -> list[float]:
    """The times [s] at which the pilot's depth-runaway report began
    (``DepthPilot.runaway_monitor``), filled as the pilot flies."""
    began: list[float] = []
    command = pilot.command
    reported = [False]

    def command_and_listen(t: float) -> tuple[float, str]:
        out = command(t)
        now = pilot.runaway_monitor.state is not None
        if now and not reported[0]:
            began.append(round(t, 2))
        reported[0] = now
        return out

    pilot.command = command_and_listen  # type: ignore[method-assign]
    return began


def fly(design: VehicleParams, plant: VehicleParams, z0: float, z1: float, learn: bool,
        duration: float = 200.0, environment: Any = None, seed: int | None = None
        ) -> tuple[dict[str, Any], DepthPilot]:
    """One cold-start change on ``plant`` by the pilot of ``design``, thrust held; with the
    times a depth runaway was reported (``runaway_reported_s``). With ``seed``, the pilot
    reads the realistic sensor noise (``SensorNoise.realistic``) drawn from it."""
    pilot = DepthPilot.for_vehicle(design, PilotSettings(learn=learn))
    runaway = listen_for_runaway(pilot)
    noise = None if seed is None else SensorNoise.realistic().sigmas()
    run = run_closed_loop(plant, [(0.0, z1)], duration, z0=z0, u0=U0,
                          environment=environment, pilot=pilot, sensor_noise=noise,
                          seed=0 if seed is None else seed)
    return {**_metrics(run, z1), 'runaway_reported_s': runaway}, pilot


def plants(vehicles: tuple[str, ...]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for name in vehicles:
        design = load_vehicle(CONFIG / f'{name}.yaml')
        plant = foreign_plant(design, U0)
        rows: dict[str, Any] = {'plant': {'CZbar': plant.CZbar, 'CMbar': plant.CMbar,
                                          'CMuw': plant.CMuw, 'CM0': plant.CM0,
                                          'B_minus_W_N': plant.B - plant.m * plant.g}}
        for z0, z1 in CHANGES:
            t0 = time.perf_counter()
            bound: float | None = None
            try:
                bound = settling_bound(plant, z0, z1, U0, THETA_MAX).settling_time
            except DesignError as exc:  # no plan within the search's horizon: said, not hidden
                error = str(exc)
            t_bound = time.perf_counter() - t0
            case: dict[str, Any] = {'time_optimal_bound_s': bound,
                                    'bound_seconds': round(t_bound, 1)}
            if bound is None:
                case['bound_error'] = error
            for label, learn in (('learning', True), ('without_learning', False)):
                figures, pilot = fly(design, plant, z0, z1, learn)
                settle = figures['settling_time_s']
                figures['settling_over_bound'] = (round(settle / bound, 3)
                                                  if settle is not None and bound is not None
                                                  else None)
                if learn:
                    est = pilot.controller.learner
                    assert est is not None
                    figures['learned'] = dict(zip(
                        ('buoyancy', 'plane_force', 'hull_lift', 'moment', 'plane_moment',
                         'munk', 'pitch_damping'),
                        (round(v, 4) for v in est.estimate.values)))
                case[label] = figures
            rows[f'{z0:g}->{z1:g}m'] = case
            print(name, z0, z1, json.dumps(case), flush=True)
        out[name] = rows
    return out


def _sequence(design: VehicleParams, plant: VehicleParams, learn: bool) -> dict[str, Any]:
    """Ten alternating changes in one cold-start flight by the pilot learning or not: each
    change's settling time [s] and peak pitch [deg], the first over the tenth, and the
    first over the ninth (the last change the same way as the first)."""
    pilot = DepthPilot.for_vehicle(design, PilotSettings(learn=learn))
    commands = [(k * SEQUENCE_LEG, SEQUENCE[(k + 1) % 2]) for k in range(10)]
    run = run_closed_loop(plant, commands, 10 * SEQUENCE_LEG, z0=SEQUENCE[0], u0=U0,
                          pilot=pilot)
    legs = [_metrics(run, z, t, t + SEQUENCE_LEG) for t, z in commands]
    times = [leg['settling_time_s'] for leg in legs]

    def over(later: float | None) -> float | None:
        return round(times[0] / later, 3) if times[0] is not None and later is not None \
            else None

    return {'settling_time_s': times,
            'peak_pitch_deg': [leg['peak_pitch_deg'] for leg in legs],
            'first_over_tenth': over(times[9]), 'first_over_ninth': over(times[8])}


def sequence(vehicles: tuple[str, ...]) -> dict[str, Any]:
    """Ten alternating changes in one cold-start flight: the first against the tenth, with
    learning (the keys of :func:`_sequence`) and, under ``without_learning``, without."""
    out: dict[str, Any] = {}
    for name in vehicles:
        design = load_vehicle(CONFIG / f'{name}.yaml')
        plant = foreign_plant(design, U0)
        out[name] = {**_sequence(design, plant, True),
                     'without_learning': _sequence(design, plant, False)}
        print(name, 'sequence', json.dumps(out[name]), flush=True)
    return out


def noisy(vehicles: tuple[str, ...], rows: dict[str, Any]) -> dict[str, Any]:
    """The plants and changes of :func:`plants` read through the realistic sensor noise
    (seeds :data:`NOISE_SEEDS`), with learning and without: settling over the plant's
    bound (from ``rows``, the plants' figures), ``null`` where it never settles."""
    out: dict[str, Any] = {}
    for name in vehicles:
        design = load_vehicle(CONFIG / f'{name}.yaml')
        plant = foreign_plant(design, U0)
        for z0, z1 in CHANGES:
            key = f'{z0:g}->{z1:g}m'
            bound = rows[name][key]['time_optimal_bound_s']
            case: dict[str, Any] = {}
            for label, learn in (('learning', True), ('without_learning', False)):
                ratios = []
                for seed in NOISE_SEEDS:
                    figures, _ = fly(design, plant, z0, z1, learn, seed=seed)
                    settle = figures['settling_time_s']
                    ratios.append(None if settle is None or bound is None
                                  else round(settle / bound, 3))
                case[label] = ratios
            out[f'{name} {key}'] = case
            print(name, key, 'noisy', json.dumps(case), flush=True)
    return out


def held_thrust(vehicles: tuple[str, ...]) -> dict[str, Any]:
    """The vehicle files themselves, thrust held: peak pitch over the limit."""
    out: dict[str, Any] = {}
    for name in vehicles:
        design = load_vehicle(CONFIG / f'{name}.yaml')
        for error in (None, 'buoyancy+1%', 'fins*0.7'):
            real, environment = (design, None) if error is None else \
                model_error_plant(design, error)
            for z0, z1 in CHANGES:
                key = f'{name}{"" if error is None else " " + error} {z0:g}->{z1:g}m'
                out[key] = {}
                for label, learn in (('learning', True), ('without_learning', False)):
                    figures, pilot = fly(design, real, z0, z1, learn,
                                         environment=environment)
                    out[key][label] = figures
                    out[key][label]['limited'] = pilot.climb_limits().limited
                print(key, json.dumps(out[key]), flush=True)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--quick', action='store_true', help='the REMUS 100 only')
    args = parser.parse_args()
    vehicles = ('remus100',) if args.quick else VEHICLES
    t0 = time.perf_counter()
    load = os.getloadavg()[0]
    figures: dict[str, Any] = {'plants': plants(vehicles), 'sequence': sequence(vehicles),
                               'held_thrust': held_thrust(vehicles)}
    figures['noisy'] = noisy(vehicles, figures['plants'])
    ratios = [case[label]['settling_over_bound']
              for rows in figures['plants'].values()
              for key, case in rows.items() if key != 'plant'
              for label in ('learning',)]
    over = [case[label]['over_limit_deg'] for rows in figures['plants'].values()
            for key, case in rows.items() if key != 'plant'
            for label in ('learning', 'without_learning')]
    over += [case[label]['over_limit_deg'] for case in figures['held_thrust'].values()
             for label in ('learning', 'without_learning')]
    figures['worst_settling_over_bound'] = (max(r for r in ratios if r is not None)
                                            if all(r is not None for r in ratios) else None)
    learned = [case['without_learning']['settling_over_bound']
               for rows in figures['plants'].values()
               for key, case in rows.items() if key != 'plant']
    figures['worst_settling_over_bound_without_learning'] = (
        max(r for r in learned if r is not None) if all(r is not None for r in learned)
        else None)
    figures['worst_over_limit_deg'] = max(over)
    figures['all_pass'] = bool(figures['worst_settling_over_bound'] is not None
                               and figures['worst_settling_over_bound'] <= RATIO_GOAL
                               and figures['worst_over_limit_deg'] <= PITCH_MARGIN_DEG)
    figures['goals'] = {'settling_over_bound': RATIO_GOAL, 'over_limit_deg': PITCH_MARGIN_DEG}
    figures['machine'] = {'load_average_1min_at_start': round(load, 2),
                          'wall_time_s': round(time.perf_counter() - t0, 1),
                          'cpus': os.cpu_count()}
    if not args.quick:
        print(save_figures('foreign_plants', figures))
    else:
        print(json.dumps({k: figures[k] for k in ('worst_settling_over_bound',
                                                  'worst_over_limit_deg', 'all_pass')}))


if __name__ == '__main__':
    main()
