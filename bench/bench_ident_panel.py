"""Benchmark: identification on plants that are not the base file's structure.

Each case flies a plant in closed loop with the project's depth pilot and BAR doublets
(:func:`auv_gap.synth.simulate`, realistic sensor noise), writes the flight in one of
the log forms a user brings, and runs ``auv ident`` on it against a base file that is wrong in
a known way. The plants (``PLANTS``):

* ``xflow``: the vehicle file with the quadratic cross-flow terms of strip theory over its
  hull (:func:`auv_sim.hull.crossflow_coefficients`); the model's form, so every coefficient
  has a true value. Bases: its cross-flow terms 0.1x or 20x the plant's, and its linear heave
  and pitch coefficients 20-30 % off;
* ``strip``: the vehicle file without quadratic terms, its hull's cross-flow drag integrated
  strip by strip with the coupled cross-flow (the ``hull_crossflow`` effect of
  :mod:`auv_sim.environment`): not the model's form, no true values; base: the vehicle file
  (the REMUS 100 with Prestero's quadratic terms, the A18M without);
* ``plane``: the ``xflow`` plant with a dive plane 40 % weaker than its file (``--fit-planes``).

Log forms: ``bag50`` the contract bag at 50 Hz without the force topic, ``forces50``
with it (a simulator's bag: the true state, no sensor noise), ``ros10`` a third-party ROS 2
bag at 10 Hz (Odometry, Imu, FluidPressure; read through
``config/maps/ros2_odometry_imu_pressure.yaml``), ``text2`` a
vendor text log at 2 Hz with the depth in 0.1 m steps and the speed of a 1 Hz DVL repeated on
every row (``config/maps/text_2hz_deg_cm.yaml``: q and w differenced, v assumed 0). Log
lengths of 2, 15 and 30 minutes.

Scored on an independent flight of the same plant (another seed, doublets shifted; 10
minutes, 50 Hz, every state measured): the free-run depth rms of the written model and of the
base (:mod:`auv_ident.freerun` windows, from the logged state; a run that writes no vehicle
file leaves the base as the answer). Figures:

* ``wrong_sign_written``: coefficients written outside the sign physics gives them
  (:mod:`auv_ident.identify.physics`), goal 0;
* ``worse_than_base``: runs whose written model predicts the independent flight's depth worse
  than the base, by the validation's rule (the windows' mean log rms ratio above 1 % and two
  of its standard errors, and the pooled rms 5 mm apart), goal 0; and
  ``worse_than_base_any_amount``: worse by any amount, however small;
* ``coverage``: true values inside the reported 95 % intervals, over the coefficients of the
  identified equations of the plants that have true values, goal 0.9;
* ``median_improvement``: median of ``1 - rms_written / rms_base`` over the runs.

A few cases also run the former method (``--unbounded --no-priors --no-validation
--output-error never --structure file``) for comparison (``former``).

Run: ``. .venv/bin/auv-env && python bench/bench_ident_panel.py [--cases NAME ...]``
(writes ``bench/results/ident_panel.json``; about an hour on 2 shared cores).
"""
from __future__ import annotations

import argparse
import contextlib
import dataclasses
import io
import json
import math
import os
import pathlib
import tempfile
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from timing import save_figures

ROOT = pathlib.Path(__file__).resolve().parents[1]
TEXT_MAP = ROOT / 'config' / 'maps' / 'text_2hz_deg_cm.yaml'
ROS_MAP = ROOT / 'config' / 'maps' / 'ros2_odometry_imu_pressure.yaml'
SAMPLE = 0.02
#: Noise seed of the first case (fixed before any run); the validation flight adds 1000.
SEED = 500
#: Linear heave and pitch coefficients of the ``xflow`` bases, as factors of the plant's.
BASE_LINEAR = {'CZuw': 1.25, 'CZuq': 1.3, 'CMuw': 0.8, 'CMuq': 0.7}
QUADRATIC = ('Yvv', 'Yrr', 'Zww', 'Zqq', 'Mww', 'Mqq', 'Nvv', 'Nrr')

