"""Robustness of the depth pilot on plants that are not its design model (A18M).

The pilot is designed on ``config/a18m.yaml`` (default weights, theta_max 25 deg, 10 Hz) and
flown with the offline closed loop (:func:`auv_depth_lqr.robustness.fly`: the 6-DOF simulator
at its RK4 step, lockstep) on:

* **per-effect table**: each effect or model error alone (:func:`catalogue`: current 0.3 m/s
  from four directions, pilot told its water speed and not told; buoyancy +-1 % of the
  weight; plane delay 0.3 s; plane lag 0.5 s; plane bias +-1 deg; pitch-sensor bias
  +-0.5 deg; depth-sensor noise 0.05 m; CZuw, CMuw, CZuq, CMuq, CZbar, CMbar, Iy, Mqdot,
  Zwdot each x0.7 and x1.3), on a 30 m climb (40 -> 10 m) and a 30 m dive (10 -> 40 m) at
  2 m/s;
* **identified model**: the true vehicle is the A18M with CZuw x1.2, CMuw x1.25, CZuq x1.2,
  CMuq x0.75 and CMbar x0.85; its surge and pitch missions are simulated, written as bags
  with navigation-grade sensor noise (:meth:`SensorNoise.realistic`) and no force topic, and
  identified with ``auv ident --vehicle config/a18m.yaml --fit-planes`` (forces from the
  motion; the plane's CZbar and CMbar fitted too); the pilot designed on the identified file
  flies the true vehicle;
* **Monte Carlo**: ``--plants`` plants (default 1000), every effect and error at once,
  drawn by :func:`draw_plant` with :class:`Distribution` defaults (each of the nine
  parameters x U(0.7, 1.3); current 0.3 m/s from U(0, 360) deg, pilot told its water speed
  with probability 1/2; buoyancy U(-1, +1) % of the weight; plane delay U(0, 0.3) s; plane
  lag U(0.1, 0.5) s; plane bias U(-1, 1) deg; pitch-sensor bias U(-0.5, 0.5) deg; depth
  noise sigma U(0, 0.05) m), each flying a depth change drawn from -30, -10, +10, +30 m
  (equal odds) from a start depth U(40, 60) m (climbs) or U(10, 30) m (dives) at 2 m/s;
  with ``--own-bound N`` the first N flights are also judged against the time-optimal bound
  of their plant's own model (:func:`plant_bound`);
* **Monte Carlo on the identification's intervals** (``--family ident``): the same draws,
  but each coefficient ``auv ident`` identifies (CZuw, CMuw, CZuq, CMuq, CZbar, CMbar;
  identified as in the identified-model case, in the same run) varies within the larger of
  its 95 % interval and the error the identification made on that true vehicle, relative to
  its value; the coefficients it does not identify (Iy, Mqdot, Zwdot) keep U(0.7, 1.3).
  The identified values are apparent ones (``Distribution.apparent``): the identification
  reconstructs forces with the file's added masses, so a plant whose heave added mass
  differs has the Munk moment of that difference on its ``CMuw`` (what the identification
  of that plant would have measured is the drawn value). Written under
  ``monte_carlo_ident`` with the spreads it used;
* **attribution** (``--attribute N``): the first N failed plants of the Monte Carlo flown
  again without one group of errors at a time (each coefficient, all coefficients, the plane
  and inertia coefficients, plane delay and lag, buoyancy, current, biases): the share
  of them that then passes says which errors make the failures.

Criteria (:class:`Criteria`): settled within 2x the time-optimal bound of the design model
(:func:`auv_depth_lqr.bound.settling_bound`, same change and speed), ``|theta| < 35 deg``
(no tumble), pitch limit exceeded by at most 2 deg, ``|mean depth error|`` over the last 10 s
below 0.1 m. Each flight also records the pilot's plane-authority level at its end
(:mod:`auv_depth_lqr.authority`); each share group counts the flights it called ``low``, among
all and among the failed. With ``--learn`` the per-effect table's and the Monte Carlo's
pilot learns its plant (``PilotSettings(learn=True)``), written under
``per_effect_learning`` and ``monte_carlo_learning`` (``monte_carlo_ident_learning``); the
identified-model case is flown without. With ``--told`` every Monte-Carlo pilot is told its
surge speed through the water (``PilotSettings.water_speed``; as drawn, about half are not and
schedule on the speed over ground, which a current offsets), the same plants and changes
otherwise, written under the family's key with ``_told``. Runs in a process pool
(``--workers``, default 2). Run:
``. .venv/bin/auv-env && python bench/bench_robustness.py --plants 1000``
(writes ``bench/results/robustness.json``).
"""
from __future__ import annotations

