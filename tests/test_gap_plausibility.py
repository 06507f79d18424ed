"""Unit tests of the gap diagnosis's honesty checks: residual tests against hand-worked values
and Monte Carlo sizes, plausible ranges of the catalogue against hand-computed physics, the
model-coefficient effects against the simulator with a changed vehicle file, and the wording."""
from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import A18M
from scipy import stats

from auv_gap import residuals
from auv_gap.catalogue import CATALOGUE, Parameter, Perturbation
from auv_gap.fit import FitResult
from auv_gap.problem import CH_INDEX, EffectSet, Problem
from auv_gap.synth import Scenario, simulate
from auv_gap.wording import describe
from auv_sim.params import load_vehicle

SHORT = Scenario(duration=300.0, z0=60.0, u0=2.0,
                 depth=((0.0, 60.0), (60.0, 80.0), (200.0, 65.0)),
                 thrust=((0.0, 55.0), (150.0, 100.0)),
                 doublets=((30.0, 0.08, 3.0), (110.0, 0.1, 2.0), (170.0, 0.06, 5.0),
                           (240.0, 0.1, 3.0)))


@pytest.fixture(scope='module')
def vehicle():  # type: ignore[no-untyped-def]
    return load_vehicle(A18M)


# -- residual tests ---------------------------------------------------------------------------
def test_ljung_box_hand_worked() -> None:
    """x = 1..5: mean 3, deviations -2..2, c0 = 10, rho_1 = (2 + 0 + 0 + 2) / 10 = 0.4,
    Q = n (n + 2) rho_1^2 / (n - 1) = 5 * 7 * 0.16 / 4 = 1.4."""
    q, p = residuals.ljung_box([np.arange(1.0, 6.0)], lags=1)
    assert q == pytest.approx(1.4, rel=1e-12)
    assert p == pytest.approx(float(stats.chi2.sf(1.4, 1)), rel=1e-12)
    assert p == pytest.approx(0.2367, abs=1e-4)


def test_ljung_box_pools_pieces_without_crossing_them() -> None:
    """Two pieces 1..3 and 3..5: pooled mean 3, products within pieces only:
    c0 = 4 + 1 + 0 + 0 + 1 + 4 = 10, lag 1: (-2)(-1) + (-1)(0) + (0)(1) + (1)(2) = 4."""
    q, _ = residuals.ljung_box([np.array([1.0, 2.0, 3.0]), np.array([3.0, 4.0, 5.0])], lags=1)
    assert q == pytest.approx(6 * 8 * 0.16 / 5, rel=1e-12)


def test_residual_tests_size_and_power() -> None:
    """White noise is rejected at about the nominal rate; an AR(1) residual always."""
    rng = np.random.default_rng(0)
    n_rep, rejected = 300, 0
    for _ in range(n_rep):
        _, p = residuals.ljung_box([rng.standard_normal(300)])
        rejected += p < 0.05
    assert 0.02 <= rejected / n_rep <= 0.09, rejected / n_rep
    e = np.zeros(300)
    for k in range(1, 300):
        e[k] = 0.5 * e[k - 1] + rng.standard_normal()
    assert residuals.ljung_box([e])[1] < 1e-6


def _ar1(rng: np.random.Generator, n: int, phi: float) -> np.ndarray:
    x = np.zeros(n)
    x[0] = rng.standard_normal() / math.sqrt(1 - phi ** 2)
    for k in range(1, n):
        x[k] = phi * x[k - 1] + rng.standard_normal()
    return x


def test_cross_correlation_of_autocorrelated_series_keeps_its_level() -> None:
    """Independent AR(1) series (phi = 0.9): Bartlett's variance keeps the false-alarm rate
    near the nominal 5 %, where the white-noise variance 1/n would reject most of the time."""
    rng = np.random.default_rng(1)
    n_rep, rej_bartlett, rej_naive = 200, 0, 0
    for _ in range(n_rep):
        a, b = _ar1(rng, 400, 0.9), _ar1(rng, 400, 0.9)
        r, _, p, n_eff = residuals.cross_correlation([a], [b], max_lag=0, acf_lags=60)
        rej_bartlett += p < 0.05
        rej_naive += 2.0 * stats.norm.sf(abs(r) * math.sqrt(400)) < 0.05
        assert n_eff < 100  # 400 (1 - phi^2) / (1 + phi^2) = 42 in theory
    assert rej_bartlett / n_rep <= 0.10, rej_bartlett / n_rep
    assert rej_naive / n_rep >= 0.3, rej_naive / n_rep


