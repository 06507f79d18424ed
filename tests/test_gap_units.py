"""Unit tests of the gap diagnosis: the catalogue's own effect implementations against the
simulator's (two separate implementations must agree), the registry, log checks and errors."""
from __future__ import annotations

import numpy as np
import pytest
from conftest import A18M

from auv_gap import catalogue
from auv_gap.catalogue import (
    CATALOGUE,
    Effect,
    Parameter,
    Perturbation,
    register,
    separating_manoeuvre,
)
from auv_gap.errors import GapError
from auv_gap.logs import from_arrays
from auv_gap.problem import CH_INDEX, EffectSet, Problem
from auv_gap.synth import Scenario, simulate
from auv_sim.environment import EFFECT_FIELDS, declare_effect, undeclare_effect
from auv_sim.params import load_vehicle

#: A short flight: a depth change, a speed change and BAR doublets (300 s).
SHORT = Scenario(duration=300.0, z0=60.0, u0=2.0,
                 depth=((0.0, 60.0), (60.0, 80.0), (200.0, 65.0)),
                 thrust=((0.0, 55.0), (150.0, 100.0)),
                 doublets=((30.0, 0.08, 3.0), (110.0, 0.1, 2.0), (170.0, 0.06, 5.0),
                           (240.0, 0.1, 3.0)))

#: effect -> (the simulator's effects document, the catalogue's parameters for the same thing)
ORACLES = {
    'current': ({'current': {'north': 0.3, 'east': -0.2, 'down': 0.02}},
                {'north': 0.3, 'east': -0.2, 'down': 0.02}),
    'buoyancy_offset': ({'buoyancy_offset': {'dB': 30.0}}, {'dB': 30.0}),
    'buoyancy_depth': ({'buoyancy_depth': {'k': -5e-5}}, {'k': -5e-5}),
    'actuator_delay': ({'actuator_delay': {'bar': 0.4}}, {'bar': 0.4}),
    'actuator_lag': ({'actuator_lag': {'bar_tau': 1.0}}, {'bar_tau': 1.0}),
    'actuator_rate_limit': ({'actuator_rate_limit': {'bar_rate': 0.05}}, {'bar_rate': 0.05}),
    'bar_bias': ({'bar_bias': {'bias': 0.02}}, {'bias': 0.02}),
    'crossflow_drag': ({'crossflow_drag': {'Zww': -3000.0, 'Mqq': -20000.0}},
                       {'Zww': -3000.0, 'Mqq': -20000.0, 'Yvv': 0.0, 'Nrr': 0.0}),
    'cg_offset': ({'cg_offset': {'dxg': 0.005, 'dzg': 0.002}}, {'dxg': 0.005, 'dzg': 0.002}),
    'pitch_sensor_bias': ({'pitch_sensor_bias': {'bias': 0.02}}, {'bias': 0.02}),
    'depth_sensor_bias': ({'depth_sensor_bias': {'bias': 0.3}}, {'bias': 0.3}),
    'current_shear': ({'current_shear': {'north': 0.004, 'east': -0.002}},
                      {'north': 0.004, 'east': -0.002}),
    'current_drift': ({'current_drift': {'north': 3e-4, 'east': -2e-4}},
                      {'north': 3e-4, 'east': -2e-4}),
    'added_mass': ({'added_mass': {'Zwdot': 1.4, 'Mqdot': 0.7}}, {'Zwdot': 1.4, 'Mqdot': 0.7}),
    'depth_sensor_scale': ({'depth_sensor_scale': {'scale': 1.02}}, {'scale': 1.02}),
    'depth_sensor_latency': ({'depth_sensor_latency': {'latency': 0.4}}, {'latency': 0.4}),
    'pitch_sensor_scale': ({'pitch_sensor_scale': {'scale': 1.05}}, {'scale': 1.05}),
    'pitch_sensor_latency': ({'pitch_sensor_latency': {'latency': 0.2}}, {'latency': 0.2}),
    'plane_effectiveness': ({'plane_effectiveness': {'gain': 0.7}}, {'gain': 0.7}),
    'thrust_error': ({'thrust_error': {'gain': 1.2}}, {'gain': 1.2}),
    'coefficients': ({'coefficients': {'CZuw': 1.3, 'CMuq': 1.3, 'CM0': 1.5}},
                     {'CZuw': 1.3, 'CMuw': 1.0, 'CZuq': 1.0, 'CMuq': 1.3, 'CZbar': 1.0,
                      'CMbar': 1.0, 'Ksh': 1.0, 'CZ0': 1.0, 'CM0': 1.5}),
}


@pytest.fixture(scope='module')
def vehicle():  # type: ignore[no-untyped-def]
    return load_vehicle(A18M)


