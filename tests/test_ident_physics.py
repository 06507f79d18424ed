"""Identification that stays physical: the posterior of the priors and the data inside the
physical bounds, coefficients left at their priors when the data do not inform them, an
equation with R^2 < 0 not identified, priors from the file's sources, the record's name in
its sources.

Oracles: the scalar Gaussian posterior worked by hand; hand-built records whose forces come
from the model with known coefficients (some of a sign physics does not allow); source texts
whose widths follow from the table in :mod:`auv_ident.identify.priors`.
"""
from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest

from auv_ident.identify import EQUATIONS, ForceRecord, build_system, identify
from auv_ident.identify.fit import fit_equation
from auv_ident.identify.posterior import combine, interval
from auv_ident.identify.priors import prior, source_kind
from auv_sim.environment import Environment
from auv_sim.hull import crossflow_coefficients
from auv_sim.model import wrench_series
from auv_sim.params import VehicleParams, load_vehicle

ROOT = pathlib.Path(__file__).resolve().parents[1]
A18M = ROOT / 'config' / 'a18m.yaml'
DT = 0.02


@pytest.fixture(scope='module')
def base() -> VehicleParams:
    return load_vehicle(A18M)


def record(vehicle: VehicleParams, n: int = 12000, w_amp: float = 0.03, noise: float = 0.0,
           seed: int = 0, name: str = 'synthetic') -> ForceRecord:
    """Velocities with independent excitation; forces from the model's hydrodynamic row of
    ``vehicle`` (optionally with white noise [N, N m])."""
    t = DT * np.arange(n)
    nu = np.zeros((n, 6))
    nu[:, 0] = 2.0 + 0.6 * np.sin(2 * np.pi * t / 300.0)
    nu[:, 2] = w_amp * np.sin(2 * np.pi * t / 23.0) + 0.01
    nu[:, 4] = 0.02 * np.sin(2 * np.pi * t / 9.0)
    X = np.zeros((n, 15))
    X[:, 6:12] = nu
    env = Environment()
    tau = wrench_series(t, X, vehicle.as_array(), env.env_vector(), env.profile())[:, 0].copy()
    if noise:
        tau += noise * np.random.default_rng(seed).standard_normal(tau.shape)
    return ForceRecord(name, t, nu, tau)


def test_scalar_posterior_is_the_hand_worked_one() -> None:
    # data: estimate 2.0 with information 4 (sd 0.5); prior 1.0, sd 1: precision 5,
    # mean (4 * 2 + 1 * 1) / 5 = 1.8, sd sqrt(1/5)
    post = combine(np.array([2.0]), np.array([[4.0]]), np.array([1.0]), np.array([1.0]),
                   np.array([-np.inf]), np.array([np.inf]))
    assert post.theta[0] == pytest.approx(1.8, rel=1e-12)
    assert post.cov[0, 0] == pytest.approx(0.2, rel=1e-12)
    assert post.information[0] == pytest.approx(0.8, rel=1e-12)
    # the same with the bound theta <= 1.5: on it, and the interval truncated below it
    post = combine(np.array([2.0]), np.array([[4.0]]), np.array([1.0]), np.array([1.0]),
                   np.array([-np.inf]), np.array([1.5]))
    assert post.theta[0] == 1.5 and post.at_bound[0]
    # highest density: from the bound inwards, 95 % of N(1.8, 0.2) below 1.5 (by hand: the
    # mass below 1.5 is Phi(-0.3 / sqrt(0.2)) = Phi(-0.6708) = 0.2512; its lowest 5 % ends at
    # 1.8 + sqrt(0.2) Phi^-1(0.05 x 0.2512) = 1.8 - 0.4472 x 2.2397 = 0.7984)
    lo, hi = interval(1.5, float(post.unbounded[0]), math.sqrt(0.2), 100.0, -np.inf, 1.5, True)
    assert hi == 1.5 and lo == pytest.approx(0.7984, abs=2e-3)
    # far past the bound (50 sd): the truncated normal is an exponential tail of scale
    # sd^2 / 50 to first order in 1 / 50^2 (its 95 % within ln 20 = 2.996 scales), never of
    # zero width
    lo, hi = interval(0.0, 50.0, 1.0, 100.0, -np.inf, 0.0, True)
    assert hi == 0.0 and -lo == pytest.approx(math.log(20.0) / 50.0, rel=0.01)