#: name -> (vehicle, plant, base, form, minutes, extra options, compare with the former)
CASES: dict[str, tuple[str, str, str, str, float, tuple[str, ...], bool]] = {
    'remus_x0.1_bag50': ('remus100', 'xflow', 'x0.1', 'bag50', 15, (), True),
    'remus_x20_bag50': ('remus100', 'xflow', 'x20', 'bag50', 15, (), True),
    'remus_x20_forces50': ('remus100', 'xflow', 'x20', 'forces50', 15, (), False),
    'remus_x20_ros10': ('remus100', 'xflow', 'x20', 'ros10', 15, (), False),
    'remus_x20_text2': ('remus100', 'xflow', 'x20', 'text2', 15, (), True),
    'remus_x0.1_bag50_2min': ('remus100', 'xflow', 'x0.1', 'bag50', 2, (), False),
    'remus_x20_text2_2min': ('remus100', 'xflow', 'x20', 'text2', 2, (), False),
    'remus_x20_bag50_30min': ('remus100', 'xflow', 'x20', 'bag50', 30, (), False),
    'remus_strip_bag50': ('remus100', 'strip', 'file', 'bag50', 15, (), True),
    'remus_strip_text2': ('remus100', 'strip', 'file', 'text2', 15, (), False),
    'remus_plane_bag50': ('remus100', 'plane', 'plant_file', 'bag50', 15, ('--fit-planes',),
                          False),
    'a18m_x0.1_bag50': ('a18m', 'xflow', 'x0.1', 'bag50', 15, (), True),
    'a18m_x20_text2': ('a18m', 'xflow', 'x20', 'text2', 15, (), True),
    'a18m_x20_forces50_2min': ('a18m', 'xflow', 'x20', 'forces50', 2, (), False),
    'a18m_strip_bag50': ('a18m', 'strip', 'file', 'bag50', 15, (), False),
    'a18m_strip_text2_2min': ('a18m', 'strip', 'file', 'text2', 2, (), False),
    'a18m_plane_bag50': ('a18m', 'plane', 'plant_file', 'bag50', 15, ('--fit-planes',),
                         False),
    'a18m_plane_text2': ('a18m', 'plane', 'plant_file', 'text2', 15, ('--fit-planes',),
                         False),
}


def vehicle_file(name: str) -> Any:
    from auv_sim.params import load_vehicle

    return load_vehicle(ROOT / 'config' / f'{name}.yaml')


def plant_of(vehicle: str, plant: str) -> tuple[Any, dict[str, Any], bool]:
    """The plant's parameters, its effects document and whether its coefficients are the
    model's (true values exist)."""
    from auv_sim.hull import crossflow_coefficients

    v = vehicle_file(vehicle)
    strip = crossflow_coefficients(v.L_ref, v.diameter, v.rho)
    if plant == 'xflow':
        return v.replace(**strip), {'effects': {}}, True
    if plant == 'plane':
        p = v.replace(**strip)
        return p.replace(CZbar=0.6 * p.CZbar, CMbar=0.6 * p.CMbar), {'effects': {}}, True
    if plant == 'strip':
        p = v.replace(**{k: 0.0 for k in QUADRATIC})
        return p, {'effects': {'hull_crossflow': {'cd': 1.1, 'length': v.L_ref,
                                                  'diameter': v.diameter}}}, False
    raise ValueError(plant)


def base_of(vehicle: str, plant: Any, base: str, workdir: pathlib.Path) -> pathlib.Path:
    """The base file of a case, written into ``workdir``."""
    from auv_sim.params import save_vehicle

    v = vehicle_file(vehicle)
    if base == 'file':
        return ROOT / 'config' / f'{vehicle}.yaml'
    if base == 'plant_file':
        b = plant.replace(CZbar=v.CZbar, CMbar=v.CMbar) if v.CZbar else plant
        b = b.replace(**{k: plant.values[k] for k in QUADRATIC})
    else:
        k = float(base[1:])
        b = plant.replace(**{q: k * plant.values[q] for q in QUADRATIC},
                          **{c: f * plant.values[c] for c, f in BASE_LINEAR.items()})
    path = workdir / f'base_{vehicle}_{base}.yaml'
    save_vehicle(b, path)
    return path


