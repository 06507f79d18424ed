"""Benchmark: the gap diagnosis on poor logs: the same flights logged at 2, 10 and 50 Hz.

Each plant (the A18M with one effect the diagnosis is not told, or none) flies the
15-minute closed-loop panel flight (:func:`auv_gap.synth.panel_scenario`) with
realistic sensor noise. The run is written as a vendor's whitespace text log
(:func:`auv_logs.synth.write_text`: depth in cm, roll, pitch, heading in degrees,
speed in cm/s, two elevators, a rudder, rpm; no sway, no heave velocity, no rates, commands
sampled at the log's rows) every 25th, 5th and every 50 Hz sample, read back through
``config/maps/text_2hz_deg_cm.yaml`` (so ``q`` and ``w`` are derived, ``v`` assumed 0) and
diagnosed against the nominal A18M file. A reference column diagnoses the 50 Hz contract
log with every state measured.

Classification of a verdict: ``right`` (clean: ``no_gap``; an effect: ``explained`` with
exactly the true effect, or ``ambiguous`` naming it); ``honest`` (not right, but no confident
claim: ``unexplained``, ``partly_explained``, ``ambiguous`` without the truth, or ``no_gap``
when the effect is below what the log's period resolves); ``missed`` (``no_gap`` although
the effect is resolvable at that period: the noise floor of the log hides it); ``wrong``
(``explained`` with another effect or with more than the truth, or ``explained`` on a clean
plant). Target: no ``wrong``. What the 2 Hz log cannot resolve (a plane delay or lag below
the 0.5 s sample period) is expected to come out ``honest``, not ``right``.

A second part (``ident_2hz``) measures the 95 % interval coverage of ``auv ident --map`` on
2 Hz text logs of the surge mission (Ksh) and the pitch mission (heave, pitch) over noise
seeds.

Run: ``. .venv/bin/auv-env && python bench/bench_poor_data.py [--rates 2 10 50]
[--cases ...] [--ident-seeds N] [--skip-gap]`` (writes ``bench/results/poor_data.json``;
the gap panel takes about 10 minutes on 2 shared cores, the identification part about 10 s
per seed).
"""
from __future__ import annotations

import argparse
import json
import pathlib
import tempfile
import time
from typing import Any

from timing import save_figures

ROOT = pathlib.Path(__file__).resolve().parents[1]
MAP = ROOT / 'config' / 'maps' / 'text_2hz_deg_cm.yaml'
SAMPLE = 0.02          # s, the simulation's sample period
SEED = 300             # noise seed of the first case, fixed before any run

#: name -> (effects document, true effect set, smallest log period [s] that resolves it)
CASES: dict[str, tuple[dict[str, Any], set[str], float]] = {
    'clean': ({'effects': {}}, set(), 1.0),
    'current': ({'effects': {'current': {'north': 0.3, 'east': -0.2, 'down': 0.0}}},
                {'current'}, 1.0),
    'buoyancy_20N': ({'effects': {'buoyancy_offset': {'dB': 20.0}}}, {'buoyancy_offset'}, 1.0),
    'plane_lag_0.5': ({'effects': {'actuator_lag': {'bar_tau': 0.5}}}, {'actuator_lag'}, 0.25),
    'plane_delay_0.3': ({'effects': {'actuator_delay': {'bar': 0.3}}}, {'actuator_delay'},
                        0.15),
}


def classify(true: set[str], resolvable: bool, report: dict[str, Any]) -> str:
    """``right``, ``honest`` or ``wrong`` (see the module docstring)."""
    verdict, best = report['verdict'], report['best']
    named = set(best.split('+')) if best else set()
    if not true:
        if verdict == 'no_gap':
            return 'right'
        return 'wrong' if verdict == 'explained' else 'honest'
    if verdict == 'explained':
        return 'right' if named == true else 'wrong'
    if verdict == 'ambiguous' and true <= named | set(report['ambiguous_with']):
        return 'right'
    if verdict == 'no_gap' and resolvable:
        return 'missed'
    return 'honest'


