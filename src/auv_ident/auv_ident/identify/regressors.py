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
from numba import njit

from auv_ident.identify.equations import Equation
from auv_ident.identify.records import ForceRecord
from auv_sim.model import HYDRO_AXIS, HYDRO_TERMS, hydro_basis, hydro_basis_series
from auv_sim.params import VehicleParams


def component_terms(equation: Equation) -> tuple[str, ...]:
    """Names of the model's hydrodynamic terms on the equation's wrench component (in
    :data:`auv_sim.model.HYDRO_TERMS` order)."""
    return tuple(HYDRO_TERMS[k] for k in _term_indices(equation))


def _term_indices(equation: Equation) -> np.ndarray:
    """Indices into :data:`auv_sim.model.HYDRO_TERMS` of the terms on the equation's
    component."""
    return np.flatnonzero(np.asarray(HYDRO_AXIS) == equation.axis)


def as_slice(idx: np.ndarray) -> slice | np.ndarray:
    """Sorted indices ``idx`` as a slice when they are contiguous (selecting by it takes no
    copy), else as they are."""
    if len(idx) and int(idx[-1]) - int(idx[0]) + 1 == len(idx):
        return slice(int(idx[0]), int(idx[-1]) + 1)
    return idx


def term_selection(equation: Equation) -> slice | np.ndarray:
    """The equation's terms among the columns of :func:`basis_columns` (:func:`as_slice`)."""
    return as_slice(_term_indices(equation))


def basis_columns(nu: np.ndarray, params: VehicleParams) -> np.ndarray:
    """Columns of every model term (:data:`auv_sim.model.HYDRO_TERMS` order, (N, T)) for
    velocities ``nu`` (N, 6) body FRD [m/s, rad/s]; in N (forces) or N m (moments) per unit
    coefficient, from :func:`auv_sim.model.hydro_basis_series`."""
    basis: np.ndarray = hydro_basis_series(np.ascontiguousarray(nu, dtype=np.float64),
                                           params.as_array(), np.arange(len(HYDRO_TERMS)))
    return basis


def regressor_columns(equation: Equation, nu: np.ndarray, params: VehicleParams
                      ) -> dict[str, np.ndarray]:
    """Column of every model term on the equation's component (:func:`component_terms`)
    for velocities ``nu`` (N, 6) body FRD [m/s, rad/s]; columns in N (forces) or N m
    (moments) per unit coefficient, from :func:`auv_sim.model.hydro_basis_series`."""
    terms = _term_indices(equation)
    basis = hydro_basis_series(np.ascontiguousarray(nu, dtype=np.float64), params.as_array(),
                               terms)
    return {HYDRO_TERMS[k]: basis[:, j] for j, k in enumerate(terms)}


def filtered(columns: np.ndarray, kernel: np.ndarray | None) -> np.ndarray:
    """Columns (N, k) filtered by the symmetric FIR ``kernel`` (same length; ends unused)."""
    if kernel is None:
        return columns
    out = np.empty_like(columns)
    for j in range(columns.shape[1]):
        out[:, j] = np.convolve(columns[:, j], kernel, mode='same')
    return out


def unbiased_basis(rec: ForceRecord, base: VehicleParams) -> np.ndarray:
    """Columns of every model term (:func:`basis_columns`, (N, T)) of ``rec``; for a record
    with a noise model (velocities with white noise of std ``sigma_c``), less their
    second-order mean shift from that noise, ``1/2 sum_c sigma_c^2 d^2 col / d nu_c^2``
    (``(f(nu + s) + f(nu - s) - 2 f(nu)) / 2`` with ``s = sigma_c``), the errors-in-variables
    bias of a nonlinear column such as ``u|u|``. Computed for all terms at once: every
    equation takes its own (:func:`term_selection`)."""
    if rec.noise is None:
        return basis_columns(rec.nu, base)
    out: np.ndarray = _unbiased_kernel(np.ascontiguousarray(rec.nu, dtype=np.float64),
                                       base.as_array(),
                                       np.asarray(rec.noise.sigma[6:12], dtype=np.float64))
    return out


#: Number of model terms (columns of :func:`basis_columns`).
N_TERMS = len(HYDRO_TERMS)