import argparse
import dataclasses
import functools
import json
import math
import multiprocessing
import pathlib
import platform
import tempfile
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
from timing import save_figures

from auv_depth_lqr.bound import settling_bound
from auv_depth_lqr.pilot import PilotSettings
from auv_depth_lqr.robustness import (
    MODEL_PARAMETERS,
    Distribution,
    Manoeuvre,
    Plant,
    catalogue,
    draw_plant,
    fly,
)
from auv_sim.params import VehicleParams, load_vehicle

ROOT = pathlib.Path(__file__).resolve().parents[1]
VEHICLE = ROOT / 'config' / 'a18m.yaml'
THETA_MAX = math.radians(25.0)
U0 = 2.0
TABLE_MANOEUVRES = {'climb_40_10': Manoeuvre(40.0, 10.0, U0),
                    'dive_10_40': Manoeuvre(10.0, 40.0, U0)}
MC_CHANGES = (-30.0, -10.0, 10.0, 30.0)
#: The true vehicle of the identified-model case: factors on the A18M file.
IDENT_TRUTH = {'CZuw': 1.2, 'CMuw': 1.25, 'CZuq': 1.2, 'CMuq': 0.75, 'CMbar': 0.85}
IDENT_MISSIONS = ('surge', 'pitch')
#: Results key of each Monte-Carlo family.
MC_KEYS = {'uniform': 'monte_carlo', 'ident': 'monte_carlo_ident'}
IDENT_SEEDS = (300, 301)


def time_optimal_bound(change: tuple[float, float]) -> float:
    """Time-optimal settling bound [s] of ``(dz [m], u0 [m/s])`` on the design model (the
    vertical-plane model does not depend on the start depth)."""
    dz, u0 = change
    params = load_vehicle(VEHICLE)
    z0 = 40.0 if dz < 0 else 10.0
    return settling_bound(params, z0, z0 + dz, u0, THETA_MAX).settling_time


def plant_bound(job: tuple[VehicleParams, Plant, Manoeuvre]) -> float | None:
    """Time-optimal settling bound [s] of ``manoeuvre`` on the plant's own vertical-plane
    model: its coefficient factors and the environment's parameter changes (buoyancy offset,
    plane lag) applied; the plane delay and bias, the current and the sensor errors cannot be
    given to the bound, so it is optimistic for the plant. None when no BAR sequence settles
    the plant within the bound's horizon."""
    from auv_depth_lqr.errors import DesignError

    design, plant, m = job
    vehicle = plant.environment().apply_to(plant.vehicle(design))
    try:
        return settling_bound(vehicle, m.z0, m.z1, m.u0, THETA_MAX).settling_time
    except DesignError:
        return None


def own_bound_figures(rows: list[dict[str, Any]], bounds: list[float | None]
                      ) -> dict[str, Any]:
    """The flights ``rows`` judged against their plants' own bounds ``bounds`` beside the
    design model's: shares settled within 2x each (all other criteria as flown)."""
    n = len(rows)
    within_design = within_own = no_bound = 0
    ratios = []
    for row, own in zip(rows, bounds):
        t = row['settling_time_s']
        within_design += bool(row['checks'].get('settled'))
        if own is None:
            no_bound += 1
            continue
        ratios.append(own / row['bound_s'])
        within_own += t is not None and t <= 2.0 * own
    return {'plants': n, 'settled_within_2x_design_bound': round(within_design / n, 4),
            'settled_within_2x_own_bound': round(within_own / n, 4),
            'no_own_bound': no_bound,
            'own_over_design_bound': {'min': round(min(ratios), 3),
                                      'median': round(float(np.median(ratios)), 3),
                                      'max': round(max(ratios), 3)} if ratios else None}