def _row(case: str, rate: float, report: dict[str, Any], true: set[str], resolvable: bool,
         seconds: float) -> dict[str, Any]:
    best = report['best']
    entry = next((c for c in report['candidates'] if c['effect'] == best), None)
    return {'case': case, 'rate_hz': rate, 'verdict': report['verdict'], 'best': best,
            'ambiguous_with': report['ambiguous_with'],
            'class': classify(true, resolvable, report),
            'params': entry['params'] if entry else {},
            'ci95': entry['ci95'] if entry else {},
            'shrink': report['held_out']['shrink'],
            'left_out': report.get('signals', {}).get('left_out', {}),
            'statement': report['statement'], 'seconds': round(seconds, 1)}


def run(cases: list[str] | None = None, rates: list[float] | None = None,
        ident_seeds: int = 20) -> dict[str, Any]:
    """Every figure of this benchmark (``bench/run_all.py`` calls it with the defaults): the
    gap panel and the 2 Hz identification coverage."""
    figures = panel(cases or list(CASES), rates or [2.0, 10.0, 50.0])
    if ident_seeds:
        figures['ident_2hz'] = ident_coverage(ident_seeds)
    return figures


def panel(cases: list[str], rates: list[float]) -> dict[str, Any]:
    """The gap verdicts of ``cases`` at ``rates`` [Hz] and the reference (module docstring)."""
    from auv_gap import synth
    from auv_gap.diagnose import diagnose
    from auv_gap.logs import from_contract_arrays
    from auv_logs import synth as realsynth
    from auv_logs.contract_bag import contract_arrays
    from auv_logs.importer import import_log
    from auv_logs.mapping import load_map

    vehicle = load_vehicle_file()
    logmap = load_map(MAP)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for k, case in enumerate(cases):
            env, true, finest = CASES[case]
            t0 = time.perf_counter()
            log = synth.simulate(vehicle, env, synth.panel_scenario(), seed=SEED + k)
            print(f'{case}: simulated in {time.perf_counter() - t0:.0f} s', flush=True)
            t0 = time.perf_counter()
            r = diagnose(vehicle, log.gap_logs(case)).report
            rows.append(_row(case, 1.0 / SAMPLE, r, true, True, time.perf_counter() - t0)
                        | {'log': 'contract, every state measured'})
            print(f'  reference 50 Hz: {r["verdict"]} {r["best"]} ({rows[-1]["class"]})',
                  flush=True)
            rec = realsynth.record_of(log.t, log.state, log.commands)
            for rate in rates:
                every = max(1, int(round(1.0 / (rate * SAMPLE))))
                path = pathlib.Path(tmp) / f'{case}_{rate:g}hz.txt'
                realsynth.write_text(path, rec, every=every)
                t0 = time.perf_counter()
                imported = import_log(logmap, path)
                pieces = from_contract_arrays(case, contract_arrays(imported),
                                              [imported.report])
                r = diagnose(vehicle, pieces).report
                period = every * SAMPLE
                rows.append(_row(case, rate, r, true, period <= finest,
                                 time.perf_counter() - t0)
                            | {'log': 'text (q, w derived; v assumed 0)'})
                print(f'  {rate:g} Hz: {r["verdict"]} {r["best"]} ({rows[-1]["class"]})',
                      flush=True)
    text_rows = [r for r in rows if r['log'].startswith('text')]
    return {
        'benchmark': 'gap diagnosis on poor logs (2/10/50 Hz text logs)',
        'vehicle': 'config/a18m.yaml', 'map': 'config/maps/text_2hz_deg_cm.yaml',
        'flight': 'panel_scenario (15 min, closed loop)', 'noise_seed_first': SEED,
        'rows': rows,
        'wrong': sum(r['class'] == 'wrong' for r in text_rows),
        'right': sum(r['class'] == 'right' for r in text_rows),
        'honest': sum(r['class'] == 'honest' for r in text_rows),
        'missed': sum(r['class'] == 'missed' for r in text_rows),
        'text_cases': len(text_rows),
    }