def scenario(vehicle: str, minutes: float, shift: float = 0.0, fast: bool = False) -> Any:
    """The closed-loop flight: depth changes, thrust steps and BAR doublets repeating every
    300 s, for ``minutes``; ``shift`` [s] moves the doublets (the validation flight);
    ``fast``: the REMUS 100 at 2-2.4 m/s (with a plane 40 % weaker it trims above 1.9 m/s)."""
    from auv_gap import synth

    duration = 60.0 * minutes
    n = int(math.ceil(duration / 300.0))
    if vehicle == 'remus100' and fast:
        z0, u0, amp = 30.0, 2.1, 1.0
        depths, thrusts = (30.0, 34.0, 29.0, 33.0), (8.2, 9.2, 7.6)
    elif vehicle == 'remus100':    # trims above 1.17 m/s only: thrust for 1.5-2.1 m/s
        z0, u0, amp = 30.0, 1.5, 1.0
        depths, thrusts = (30.0, 34.0, 29.0, 33.0), (4.6, 6.5, 4.3)
    else:
        z0, u0, amp = 60.0, 2.0, 2.0
        depths, thrusts = (60.0, 72.0, 55.0, 66.0), (55.0, 110.0, 40.0)
    times = (0.0, 60.0, 150.0, 230.0)
    dbl = ((20.0, 0.03, 2.0), (45.0, 0.04, 1.0), (90.0, 0.025, 3.0), (125.0, 0.04, 1.5),
           (175.0, 0.03, 2.5), (210.0, 0.05, 1.0), (260.0, 0.03, 2.0), (285.0, 0.02, 4.0))
    depth, thrust, doublets = [], [], []
    for k in range(n):
        o = 300.0 * k
        depth += [(o + t, z) for t, z in zip(times, depths)]
        thrust += [(o + t, f) for t, f in zip((0.0, 100.0, 200.0), thrusts)]
        doublets += [(o + t + shift, amp * a, h) for t, a, h in dbl if o + t + shift < duration]
    return synth.Scenario(duration=duration, z0=z0, u0=u0, depth=tuple(depth),
                          thrust=tuple(thrust), doublets=tuple(doublets))


def write_form(form: str, log: Any, path: pathlib.Path) -> tuple[list[str], list[str]]:
    """Write the flight ``log`` in log form ``form``; returns the log paths and the extra
    ``auv ident`` options (the map)."""
    from auv_logs import synth as realsynth
    from auv_logs.simlog import write_record

    if form == 'bag50':
        write_record(path, log.record, forces=False, sent_commands=log.commands)
        return [str(path)], []
    if form == 'forces50':     # a simulator's bag: its true state and forces
        truth = dataclasses.replace(log.record, measured=log.record.x.copy())
        write_record(path, truth, forces=True, sent_commands=log.commands)
        return [str(path)], []
    rec = realsynth.record_of(log.t, log.state, log.commands)
    if form == 'ros10':
        realsynth.write_ros2(path, rec, every=5)
        return [str(path)], ['--map', str(ROS_MAP)]
    if form == 'text2':
        meas = rec.measured.copy()
        meas[:, 2] = np.round(meas[:, 2] / 0.1) * 0.1          # depth in 0.1 m steps
        dvl = np.arange(len(meas)) // 50 * 50                   # a 1 Hz DVL, held
        meas[:, 6] = meas[dvl, 6]
        held = dataclasses.replace(rec, measured=meas)
        txt = path.with_suffix('.txt')
        realsynth.write_text(txt, held, every=25)
        return [str(txt)], ['--map', str(TEXT_MAP)]
    raise ValueError(form)


def held_out_depth(log: Any, base: Any, written: Any) -> dict[str, float]:
    """Free-run depth rms [m] of the base and the written model on an independent flight
    (every window scored, started from the logged state)."""
    from auv_ident.freerun import split_windows, window_length
    from auv_ident.identify import LoggedRun
    from auv_ident.validate import validate

    run = LoggedRun(t=log.t, state=log.state, commands=dict(log.commands))
    length, _ = window_length(base, [run])
    windows = [w.__class__(w.record, w.i0, w.i1, True)
               for w in split_windows([run], length, hold=False)]
    val = validate([run], windows, base, written)
    return {'base': val.rms['base']['z'], 'written': val.rms['identified']['z'],
            'windows': val.windows, 'verdict': val.verdict, 'ratio': val.ratio['z'],
            'margin': val.margin['z']}


