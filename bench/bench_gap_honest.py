"""Benchmark: how honest the gap diagnosis is, inside and outside its catalogue.

A panel of 15-minute closed-loop logs (the panel flight, :func:`auv_gap.synth.
panel_scenario`) and 10-minute open-loop logs (:func:`auv_gap.synth.open_loop_scenario`)
with realistic sensor noise, each of a plant the diagnosis is not told:

* ``inside``: catalogue effects at magnitudes from barely visible to large, single and in
  pairs, among them a current sheared with depth (also made with the simulator's profile
  table), a current drifting in time, an added-mass error, depth and pitch sensor scale and
  latency; the truth is the effect file. Counted right when the verdict is ``explained`` with
  exactly the true set, or ``ambiguous`` with the true set among the named;
* ``coefficients``: the plant's own coefficients differ from the file (heave and pitch damping
  30 % higher, plane effectiveness 70 %, Munk moment 20 % lower, surge drag 30 % higher,
  zero-lift force and moment twice the file's): right
  when named by ``coefficients`` or ``plane_effectiveness``; never to be ``explained`` by
  another effect;
* ``outside``: forms the catalogue lacks (a shear that stops inside the depths flown, alone
  and on top of a buoyancy error, a vertical current changing with depth, internal waves,
  tidal oscillations along and across the track shorter than or about the log, a surface
  current decaying exponentially with depth, a cross-flow drag beyond what the hull can
  have, a thrust line off the body origin, a plane whose lift saturates, buoyancy changing in
  time, a depth sensor's zero drifting): wrong when ``explained``;
* ``clean``: no effect, several seeds: a false alarm is any verdict but ``no_gap``.

Figures: right effect named, clean false alarms, outside cases wrongly explained (goal 0),
inside cases explained by a wrong set, median shrink of the in-catalogue cases, and the share
of true parameter values inside the reported 95 % intervals. Interval coverage over many seeds
is measured by ``bench/bench_gap_coverage.py``.

Run: ``. .venv/bin/auv-env && python bench/bench_gap_honest.py [--cases NAME ...]`` (updates
bench/results/gap_honest.json; about 45 cases at 30-90 s each on 2 shared cores; with
``--cases`` only those are run and the others kept from the saved file). Case ``k`` of
:data:`CASES` is flown with noise seed ``23 + k``.
"""
from __future__ import annotations

import argparse
import json
import math
import pathlib
import statistics
import time
from typing import Any

from gap_truth import truth_in_intervals
from timing import save_figures

ROOT = pathlib.Path(__file__).resolve().parents[1]

#: name -> (kind, vehicle-file factors, environment document, truth {effect: {param: value}},
#: flight 'closed' or 'open')
Case = tuple[str, dict[str, float], dict[str, Any], dict[str, dict[str, float]], str]


def _fx(**effects: dict[str, float]) -> dict[str, Any]:
    return {'effects': effects}