def ident_truth(design: VehicleParams) -> VehicleParams:
    """The true vehicle of the identified-model case: ``design`` with :data:`IDENT_TRUTH`."""
    return design.replace(**{k: design.values[k] * f for k, f in IDENT_TRUTH.items()})


def identify_truth(truth: VehicleParams, base_path: pathlib.Path, workdir: pathlib.Path,
                   seeds: Sequence[int] = IDENT_SEEDS, fit_planes: bool = True
                   ) -> tuple[VehicleParams, dict[str, Any]]:
    """Identify ``truth`` with ``auv ident`` (``--fit-planes`` unless ``fit_planes`` is
    False) from its simulated surge and pitch missions logged with realistic sensor noise (no
    force topic); returns the identified vehicle and the identification's coefficients
    (value, ci95)."""
    from auv_ident import cli
    from auv_logs.simlog import SensorNoise, write_record
    from auv_sim.missions import load_mission, run_mission

    bags = []
    for name, seed in zip(IDENT_MISSIONS, seeds):
        rec = run_mission(truth, load_mission(name))
        write_record(workdir / name, rec, forces=False, noise=SensorNoise.realistic(),
                     seed=seed)
        bags.append(str(workdir / name))
    out = workdir / 'ident'
    parser = argparse.ArgumentParser()
    cli.add_arguments(parser)
    args = parser.parse_args([*bags, '--vehicle', str(base_path), '--out', str(out),
                              '--equations', 'surge', 'heave', 'pitch', '--no-nelder-mead',
                              *(['--fit-planes'] if fit_planes else [])])
    if cli.run(args) != 0:
        raise RuntimeError('auv ident failed')
    report = json.loads((out / 'report.json').read_text())
    return load_vehicle(out / 'vehicle.yaml'), report['coefficients']


def mc_key(family: str, learn: bool, told: bool = False) -> str:
    """Results key of a Monte-Carlo family, flown with learning (``learn``) or without, with
    every pilot told its water speed (``told``) or as drawn."""
    return MC_KEYS[family] + ('_learning' if learn else '') + ('_told' if told else '')


ALL_MC_KEYS = tuple(mc_key(f, learn, told) for f in MC_KEYS for learn in (False, True)
                    for told in (False, True))


def table_keys(learn: bool) -> tuple[str, str, str]:
    """Results keys of the per-effect table, its all-pass flag and its wall time, flown with
    learning (``learn``: ``per_effect_learning...``) or without (``per_effect...``)."""
    name = 'per_effect_learning' if learn else 'per_effect'
    return name, f'{name}_all_pass', f'{name}_wall_s'


def _fly(job: tuple[VehicleParams, Plant, Manoeuvre, float], learn: bool = False
         ) -> dict[str, Any]:
    design, plant, manoeuvre, bound = job
    t0 = time.perf_counter()
    outcome, _ = fly(design, plant, manoeuvre, bound, PilotSettings(learn=learn))
    figures = outcome.as_dict()
    figures['wall_s'] = round(time.perf_counter() - t0, 2)
    return figures


def _draw_manoeuvre(rng: np.random.Generator) -> Manoeuvre:
    dz = float(rng.choice(MC_CHANGES))
    z0 = float(rng.uniform(40.0, 60.0) if dz < 0 else rng.uniform(10.0, 30.0))
    return Manoeuvre(round(z0, 2), round(z0 + dz, 2), U0)


