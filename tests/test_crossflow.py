"""Quadratic cross-flow drag of the vehicle file (Prestero 2001): force law, Jacobians, file.

Oracles: the force law written out here by hand, ``Z = ... + Zww w|w| + Zqq q|q|``,
``M = ... + Mww w|w| + Mqq q|q|`` (and sway/yaw), with its derivative ``2 Zww |w|``; central
differences of the same kernel for the complex-step Jacobian at ``w = 0``, where ``|w|`` is
not analytic.
"""
from __future__ import annotations

import pathlib

import numpy as np
import pytest

from auv_sim.environment import Environment
from auv_sim.errors import ParameterError
from auv_sim.model import NX, wrenches
from auv_sim.params import OPTIONAL, VehicleParams, load_vehicle, parse_vehicle, vehicle_document

ROOT = pathlib.Path(__file__).resolve().parents[1]
_H = 1e-30


@pytest.fixture(scope='module')
def remus() -> VehicleParams:
    return load_vehicle(ROOT / 'config' / 'remus100.yaml')


def hydro(p: VehicleParams, x: np.ndarray, env: Environment | None = None) -> np.ndarray:
    """Hydrodynamic row of the model's wrench (body FRD) [N, N m] at state x."""
    env = env or Environment()
    out = np.zeros((4, 6), dtype=x.dtype)
    wrenches(0.0, x, p.as_array(), env.env_vector(), env.profile(), out)
    return out[0]


def state(u: float, v: float = 0.0, w: float = 0.0, q: float = 0.0, r: float = 0.0
          ) -> np.ndarray:
    x = np.zeros(NX)
    x[2], x[6], x[7], x[8], x[10], x[11] = 20.0, u, v, w, q, r
    return x


@pytest.mark.parametrize(('v', 'w', 'q', 'r'), [(0.1, -0.3, 0.2, -0.15),
                                                (-0.25, 0.4, -0.3, 0.1)])
def test_quadratic_terms_follow_prestero_law(remus: VehicleParams, v: float, w: float,
                                             q: float, r: float) -> None:
    """The file's terms minus the same vehicle without them is Prestero's quadratic law."""
    bare = remus.replace(**{k: 0.0 for k in OPTIONAL})
    diff = hydro(remus, state(1.5, v, w, q, r)) - hydro(bare, state(1.5, v, w, q, r))
    expected = [0.0,
                -1310.0 * v * abs(v) + 0.632 * r * abs(r),     # Yvv, Yrr (table B.1)
                -131.0 * w * abs(w) - 0.632 * q * abs(q),      # Zww, Zqq (table B.1)
                0.0,
                3.18 * w * abs(w) - 188.0 * q * abs(q),        # Mww, Mqq (table B.2)
                -3.18 * v * abs(v) - 94.0 * r * abs(r)]        # Nvv, Nrr (table B.2)
    np.testing.assert_allclose(diff, expected, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize('w0', [0.0, 0.2, -0.2])
def test_complex_step_jacobian_matches_central_differences(remus: VehicleParams,
                                                           w0: float) -> None:
    """d(wrench)/dw and d/dq by complex step equal central differences, also at w = q = 0
    (where w|w| has slope 0 and no second derivative)."""
    for index in (8, 10):
        x = state(1.5, w=w0, q=w0).astype(complex)
        x[index] += 1j * _H
        cs = hydro(remus, x).imag / _H
        h = 1e-6
        xp, xm = state(1.5, w=w0, q=w0), state(1.5, w=w0, q=w0)
        xp[index] += h
        xm[index] -= h
        fd = (hydro(remus, xp) - hydro(remus, xm)) / (2 * h)
        # central differences of w|w| at 0 carry an error Zww h (h = 1e-6): 1.3e-4 N
        np.testing.assert_allclose(cs, fd, rtol=1e-6, atol=2e-4)
    # the quadratic part's slope is 2 Zww |w| (Zuw part measured from the bare vehicle)
    bare = remus.replace(**{k: 0.0 for k in OPTIONAL})
    slopes = []
    for p in (remus, bare):
        x = state(1.5, w=w0).astype(complex)
        x[8] += 1j * _H
        slopes.append(hydro(p, x).imag / _H)
    assert slopes[0][2] - slopes[1][2] == pytest.approx(2 * -131.0 * abs(w0), abs=1e-9)
    assert slopes[0][4] - slopes[1][4] == pytest.approx(2 * 3.18 * abs(w0), abs=1e-9)
    # Prestero's Zuw u at w = 0 exactly (no step error): -28.6 kg/m x 1.5 m/s
    if w0 == 0.0:
        assert slopes[0][2] == pytest.approx(-28.6 * 1.5, rel=1e-12)


def test_environment_effect_adds_to_the_file(remus: VehicleParams) -> None:
    env = Environment(effects={'crossflow_drag': {'Zww': -50.0, 'Mqq': -20.0}})
    x = state(1.5, w=0.3, q=0.2)
    diff = hydro(remus, x, env) - hydro(remus, x)
    assert diff[2] == pytest.approx(-50.0 * 0.09, rel=1e-12)
    assert diff[4] == pytest.approx(-20.0 * 0.04, rel=1e-12)


def test_files_without_crossflow_have_none_and_bad_values_are_refused() -> None:
    a18m = load_vehicle(ROOT / 'config' / 'a18m.yaml')
    assert all(a18m.values[k] == 0.0 for k in OPTIONAL)
    doc = vehicle_document(a18m)
    doc['crossflow'] = {'Zww': {'value': 25.0, 'unit': 'kg/m'}}
    with pytest.raises(ParameterError, match=r'crossflow\.Zww = 25.0 must be <= 0'):
        parse_vehicle(doc)
    doc['crossflow'] = {'Mww': {'value': 1.0, 'unit': 'kg/m'}}
    with pytest.raises(ParameterError, match=r"crossflow\.Mww is in 'kg/m', expected 'kg'"):
        parse_vehicle(doc)
    doc['crossflow'] = {'Mqq': {'value': -3.0, 'unit': 'kg m^2'}}
    assert parse_vehicle(doc).Mqq == -3.0 and parse_vehicle(doc).Zww == 0.0
