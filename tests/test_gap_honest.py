"""The gap diagnosis outside its catalogue: plants that differ from the model in ways no
catalogue effect describes (a current whose shear stops inside the depths flown, a cross-flow
drag beyond what the hull can have) must never be declared ``explained``; plants whose own
coefficients differ from the file must be named as such or not explained at all, never by a
wrong effect; an added-mass error is named as such or through the Munk moment; a linear shear
made with the simulator's profile table is named; a physically sized cross-flow drag is still
found.

The plants are made with the simulator's own means (its environment: a current profile; or a
vehicle file with changed coefficients), 15 minutes of closed-loop flight with sensor noise.
The truth is what the plant was given, never a number of the diagnosis's.
"""
from __future__ import annotations

from typing import Any

import pytest
from conftest import A18M

from auv_gap import synth
from auv_gap.diagnose import diagnose
from auv_gap.verdict import Diagnosis
from auv_sim.params import VehicleParams, load_vehicle

#: case -> (changes to the vehicle file as factors, the simulator's environment document)
CASES: dict[str, tuple[dict[str, float], dict[str, Any]]] = {
    # outside the catalogue: a shear that stops at 75 m, inside the depths flown (55-95 m)
    'shear_kinked': ({}, {'effects': {}, 'current_profile': [[50.0, 0.0, 0.0, 0.0],
                                                              [75.0, 0.4, 0.0, 0.0]]}),
    # inside: a linear shear from the surface, made with the simulator's profile table
    # (0 at 0 m, 0.4/0.2 m/s north/east at 200 m: S = 0.002, 0.001 1/s)
    'current_shear': ({}, {'effects': {}, 'current_profile': [[0.0, 0.0, 0.0, 0.0],
                                                               [200.0, 0.4, 0.2, 0.0]]}),
    'crossflow_cd_3': ({}, {'effects': {'crossflow_drag': {'Zww': -3400.0, 'Mqq': -10300.0}}}),
    # the model's own coefficients
    'plane_70_percent': ({'CZbar': 0.7, 'CMbar': 0.7}, {'effects': {}}),
    'added_mass_30': ({'Zwdot': 1.3}, {'effects': {}}),
    # in the catalogue, physically sized: cross-flow drag coefficient 1.0 on the hull
    'crossflow_cd_1': ({}, {'effects': {'crossflow_drag': {'Zww': -1124.0, 'Mqq': -3420.0}}}),
}


def _plant(vehicle: VehicleParams, factors: dict[str, float]) -> VehicleParams:
    return vehicle.replace(**{k: f * getattr(vehicle, k) for k, f in factors.items()})


@pytest.fixture(scope='module')
def vehicle():  # type: ignore[no-untyped-def]
    return load_vehicle(A18M)


@pytest.fixture(scope='module')
def panel(vehicle):  # type: ignore[no-untyped-def]
    cache: dict[str, Diagnosis] = {}

    def get(case: str) -> Diagnosis:
        if case not in cache:
            factors, env = CASES[case]
            log = synth.simulate(_plant(vehicle, factors), env, seed=11)
            cache[case] = diagnose(vehicle, log.gap_logs())
        return cache[case]
    return get


@pytest.mark.parametrize('case', [
    'shear_kinked',
    'crossflow_cd_3',
])
def test_outside_the_catalogue_is_never_explained(panel, case: str) -> None:  # type: ignore
    """Never ``explained``; a best beyond its typical range is said to be so (a finding to
    check, see the cross-flow case below), never one beyond what physics allows."""
    r = panel(case).report
    assert r['verdict'] in ('partly_explained', 'unexplained', 'ambiguous'), \
        (r['verdict'], r['best'], r['statement'])
    for c in r['candidates']:
        if c['effect'] == r['best']:
            assert c['plausible'] or ('is beyond the typical range (' in r['statement']
                                      and '): check ' in r['statement']), c


def test_crossflow_beyond_the_hull_is_an_atypical_finding(panel) -> None:  # type: ignore
    """Zww = -3400 kg/m is a cross-flow drag coefficient of 3 on this hull: beyond the typical
    Cd of 0.6-1.2 but a drag (dissipative), so possible: the fit that finds it is named as a
    finding with its typical range and what to check, the verdict at most partly explained;
    it was listed as "not a physical explanation" when the plausible range was the only one
    (and the answer was a coefficient refit leaving structure of its form)."""
    r = panel('crossflow_cd_3').report
    assert r['best'] == 'crossflow_drag', (r['verdict'], r['best'], r['statement'])
    assert r['verdict'] in ('partly_explained', 'ambiguous')
    entry = next(c for c in r['candidates'] if c['effect'] == 'crossflow_drag')
    assert not entry['plausible']
    assert abs(entry['params']['Zww'] / -3400.0 - 1.0) < 0.15, entry['params']
    assert 'Zww = ' in r['statement'] and 'beyond the typical range' in r['statement']
    assert "check the hull's cross-flow drag" in r['statement']


