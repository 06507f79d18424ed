"""Fit the equations: solve, estimate the covariance, report intervals and statistics.

Per equation: the least-squares coefficients (:mod:`auv_ident.identify.regression`), their
covariance (:mod:`auv_ident.identify.covariance`), 95 % intervals, R^2, NRMSE = rms(residual) /
(max - min of the measured force), the condition number of the column-scaled regressor and
the coefficients' correlation matrix. Data that cannot identify a coefficient raise
:class:`~auv_ident.errors.NotIdentifiableError` naming it and the manoeuvre that would
excite it.

Assumed: no water current during the manoeuvres (the velocities over ground are the
velocities through the water), as in the report.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from auv_ident.errors import IdentificationError, NotIdentifiableError
from auv_ident.identify.covariance import ERROR_METHODS, coefficient_covariance
from auv_ident.identify.equations import EQUATIONS, EXCITATION, excitation_amplitude
from auv_ident.identify.records import ForceRecord
from auv_ident.identify.regression import (
    LinearSystem,
    build_system,
    check_identifiable,
    column_scale,
    conditioning,
    nelder_mead,
    solve,
)
from auv_ident.identify.results import (
    CoefficientEstimate,
    EquationFit,
    Identification,
    t_interval,
)
from auv_sim.params import VehicleParams


def fit_equation(system: LinearSystem, base: VehicleParams,
                 bounds: Mapping[str, tuple[float, float]] | None = None,
                 errors: str = 'hac', check: bool = True) -> EquationFit:
    """Solve one equation and compute its statistics (see the module docstring)."""
    if errors not in ERROR_METHODS:
        raise IdentificationError(f'unknown standard-error method {errors!r} '
                                  f'(known: {", ".join(ERROR_METHODS)})')
    if check:
        check_identifiable(system)
    theta, at_bound = solve(system, bounds)
    A = system.A
    n, p = A.shape
    resid = system.b - system.regressors @ theta
    fitted = system.measured - resid
    scale = column_scale(A)
    cv = coefficient_covariance(system, resid, theta, base, errors)
    cov = cv.scaled / np.outer(scale, scale)
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    d = np.sqrt(np.diag(cv.scaled))
    corr = cv.scaled / np.outer(d, d) if np.all(d > 0) else np.eye(p)
    cond, _ = conditioning(A)
    rng = float(np.ptp(system.measured)) if n else 0.0
    tss = float(np.sum((system.measured - system.measured.mean()) ** 2))
    rss = float(resid @ resid)
    rmse = math.sqrt(rss / n) if n else math.nan
    excited = exciting_records(system)
    coefs = tuple(
        CoefficientEstimate(name=name, value=float(theta[k]), std_error=float(se[k]),
                            ci95=t_interval(float(theta[k]), float(se[k]), cv.dof),
                            base=float(base.values[name]), at_bound=bool(at_bound[k]),
                            records=excited[name])
        for k, name in enumerate(system.names))
    return EquationFit(
        equation=system.equation, coefficients=coefs, fixed=dict(system.fixed),
        r2=1.0 - rss / tss if tss > 0 else math.nan,
        nrmse=rmse / rng if rng > 0 else math.nan, rmse=rmse, condition_number=cond,
        correlation=corr, n_samples=n, n_effective=cv.n_effective, hac_lags=cv.lags,
        errors=errors, t=system.t, measured=system.measured, fitted=fitted,
        record_index=system.record_index, record_names=system.record_names,
        covariance=cv.method, noise_ratio=cv.noise_ratio)


def exciting_records(system: LinearSystem) -> dict[str, tuple[str, ...]]:
    """For each coefficient, the records whose own data pass its excitation test."""
    out: dict[str, tuple[str, ...]] = {}
    for name in system.names:
        exc = EXCITATION[name]
        names = []
        for i, rname in enumerate(system.record_names):
            x = system.excitation[system.record_index == i, exc.variable]
            if len(x) and excitation_amplitude(name, x) >= exc.threshold:
                names.append(rname)
        out[name] = tuple(dict.fromkeys(names))
    return out


def identify(records: Sequence[ForceRecord], base: VehicleParams, *,
             equations: Sequence[str] | None = None, fit_offsets: bool = False,
             bounds: Mapping[str, tuple[float, float]] | None = None,
             errors: str = 'hac', partial: bool = False,
             fit_planes: bool = False) -> Identification:
    """Identify the coefficients of ``equations`` (default: all five) from ``records``.

    Every equation is fitted on all records pooled (each equation holds on every manoeuvre;
    the ones that do not excite a coefficient add little information, not bias).

    Args:
        records: force records (see :class:`ForceRecord`), one source for all.
        base: the vehicle the identified values replace (and the fixed CZ0/CM0 come from).
        equations: names from :data:`EQUATIONS`.
        fit_offsets: fit CZ0 and CM0 too (else fixed at the base values, as the report).
        fit_planes: fit the dive plane's CZbar and CMbar too (forces from motion; else fixed
            at the base values, as the report).
        bounds: name -> (lo, hi) for a bounded solve (e.g. :data:`SIGN_BOUNDS`).
        errors: standard-error method, one of :data:`ERROR_METHODS`.
        partial: an equation the data cannot identify is left out and said so in
            ``not_identifiable`` (which coefficient, why, what would fix it) instead of
            raising; it raises only when no equation is left.

    Raises:
        NotIdentifiableError: a coefficient lacks excitation or two cannot be separated
            (with ``partial``: every equation).
        IdentificationError: bad records, unknown equation or option.
    """
    if not records:
        raise IdentificationError('no data: give at least one record')
    sources = {r.source for r in records}
    if len(sources) != 1:
        raise IdentificationError(f'records mix force sources {sorted(sources)}; use one')
    names = list(EQUATIONS) if equations is None else list(dict.fromkeys(equations))
    for name in names:
        if name not in EQUATIONS:
            raise IdentificationError(f'unknown equation {name!r} (known: {list(EQUATIONS)})')
    for key in (bounds or {}):
        if not any(key in (*e.coefficients, e.offset, e.plane) for e in EQUATIONS.values()):
            raise IdentificationError(f'bound given for unknown coefficient {key!r}')
    fits: dict[str, EquationFit] = {}
    left_out: dict[str, str] = {}
    for name in names:
        system = build_system(records, EQUATIONS[name], base, fit_offsets, fit_planes)
        try:
            fits[name] = fit_equation(system, base, bounds, errors)
        except NotIdentifiableError as exc:
            if not partial:
                raise
            left_out[name] = str(exc)
    if not fits:
        raise NotIdentifiableError('no equation can be identified from these data: '
                                   + '; '.join(f'{k}: {v}' for k, v in left_out.items()))
    values = {c.name: c.value for f in fits.values() for c in f.coefficients}
    try:
        params = base.replace(**values)
    except ValueError as exc:
        raise IdentificationError(f'identified values are not a valid vehicle: {exc}') from None
    return Identification(fits=fits, base=base, params=params, source=sources.pop(),
                          errors=errors, fit_offsets=fit_offsets, bounds=dict(bounds or {}),
                          not_identifiable=left_out, fit_planes=fit_planes)



def compare_nelder_mead(records: Sequence[ForceRecord], result: Identification,
                        x0: Mapping[str, float] | None = None) -> dict[str, dict[str, Any]]:
    """Run the report's bounded Nelder-Mead on the same data as ``result`` and compare.

    For each equation: the least-squares and the Nelder-Mead coefficients, their largest
    relative difference and the two sums of squares. The search starts from ``x0`` (default:
    the base vehicle's values, as the report started from its prior values) and uses the
    bounds of ``result`` (unbounded coefficients get none).
    """
    out: dict[str, dict[str, Any]] = {}
    for name, fit in result.fits.items():
        system = build_system(records, fit.equation, result.base, result.fit_offsets,
                              result.fit_planes)
        lsq = np.array([c.value for c in fit.coefficients])
        start = [(x0 or {}).get(c, result.base.values[c]) for c in system.names]
        nm = nelder_mead(system, start, result.bounds)
        rel = np.abs(nm - lsq) / np.maximum(np.abs(lsq), 1e-12)
        out[name] = {'names': list(system.names), 'least_squares': lsq.tolist(),
                     'nelder_mead': nm.tolist(), 'max_relative_difference': float(rel.max()),
                     'sum_of_squares_least_squares': system.sum_of_squares(lsq),
                     'sum_of_squares_nelder_mead': system.sum_of_squares(nm)}
    return out