def _values(es: EffectSet, params: dict[str, float]) -> np.ndarray:
    return np.array([params[p.name] for _, p in es.params])


def test_catalogue_holds_the_contract_effects() -> None:
    names = {'current', 'buoyancy_offset', 'buoyancy_depth', 'actuator_delay', 'actuator_lag',
             'actuator_rate_limit', 'bar_bias', 'crossflow_drag', 'cg_offset',
             'depth_sensor_bias', 'pitch_sensor_bias'}
    assert names <= set(CATALOGUE)


@pytest.mark.parametrize('name', sorted(ORACLES))
def test_catalogue_effect_reproduces_the_simulator(vehicle, name: str) -> None:  # type: ignore
    """Noise-free log made by the simulator's effect; the catalogue's implementation with the
    same parameters must reproduce it in free run and in equation error."""
    doc, params = ORACLES[name]
    log = simulate(vehicle, {'effects': doc}, SHORT, noise=np.zeros(12))
    pr = Problem(vehicle, log.gap_logs(), window=60.0)
    es = EffectSet([name], vehicle)
    true = es.perturbation(_values(es, params))
    nominal = Perturbation.nominal(vehicle)
    out, ref = pr.free_run([nominal, true], pr.select(None))
    rms = np.sqrt(np.mean((out - ref[None])[:, :, CH_INDEX] ** 2, axis=1))
    assert rms[1, 0] < 0.03, f'depth RMS {rms[1, 0]:.4f} m with the true {name}'
    assert rms[1, 1] < 6e-4, f'pitch RMS {rms[1, 1]:.2e} rad with the true {name}'
    e_nom = pr.equation_error(nominal)
    e_true = pr.equation_error(true)
    # the equation error with the effect is at the level of the clean model's
    clean = Problem(vehicle, simulate(vehicle, None, SHORT, noise=np.zeros(12)).gap_logs())
    e_clean = np.sqrt(np.mean(clean.equation_error(nominal) ** 2, axis=0))
    rms_nom = np.sqrt(np.mean(e_nom ** 2, axis=0))
    rms_true = np.sqrt(np.mean(e_true ** 2, axis=0))
    assert np.all(rms_true <= np.maximum(1.5 * e_clean, 0.05 * rms_nom) + 1e-6), rms_true
    if name != 'depth_sensor_bias':  # a constant depth offset is invisible to the dynamics
        gap_nom = np.sqrt(np.mean((out[0] - ref)[:, CH_INDEX] ** 2, axis=0))
        assert np.max(gap_nom / np.maximum(rms[1], 1e-9)) > 3.0 or \
            np.max(np.sqrt(np.mean(e_nom ** 2, axis=0)) / np.sqrt(np.mean(e_true ** 2, axis=0))
                   ) > 3.0


def test_depth_sensor_bias_is_not_identifiable(vehicle) -> None:  # type: ignore
    from auv_gap.fit import EquationFit
    log = simulate(vehicle, {'effects': ORACLES['depth_sensor_bias'][0]}, SHORT, seed=1)
    pr = Problem(vehicle, log.gap_logs())
    fit = EquationFit(pr).fit(EffectSet(['depth_sensor_bias'], vehicle))
    assert not fit.active.any()
    assert (fit.lo95[0], fit.hi95[0]) == (-10.0, 10.0)


def test_register_a_new_effect_plugs_in(vehicle) -> None:  # type: ignore
    class HeaveForce(Effect):
        name = 'test_heave_force'
        description = 'a constant body heave force (N)'
        signature = {'speed change': 0.0}

        def parameters(self, v):  # type: ignore[no-untyped-def]
            return (Parameter('Z', 'N', -100.0, 100.0, 0.0, 5.0),)

        def apply(self, pert, values, v):  # type: ignore[no-untyped-def]
            pert.C[0, 2] += values[0]

    with pytest.raises(GapError, match='not declared in the effect registry'):
        register(HeaveForce())
    declare_effect('test_heave_force', {'Z': ('N', 0.0)})
    try:
        register(HeaveForce())
        es = EffectSet(['test_heave_force'], vehicle)
        assert es.perturbation(np.array([7.0])).C[0, 2] == 7.0
        with pytest.raises(GapError, match='registered already'):
            register(HeaveForce())
    finally:
        CATALOGUE.pop('test_heave_force', None)
        undeclare_effect('test_heave_force')


def test_every_catalogue_effect_is_declared_with_its_units(vehicle) -> None:  # type: ignore
    """One registry: each catalogue parameter is a field of the simulator's declared effect,
    in the declared unit; a unit that differs is an error."""
    for name, effect in CATALOGUE.items():
        units = {p.name: p.unit for p in effect.parameters(vehicle)}
        declared = {k: EFFECT_FIELDS[name][k][0] for k in units}
        assert units == declared, name

    class Wrong(Effect):
        name = 'current_shear'

        def parameters(self, v):  # type: ignore[no-untyped-def]
            return (Parameter('north', 'm/s', -1.0, 1.0, 0.0, 0.1),)

    with pytest.raises(GapError, match="declared in '1/s'"):
        catalogue.check_declared(Wrong(), vehicle)


