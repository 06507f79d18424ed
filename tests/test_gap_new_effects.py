"""The catalogue's newer effects found in short (5-minute) simulated logs: a current sheared
with depth and drifting in time, depth and pitch sensor scale and latency, an added-mass
error. The log is made by the simulator's implementation of the declared effect
(auv_sim.environment), the diagnosis uses its own (auv_ident.gap.catalogue) and is told
nothing of the effect."""
from __future__ import annotations

import pytest
from conftest import A18M
from test_gap_units import SHORT

from auv_ident.gap.diagnose import diagnose
from auv_ident.gap.synth import simulate
from auv_sim.params import load_vehicle

#: effect -> its fields in the simulator's effects document (also the true values)
NAMED = {
    'current_shear': {'north': 0.004, 'east': -0.002},
    'current_drift': {'north': 3e-4, 'east': -2e-4},
    'depth_sensor_scale': {'scale': 1.02},
    'pitch_sensor_scale': {'scale': 1.05},
    'pitch_sensor_latency': {'latency': 0.2},
    'depth_sensor_latency': {'latency': 0.4},
}


@pytest.fixture(scope='module')
def vehicle():  # type: ignore[no-untyped-def]
    return load_vehicle(A18M)


#: Measured failures on the 5-minute log flown by the LQR pilot (strict xfails: they run and
#: must fail; see docs/gap-diagnosis.md).
KNOWN = {
    'depth_sensor_scale': ('unexplained: "No plausible effect of the catalogue explains the '
                           'gap" (a 15-minute panel log of a 1.02 scale is explained)'),
    'depth_sensor_latency': ('named, but its interval 0.4015 to 0.4204 s misses the true '
                             '0.4 s: the equation-error estimate of a depth latency is biased'),
}


@pytest.mark.parametrize('name', [
    pytest.param(n, marks=pytest.mark.xfail(strict=True, reason=KNOWN[n])) if n in KNOWN
    else n for n in sorted(NAMED)])
def test_diagnosis_names_the_effect_with_the_truth_inside(vehicle, name: str) -> None:  # type: ignore
    truth = NAMED[name]
    log = simulate(vehicle, {'effects': {name: truth}}, SHORT, seed=3)
    report = diagnose(vehicle, log.gap_logs(), window=30.0).report
    assert report['verdict'] == 'explained', report['statement']
    assert report['best'] == name, report['statement']
    best = next(c for c in report['candidates'] if c['effect'] == name)
    for key, value in truth.items():
        lo, hi = best['ci95'][key]
        assert lo <= value <= hi, (key, value, lo, hi)


def test_added_mass_is_named_with_the_truth_inside(vehicle) -> None:  # type: ignore
    """Heave added mass 40 % larger. It acts on the heave inertia and, through the
    added-mass Coriolis terms, on the Munk moment, which the model's CMuw can also absorb:
    the diagnosis names ``added_mass`` (``ambiguous`` with the coefficients allowed: both
    change the Munk moment; plane doublets of several periods separate them), with Zwdot's
    factor inside its interval and Mqdot, unchanged, covering 1."""
    log = simulate(vehicle, {'effects': {'added_mass': {'Zwdot': 1.4}}}, SHORT, seed=3)
    report = diagnose(vehicle, log.gap_logs(), window=30.0).report
    assert report['verdict'] in ('explained', 'ambiguous'), report['statement']
    assert report['best'] == 'added_mass', report['statement']
    best = next(c for c in report['candidates'] if c['effect'] == 'added_mass')
    lo, hi = best['ci95']['Zwdot']
    assert lo <= 1.4 <= hi and hi - lo < 0.2, (lo, hi)
    lo, hi = best['ci95']['Mqdot']
    assert lo <= 1.0 <= hi, (lo, hi)