CASES: dict[str, Case] = {
    'current_large': ('inside', {}, _fx(current={'north': 0.5, 'east': -0.3, 'down': 0.0}),
                      {'current': {'north': 0.5, 'east': -0.3}}, 'closed'),
    'current_small': ('inside', {}, _fx(current={'north': 0.05, 'east': 0.0, 'down': 0.0}),
                      {'current': {'north': 0.05}}, 'closed'),
    'buoyancy_8N': ('inside', {}, _fx(buoyancy_offset={'dB': 8.0}),
                    {'buoyancy_offset': {'dB': 8.0}}, 'closed'),
    'buoyancy_-60N_open': ('inside', {}, _fx(buoyancy_offset={'dB': -60.0}),
                           {'buoyancy_offset': {'dB': -60.0}}, 'open'),
    'delay_0.25': ('inside', {}, _fx(actuator_delay={'bar': 0.25}),
                   {'actuator_delay': {'bar': 0.25}}, 'closed'),
    'lag_0.7_open': ('inside', {}, _fx(actuator_lag={'bar_tau': 0.7}),
                     {'actuator_lag': {'bar_tau': 0.7}}, 'open'),
    'rate_0.08': ('inside', {}, _fx(actuator_rate_limit={'bar_rate': 0.08}),
                  {'actuator_rate_limit': {'bar_rate': 0.08}}, 'closed'),
    'bar_bias_0.01': ('inside', {}, _fx(bar_bias={'bias': 0.01}),
                      {'bar_bias': {'bias': 0.01}}, 'closed'),
    'cg_dzg_4mm': ('inside', {}, _fx(cg_offset={'dxg': 0.0, 'dzg': 0.004}),
                   {'cg_offset': {'dzg': 0.004}}, 'closed'),
    'pitch_bias_2deg': ('inside', {}, _fx(pitch_sensor_bias={'bias': 0.035}),
                        {'pitch_sensor_bias': {'bias': 0.035}}, 'closed'),
    'crossflow_cd_0.8': ('inside', {}, _fx(crossflow_drag={'Zww': -900.0, 'Mqq': -2700.0}),
                         {'crossflow_drag': {'Zww': -900.0, 'Mqq': -2700.0}}, 'closed'),
    'current+delay': ('inside', {}, _fx(current={'north': 0.2, 'east': 0.2, 'down': 0.0},
                                        actuator_delay={'bar': 0.4}),
                      {'current': {'north': 0.2, 'east': 0.2}, 'actuator_delay': {'bar': 0.4}},
                      'closed'),
    'buoyancy+lag': ('inside', {}, _fx(buoyancy_offset={'dB': 25.0},
                                       actuator_lag={'bar_tau': 0.6}),
                     {'buoyancy_offset': {'dB': 25.0}, 'actuator_lag': {'bar_tau': 0.6}},
                     'closed'),
    'current+damping_25': ('inside', {'CZuw': 1.25}, _fx(current={'north': 0.25, 'east': 0.15,
                                                                 'down': 0.0}),
                           {'current': {'north': 0.25, 'east': 0.15},
                            'coefficients': {'CZuw': 1.25}}, 'closed'),
    'damping_30_higher': ('coefficients', {'CZuw': 1.3, 'CMuq': 1.3}, _fx(),
                          {'coefficients': {'CZuw': 1.3, 'CMuq': 1.3}}, 'closed'),
    'plane_70_open': ('coefficients', {'CZbar': 0.7, 'CMbar': 0.7}, _fx(),
                      {'plane_effectiveness': {'gain': 0.7}}, 'open'),
    'munk_20_lower': ('coefficients', {'CMuw': 0.8}, _fx(),
                      {'coefficients': {'CMuw': 0.8}}, 'closed'),
    # a linear profile from the surface (the simulator's profile table, not its shear effect)
    'shear_north': ('inside', {}, {'effects': {}, 'current_profile': [
        [0.0, 0.0, 0.0, 0.0], [200.0, 0.4, 0.2, 0.0]]},
        {'current_shear': {'north': 0.002, 'east': 0.001}}, 'closed'),
    # linear over the depths flown (55-95 m): 0.7 m/s at the surface, -0.01 1/s
    'shear_reversing': ('inside', {}, {'effects': {}, 'current_profile': [
        [40.0, 0.3, 0.0, 0.0], [100.0, -0.3, 0.0, 0.0]]},
        {'current': {'north': 0.7}, 'current_shear': {'north': -0.01}}, 'closed'),
    'shear_small': ('inside', {}, _fx(current_shear={'north': 0.0, 'east': 0.0008}),
                    {'current_shear': {'east': 0.0008}}, 'closed'),
    'drift_2e-4': ('inside', {}, _fx(current_drift={'north': 2e-4, 'east': 0.0}),
                   {'current_drift': {'north': 2e-4}}, 'closed'),
    'drift_5e-5_open': ('inside', {}, _fx(current_drift={'north': 0.0, 'east': -5e-5}),
                        {'current_drift': {'east': -5e-5}}, 'open'),
    'added_mass_30': ('inside', {'Zwdot': 1.3}, _fx(),
                      {'added_mass': {'Zwdot': 1.3}}, 'closed'),
    'added_mass_large': ('inside', {}, _fx(added_mass={'Zwdot': 1.6, 'Mqdot': 1.4}),
                         {'added_mass': {'Zwdot': 1.6, 'Mqdot': 1.4}}, 'closed'),
    'depth_scale_1.02': ('inside', {}, _fx(depth_sensor_scale={'scale': 1.02}),
                         {'depth_sensor_scale': {'scale': 1.02}}, 'closed'),
    'depth_scale_0.995_open': ('inside', {}, _fx(depth_sensor_scale={'scale': 0.995}),
                               {'depth_sensor_scale': {'scale': 0.995}}, 'open'),
    'depth_latency_0.6': ('inside', {}, _fx(depth_sensor_latency={'latency': 0.6}),
                          {'depth_sensor_latency': {'latency': 0.6}}, 'closed'),
    'pitch_scale_1.05': ('inside', {}, _fx(pitch_sensor_scale={'scale': 1.05}),
                         {'pitch_sensor_scale': {'scale': 1.05}}, 'closed'),
    'pitch_scale_0.98_open': ('inside', {}, _fx(pitch_sensor_scale={'scale': 0.98}),
                              {'pitch_sensor_scale': {'scale': 0.98}}, 'open'),
    'pitch_latency_0.1': ('inside', {}, _fx(pitch_sensor_latency={'latency': 0.1}),
                          {'pitch_sensor_latency': {'latency': 0.1}}, 'closed'),
    'pitch_latency_0.35': ('inside', {}, _fx(pitch_sensor_latency={'latency': 0.35}),
                           {'pitch_sensor_latency': {'latency': 0.35}}, 'closed'),
    # a shear that stops inside the depths flown (kink at 75 m): not linear
    'shear_kinked': ('outside', {}, {'effects': {}, 'current_profile': [
        [50.0, 0.0, 0.0, 0.0], [75.0, 0.4, 0.0, 0.0]]}, {}, 'closed'),
    'tidal_oscillation_300': ('outside', {}, _fx(current_oscillation={'north': 0.15,
                                                                      'period': 300.0}),
                              {}, 'closed'),
    'current_down_shear': ('outside', {}, {'effects': {}, 'current_profile': [
        [50.0, 0.0, 0.0, -0.05], [100.0, 0.0, 0.0, 0.05]]}, {}, 'closed'),
    'clean_4_open': ('clean', {}, _fx(), {}, 'open'),
    'internal_wave': ('outside', {}, _fx(current_oscillation={'down': 0.05, 'period': 120.0}),
                      {}, 'closed'),
    'tidal_drift_open': ('outside', {}, _fx(current_oscillation={'north': 0.3,
                                                                 'period': 900.0}),
                         {}, 'open'),
    'surge_drag_30': ('coefficients', {'Ksh': 1.3}, _fx(), {'coefficients': {'Ksh': 1.3}},
                      'closed'),
    'crossflow_cd_3': ('outside', {}, _fx(crossflow_drag={'Zww': -3400.0, 'Mqq': -10300.0}),
                       {}, 'closed'),
    # zero-lift force and moment twice the file's: offsets that grow with u^2 (the panel flies
    # three speeds), which no constant buoyancy or centre-of-gravity error reproduces; CZ0 and
    # CM0 are among the coefficients the `coefficients` candidate re-fits
    'zero_lift_x2': ('coefficients', {'CZ0': 2.0, 'CM0': 2.0}, _fx(),
                     {'coefficients': {'CZ0': 2.0, 'CM0': 2.0}}, 'closed'),
    # an outside form on top of an inside one: only part of the gap can be named
    'kinked_shear+buoyancy': ('outside', {}, {
        'effects': {'buoyancy_offset': {'dB': 15.0}},
        'current_profile': [[50.0, 0.0, 0.0, 0.0], [75.0, 0.0, 0.3, 0.0]]}, {}, 'closed'),
    'internal_wave_600_open': ('outside', {}, _fx(current_oscillation={'down': 0.03,
                                                                       'period': 600.0}),
                               {}, 'open'),
    'cross_tidal_450': ('outside', {}, _fx(current_oscillation={'east': 0.2, 'period': 450.0}),
                        {}, 'closed'),
    'clean_1': ('clean', {}, _fx(), {}, 'closed'),
    'clean_2': ('clean', {}, _fx(), {}, 'closed'),
    'clean_3_open': ('clean', {}, _fx(), {}, 'open'),
    # a wind-driven surface current decaying with depth, 0.8 / 0.3 m/s north / east at the
    # surface, e-folding over 25 m (an Ekman-like profile): curved over the depths flown
    'surface_current_decaying': ('outside', {}, {'effects': {}, 'current_profile': [
        [z, 0.8 * math.exp(-z / 25.0), 0.3 * math.exp(-z / 25.0), 0.0]
        for z in range(0, 161, 10)]}, {}, 'closed'),
    # the propeller's thrust line 4 cm below the body origin: a pitch moment z T that follows
    # the thrust (in steady flight like a zero-lift moment, apart from it when the speed
    # changes)
    'thrust_line_4cm': ('outside', {}, _fx(thrust_moment={'zt': 0.04}), {}, 'closed'),
    'thrust_line_-3cm_open': ('outside', {}, _fx(thrust_moment={'zt': -0.03}), {}, 'open'),
    # the plane's lift saturating (a tanh of the angle over 8 / 12 deg): a gain near 1 at small
    # angles and less at large ones, which no single plane effectiveness reproduces
    'plane_stall_8deg': ('outside', {}, _fx(plane_stall={'angle': 0.14}), {}, 'closed'),
    'plane_stall_12deg_open': ('outside', {}, _fx(plane_stall={'angle': 0.21}), {}, 'open'),
    # buoyancy changing in time: a slow leak (-0.02 N/s, -12 N over the log) and a variable
    # ballast pump (+0.012 N/s)
    'flooding_open': ('outside', {}, _fx(buoyancy_drift={'rate': -0.02}), {}, 'open'),
    'ballast_pump': ('outside', {}, _fx(buoyancy_drift={'rate': 0.012}), {}, 'closed'),
    # the depth sensor's zero drifting (tide, weather on a vented sensor): 0.45 m over the log
    'depth_zero_drift': ('outside', {}, _fx(depth_sensor_drift={'rate': 5e-4}), {}, 'closed'),
}