def test_a_coefficient_of_an_impossible_sign_stops_on_its_bound(base: VehicleParams) -> None:
    # a plant with pitch anti-damping (CMuq = +0.3): the fit may not follow it
    plant = base.replace(CMuq=0.3)
    fit = identify([record(plant, noise=2.0)], base, equations=['pitch']).fits['pitch']
    c = {k.name: k for k in fit.coefficients}['CMuq']
    assert c.value == 0.0 and c.at_bound
    assert c.note.startswith('the data push CMuq past 0: the model\'s structure cannot express '
                             'what the vehicle does (see: the quadratic cross-flow terms')
    assert c.ci95[0] < c.ci95[1] == 0.0
    # unbounded (the former behaviour) it follows the data to the impossible sign
    free = identify([record(plant, noise=2.0)], base, equations=['pitch'], bounds={})
    assert free.coefficients['CMuq'].value == pytest.approx(0.3, rel=0.02)


def test_an_uninformed_coefficient_stays_at_its_prior(base: VehicleParams) -> None:
    # Zww fitted with the linear terms on a record whose w is 100 times too small to tell
    # w|w| from u w at this noise: left at the file's value with the prior's interval
    rec = record(base, w_amp=3e-4, noise=20.0, seed=4)
    system = build_system([rec], EQUATIONS['heave'], base, free=('Zww',))
    fit = fit_equation(system, base, check=False)
    z = {c.name: c for c in fit.coefficients}['Zww']
    pr = prior('Zww', base)
    assert z.at_prior and z.value == base.Zww == 0.0
    assert z.ci95 == pytest.approx((-1.96 * pr.sd, 1.96 * pr.sd), rel=1e-12)
    assert z.note.startswith('left at its prior (the file value)')
    assert {c.name: c for c in fit.coefficients}['CZuw'].informed > 0.99


def test_an_equation_with_negative_r2_is_not_identified(base: VehicleParams) -> None:
    # the measured heave force: +8 qs u w (a sign physics excludes) on a large offset; the
    # physical fit explains less than the mean: heave not identified, its values the base's
    plant = base.replace(CZuw=8.0, CZuq=0.0)
    rec = record(plant)
    tau = rec.tau.copy()
    tau[:, 2] += 400.0
    rec = ForceRecord('offset', rec.t, rec.nu, tau)
    result = identify([rec], base, equations=['heave', 'pitch'], partial=True)
    assert not result.fits['heave'].identified and result.fits['heave'].r2 < 0.0
    assert result.not_identifiable['heave'].startswith('R^2 = ')
    assert 'heave' not in {k for k, f in result.fits.items() if f.identified}
    assert result.params.CZuw == base.CZuw and result.params.CZuq == base.CZuq
    assert result.fits['pitch'].identified


def test_priors_follow_the_sources(base: VehicleParams) -> None:
    assert source_kind('identified from pitch (heave fit), forces reconstructed from the '
                       'logged motion, +-0.0123 (95 %)') == ('identified', 0.0123)
    v = base.replace(CZuw=-3.0, CMuq=-0.5, Zww=0.0)
    v = v.__class__(name=v.name, values=v.values, path=v.path, sources={
        **v.sources, 'CZuw': 'measured in a tow tank', 'CMuq': 'estimated: scaled',
        'CMuw': 'identified from a (pitch fit), forces, +-0.098 (95 %)',
        'Zww': 'Prestero 2001 table B.1'})
    assert prior('CZuw', v).sd == pytest.approx(0.3, rel=1e-12)        # 10 %
    assert prior('CMuq', v).sd == pytest.approx(0.5, rel=1e-12)        # 100 %
    assert prior('CMuw', v).sd == pytest.approx(0.05, rel=1e-12)       # 0.098 / 1.96
    # a quadratic term of value 0: no zero width, the strip theory of the file's hull
    strip = crossflow_coefficients(v.L_ref, v.diameter, v.rho)['Zww']
    assert prior('Zww', v).sd == pytest.approx(abs(strip), rel=1e-12) and strip < 0


def test_the_record_keeps_its_name_in_the_vehicle_sources(base: VehicleParams,
                                                          tmp_path: pathlib.Path) -> None:
    from auv_ident.motion import reconstruct
    from auv_ident.report import coefficient_sources
    from auv_sim.missions import load_mission, run_mission

    rec = run_mission(base, load_mission('pitch'))
    cmds = {}
    for j, ch in enumerate(('bar', 'helm', 'thrust')):
        change = np.flatnonzero(np.diff(rec.cmd[:, j], prepend=np.nan) != 0)
        cmds[ch] = (rec.t[change], rec.cmd[change, j])
    fr = reconstruct(rec.t, rec.x[:, :12], cmds, base, name='dive_0412')
    assert fr.name == 'dive_0412'
    result = identify([fr], base, equations=['pitch'])
    assert coefficient_sources(result)['CMuq'].startswith('identified from dive_0412 (pitch')