def wrong_signs(report: dict[str, Any], base: Any) -> list[str]:
    """Coefficients of the report outside the sign physics allows."""
    from auv_ident.identify.physics import constraint

    out = []
    for name, c in report.get('coefficients', {}).items():
        con = constraint(name, base)
        if not (con.lo <= c['value'] <= con.hi):
            out.append(name)
    return out


def run_ident(paths: list[str], base_path: pathlib.Path, out: pathlib.Path,
              options: list[str]) -> tuple[int, float, str]:
    """``auv ident`` in process; exit status, seconds, stderr."""
    from auv_ident import cli

    err = io.StringIO()
    t0 = time.perf_counter()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        status = cli.main([*paths, '--vehicle', str(base_path), '--out', str(out),
                           '--no-nelder-mead', '--partial', *options])
    return status, time.perf_counter() - t0, err.getvalue()


def run_case(name: str, k: int, workdir: pathlib.Path) -> dict[str, Any]:
    """One case of the panel (module docstring)."""
    from auv_gap import synth
    from auv_sim.params import load_vehicle

    vehicle, plant_name, base_name, form, minutes, options, former = CASES[name]
    plant, effects, has_truth = plant_of(vehicle, plant_name)
    base_path = base_of(vehicle, plant, base_name, workdir)
    base = load_vehicle(base_path)
    t0 = time.perf_counter()
    fast = plant_name == 'plane'
    log = synth.simulate(plant, effects, scenario(vehicle, minutes, fast=fast), seed=SEED + k)
    check = synth.simulate(plant, effects, scenario(vehicle, 10, shift=7.0, fast=fast),
                           seed=SEED + 1000 + k)
    sim_s = time.perf_counter() - t0
    paths, map_opts = write_form(form, log, workdir / name)
    row: dict[str, Any] = {'case': name, 'vehicle': vehicle, 'plant': plant_name,
                           'base': base_name, 'form': form, 'minutes': minutes,
                           'options': list(options), 'true_values': has_truth,
                           'simulate_s': round(sim_s, 1)}
    runs = [('new', [*map_opts, *options])]
    if former:
        runs.append(('former', [*map_opts, *options, '--unbounded', '--no-priors',
                                '--no-validation', '--output-error', 'never',
                                '--structure', 'file']))
    for label, opts in runs:
        out = workdir / f'{name}_{label}'
        status, secs, err = run_ident(paths, base_path, out, opts)
        entry: dict[str, Any] = {'status': status, 'seconds': round(secs, 1)}
        if status not in (0, 3):
            entry['error'] = err.strip().splitlines()[-1] if err.strip() else ''
            row[label] = entry
            continue
        report = json.loads((out / 'report.json').read_text())
        written_path = out / 'vehicle.yaml'
        written = load_vehicle(written_path) if written_path.exists() else base
        depth = held_out_depth(check, base, written)
        coefs = report.get('coefficients', {})
        cover = {}
        if has_truth:
            for cname, c in coefs.items():
                lo, hi = c['ci95']
                cover[cname] = bool(lo <= plant.values[cname] <= hi)
        entry.update({
            'written': written_path.exists(),
            'validation': (report.get('validation') or {}).get('verdict'),
            'derivatives': report.get('derivatives', ''),
            'wrong_sign': wrong_signs(report, base) if written_path.exists() else [],
            'coefficients': {c: {'value': v['value'], 'ci95': v['ci95'], 'base': v['base'],
                                 'true': plant.values[c] if has_truth else None,
                                 'at_bound': v.get('at_bound', False),
                                 'at_prior': v.get('at_prior', False),
                                 'method': v.get('method', '')}
                             for c, v in coefs.items()},
            'structures': {e: v.get('structure') for e, v in report.get('equations', {}).items()},
            'r2': {e: v.get('r2') for e, v in report.get('equations', {}).items()},
            'covered': cover,
            'depth_rms_base': depth['base'], 'depth_rms_written': depth['written'],
            'improvement': 1.0 - depth['written'] / depth['base'],
            'independent_verdict': depth['verdict'],
            'window_ratio': depth['ratio'], 'window_margin': depth['margin'],
            'worse_than_base': depth['verdict'] in ('worse', 'diverges'),
            'worse_than_base_any_amount': bool(depth['written'] > depth['base']),
        })
        row[label] = entry
    return row