def _truth_covered(report: dict[str, Any], truth: dict[str, dict[str, float]]
                   ) -> list[bool]:
    return [bool(lo <= value <= hi) for _, value, lo, hi in truth_in_intervals(report, truth)]


def _right(kind: str, report: dict[str, Any], truth: dict[str, dict[str, float]]) -> bool:
    verdict, best = report['verdict'], report['best']
    if kind == 'clean':
        return bool(verdict == 'no_gap')
    if kind == 'outside':
        return bool(verdict != 'explained')
    true = set(truth)
    named = set(best.split('+')) if best else set()
    if kind == 'coefficients':
        ok = {'coefficients', 'plane_effectiveness'}
        return bool(verdict in ('explained', 'ambiguous') and named and named <= ok)
    if verdict == 'explained':
        return named == true
    if verdict == 'ambiguous':
        return true <= named | set(report['ambiguous_with'])
    return False


def panel(seed: int = 23, only: frozenset[str] = frozenset(),
          saved: list[dict[str, Any]] | None = None) -> dict[str, Any]:
    """Run the panel (the cases of ``only``, the others kept from ``saved`` rows); per-case
    rows and the summary figures."""
    from auv_gap import synth
    from auv_gap.diagnose import diagnose
    from auv_sim.params import load_vehicle

    vehicle = load_vehicle(ROOT / 'config' / 'a18m.yaml')
    rows = []
    for k, (name, (kind, factors, env, truth, flight)) in enumerate(CASES.items()):
        if only and name not in only:
            continue
        plant = vehicle.replace(**{p: f * getattr(vehicle, p) for p, f in factors.items()})
        scenario = synth.panel_scenario() if flight == 'closed' else synth.open_loop_scenario()
        t0 = time.perf_counter()
        log = synth.simulate(plant, env, scenario, seed=seed + k)
        r = diagnose(vehicle, log.gap_logs()).report
        rows.append({'case': name, 'kind': kind, 'flight': flight, 'verdict': r['verdict'],
                     'best': r['best'], 'ambiguous_with': r['ambiguous_with'],
                     'right': _right(kind, r, truth), 'shrink': r['held_out']['shrink'],
                     'covered': _truth_covered(r, truth) if kind == 'inside' else [],
                     'implausible': [i['effect'] for i in r['implausible']],
                     'statement': r['statement'], 'seconds': time.perf_counter() - t0})
        print(f'{name}: {r["verdict"]} {r["best"]} right={rows[-1]["right"]}', flush=True)
        print('row ' + json.dumps(rows[-1]), flush=True)
    if only:
        fresh = {row['case'] for row in rows}
        rows = [row for row in (saved or []) if row['case'] not in fresh
                and row['case'] in CASES] + rows
        rows.sort(key=lambda row: list(CASES).index(row['case']))
    return summarise(rows)


