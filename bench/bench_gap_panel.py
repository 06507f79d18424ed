"""Benchmark: the effect panel of the gap diagnosis, one case per file of ``config/effects``.

For each effect file a 15-minute closed-loop log (the panel flight,
:func:`auv_gap.synth.panel_scenario`, noise seed 11) is flown on the simulator with that
effect and realistic sensor noise, and the diagnosis, told nothing, must name the effect (or
say it cannot tell it from another), bracket its size with its 95 % interval and shrink the
held-out depth RMS to at most 0.8 of the nominal model's. Also: a clean log (no gap) and two
effects at once. Special cases, judged by :func:`judge`:

* effects the dynamics cannot see (a depth-sensor bias: the log is consistent with the model
  at another depth): the verdict must be ``no_gap``;
* a form the catalogue lacks (a current oscillating in time): ``unexplained`` or
  ``partly_explained``;
* a magnitude beyond the typical range (the file's cross-flow drag, Zww = -2000 kg/m,
  Mqq = -10000 kg m^2, is a cross-flow drag coefficient of 1.8 and 2.9 on the A18M's
  4.6 m x 0.477 m hull, beyond the 0.6-1.2 of a cylinder, Hoerner 1965, but within the
  catalogue's possible range, `config/plausible_ranges.yaml`): never ``explained``. Either
  flagged in ``implausible``, or named as a finding beyond the typical range (verdict
  ``partly_explained`` or ``ambiguous``) with the truth inside its 95 % intervals.

Figures: per case the verdict, the best candidate, pass and the reason it fails; the count
passed. ``tests/test_gap_panel.py`` flies a few of these cases with the same judge.

Run: ``. .venv/bin/auv-env && python bench/bench_gap_panel.py [--cases NAME ...]`` (updates
bench/results/gap_panel.json; about 15 cases at 5-40 s each).
"""
from __future__ import annotations

import argparse
import json
import pathlib
import time
from typing import Any

import yaml
from gap_truth import truth_in_intervals
from timing import save_figures

ROOT = pathlib.Path(__file__).resolve().parents[1]

#: effect file name -> its effects document (``{effect: {parameter: value}}``)
EFFECT_FILES: dict[str, dict[str, dict[str, float]]] = {
    p.stem: yaml.safe_load(p.read_text())['effects']
    for p in sorted((ROOT / 'config' / 'effects').glob('*.yaml'))}
#: case -> the true effects of the plant
CASES: dict[str, dict[str, dict[str, float]]] = {
    **EFFECT_FILES,
    'clean': {},
    'two_effects': {**EFFECT_FILES['current'], **EFFECT_FILES['actuator_delay']},
}
#: Effects the dynamics cannot see at all: with them the log is consistent with the model.
INVISIBLE = {'depth_sensor_bias'}
#: Effects of a form the catalogue does not have.
OUTSIDE = {'current_oscillation'}
#: Effect files whose magnitude is beyond the typical range on this hull, within the possible
#: one (module docstring).
ATYPICAL = {'crossflow_drag'}
#: Noise seed of every panel log.
SEED = 11


def judge(report: dict[str, Any], truth: dict[str, dict[str, float]]) -> str | None:
    """Why the diagnosis ``report`` (the report.json document) of a plant with the effects
    ``truth`` is wrong, or None when it is right (rules in the module docstring)."""
    effects = set(truth)
    if not effects or effects <= INVISIBLE:
        if report['verdict'] != 'no_gap' or report['best'] is not None:
            return f"verdict {report['verdict']} ({report['best']}), expected no_gap"
        return None
    if effects & OUTSIDE:
        if report['verdict'] not in ('unexplained', 'partly_explained'):
            return f"verdict {report['verdict']} ({report['best']}) for a form outside"
        return None
    if effects & ATYPICAL:
        if report['best'] is not None and effects & set(report['best'].split('+')):
            # named: an atypical finding, never the explanation, its intervals on the truth
            if report['verdict'] not in ('partly_explained', 'ambiguous'):
                return f"an atypical {report['best']} {report['verdict']}"
            for key, true, lo, hi in truth_in_intervals(report, truth):
                if not lo <= true <= hi:
                    return f'{key}: truth {true} outside [{lo}, {hi}]'
            return None
        flagged = {n for i in report['implausible'] for n in i['effect'].split('+')}
        if not effects <= flagged:
            return f'not flagged implausible: {sorted(effects - flagged)}'
        return None
    if report['verdict'] not in ('explained', 'ambiguous'):
        return f"verdict {report['verdict']}"
    named = set(report['best'].split('+'))
    if report['verdict'] == 'explained' and named != effects:
        return f"explained by {report['best']}"
    if report['verdict'] == 'ambiguous':
        if not effects <= named | set(report['ambiguous_with']):
            return f"ambiguous between {report['best']} and {report['ambiguous_with']}"
        if not report['suggested_manoeuvre']:
            return 'ambiguous without a suggested manoeuvre'
    for key, true, lo, hi in truth_in_intervals(report, truth):
        if not lo <= true <= hi:
            entry = next(c for c in report['candidates'] if c['effect'] == report['best'])
            return f"{key}: truth {true} outside [{lo}, {hi}] (estimate {entry['params'][key]})"
    if report['held_out']['shrink'] < 0.8:
        return f"held-out shrink {report['held_out']['shrink']:.2f} < 0.8"
    return None


def diagnose_case(case: str) -> Any:
    """The diagnosis (:class:`auv_gap.verdict.Diagnosis`) of the panel log of ``case``
    (the A18M, noise seed :data:`SEED`)."""
    from auv_gap import synth
    from auv_gap.diagnose import diagnose
    from auv_sim.params import load_vehicle

    vehicle = load_vehicle(ROOT / 'config' / 'a18m.yaml')
    log = synth.simulate(vehicle, {'effects': CASES[case]}, seed=SEED)
    return diagnose(vehicle, log.gap_logs())


def run(cases: list[str] | None = None) -> dict[str, Any]:
    """Diagnose every case (or ``cases``) and judge it; figures per case and the count."""
    rows: dict[str, Any] = {}
    for case in cases or sorted(CASES):
        t0 = time.perf_counter()
        report = diagnose_case(case).report
        why = judge(report, CASES[case])
        rows[case] = {'truth': CASES[case], 'verdict': report['verdict'],
                      'best': report['best'], 'shrink': report['held_out'].get('shrink'),
                      'pass': why is None, 'why_not': why or '',
                      'wall_s': round(time.perf_counter() - t0, 1)}
        print(case, rows[case]['verdict'], rows[case]['best'], why or 'ok', flush=True)
    return {'benchmark': 'gap diagnosis effect panel (config/effects)', 'seed': SEED,
            'cases': rows, 'passed': sum(r['pass'] for r in rows.values()),
            'total': len(rows)}


if __name__ == '__main__':
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--cases', nargs='*', choices=sorted(CASES), help='only these cases')
    args = ap.parse_args()
    figures = run(args.cases)
    saved = ROOT / 'bench' / 'results' / 'gap_panel.json'
    if args.cases and saved.exists():  # keep the cases not run
        old = json.loads(saved.read_text())
        figures['cases'] = {**old['cases'], **figures['cases']}
        figures['passed'] = sum(r['pass'] for r in figures['cases'].values())
        figures['total'] = len(figures['cases'])
    print(save_figures('gap_panel', figures))