def summarise(rows: list[dict[str, Any]], label: str) -> dict[str, Any]:
    """The panel's figures for runs ``label`` (``new`` or ``former``)."""
    runs = [r[label] for r in rows if label in r and 'improvement' in r[label]]
    covered = [ok for r in rows if label in r and r['true_values']
               for ok in r[label].get('covered', {}).values()]
    return {
        'runs': len(runs),
        'failed': sum(1 for r in rows if label in r and 'improvement' not in r[label]),
        'written': sum(1 for r in runs if r['written']),
        'wrong_sign_written': sum(len(r['wrong_sign']) for r in runs),
        'worse_than_base': sum(1 for r in runs if r['worse_than_base']),
        'worse_than_base_any_amount': sum(1 for r in runs if r['worse_than_base_any_amount']),
        'coverage': (sum(covered) / len(covered)) if covered else None,
        'intervals_with_truth': len(covered),
        'median_improvement': float(np.median([r['improvement'] for r in runs]))
        if runs else None,
        'median_seconds': float(np.median([r['seconds'] for r in runs])) if runs else None,
    }


def run(cases: list[str] | None = None,
        progress: Callable[[list[dict[str, Any]]], None] | None = None) -> dict[str, Any]:
    """Every case (``bench/run_all.py`` calls it with the defaults); ``progress`` gets the
    rows so far after each case."""
    names = cases or list(CASES)
    load0 = os.getloadavg()[0]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            k = list(CASES).index(name)
            t0 = time.perf_counter()
            try:
                row = run_case(name, k, pathlib.Path(tmp))
            except Exception as exc:
                row = {'case': name, 'error': f'{type(exc).__name__}: {exc}',
                       'true_values': False, 'minutes': CASES[name][4]}
            rows.append(row)
            if progress is not None:
                progress(rows)
            new = row.get('new', {})
            print(f'{name}: {new.get("validation")} written={new.get("written")} '
                  f'improvement={new.get("improvement", math.nan):.3f} '
                  f'wrong={new.get("wrong_sign")} cover={sum(new.get("covered", {}).values())}'
                  f'/{len(new.get("covered", {}))} ({time.perf_counter() - t0:.0f} s)',
                  flush=True)
    two_min = [r['new']['seconds'] for r in rows if r['minutes'] == 2 and 'new' in r]
    failed = [r['case'] for r in rows if 'error' in r]
    return {
        'benchmark': 'identification panel: plants that are not the base file\'s structure',
        'noise_seed_first': SEED, 'base_linear_factors': BASE_LINEAR,
        'new': summarise(rows, 'new'), 'former': summarise(rows, 'former'),
        'two_minute_log_seconds_max': max(two_min) if two_min else None,
        'cases_failed': failed,
        'goals': {'wrong_sign_written': 0, 'worse_than_base': 0, 'coverage': 0.9,
                  'two_minute_log_seconds': 30.0},
        'rows': rows,
        'machine': {'cpus': os.cpu_count(), 'load_average': [load0, os.getloadavg()[0]]},
    }


if __name__ == '__main__':
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--cases', nargs='+', choices=list(CASES), default=None)
    args = parser.parse_args()
    partial = pathlib.Path(tempfile.gettempdir()) / 'ident_panel_rows.json'
    figures = run(args.cases, lambda rows: partial.write_text(json.dumps(rows, indent=1)))
    if args.cases is None:
        save_figures('ident_panel', figures)
    print(json.dumps({k: v for k, v in figures.items() if k != 'rows'}, indent=2))