@pytest.mark.parametrize('case,truth', [
    # heave and pitch damping 30 % higher: bench/bench_gap_honest.py (damping_30_higher)
    ('plane_70_percent', {'CZbar': 0.7, 'CMbar': 0.7}),
])
def test_coefficient_errors_are_named_or_not_explained(panel, case: str,  # type: ignore
                                                       truth: dict[str, float]) -> None:
    r = panel(case).report
    best = r['best'] or ''
    assert 'crossflow_drag' not in best and 'actuator' not in best, (r['verdict'], best)
    if r['verdict'] != 'explained':
        return
    entry = next(c for c in r['candidates'] if c['effect'] == best)
    if best == 'plane_effectiveness':
        lo, hi = entry['ci95']['gain']
        assert lo <= truth['CZbar'] <= hi
        return
    assert best == 'coefficients', best
    for name, true in truth.items():
        lo, hi = entry['ci95'][name]
        assert lo <= true <= hi, (name, true, lo, hi, entry['params'][name])
    assert 'low' in r['statement'] or 'high' in r['statement']


def test_added_mass_error_is_named_or_shows_as_the_munk_moment(panel, vehicle) -> None:  # type: ignore
    """Heave added mass 30 % above the file. Named as ``added_mass``: Zwdot's factor 1.3
    inside its interval. Named as the model's coefficients: in the simulator the added-mass
    Coriolis terms give the pitch (Munk) moment ``(Xudot - Zwdot) ur wr``, so the plant's
    moment in ``ur wr`` is larger by ``-0.3 Zwdot = 204 kg``: the same as a factor
    ``1 - 0.3 Zwdot / (qs L CMuw)`` on the file's CMuw (0.52 for the A18M), which must then be
    inside CMuw's interval. Nothing else may be named."""
    r = panel('added_mass_30').report
    best = r['best'] or ''
    named = set(best.split('+')) - {''}
    assert named <= {'added_mass', 'coefficients'}, (r['verdict'], best)
    if r['verdict'] not in ('explained', 'ambiguous') or len(named) != 1:
        return
    entry = next(c for c in r['candidates'] if c['effect'] == best)
    if best == 'added_mass':
        lo, hi = entry['ci95']['Zwdot']
        assert lo <= 1.3 <= hi, (lo, hi, entry['params']['Zwdot'])
        return
    qs_l = 0.5 * vehicle.rho * vehicle.S_ref * vehicle.L_ref
    munk = 1.0 - 0.3 * vehicle.Zwdot / (qs_l * vehicle.CMuw)
    assert munk == pytest.approx(0.523, abs=0.002)
    lo, hi = entry['ci95']['CMuw']
    assert lo <= munk <= hi, (lo, hi, entry['params']['CMuw'])


def test_linear_shear_from_a_profile_is_named(panel) -> None:  # type: ignore
    """A current profile growing linearly from the surface is the catalogue's
    ``current_shear`` (S = 0.002 north, 0.001 east [1/s]), made by the simulator's profile
    table rather than its shear effect."""
    r = panel('current_shear').report
    assert r['verdict'] in ('explained', 'ambiguous'), (r['verdict'], r['statement'])
    assert 'current_shear' in (r['best'] or '').split('+'), r['best']
    if r['best'] == 'current_shear':
        entry = next(c for c in r['candidates'] if c['effect'] == 'current_shear')
        for key, true in (('north', 0.002), ('east', 0.001)):
            lo, hi = entry['ci95'][key]
            assert lo <= true <= hi, (key, lo, hi)


def test_physically_sized_crossflow_drag_is_still_found(panel) -> None:  # type: ignore
    r = panel('crossflow_cd_1').report
    assert r['verdict'] in ('explained', 'ambiguous'), (r['verdict'], r['statement'])
    named = set(r['best'].split('+')) | set(r['ambiguous_with'])
    assert 'crossflow_drag' in named, r['best']
    if r['best'] == 'crossflow_drag':
        entry = r['candidates'][[c['effect'] for c in r['candidates']].index('crossflow_drag')]
        lo, hi = entry['ci95']['Zww']
        assert lo <= -1124.0 <= hi, (lo, hi)
