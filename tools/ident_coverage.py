#!/usr/bin/env python3
"""Monte Carlo coverage of the 95 % intervals of the motion-based identification.

The three missions (surge, pitch, yaw) are simulated once with the vehicle file; for each of
``--runs`` replications, white sensor noise (default: :meth:`SensorNoise.realistic`, depth
0.02 m, angles 0.1 deg, velocities 0.01 m/s, rates 0.1 deg/s) is added to the logged state
by :func:`auv_logs.simlog.measured_state`, as :func:`auv_logs.simlog.write_record` adds
it (``numpy.random.default_rng(seed)``, one draw per mission), the forces are reconstructed
from the noisy motion (:func:`auv_ident.motion.records_from_topics`, in-memory topic arrays
instead of bags) and the coefficients identified (:func:`auv_ident.identify.identify`).
Replication ``k`` uses the noise seeds ``first + 3 k + (0, 1, 2)`` for (surge, pitch, yaw).

Printed per coefficient: the coverage of the 95 % interval (fraction of runs whose interval
holds the file's value, with its binomial standard error), the mean and the rms of
``|error| / se`` (a calibrated method gives rms near 1; mean near 0.8), the ratio of the
mean standard error to the empirical spread of the estimates (near 1 when calibrated), and
the mean interval half-width relative to the true value [%].

Example::

    python tools/ident_coverage.py --runs 40 --errors hac
"""
from __future__ import annotations

import argparse
import json
import math
import pathlib
import sys
import time
from typing import Any

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
MISSIONS = ('surge', 'pitch', 'yaw')


def topic_arrays(rec: Any, noise: Any, seed: int) -> dict[str, np.ndarray]:
    """The topic arrays a bag of ``rec`` written by ``write_record(..., forces=False,
    noise=noise, seed=seed)`` reads back as (state with noise; command change points)."""
    from auv_ident.motion import COMMAND_TOPICS, STATE_FIELDS, STATE_TOPIC
    from auv_logs.simlog import applied_commands, measured_state

    meas = measured_state(rec, noise, seed)
    t = np.round(np.asarray(rec.t, float) * 1e9) / 1e9
    st = np.zeros(len(t), dtype=[('t', float)] + [(f, float) for f in STATE_FIELDS])
    st['t'] = t
    for j, f in enumerate(STATE_FIELDS):
        st[f] = meas[:, j]
    arrays = {STATE_TOPIC: st}
    for ch, (times, values) in applied_commands(rec).items():
        arr = np.zeros(len(times), dtype=[('t', float), ('value', float)])
        arr['t'] = np.round(np.asarray(times, float) * 1e9) / 1e9
        arr['value'] = values
        arrays[COMMAND_TOPICS[ch]] = arr
    return arrays


def identify_replication(base: Any, recs: dict[str, Any], noise: Any, seeds: tuple[int, ...],
                         window_s: float = 1.0, errors: str = 'hac') -> Any:
    """Identification from the motion of the missions' records ``recs`` (name -> Record)
    with sensor ``noise`` drawn with ``seeds`` (one per mission, in :data:`MISSIONS`
    order)."""
    from auv_ident.identify import identify
    from auv_ident.motion import records_from_topics

    records = []
    for m, seed in zip(MISSIONS, seeds):
        arrays = topic_arrays(recs[m], noise, seed)
        records += records_from_topics(arrays, base, 'motion', name=m, window_s=window_s)
    return identify(records, base, errors=errors)


