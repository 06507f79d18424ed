"""Regressor columns from the model's own hydrodynamic terms.

The hydrodynamic wrench of the model (:func:`auv_sim.model.wrenches`, body FRD about the body
origin) is linear in the vehicle file's coefficients: component ``HYDRO_AXIS[k]`` gets
``coefficient_k * basis_k(nu_r)`` for every term ``k`` of :data:`auv_sim.model.HYDRO_TERMS`
(:func:`auv_sim.model.hydro_basis`: the report's section 2 terms, ``-qs C_XF(Re) u|u|``,
``qs u w``, ``qs L u q``, ... and the quadratic cross-flow drag ``w|w|``, ``q|q|``, ...).
So the regressor column of a coefficient is the model's term for a unit coefficient, and the
terms of an equation's component that are not fitted are known (the base vehicle's value
times the same column). Velocities are through the water; with no current (the
identification's assumption) they are the logged velocities over ground.
"""
from __future__ import annotations

import numpy as np

from auv_ident.identify.equations import Equation
from auv_ident.identify.records import ForceRecord
from auv_sim.model import HYDRO_AXIS, HYDRO_TERMS, hydro_basis_series
from auv_sim.params import VehicleParams


def component_terms(equation: Equation) -> tuple[str, ...]:
    """Names of the model's hydrodynamic terms on the equation's wrench component (in
    :data:`auv_sim.model.HYDRO_TERMS` order)."""
    return tuple(HYDRO_TERMS[k] for k in _term_indices(equation))


def _term_indices(equation: Equation) -> np.ndarray:
    """Indices into :data:`auv_sim.model.HYDRO_TERMS` of the terms on the equation's
    component."""
    return np.flatnonzero(np.asarray(HYDRO_AXIS) == equation.axis)


def regressor_columns(equation: Equation, nu: np.ndarray, params: VehicleParams
                      ) -> dict[str, np.ndarray]:
    """Column of every model term on the equation's component (:func:`component_terms`)
    for velocities ``nu`` (N, 6) body FRD [m/s, rad/s]; columns in N (forces) or N m
    (moments) per unit coefficient, from :func:`auv_sim.model.hydro_basis_series`."""
    terms = _term_indices(equation)
    basis = hydro_basis_series(np.ascontiguousarray(nu, dtype=np.float64), params.as_array(),
                               terms)
    return {HYDRO_TERMS[k]: basis[:, j] for j, k in enumerate(terms)}


def _stepped_columns(equation: Equation, nu: np.ndarray, channel: int, step: float,
                     params: VehicleParams) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """:func:`regressor_columns` at ``nu`` with ``+step`` and with ``-step`` on one channel
    (0..5: u, v, w [m/s], p, q, r [rad/s]), for central differences."""
    up, dn = nu.copy(), nu.copy()
    up[:, channel] += step
    dn[:, channel] -= step
    return regressor_columns(equation, up, params), regressor_columns(equation, dn, params)


def filtered(columns: np.ndarray, kernel: np.ndarray | None) -> np.ndarray:
    """Columns (N, k) filtered by the symmetric FIR ``kernel`` (same length; ends unused)."""
    if kernel is None:
        return columns
    out = np.empty_like(columns)
    for j in range(columns.shape[1]):
        out[:, j] = np.convolve(columns[:, j], kernel, mode='same')
    return out


def unbiased_columns(equation: Equation, rec: ForceRecord, base: VehicleParams
                     ) -> dict[str, np.ndarray]:
    """Regressor columns of ``rec``; for a record with a noise model (velocities with white
    noise of std ``sigma_c``), less their second-order mean shift from that noise,
    ``1/2 sum_c sigma_c^2 d^2 col / d nu_c^2`` (``(f(nu + s) + f(nu - s) - 2 f(nu)) / 2`` with
    ``s = sigma_c``), the errors-in-variables bias of a nonlinear column such as ``u|u|``."""
    cols = regressor_columns(equation, rec.nu, base)
    if rec.noise is None:
        return cols
    out = {k: v.copy() for k, v in cols.items()}
    for c in range(6):
        s = float(rec.noise.sigma[6 + c])
        if s <= 0.0:
            continue
        cu, cd = _stepped_columns(equation, rec.nu, c, s, base)
        for k in out:
            out[k] -= 0.5 * (cu[k] + cd[k] - 2.0 * cols[k])
    return out


def gradient_differences(equation: Equation, nu: np.ndarray, base: VehicleParams
                         ) -> tuple[np.ndarray, np.ndarray]:
    """The central differences :func:`hydro_gradient` combines, which do not depend on the
    coefficients: per term of the equation's component (:func:`component_terms` order) and
    velocity channel ``c`` (0..5: u, v, w [m/s], p, q, r [rad/s]) ``col(nu + h_c) - col(nu -
    h_c)`` at every row of ``nu`` (N, 6), shape (k, 6, N), and the steps ``h_c`` (6,)."""
    terms = component_terms(equation)
    diffs = np.empty((len(terms), 6, len(nu)))
    steps = np.empty(6)
    for c in range(6):
        h = 1e-6 * (1.0 + float(np.max(np.abs(nu[:, c]))))
        cu, cd = _stepped_columns(equation, nu, c, h, base)
        for j, k in enumerate(terms):
            diffs[j, c] = cu[k] - cd[k]
        steps[c] = h
    return diffs, steps


def hydro_gradient(equation: Equation, nu: np.ndarray, coefficients: dict[str, float],
                   base: VehicleParams,
                   differences: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """``d/d nu`` of the equation's hydrodynamic component ``sum_k c_k col_k`` for the
    coefficients ``coefficients`` (name -> value; names that are not hydrodynamic terms, such
    as a fitted plane coefficient, are left out) at every row of ``nu`` (N, 6) [N or N m per
    m/s or rad/s], central differences; ``differences``: :func:`gradient_differences` of
    ``nu``, when already computed."""
    diffs, steps = differences if differences is not None else gradient_differences(
        equation, nu, base)
    index = {k: j for j, k in enumerate(component_terms(equation))}
    out = np.zeros((len(nu), 6))
    for c in range(6):
        out[:, c] = sum(v * diffs[index[k], c] for k, v in coefficients.items()
                        if k in index) / (2.0 * float(steps[c]))
    return out