def test_residual_tests_name_what_the_rest_follows() -> None:
    rng = np.random.default_rng(2)
    z = [np.linspace(50.0, 90.0, 60) + rng.standard_normal(60) for _ in range(5)]
    res = [0.05 * (p - 70.0) + rng.standard_normal(60) for p in z]
    white, _, left = residuals.residual_tests([residuals.Group(
        {'heave': res}, {'z': z, 'u': [rng.standard_normal(60) for _ in range(5)]}, 1.0,
        white=True)])
    assert not white
    assert any(t.startswith('heave: grows with depth') for t in left), left
    clean = [rng.standard_normal(60) for _ in range(5)]
    white, _, left = residuals.residual_tests([residuals.Group(
        {'heave': clean}, {'z': z}, 1.0, white=True)])
    assert white, left



def test_predictive_gain_hand_worked() -> None:
    """Losses a = (3, 1 | 2, 2), b = (1, 1 | 1, 1): d = (2, 0 | 1, 1), mean 1, deviations
    (1, -1 | 0, 0); gamma_0 = 2 / 4 = 0.5, gamma_1 (within pieces) = -1 / 4; Newey-West with
    one lag: 0.5 + 2 (1/2) (-0.25) = 0.25; t = 1 / sqrt(0.25 / 4) = 4; n_eff = 4 * 0.5 / 0.25."""
    t, p, n_eff = residuals.predictive_gain([np.array([3.0, 1.0]), np.array([2.0, 2.0])],
                                            [np.ones(2), np.ones(2)], lags=1)
    assert t == pytest.approx(4.0, rel=1e-12)
    assert p == pytest.approx(float(stats.norm.sf(4.0)), rel=1e-12)
    assert n_eff == pytest.approx(8.0, rel=1e-12)


def test_predictive_gain_level_and_power_on_autocorrelated_losses() -> None:
    """Loss differentials AR(1) (phi = 0.9) in 4 pieces of 150 samples: with no gain the
    one-sided 5 % test rejects near its level (the naive i.i.d. standard error would reject
    far more often); a mean gain of 1.5 innovation sd, 3.7 standard errors of the mean
    (long-run sd 1 / (1 - phi) = 10 over sqrt(600)), is found nearly always."""
    rng = np.random.default_rng(3)
    n_rep, rejected, naive, found = 200, 0, 0, 0
    for _ in range(n_rep):
        d = [_ar1(rng, 150, 0.9) for _ in range(4)]
        _, p, _ = residuals.predictive_gain(d, [np.zeros(150)] * 4, lags=75)
        rejected += p < 0.05
        allv = np.concatenate(d)
        naive += stats.norm.sf(allv.mean() / (allv.std(ddof=1) / math.sqrt(allv.size))) < 0.05
        _, p, _ = residuals.predictive_gain([x + 1.5 for x in d], [np.zeros(150)] * 4, lags=75)
        found += p < 0.05
    assert rejected / n_rep <= 0.10, rejected / n_rep
    assert naive / n_rep >= 0.2, naive / n_rep
    assert found / n_rep >= 0.9, found / n_rep

# -- plausible ranges -------------------------------------------------------------------------
def test_every_parameter_has_a_plausible_range_with_a_source(vehicle) -> None:  # type: ignore
    for effect in CATALOGUE.values():
        for p in effect.parameters(vehicle):
            plo, phi = p.plausible_range
            assert p.plausible is not None and p.source, (effect.name, p.name)
            assert plo < phi and p.lo < phi and plo < p.hi, (effect.name, p.name)
            # a fit can run past the range at one end at least (else no fit is implausible)
            assert p.lo < plo or phi < p.hi, (effect.name, p.name)
            assert plo <= p.absent <= phi, (effect.name, p.name)