def run(runs: int, first: int, errors: str, vehicle: pathlib.Path, scale: float,
        window_s: float, verbose: bool) -> dict[str, dict[str, Any]]:
    """Coverage statistics per coefficient over ``runs`` replications (see module doc)."""
    from auv_logs.simlog import SensorNoise
    from auv_sim.missions import load_mission, run_mission
    from auv_sim.params import load_vehicle

    base = load_vehicle(vehicle)
    recs = {m: run_mission(base, load_mission(m)) for m in MISSIONS}
    real = SensorNoise.realistic()
    noise = SensorNoise(real.position * scale, real.angle * scale, real.velocity * scale,
                        real.rate * scale)
    rows: dict[str, list[tuple[float, float, float, float]]] = {}
    methods: dict[str, list[tuple[str, float]]] = {}
    t0 = time.perf_counter()
    for k in range(runs):
        seeds = tuple(first + 3 * k + i for i in range(len(MISSIONS)))
        result = identify_replication(base, recs, noise, seeds, window_s, errors)
        for name, c in result.coefficients.items():
            rows.setdefault(name, []).append((c.value, c.std_error, *c.ci95))
        for eq, fit in result.fits.items():
            methods.setdefault(eq, []).append((fit.covariance.split(' (')[0].split(',')[0],
                                               fit.noise_ratio))
        if verbose:
            print(f'run {k + 1}/{runs} ({time.perf_counter() - t0:.0f} s)', file=sys.stderr)
    out: dict[str, dict[str, Any]] = {}
    for eq, used in methods.items():
        kinds = sorted({k for k, _ in used})
        ratios = np.array([r for _, r in used], float)
        out[f'equation {eq}'] = {
            'covariance': {k: sum(1 for u, _ in used if u == k) for k in kinds},
            'noise_ratio_mean': float(np.nanmean(ratios)) if np.any(np.isfinite(ratios))
            else math.nan}
    for name, vals in rows.items():
        a = np.array(vals)
        true = float(base.values[name])
        value, se, lo, hi = a.T
        z = np.abs(value - true) / se
        covered = (lo <= true) & (true <= hi)
        cov = float(np.mean(covered))
        out[name] = {
            'coverage': cov, 'coverage_se': math.sqrt(max(cov * (1 - cov), 1e-12) / len(a)),
            'misses': int(np.count_nonzero(~covered)),
            'mean_abs_z': float(np.mean(z)), 'rms_z': float(np.sqrt(np.mean(z ** 2))),
            'se_over_spread': float(np.mean(se) / np.std(value, ddof=1)) if len(a) > 1
            else math.nan,
            'bias_over_se': float((np.mean(value) - true) / np.mean(se)),
            'half_width_pct': float(np.mean((hi - lo) / 2) / abs(true) * 100),
            'max_rel_error_pct': float(np.max(np.abs(value - true)) / abs(true) * 100),
        }
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--runs', type=int, default=40, help='replications (default 40)')
    parser.add_argument('--first', type=int, default=1000,
                        help='first noise seed (default 1000; the round-trip test uses 100-102)')
    parser.add_argument('--errors', default='hac', help='standard-error method (default hac)')
    parser.add_argument('--vehicle', type=pathlib.Path, default=ROOT / 'config' / 'a18m.yaml')
    parser.add_argument('--noise-scale', type=float, default=1.0,
                        help='multiplier on the realistic sensor noise (default 1)')
    parser.add_argument('--window', type=float, default=1.0,
                        help='derivative window [s] (default 1)')
    parser.add_argument('--json', type=pathlib.Path, help='also write the table as JSON here')
    parser.add_argument('-v', '--verbose', action='store_true', help='progress on stderr')
    args = parser.parse_args(argv)
    t0 = time.perf_counter()
    res = run(args.runs, args.first, args.errors, args.vehicle, args.noise_scale, args.window,
              args.verbose)
    print(f'{args.runs} runs, errors={args.errors}, noise x{args.noise_scale:g}, '
          f'window {args.window:g} s, {time.perf_counter() - t0:.0f} s')
    print(f'{"coef":6s} {"coverage":>14s} {"miss":>5s} {"mean|z|":>8s} {"rms z":>7s} '
          f'{"se/sd":>7s} {"bias/se":>8s} {"+-95% [%]":>10s} {"max err [%]":>11s}')
    for name, r in res.items():
        if name.startswith('equation '):
            continue
        print(f'{name:6s} {100 * r["coverage"]:7.1f} +-{100 * r["coverage_se"]:4.1f} % '
              f'{r["misses"]:5d} {r["mean_abs_z"]:8.2f} {r["rms_z"]:7.2f} '
              f'{r["se_over_spread"]:7.2f} {r["bias_over_se"]:+8.2f} '
              f'{r["half_width_pct"]:10.2f} {r["max_rel_error_pct"]:11.2f}')
    for name, r in res.items():
        if name.startswith('equation '):
            print(f'{name}: covariance {r["covariance"]}, observed / predicted residual '
                  f'variance {r["noise_ratio_mean"]:.3f}')
    if args.json:
        args.json.write_text(json.dumps(res, indent=2))
    return 0


if __name__ == '__main__':
    sys.exit(main())