@njit(cache=True)
def _unbiased_kernel(NU, P, sigma):  # type: ignore[no-untyped-def]
    """:func:`unbiased_basis` row by row: the basis of :func:`auv_sim.model.hydro_basis` at
    ``NU`` (N, 6) [m/s, rad/s] less ``(f(nu + s) + f(nu - s) - 2 f(nu)) / 2`` for each
    velocity channel with noise std ``s = sigma[c] > 0`` (6,), channels in order."""
    n = NU.shape[0]
    out = np.empty((n, N_TERMS))
    v = np.empty(6)
    for i in range(n):
        b = hydro_basis(NU[i, 0], NU[i, 1], NU[i, 2], NU[i, 3], NU[i, 4], NU[i, 5], P)
        for j in range(N_TERMS):
            out[i, j] = b[j]
        for c in range(6):
            s = sigma[c]
            if s <= 0.0:
                continue
            for a in range(6):
                v[a] = NU[i, a]
            v[c] = NU[i, c] + s
            bu = hydro_basis(v[0], v[1], v[2], v[3], v[4], v[5], P)
            v[c] = NU[i, c] - s
            bd = hydro_basis(v[0], v[1], v[2], v[3], v[4], v[5], P)
            for j in range(N_TERMS):
                out[i, j] -= 0.5 * (bu[j] + bd[j] - 2.0 * b[j])
    return out


def unbiased_columns(equation: Equation, rec: ForceRecord, base: VehicleParams,
                     basis: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """:func:`unbiased_basis` of ``rec`` for the terms of the equation's component
    (:func:`component_terms`: name -> column (N,) [N or N m per unit coefficient]);
    ``basis``: that of ``rec``, when already computed."""
    full = unbiased_basis(rec, base) if basis is None else basis
    return {HYDRO_TERMS[k]: full[:, k] for k in _term_indices(equation)}


def basis_differences(nu: np.ndarray, base: VehicleParams) -> tuple[np.ndarray, np.ndarray]:
    """The central differences :func:`hydro_gradient` combines, for every model term: per
    term (:data:`auv_sim.model.HYDRO_TERMS` order) and velocity channel ``c`` (0..5: u, v, w
    [m/s], p, q, r [rad/s]) ``col(nu + h_c) - col(nu - h_c)`` at every row of ``nu`` (N, 6),
    shape (T, 6, N), and the steps ``h_c = 1e-6 (1 + max |nu_c|)`` (6,) [m/s, rad/s]."""
    steps = np.array([1e-6 * (1.0 + float(np.max(np.abs(nu[:, c])))) for c in range(6)])
    diffs: np.ndarray = _differences_kernel(np.ascontiguousarray(nu, dtype=np.float64),
                                            base.as_array(), steps)
    return diffs, steps


@njit(cache=True)
def _differences_kernel(NU, P, steps):  # type: ignore[no-untyped-def]
    """:func:`basis_differences` row by row: ``f(nu + h_c) - f(nu - h_c)`` (T, 6, N) of the
    basis of :func:`auv_sim.model.hydro_basis` at ``NU`` (N, 6), steps ``steps`` (6,)."""
    n = NU.shape[0]
    diffs = np.empty((N_TERMS, 6, n))
    v = np.empty(6)
    for i in range(n):
        for c in range(6):
            for a in range(6):
                v[a] = NU[i, a]
            v[c] = NU[i, c] + steps[c]
            bu = hydro_basis(v[0], v[1], v[2], v[3], v[4], v[5], P)
            v[c] = NU[i, c] - steps[c]
            bd = hydro_basis(v[0], v[1], v[2], v[3], v[4], v[5], P)
            for j in range(N_TERMS):
                diffs[j, c, i] = bu[j] - bd[j]
    return diffs


def gradient_differences(equation: Equation, nu: np.ndarray, base: VehicleParams,
                         differences: tuple[np.ndarray, np.ndarray] | None = None
                         ) -> tuple[np.ndarray, np.ndarray]:
    """The central differences :func:`hydro_gradient` combines, which do not depend on the
    coefficients: per term of the equation's component (:func:`component_terms` order) and
    velocity channel ``c`` (0..5: u, v, w [m/s], p, q, r [rad/s]) ``col(nu + h_c) - col(nu -
    h_c)`` at every row of ``nu`` (N, 6), shape (k, 6, N), and the steps ``h_c`` (6,);
    ``differences``: :func:`basis_differences` of ``nu``, when already computed (every
    equation takes its terms from it)."""
    diffs, steps = basis_differences(nu, base) if differences is None else differences
    return diffs[term_selection(equation)], steps


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
    acc = np.zeros((6, len(nu)))   # all channels at once, the terms summed in order
    for k, v in coefficients.items():
        if k in index:
            acc += v * diffs[index[k]]
    out: np.ndarray = (acc / (2.0 * np.asarray(steps, float))[:, None]).T
    return out