def test_crossflow_drag_is_dissipative_and_bounded_by_a_hull_cd_of_1_2(vehicle) -> None:  # type: ignore
    """A18M: L = 4.6 m, D = 0.477 m, rho = 1025 kg/m^3: 1/2 rho D L = 1124.5 kg/m;
    Cd = 1.2 gives 1349.4 kg/m, and over the length (L^4 / 32) 4104.8 kg m^2."""
    params = {p.name: p for p in CATALOGUE['crossflow_drag'].parameters(vehicle)}
    assert params['Zww'].plausible_range == pytest.approx((-1349.4, 0.0), abs=0.1)
    assert params['Mqq'].plausible_range == pytest.approx((-4104.8, 0.0), abs=0.5)
    assert params['Zww'].is_plausible(-800.0)
    assert not params['Zww'].is_plausible(150.0)      # anti-damping
    assert not params['Zww'].is_plausible(-6000.0)    # Cd 5.3
    assert params['Zww'].is_plausible(0.0)            # absent: no effect, not an excess


def test_buoyancy_and_lag_ranges(vehicle) -> None:  # type: ignore
    (db,) = CATALOGUE['buoyancy_offset'].parameters(vehicle)
    w = 620.0 * 9.81
    assert db.plausible_range == pytest.approx((-0.02 * w, 0.02 * w))
    (lag,) = CATALOGUE['actuator_lag'].parameters(vehicle)
    assert lag.plausible_range[0] == 0.0 and not lag.is_plausible(-0.1)
    assert not Parameter('x', 'm', -1.0, 1.0, 0.0, 0.1, (-0.5, 0.5)).is_plausible(0.5)


# -- the model's own coefficients -------------------------------------------------------------
@pytest.mark.parametrize('name,changes,values', [
    ('coefficients', {'CZuw': 1.3, 'CMuq': 1.3, 'CZbar': 0.8, 'Ksh': 1.3, 'CZ0': 2.0,
                      'CM0': 2.0},
     {'CZuw': 1.3, 'CMuw': 1.0, 'CZuq': 1.0, 'CMuq': 1.3, 'CZbar': 0.8, 'CMbar': 1.0,
      'Ksh': 1.3, 'CZ0': 2.0, 'CM0': 2.0}),
    ('plane_effectiveness', {'CZbar': 0.7, 'CMbar': 0.7}, {'gain': 0.7}),
])
def test_coefficient_effects_reproduce_a_changed_vehicle_file(vehicle, name: str, changes,  # type: ignore
                                                              values) -> None:
    """The simulator flying a vehicle file with changed coefficients (its own physics) and the
    catalogue's wrench terms on the nominal file must give the same free run."""
    plant = vehicle.replace(**{k: f * getattr(vehicle, k) for k, f in changes.items()})
    log = simulate(plant, None, SHORT, noise=np.zeros(12))
    pr = Problem(vehicle, log.gap_logs(), window=60.0)
    es = EffectSet([name], vehicle)
    true = es.perturbation(np.array([values[p.name] for _, p in es.params]))
    out, ref = pr.free_run([Perturbation.nominal(vehicle), true], pr.select(None))
    rms = np.sqrt(np.mean((out - ref[None])[:, :, CH_INDEX] ** 2, axis=1))
    assert rms[1, 0] < 0.03 and rms[1, 0] < 0.1 * rms[0, 0], rms[:, 0]
    assert rms[1, 1] < 6e-4, rms[:, 1]
    if 'Ksh' in changes:
        assert rms[1, 2] < 0.1 * rms[0, 2], rms[:, 2]  # surge speed


# -- wording ----------------------------------------------------------------------------------
def test_wording_of_a_current_and_of_coefficients(vehicle) -> None:  # type: ignore
    es = EffectSet(['current', 'coefficients'], vehicle)
    n = len(es.params)
    values = np.array([0.3 * math.cos(math.radians(30)), 0.3 * math.sin(math.radians(30)),
                       0.0, 1.3, 1.0, 1.0, 0.8, 1.0, 1.0, 1.0, 1.0, 1.0])
    lo, hi = values - 0.02, values + 0.02
    active = np.array([True, True, False, True, False, False, True, False, False, False,
                       False, False])
    text = describe(FitResult(es, values, active, lo, hi, 'free_run'))
    assert n == 12
    assert '0.30 m/s towards 030 deg' in text
    assert "the model's CZuw is 30 % low" in text
    assert "the model's CMuq is 20 % high" in text
    assert text.endswith('after re-fitting CZuw, CMuq')