def _shares(rows: list[dict[str, Any]]) -> dict[str, Any]:
    n = len(rows)
    flown = [r for r in rows if not r['error']]

    def share(key: str) -> float:
        return round(sum(1 for r in flown if r['checks'][key]) / n, 4) if n else math.nan

    ratios = [r['settling_over_bound'] for r in flown if r['settling_over_bound'] is not None]
    return {
        'plants': n,
        'not_flown': n - len(flown),
        'share_settled_within_2x_bound': share('settled'),
        'share_tumbled': round(1.0 - share('no_tumble'), 4),
        'share_pitch_limit_exceeded_by_more_than_2deg': round(1.0 - share('pitch_limit'), 4),
        'share_all_criteria': round(sum(1 for r in flown if r['pass']) / n, 4),
        'worst_steady_error_m': max((r['steady_error_m'] for r in flown), default=None),
        'worst_settling_over_bound': max(ratios) if ratios else None,
        'median_settling_over_bound': round(float(np.median(ratios)), 3) if ratios else None,
        'worst_pitch_excess_deg': max((r['pitch_excess_deg'] for r in flown), default=None),
        'worst_peak_pitch_deg': max((r['peak_pitch_deg'] for r in flown), default=None),
        'share_recovery_used': round(sum(1 for r in flown if r['recovery_time_s'] > 0) / n, 4),
        'plane_authority_low': sum(1 for r in flown if r['authority'] == 'low'),
        'plane_authority_low_among_failed': sum(1 for r in flown
                                                if r['authority'] == 'low' and not r['pass']),
        'failed': sum(1 for r in flown if not r['pass']),
    }


def _features(design: VehicleParams, plant: Plant) -> dict[str, float]:
    """The drawn errors of a Monte-Carlo plant as numbers: parameter factors [-], current
    along the heading (north; the vehicle heads north) and across [m/s], buoyancy offset
    [% of the weight], plane delay and lag [s], plane and pitch-sensor bias [deg], depth
    noise [m]."""
    e = plant.effects
    return {**plant.factors,
            'current_following_m_s': e['current']['north'],
            'current_cross_m_s': e['current']['east'],
            'buoyancy_pct_of_weight': 100.0 * e['buoyancy_offset']['dB'] / design.W,
            'plane_delay_s': e['actuator_delay']['bar'],
            'plane_lag_s': e['actuator_lag']['bar_tau'],
            'bar_bias_deg': math.degrees(e['bar_bias']['bias']),
            'pitch_bias_deg': math.degrees(e['pitch_sensor_bias']['bias']),
            'depth_noise_m': plant.depth_noise}


def _drivers(features: list[dict[str, float]], failed: list[bool]) -> dict[str, Any]:
    """For each drawn error: its tertile edges over the plants and the share of the plants
    in each tertile (low, middle, high) that failed a criterion."""
    out: dict[str, Any] = {}
    fails = np.array(failed, dtype=float)
    for key in features[0]:
        v = np.array([f[key] for f in features])
        lo, hi = np.quantile(v, [1.0 / 3.0, 2.0 / 3.0])
        groups = (v <= lo, (v > lo) & (v <= hi), v > hi)
        out[key] = {'tertile_edges': [round(float(lo), 4), round(float(hi), 4)],
                    'failed_share': [round(float(fails[g].mean()), 3) for g in groups]}
    return out


def ident_spreads(coefficients: dict[str, Any], truth: VehicleParams) -> dict[str, float]:
    """Relative spreads of the coefficients an identification gave (``{name: {'value',
    'ci95'}}``) of the vehicle ``truth``: for each of :data:`MODEL_PARAMETERS` it identified,
    the larger of the 95 % interval's half-width and the error against the truth, relative
    to the identified value (see the module docstring)."""
    spreads = {}
    for name, c in coefficients.items():
        if name not in MODEL_PARAMETERS:
            continue
        value = float(c['value'])
        half = 0.5 * abs(float(c['ci95'][1]) - float(c['ci95'][0]))
        error = abs(value - float(truth.values[name]))
        spreads[name] = round(max(half, error) / abs(value), 4)
    return spreads


