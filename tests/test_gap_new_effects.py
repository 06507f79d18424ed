"""The catalogue's newer effects found in short simulated logs: a current sheared with depth
and drifting in time, depth and pitch sensor scale and latency, an added-mass error. The log
is made by the simulator's implementation of the declared effect (auv_sim.environment), the
diagnosis uses its own (auv_ident.gap.catalogue) and is told nothing of the effect."""
from __future__ import annotations

import numpy as np
import pytest
from conftest import A18M
from test_gap_units import SHORT

from auv_ident.gap.catalogue import Perturbation
from auv_ident.gap.diagnose import diagnose
from auv_ident.gap.fit import EquationFit, FreeRunFit
from auv_ident.gap.problem import CH_INDEX, EffectSet, Problem
from auv_ident.gap.synth import simulate
from auv_sim.params import load_vehicle

#: effect -> its fields in the simulator's effects document (also the true values)
NAMED = {
    'current_shear': {'north': 0.004, 'east': -0.002},
    'current_drift': {'north': 3e-4, 'east': -2e-4},
    'depth_sensor_scale': {'scale': 1.02},
    'pitch_sensor_scale': {'scale': 1.05},
    'pitch_sensor_latency': {'latency': 0.2},
}


@pytest.fixture(scope='module')
def vehicle():  # type: ignore[no-untyped-def]
    return load_vehicle(A18M)


@pytest.mark.parametrize('name', sorted(NAMED))
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


def _fit(vehicle, name: str, truth: dict[str, float]):  # type: ignore[no-untyped-def]
    log = simulate(vehicle, {'effects': {name: truth}}, SHORT, seed=3)
    pr = Problem(vehicle, log.gap_logs(), window=30.0)
    es = EffectSet([name], vehicle)
    ee = EquationFit(pr).fit(es)
    pred, meas = pr.free_run([Perturbation.nominal(vehicle)], pr.select(None))
    rms = np.sqrt(np.nanmean((pred[0] - meas)[:, CH_INDEX] ** 2, axis=0))
    return es, FreeRunFit(pr, np.maximum(rms, pr.noise[list(CH_INDEX)])).fit(ee)


def test_added_mass_fit_holds_the_truth(vehicle) -> None:  # type: ignore
    """Heave added mass 40 % larger: the fit finds Zwdot's factor; Mqdot, unchanged, is
    dropped or covers 1."""
    es, fit = _fit(vehicle, 'added_mass', {'Zwdot': 1.4})
    names = [p.name for _, p in es.params]
    i, j = names.index('Zwdot'), names.index('Mqdot')
    assert fit.lo95[i] <= 1.4 <= fit.hi95[i] and fit.hi95[i] - fit.lo95[i] < 0.2
    assert fit.lo95[j] <= 1.0 <= fit.hi95[j]


def test_depth_latency_fit_holds_the_truth(vehicle) -> None:  # type: ignore
    _es, fit = _fit(vehicle, 'depth_sensor_latency', {'latency': 0.4})
    assert fit.active[0]
    assert fit.lo95[0] <= 0.4 <= fit.hi95[0] and fit.lo95[0] > 0.1