def test_unknown_effect_and_manoeuvre_are_errors() -> None:
    with pytest.raises(GapError, match="unknown effect 'wave'"):
        catalogue.get_effect('wave')

    class Bad(Effect):
        name = 'test_bad'
        signature = {'loop the loop': 1.0}

    with pytest.raises(GapError, match='unknown manoeuvre'):
        register(Bad())


def test_separating_manoeuvres() -> None:
    assert separating_manoeuvre('buoyancy_offset', 'buoyancy_depth').startswith(
        'depth excursion')
    assert separating_manoeuvre('buoyancy_offset', 'current').startswith('speed change')
    assert separating_manoeuvre('actuator_delay', 'actuator_rate_limit').startswith(
        'plane steps of several sizes')


def _cmds(t: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    return {'bar': (t[:1], np.array([-0.08])), 'thrust': (t[:1], np.array([55.0]))}


def test_log_checks() -> None:
    t = np.arange(200) * 0.02
    x = np.zeros((200, 12))
    pieces = from_arrays('ok', t, x, _cmds(t))
    assert len(pieces) == 1 and 'helm held at 0 rad' in pieces[0].notes[0]
    back = t.copy()
    back[50] = back[48]
    with pytest.raises(GapError, match='go back at sample 50'):
        from_arrays('back', back, x, _cmds(t))
    bad = x.copy()
    bad[7, 3] = np.nan
    with pytest.raises(GapError, match='non-finite state sample at index 7'):
        from_arrays('nan', t, bad, _cmds(t))
    with pytest.raises(GapError, match='no bar commands'):
        from_arrays('nobar', t, x, {'thrust': (t[:1], np.array([55.0]))})
    gap = np.concatenate([t[:100], t[100:] + 10.0])
    assert len(from_arrays('split', gap, x, _cmds(t))) == 2


def test_too_short_for_held_out_windows(vehicle) -> None:  # type: ignore
    t = np.arange(1500) * 0.02
    x = np.zeros((1500, 12))
    x[:, 6] = 2.0
    x[:, 2] = 50.0
    with pytest.raises(GapError, match='too short to hold out whole windows'):
        Problem(vehicle, from_arrays('short', t, x, _cmds(t)), window=60.0)


def test_cluster_covariance_of_parameters_that_change_nothing_is_unbounded() -> None:
    """Residuals that do not depend on the parameters at all (an effect a short or slow log
    cannot see) identify nothing: infinite variance, hence an interval over the whole
    plausible range, and no linear-algebra error."""
    from auv_gap.fit import cluster_covariance
    r = np.random.default_rng(5).standard_normal(60)
    V, df = cluster_covariance(np.zeros((60, 2)), r, np.repeat(np.arange(3), 20))
    assert np.all(np.isinf(np.diag(V))) and np.all(df == 1.0)


def test_cluster_covariance_of_a_mean_by_hand() -> None:
    """The mean of G equal clusters: CR2 is the classic variance of the mean of the cluster
    means, sum (m_g - m)^2 / (G (G - 1)), and Bell-McCaffrey's degrees of freedom are G - 1;
    a parameter informed by one cluster only gets the fewest (1)."""
    from auv_gap.fit import cluster_covariance
    rng = np.random.default_rng(4)
    G, n = 6, 40
    y = rng.standard_normal(G * n) + np.repeat(rng.standard_normal(G), n)
    clusters = np.repeat(np.arange(G), n)
    J = np.ones((G * n, 1))
    r = y - y.mean()
    V, df = cluster_covariance(J, r, clusters)
    means = y.reshape(G, n).mean(axis=1)
    assert V[0, 0] == pytest.approx(np.sum((means - means.mean()) ** 2) / (G * (G - 1)),
                                    rel=1e-9)
    assert df[0] == pytest.approx(G - 1, rel=1e-9)
    # a slope informed (almost) by one cluster: its x is 10 times larger there. Its
    # variance rests on one cluster's residuals: about 1 degree of freedom, against about
    # G - 1 when every cluster informs it alike
    for spread, lo, hi in ((1.0, G - 2.0, G - 1.0), (0.1, 1.0, 1.5)):
        x = rng.standard_normal(G * n) * np.where(clusters == 2, 1.0, spread)
        _, df2 = cluster_covariance(np.column_stack([J[:, 0], x]), r, clusters)
        assert lo <= df2[1] <= hi + 1e-9, (spread, df2)