#: The errors the attribution removes, one group at a time, from failed Monte-Carlo plants.
ATTRIBUTION: dict[str, tuple[str, ...]] = {
    **{name: (name,) for name in MODEL_PARAMETERS},
    'all coefficients': MODEL_PARAMETERS,
    'CZbar, CMbar, Iy, Mqdot, Zwdot': ('CZbar', 'CMbar', 'Iy', 'Mqdot', 'Zwdot'),
    'plane delay and lag': ('actuator_delay', 'actuator_lag'),
    'buoyancy offset': ('buoyancy_offset',),
    'current': ('current',),
    'plane and pitch-sensor biases': ('bar_bias', 'pitch_sensor_bias'),
}


def without(plant: Plant, group: str) -> Plant:
    """``plant`` without the errors of the attribution group ``group``
    (:data:`ATTRIBUTION`: coefficient factors set to 1, effects removed)."""
    names = ATTRIBUTION[group]
    return dataclasses.replace(
        plant, factors={k: v for k, v in plant.factors.items() if k not in names},
        effects={k: v for k, v in plant.effects.items() if k not in names})


def run(plants: int = 1000, workers: int = 2, seed: int = 2026,
        table: bool = True, mc: bool = True, own_bound: int = 0,
        family: str = 'uniform', attribute: int = 0, learn: bool = False,
        told: bool = False) -> dict[str, Any]:
    """Per-effect table, identified-model case (``table``) and Monte Carlo (``mc``; its
    first ``own_bound`` flights also judged against their plants' own bounds; ``family``
    ``uniform`` or ``ident``, see the module docstring; its first ``attribute`` failed
    plants flown again without each group of :data:`ATTRIBUTION`; with ``learn``, the
    Monte Carlo's pilot learns its plant, ``PilotSettings(learn=True)``; with ``told``,
    every Monte-Carlo pilot is told its water speed); returns the figures."""
    design = load_vehicle(VEHICLE)
    truth = ident_truth(design)
    if table or (mc and family == 'ident'):  # one identification for both
        t0 = time.perf_counter()
        with tempfile.TemporaryDirectory() as tmp:
            identified, coefficients = identify_truth(truth, VEHICLE, pathlib.Path(tmp))
        ident_wall = time.perf_counter() - t0
    dist = (Distribution(factor_spreads=ident_spreads(coefficients, truth), apparent=True)
            if mc and family == 'ident' else Distribution())
    changes = sorted({(m.z1 - m.z0, m.u0) for m in TABLE_MANOEUVRES.values()}
                     | {(dz, U0) for dz in MC_CHANGES})
    wall0 = time.perf_counter()
    ctx = multiprocessing.get_context('fork')
    with ctx.Pool(workers) as pool:
        bounds = dict(zip(changes, pool.map(time_optimal_bound, changes)))
        bounds_wall = time.perf_counter() - wall0

        def bound_of(m: Manoeuvre) -> float:
            return bounds[(round(m.z1 - m.z0, 6), m.u0)]

        results: dict[str, Any] = {}
        if table:
            t0 = time.perf_counter()
            plants_table = catalogue(design)
            jobs = [(design, p, m, bound_of(m)) for p in plants_table.values()
                    for m in TABLE_MANOEUVRES.values()]
            rows = pool.map(functools.partial(_fly, learn=learn), jobs)
            per_effect: dict[str, dict[str, Any]] = {}
            for (_, plant, manoeuvre, _b), row in zip(jobs, rows):
                label = next(k for k, v in TABLE_MANOEUVRES.items() if v == manoeuvre)
                per_effect.setdefault(plant.name, {})[label] = row
            table_key, all_pass_key, wall_key = table_keys(learn)
            results[table_key] = per_effect
            results[all_pass_key] = all(r['pass'] for v in per_effect.values()
                                        for r in v.values())
            results[wall_key] = round(time.perf_counter() - t0, 1)

            t0 = time.perf_counter() - ident_wall  # the identification counts in its wall time
            plant = Plant('identified_model', base=truth)
            rows = pool.map(_fly, [(identified, plant, m, bound_of(m))
                                   for m in TABLE_MANOEUVRES.values()])
            results['identified_model'] = {
                'truth_factors': IDENT_TRUTH,
                'coefficients': {k: {'truth': truth.values[k], 'identified': v['value'],
                                     'ci95': v['ci95'],
                                     'error_pct': round(100 * (v['value'] / truth.values[k]
                                                               - 1), 2)}
                                 for k, v in coefficients.items()},
                'flights': dict(zip(TABLE_MANOEUVRES, rows)),
                'wall_s': round(time.perf_counter() - t0, 1),
            }

        t0 = time.perf_counter()
        rng = np.random.default_rng(seed)
        jobs = []
        drawn_told = []  # whether each pilot is told its water speed as drawn
        for i in range(plants if mc else 0):
            plant = draw_plant(design, rng, f'mc{i:04d}', dist)
            drawn_told.append(plant.water_speed_told)
            if told:
                plant = dataclasses.replace(plant, water_speed_told=True)
            manoeuvre = _draw_manoeuvre(rng)
            jobs.append((design, plant, manoeuvre, bound_of(manoeuvre)))
        rows = pool.map(functools.partial(_fly, learn=learn), jobs, chunksize=4)
        mc_wall = time.perf_counter() - t0
        t0 = time.perf_counter()
        own = pool.map(plant_bound, [(design, plant, m) for _, plant, m, _b in
                                     jobs[:own_bound]])
        own_wall = time.perf_counter() - t0
        t0 = time.perf_counter()
        failed_jobs = [job for job, row in zip(jobs, rows) if not row['pass']][:attribute]
        refly = [(name, (d, without(plant, name), m, b))
                 for name in ATTRIBUTION for (d, plant, m, b) in failed_jobs]
        reflown = pool.map(functools.partial(_fly, learn=learn), [job for _, job in refly],
                           chunksize=2)
        attribution_wall = time.perf_counter() - t0
    monte_carlo: dict[str, Any] | None = None
    if mc:
        for (_, plant, _m, _b), row in zip(jobs, rows):
            row['water_speed_told'] = plant.water_speed_told
        failures = [dict(row, factors={k: round(v, 3) for k, v in plant.factors.items()},
                         effects=plant.effects, depth_noise_m=round(plant.depth_noise, 4))
                    for (_, plant, _m, _b), row in zip(jobs, rows) if not row['pass']]
        monte_carlo = {
            'seed': seed,
            'family': family,
            'learning': learn,
            'water_speed': 'told to every pilot' if told else 'as drawn',
            'distribution': dataclasses.asdict(dist),
            'changes_m': list(MC_CHANGES),
            'all': _shares(rows),
            **{key: _shares(group) for key, group in (
                ('pilot_told_water_speed', [r for r in rows if r['water_speed_told']]),
                ('pilot_not_told_water_speed', [r for r in rows if not r['water_speed_told']]),
                ('drawn_not_told_water_speed',  # the plants whose pilots were told for --told
                 [r for r, d in zip(rows, drawn_told) if told and not d])) if group},
            'by_change': {f'{dz:+g} m': _shares([r for r in rows
                                                 if round(r['z1_m'] - r['z0_m'], 6) == dz])
                          for dz in MC_CHANGES},
            'failures': failures,
            'failed_share_by_tertile': _drivers([_features(design, plant)
                                                 for (_, plant, _m, _b) in jobs],
                                                [not row['pass'] for row in rows]),
            'wall_s': round(mc_wall, 1),
            'wall_per_plant_s': round(mc_wall / max(plants, 1), 3),
        }
        if own_bound:
            monte_carlo['own_bound'] = dict(own_bound_figures(rows[:own_bound], own),
                                            wall_s=round(own_wall, 1))
        if failed_jobs:
            passed = {name: 0 for name in ATTRIBUTION}
            for (name, _), row in zip(refly, reflown):
                passed[name] += bool(row['pass'])
            monte_carlo['attribution'] = {
                'failed_plants_reflown': len(failed_jobs),
                'share_passing_without': {k: round(v / len(failed_jobs), 3)
                                          for k, v in passed.items()},
                'wall_s': round(attribution_wall, 1)}
    return {
        'vehicle': VEHICLE.name, 'u0_m_s': U0, 'theta_max_deg': math.degrees(THETA_MAX),
        'criteria': {'settle_within_bound_x': 2.0, 'tumble_deg': 35.0,
                     'pitch_excess_max_deg': 2.0, 'steady_error_max_m': 0.1,
                     'steady_window_s': 10.0},
        'time_optimal_bounds_s': {f'{dz:+g} m at {u0:g} m/s': round(b, 2)
                                  for (dz, u0), b in bounds.items()},
        'bounds_wall_s': round(bounds_wall, 1),
        **results,
        **({mc_key(family, learn, told): monte_carlo} if monte_carlo is not None else {}),
        'workers': workers,
        'total_wall_s': round(time.perf_counter() - wall0, 1),
        'python': platform.python_version(), 'machine': platform.machine(),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--plants', type=int, default=1000, help='Monte-Carlo plants')
    parser.add_argument('--workers', type=int, default=2, help='processes')
    parser.add_argument('--seed', type=int, default=2026, help='Monte-Carlo seed')
    parser.add_argument('--no-table', action='store_true',
                        help='Monte Carlo only; the per-effect table and identified-model '
                             'figures already in the results file are kept')
    parser.add_argument('--own-bound', type=int, default=0, metavar='N',
                        help='judge the first N Monte-Carlo flights also against their '
                             'plants\' own time-optimal bounds (one optimisation each)')
    parser.add_argument('--family', choices=sorted(MC_KEYS), default='uniform',
                        help='Monte-Carlo coefficient family: uniform +-30 %% on every '
                             'coefficient, or ident: the identification\'s intervals and '
                             'errors where it identifies (see the module docstring)')
    parser.add_argument('--attribute', type=int, default=0, metavar='N',
                        help='fly the first N failed Monte-Carlo plants again without each '
                             'group of errors (coefficients one by one, plane delay and lag, '
                             'buoyancy, current, biases): the share that then passes')
    parser.add_argument('--learn', action='store_true',
                        help='the per-effect table and the Monte Carlo with the pilot '
                             'learning its plant (learn: true), written under '
                             '"per_effect_learning" and the family\'s key with "_learning" '
                             '(the identified-model case is flown without)')
    parser.add_argument('--told', action='store_true',
                        help='every Monte-Carlo pilot told its surge speed through the water '
                             '(as drawn, about half schedule on the speed over ground), written '
                             'under the family\'s key with "_told"')
    parser.add_argument('--no-mc', action='store_true',
                        help='per-effect table and identified model only; the Monte-Carlo '
                             'figures already in the results file are kept')
    args = parser.parse_args()
    if args.no_table and args.no_mc:
        parser.error('--no-table and --no-mc leave nothing to run')
    figures = run(args.plants, args.workers, args.seed, table=not args.no_table,
                  mc=not args.no_mc, own_bound=args.own_bound, family=args.family,
                  attribute=args.attribute, learn=args.learn, told=args.told)
    previous = pathlib.Path(__file__).resolve().parent / 'results' / 'robustness.json'
    kept = json.loads(previous.read_text()) if previous.exists() else {}
    keys = ((*table_keys(False), *table_keys(True), 'identified_model') if args.no_table
            else table_keys(not args.learn))
    keys += tuple(k for k in ALL_MC_KEYS
                  if args.no_mc or k != mc_key(args.family, args.learn, args.told))
    for key in keys:
        if key in kept:
            figures[key] = kept[key]
    save_figures('robustness', figures)
    summary = {k: v for k, v in figures.items()
               if k not in ('per_effect', 'per_effect_learning')}
    for key in ALL_MC_KEYS:
        if key in figures:
            summary[key] = {k: v for k, v in figures[key].items() if k != 'failures'}
    print(json.dumps(summary, indent=2))


if __name__ == '__main__':
    main()