def ident_coverage(seeds: int, rate: float = 2.0) -> dict[str, Any]:
    """95 % interval coverage of ``auv ident --map`` on text logs at ``rate`` [Hz] of the
    surge mission (Ksh, on the straight run: ``--equations surge``) and of the pitch mission
    (heave and pitch), over ``seeds`` noise seeds (realistic navigation-grade noise), against
    the vehicle file's values; also the mean and spread of ``(estimate - truth) / SE``."""
    import argparse
    import contextlib
    import io
    import statistics

    import numpy as np

    from auv_ident import cli
    from auv_logs import synth as realsynth
    from auv_logs.simlog import SensorNoise
    from auv_sim.missions import load_mission, run_mission

    vehicle = load_vehicle_file()
    every = max(1, int(round(1.0 / (rate * SAMPLE))))
    out: dict[str, Any] = {'rate_hz': rate, 'seeds': seeds}
    z: dict[str, list[float]] = {}
    hits: dict[str, int] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for mission, eqs in (('surge', ['surge']), ('pitch', ['heave', 'pitch'])):
            rec = run_mission(vehicle, load_mission(mission))
            for seed in range(seeds):
                rng = np.random.default_rng(1000 + seed)
                noise = rng.standard_normal((len(rec.t), 12)) * SensorNoise.realistic().sigmas()
                path = pathlib.Path(tmp) / f'{mission}_{seed}.txt'
                realsynth.write_text(path, rec, noise=noise, every=every)
                parser = argparse.ArgumentParser()
                cli.add_arguments(parser)
                ns = parser.parse_args([str(path), '--map', str(MAP), '--out',
                                        f'{tmp}/o', '--equations', *eqs, '--no-nelder-mead'])
                with contextlib.redirect_stdout(io.StringIO()), \
                        contextlib.redirect_stderr(io.StringIO()):
                    cli.run(ns)
                report = json.loads(pathlib.Path(f'{tmp}/o/report.json').read_text())
                for name, c in report['coefficients'].items():
                    truth = float(vehicle.values[name])
                    z.setdefault(name, []).append((c['value'] - truth) / c['std_error'])
                    hits[name] = hits.get(name, 0) + int(c['ci95'][0] <= truth <= c['ci95'][1])
            print(f'  {mission}: done', flush=True)
    for name, zs in z.items():
        out[name] = {'coverage_95': hits[name] / len(zs), 'z_mean': statistics.fmean(zs),
                     'z_sd': statistics.stdev(zs) if len(zs) > 1 else None}
    return out


def load_vehicle_file() -> Any:
    from auv_sim.params import load_vehicle

    return load_vehicle(ROOT / 'config' / 'a18m.yaml')


if __name__ == '__main__':
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--rates', type=float, nargs='+', default=[2.0, 10.0, 50.0])
    ap.add_argument('--cases', nargs='+', default=list(CASES), choices=list(CASES))
    ap.add_argument('--ident-seeds', type=int, default=20,
                    help='noise seeds of the 2 Hz identification coverage (0: skip it)')
    ap.add_argument('--skip-gap', action='store_true', help='keep the saved gap panel')
    args = ap.parse_args()
    saved = ROOT / 'bench' / 'results' / 'poor_data.json'
    figures = json.loads(saved.read_text()) if saved.exists() else {}
    if not args.skip_gap:
        figures.update(panel(args.cases, args.rates))
    if args.ident_seeds:
        figures['ident_2hz'] = ident_coverage(args.ident_seeds)
    save_figures('poor_data', figures)
    print(json.dumps({k: v for k, v in figures.items() if k != 'rows'}, indent=2))
