"""The catalogue's newer effects found in short (5-minute) simulated logs: a current sheared
with depth and drifting in time, depth and pitch sensor scale and latency, an added-mass
error. The log is made by the simulator's implementation of the declared effect
(auv_sim.environment), the diagnosis uses its own (auv_gap.catalogue) and is told
nothing of the effect."""
from __future__ import annotations

from typing import Any

import pytest
from conftest import A18M
from test_gap_units import SHORT

from auv_gap.diagnose import diagnose
from auv_gap.synth import simulate
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
    'depth_sensor_scale': ('unexplained: the scale is fitted (1.021) and explains 97 % of the '
                           'held-out gap, but its information sits in the one training window '
                           'with a depth change, so the cluster-robust interval has about 1 '
                           'degree of freedom and covers 1: "identifies nothing" (a 15-minute '
                           'panel log of a 1.02 scale is explained)'),
}


_REPORTS: dict[str, dict[str, Any]] = {}


def _report(vehicle, name: str) -> dict[str, Any]:  # type: ignore[no-untyped-def]
    """The diagnosis of the 5-minute log of effect ``name`` (once per module)."""
    if name not in _REPORTS:
        log = simulate(vehicle, {'effects': {name: NAMED[name]}}, SHORT, seed=3)
        _REPORTS[name] = diagnose(vehicle, log.gap_logs(), window=30.0).report
    return _REPORTS[name]


@pytest.mark.parametrize('name', [
    pytest.param(n, marks=pytest.mark.xfail(strict=True, reason=KNOWN[n])) if n in KNOWN
    else n for n in sorted(NAMED)])
def test_diagnosis_names_the_effect_with_the_truth_inside(vehicle, name: str) -> None:  # type: ignore
    truth = NAMED[name]
    report = _report(vehicle, name)
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
