"""Calibration of the gap diagnosis's 95 % intervals: over many noise seeds, the share of
intervals that hold the true value, per effect.

Each effect is fitted directly (equation error, then free run, no search) on 5-minute
closed-loop logs flown by the synthetic pilot with the default sensor noise; one seed is one
log. Reported per effect and parameter: the number of seeds, the coverage of the equation-error
and the reported (free-run) intervals with its binomial 95 % range (Wilson), the median
width, and the mean and spread of the estimate's error (bias against spread tells a biased
estimate from an interval too narrow).

A parameter whose interval is its whole plausible range was left out of the fit (it changes
no residual of that log, or was pruned as insignificant) and covers by construction: the
share of seeds that identified it is reported, and its coverage among those seeds. The
summary gives the lowest and median coverage over the parameters identified in at least half
the seeds and names those whose coverage is significantly below 0.95.

Run: ``. .venv/bin/auv-env && python bench/bench_gap_coverage.py [--seeds N] [--effects ...]``
(updates bench/results/gap_coverage.json, keeping the effects not run; ``--seeds 0``
recomputes the summary only; about 1-4 s per seed and effect on an idle core).
"""
from __future__ import annotations

import argparse
import json
import math
import pathlib
import statistics
import time
from typing import Any

import numpy as np
from timing import save_figures

ROOT = pathlib.Path(__file__).resolve().parents[1]

#: effect -> the simulator's fields (the true values); the parameters checked are these
TRUTH: dict[str, dict[str, float]] = {
    'actuator_delay': {'bar': 0.25},
    'buoyancy_offset': {'dB': 30.0},
    'actuator_lag': {'bar_tau': 0.6},
    'current_shear': {'north': 0.003, 'east': -0.001},
    'current_drift': {'north': 2e-4, 'east': -1e-4},
    'added_mass': {'Zwdot': 1.3},
    'depth_sensor_scale': {'scale': 1.02},
    'depth_sensor_latency': {'latency': 0.5},
    'pitch_sensor_scale': {'scale': 1.05},
    'pitch_sensor_latency': {'latency': 0.2},
    'current': {'north': 0.3, 'east': 0.15, 'down': 0.02},
    'buoyancy_depth': {'k': -2e-5},
    'actuator_rate_limit': {'bar_rate': 0.05},
    'bar_bias': {'bias': 0.02},
    'crossflow_drag': {'Zww': -2000.0, 'Mqq': -10000.0, 'Yvv': 0.0, 'Nrr': 0.0},
    'cg_offset': {'dxg': 0.005, 'dzg': 0.002},
    'depth_sensor_bias': {'bias': 0.3},
    'pitch_sensor_bias': {'bias': 0.01745},
    'plane_effectiveness': {'gain': 0.8},
    'thrust_error': {'gain': 0.9},
    'coefficients': {'CZuw': 1.3, 'CMuw': 1.0, 'CZuq': 1.0, 'CMuq': 0.8, 'CZbar': 1.0,
                     'CMbar': 1.0, 'Ksh': 1.0, 'CZ0': 1.0, 'CM0': 1.0},
}


def wilson(hits: int, n: int) -> tuple[float, float]:
    """Wilson score 95 % interval of a binomial proportion."""
    if n == 0:
        return (0.0, 1.0)
    z = 1.959964
    p = hits / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return (centre - half, centre + half)


