"""`auv ident --fit-planes`: the dive plane's CZbar and CMbar fitted from forces from motion.

Oracle: a true vehicle known by construction (the A18M with CZuw x1.2, CMuw x1.25, CZuq x1.2,
CMuq x0.75, CMbar x0.85), its surge and pitch missions simulated and logged with
navigation-grade sensor noise and no force topic, identified from the A18M file. Without the
plane fitted, the pitch fit takes the control moment of the file's CMbar (18 % above the
truth's) for granted and absorbs the error into CMuw and CMuq, with intervals that miss the
truth; with it, every fitted coefficient's 95 % interval holds the truth.
"""
from __future__ import annotations

import pathlib

import numpy as np
import pytest
from conftest import A18M, load_bench

from auv_ident.errors import IdentificationError
from auv_ident.identify import EQUATIONS, ForceRecord, identify
from auv_ident.identify.regression import build_system
from auv_sim.params import load_vehicle

PITCH_AND_HEAVE = ('CZuw', 'CZuq', 'CMuw', 'CMuq')


def test_fitting_the_plane_removes_the_pitch_fits_bias(tmp_path: pathlib.Path) -> None:
    bench = load_bench('robustness')
    design = load_vehicle(A18M)
    truth = bench.ident_truth(design)
    _, fixed = bench.identify_truth(truth, A18M, tmp_path / 'fixed', fit_planes=False)
    _, fitted = bench.identify_truth(truth, A18M, tmp_path / 'fitted')

    def error(report: dict[str, dict[str, float]], name: str) -> float:
        return abs(report[name]['value'] / truth.values[name] - 1.0)

    def inside(report: dict[str, dict[str, float]], name: str) -> bool:
        lo, hi = report[name]['ci95']
        return bool(lo <= truth.values[name] <= hi)

    # the plane fixed at the file's value: CMuw 15 % off, outside its interval
    assert 'CMbar' not in fixed
    assert error(fixed, 'CMuw') > 0.10 and not inside(fixed, 'CMuw')
    # fitted: the plane's moment within 5 %, and every coefficient's interval holds the truth
    assert set(fitted) >= {'CZbar', 'CMbar', *PITCH_AND_HEAVE}
    for name in ('CZbar', 'CMbar', *PITCH_AND_HEAVE):
        assert inside(fitted, name), (name, fitted[name], truth.values[name])
    for name in ('CMbar', 'CMuw', 'CMuq'):
        assert error(fitted, name) < 0.05, (name, fitted[name], truth.values[name])


def test_the_plane_is_fitted_only_where_it_can_be() -> None:
    base = load_vehicle(A18M)
    t = np.arange(200) * 0.02
    nu = np.zeros((200, 6))
    nu[:, 0] = 2.0
    record = ForceRecord('topic', t, nu, np.zeros((200, 6)))  # from the force topic
    with pytest.raises(IdentificationError, match=r"topic: fitting CMbar needs forces from "
                                                  r"motion"):
        build_system([record], EQUATIONS['pitch'], base, fit_plane=True)
    with pytest.raises(IdentificationError, match='fitting CZbar needs a non-zero CZbar'):
        build_system([record], EQUATIONS['heave'], base.replace(CZbar=0.0), fit_plane=True)
    # without the plane the same record is a valid (if unexcited) system
    assert build_system([record], EQUATIONS['pitch'], base).names == ('CMuw', 'CMuq')
    with pytest.raises(IdentificationError, match='bound given for unknown coefficient'):
        identify([record], base, bounds={'CMbar_typo': (-1.0, 0.0)}, fit_planes=True)


def test_an_added_mass_error_is_measured_as_munk_moment_on_cmuw(tmp_path: pathlib.Path) -> None:
    """The identification reconstructs forces with the file's added masses, so a vehicle
    whose heave added mass is 25 % lower gives a CMuw shifted by the Munk moment of the
    difference, as :func:`auv_depth_lqr.robustness.coriolis_shift` says (hand-worked there
    from Fossen's eq. 6.43): the Monte Carlo on the identification's intervals draws its
    plants so (``Distribution.apparent``). Measured: the identified CMuw is within 3 % of
    the truth's plus the shift (-0.40, 32 % of the truth's CMuw)."""
    from auv_depth_lqr.robustness import coriolis_shift

    bench = load_bench('robustness')
    design = load_vehicle(A18M)
    truth = bench.ident_truth(design)
    truth = truth.replace(Zwdot=0.75 * design.values['Zwdot'])
    _, fitted = bench.identify_truth(truth, A18M, tmp_path)
    shift = coriolis_shift(design, truth, 'CMuw')
    assert abs(shift) > 0.3 * abs(truth.values['CMuw'])
    expected = truth.values['CMuw'] + shift
    assert fitted['CMuw']['value'] == pytest.approx(expected, rel=0.03)
    assert abs(fitted['CMuw']['value'] - truth.values['CMuw']) > 0.8 * abs(shift)