def summarise(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The panel's figures from its per-case rows."""
    by = {kind: [row for row in rows if row['kind'] == kind]
          for kind in ('inside', 'coefficients', 'outside', 'clean')}
    covered = [c for row in by['inside'] for c in row['covered']]
    return {
        'cases': rows,
        'inside_right': f'{sum(r["right"] for r in by["inside"])}/{len(by["inside"])}',
        'coefficients_right': f'{sum(r["right"] for r in by["coefficients"])}/'
                              f'{len(by["coefficients"])}',
        'coefficients_wrongly_explained': sum(
            r['verdict'] == 'explained' and not r['right'] for r in by['coefficients']),
        'outside_wrongly_explained': sum(not r['right'] for r in by['outside']),
        'inside_wrongly_explained': sum(r['verdict'] == 'explained' and not r['right']
                                        for r in by['inside']),
        'outside_cases': len(by['outside']),
        'clean_false_alarms': sum(not r['right'] for r in by['clean']),
        'clean_cases': len(by['clean']),
        'median_shrink_inside': statistics.median(r['shrink'] for r in by['inside']),
        'truth_in_ci95': f'{sum(covered)}/{len(covered)}',
    }


if __name__ == '__main__':
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--cases', nargs='*', help='run these panel cases only (the others are '
                    'kept from the saved results)')
    args = ap.parse_args()
    saved = ROOT / 'bench' / 'results' / 'gap_honest.json'
    figures: dict[str, Any] = json.loads(saved.read_text()) if saved.exists() else {}
    figures['benchmark'] = 'gap diagnosis honesty panel'
    figures['panel'] = panel(only=frozenset(args.cases or ()),
                             saved=figures.get('panel', {}).get('cases'))
    figures.pop('coverage', None)  # interval coverage: bench/bench_gap_coverage.py
    save_figures('gap_honest', figures)
    print(json.dumps({k: v for k, v in figures.get('panel', {}).items() if k != 'cases'},
                     indent=2))