def run(effect: str, seeds: int, first_seed: int = 1000) -> dict[str, Any]:
    """Coverage figures of one effect over ``seeds`` seeds."""
    from auv_gap import synth
    from auv_gap.catalogue import Perturbation
    from auv_gap.fit import EquationFit, FreeRunFit
    from auv_gap.problem import CH_INDEX, EffectSet, Problem
    from auv_sim.params import load_vehicle

    vehicle = load_vehicle(ROOT / 'config' / 'a18m.yaml')
    short = synth.Scenario(duration=300.0, z0=60.0, u0=2.0,
                           depth=((0.0, 60.0), (60.0, 80.0), (200.0, 65.0)),
                           thrust=((0.0, 55.0), (150.0, 100.0)),
                           doublets=((30.0, 0.08, 3.0), (110.0, 0.1, 2.0), (170.0, 0.06, 5.0),
                                     (240.0, 0.1, 3.0)))
    truth = TRUTH[effect]
    es = EffectSet([effect], vehicle)
    names = [p.name for _, p in es.params]
    rec: dict[str, dict[str, list[float]]] = {
        k: {'ee_hit': [], 'fr_hit': [], 'width': [], 'error': [], 'identified': []}
        for k in truth}
    # a parameter whose interval is its whole plausible range was left out of the fit (it
    # changes no residual, or was pruned as insignificant): it covers by construction
    full = {p.name: p.hi - p.lo for _, p in es.params}
    t0 = time.perf_counter()
    for seed in range(first_seed, first_seed + seeds):
        log = synth.simulate(vehicle, {'effects': {effect: truth}}, short, seed=seed)
        pr = Problem(vehicle, log.gap_logs(), window=30.0)
        ee = EquationFit(pr).fit(es)
        pred, meas = pr.free_run([Perturbation.nominal(vehicle)], pr.select(None))
        rms = np.sqrt(np.nanmean((pred[0] - meas)[:, CH_INDEX] ** 2, axis=0))
        fr = FreeRunFit(pr, np.maximum(rms, pr.noise[list(CH_INDEX)])).fit(ee)
        for key, value in truth.items():
            i = names.index(key)
            rec[key]['ee_hit'].append(float(ee.lo95[i] <= value <= ee.hi95[i]))
            rec[key]['fr_hit'].append(float(fr.lo95[i] <= value <= fr.hi95[i]))
            rec[key]['width'].append(float(fr.hi95[i] - fr.lo95[i]))
            rec[key]['error'].append(float(fr.values[i] - value))
            rec[key]['identified'].append(
                float(fr.hi95[i] - fr.lo95[i] < 0.999 * full[key]))
    out: dict[str, Any] = {'seeds': seeds, 'first_seed': first_seed,
                           'seconds': time.perf_counter() - t0, 'parameters': {}}
    for key, r in rec.items():
        hits = int(sum(r['fr_hit']))
        ident = np.array(r['identified'], bool)
        ident_hits = int(np.sum(np.array(r['fr_hit'])[ident]))
        err = np.array(r['error'])
        half = np.array(r['width']) / 2.0
        out['parameters'][key] = {
            'true': truth[key],
            'coverage_free_run': hits / seeds,
            'coverage_free_run_wilson95': wilson(hits, seeds),
            'identified_share': float(ident.mean()),
            'coverage_when_identified': (ident_hits / int(ident.sum())
                                         if ident.any() else None),
            'coverage_when_identified_wilson95': wilson(ident_hits, int(ident.sum())),
            'coverage_equation_error': sum(r['ee_hit']) / seeds,
            'median_width': statistics.median(r['width']),
            'mean_error': float(err.mean()),
            'sd_error': float(err.std(ddof=1)) if seeds > 1 else 0.0,
            # the spread the intervals claim: half width / 1.96 (t quantiles aside)
            'median_claimed_sd': float(np.median(half) / 1.96),
        }
    return out


def summary(effects: dict[str, Any]) -> dict[str, Any]:
    """Figures over every effect and parameter run: the seed counts, the lowest and the
    median coverage of the parameters identified in at least half the seeds (coverage among
    the seeds that identified them), and the parameters whose coverage is significantly
    below 0.95 (the upper end of the Wilson range under 0.95)."""
    rows = [(f'{e}.{k}', r['seeds'], v) for e, r in effects.items()
            for k, v in r['parameters'].items()]
    ident = [(name, v['coverage_when_identified']) for name, _, v in rows
             if v['identified_share'] >= 0.5]
    low = [name for name, _, v in rows if v['coverage_when_identified_wilson95'][1] < 0.95]
    cov = sorted(c for _, c in ident)
    return {'effects': len(effects), 'parameters': len(rows),
            'parameters_identified': len(ident),
            'min_seeds': min(n for _, n, _ in rows), 'max_seeds': max(n for _, n, _ in rows),
            'lowest_coverage': cov[0] if cov else None,
            'lowest_parameter': min(ident, key=lambda x: x[1])[0] if ident else None,
            'median_coverage': statistics.median(cov) if cov else None,
            'significantly_low': low, 'significantly_low_count': len(low)}


if __name__ == '__main__':
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--seeds', type=int, default=100, help='seeds per effect')
    ap.add_argument('--effects', nargs='*', default=list(TRUTH), choices=list(TRUTH))
    args = ap.parse_args()
    saved = ROOT / 'bench' / 'results' / 'gap_coverage.json'
    for name in args.effects if args.seeds > 0 else ():
        result = run(name, args.seeds)
        print(name, json.dumps(result['parameters']), flush=True)
        # read again before writing: several runs may share the file (one effect each)
        figures: dict[str, Any] = json.loads(saved.read_text()) if saved.exists() else {}
        figures['benchmark'] = 'gap diagnosis interval coverage'
        figures.setdefault('effects', {})[name] = result
        figures['summary'] = summary(figures['effects'])
        save_figures('gap_coverage', figures)
    if args.seeds <= 0:   # --seeds 0: the summary of the saved runs only
        figures = json.loads(saved.read_text())
        figures['summary'] = summary(figures['effects'])
        save_figures('gap_coverage', figures)
        print(json.dumps(figures['summary'], indent=2))
