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

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from auv_contract.blas import one_blas_thread
from auv_ident.errors import IdentificationError, NotIdentifiableError
from auv_ident.identify.covariance import (
    ERROR_METHODS,
    Covariance,
    coefficient_covariance,
    correlation_time,
)
from auv_ident.identify.equations import (
    AXES,
    EQUATIONS,
    EXCITATION,
    Equation,
    excitation_amplitude,
)
from auv_ident.identify.physics import at_bound_note, constraint
from auv_ident.identify.posterior import (
    RESIDUAL_FLOOR,
    Posterior,
    combine,
    information,
    interval,
)
from auv_ident.identify.priors import CROSSFLOW as QUADRATIC_TERMS
from auv_ident.identify.priors import Prior, priors
from auv_ident.identify.records import ForceRecord
from auv_ident.identify.regression import (
    LinearSystem,
    build_system,
    check_identifiable,
    conditioning,
    nelder_mead,
    solve,
)
from auv_ident.identify.regressors import component_terms
from auv_ident.identify.results import (
    CoefficientEstimate,
    EquationFit,
    Identification,
)
from auv_sim.params import VehicleParams


def fit_equation(system: LinearSystem, base: VehicleParams,
                 bounds: Mapping[str, tuple[float, float]] | None = None,
                 errors: str = 'hac', check: bool = True, use_priors: bool = True
                 ) -> EquationFit:
    """Solve one equation and compute its statistics (see the module docstring).

    ``bounds`` (name -> (lo, hi)) on top of the physical ones
    (:mod:`auv_ident.identify.physics`; ``None``: the physical ones alone, ``{}``: none);
    ``use_priors``: the posterior of the priors (:mod:`auv_ident.identify.priors`) and the
    data, else the data alone (priors of unbounded width in effect).
    """
    if errors not in ERROR_METHODS:
        raise IdentificationError(f'unknown standard-error method {errors!r} '
                                  f'(known: {", ".join(ERROR_METHODS)})')
    if check:
        check_identifiable(system)
    limits = _limits(system.names, base, bounds)
    pri = priors(system.names, base)
    post, cv, theta_d = _posterior(system, base, errors, pri, limits, use_priors)
    # coefficients the data do not inform stay at their prior: fixed there, the rest refitted
    weak = [k for k, n in enumerate(system.names)
            if use_priors and post.information[k] < UNINFORMED and len(system.names) > 1]
    if len(weak) == len(system.names):
        post = post._replace(theta=np.array([pri[n].mean for n in system.names]))
    elif weak:
        reduced = reduce_system(system, {system.names[k]: pri[system.names[k]].mean
                                         for k in weak})
        fit = fit_equation(reduced, base, bounds, errors, check=False, use_priors=use_priors)
        kept = {c.name: c for c in fit.coefficients}
        coefs = []
        for k, name in enumerate(system.names):
            if name in kept:
                coefs.append(kept[name])
                continue
            pr = pri[name]
            coefs.append(CoefficientEstimate(
                name=name, value=pr.mean, std_error=pr.sd,
                ci95=(pr.mean - 1.96 * pr.sd, pr.mean + 1.96 * pr.sd),
                base=float(base.values[name]), at_bound=False, records=(),
                prior_sd=pr.sd, informed=float(post.information[k]),
                note=(f'left at its prior (the file value): the data reduced its spread by '
                      f'{100 * (1 - math.sqrt(max(1 - post.information[k], 0.0))):.0f} % '
                      f'only; prior {pr.why}'),
                bounds=limits[name]))
        fixed = {k: v for k, v in fit.fixed.items() if k not in {c.name for c in coefs}}
        return dataclasses.replace(fit, coefficients=tuple(coefs), fixed=fixed,
                                   data_only={**fit.data_only,
                                              **{system.names[k]: float(theta_d[k])
                                                 for k in weak}})
    theta = post.theta
    A = system.A
    n, _p = A.shape
    resid = system.b - system.regressors @ theta
    fitted = system.measured - resid
    cov = post.cov
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    se = np.maximum(se, 1e-12 * np.maximum(np.abs(theta), 1e-300))
    corr = cov / np.outer(se, se)
    cond, _ = conditioning(A)
    rng = float(np.ptp(system.measured)) if n else 0.0
    tss = float(np.sum((system.measured - system.measured.mean()) ** 2))
    rss = float(resid @ resid)
    rmse = math.sqrt(rss / n) if n else math.nan
    excited = exciting_records(system)
    coefs = []
    for k, name in enumerate(system.names):
        lo, hi = limits[name]
        ci = interval(float(theta[k]), float(post.unbounded[k]), float(se[k]), cv.dof, lo, hi,
                      bool(post.at_bound[k]))
        note = at_bound_note(name, float(theta[k]), constraint(name, base)) \
            if post.at_bound[k] else ''
        if k in weak:
            note = (f'left at its prior (the file value): the data reduced its spread by '
                    f'{100 * (1 - math.sqrt(max(1 - post.information[k], 0.0))):.0f} % only; '
                    f'prior {pri[name].why}')
            ci = (theta[k] - 1.96 * se[k], theta[k] + 1.96 * se[k])
        coefs.append(CoefficientEstimate(
            name=name, value=float(theta[k]), std_error=float(se[k]), ci95=ci,
            base=float(base.values[name]), at_bound=bool(post.at_bound[k]),
            records=excited.get(name, ()), prior_sd=pri[name].sd if use_priors else math.inf,
            informed=float(post.information[k]), note=note, bounds=(lo, hi)))
    r2 = 1.0 - rss / tss if tss > 0 else math.nan
    identified, why = True, ''
    if math.isfinite(r2) and r2 < 0.0:
        identified = False
        why = (f'R^2 = {r2:.3g} < 0: the fitted {system.equation.name} model explains less of '
               f'the measured {AXES[system.equation.axis]} than its mean does; its '
               'coefficients stay at the base file\'s values (the model\'s structure cannot '
               'express these data: an unmodelled effect, a current, derivatives too poor '
               'at this log rate)')
    return EquationFit(
        equation=system.equation, coefficients=tuple(coefs), fixed=dict(system.fixed),
        r2=r2, nrmse=rmse / rng if rng > 0 else math.nan, rmse=rmse, condition_number=cond,
        correlation=corr, n_samples=n, n_effective=cv.n_effective, hac_lags=cv.lags,
        errors=errors, t=system.t, measured=system.measured, fitted=fitted,
        record_index=system.record_index, record_names=system.record_names,
        covariance=cv.method, noise_ratio=cv.noise_ratio,
        data_only={nm: float(v) for nm, v in zip(system.names, theta_d)},
        identified=identified, why=why)


#: A coefficient whose data share of the posterior precision is below this is left at its
#: prior (its spread reduced by less than about 10 %).
UNINFORMED = 0.2


def _limits(names: Sequence[str], base: VehicleParams,
            bounds: Mapping[str, tuple[float, float]] | None) -> dict[str, tuple[float, float]]:
    """Physical bounds of ``names`` with ``bounds`` on top (``{}``: no bounds at all)."""
    if bounds is not None and len(bounds) == 0:
        return {n: (-math.inf, math.inf) for n in names}
    out = {n: (constraint(n, base).lo, constraint(n, base).hi) for n in names}
    for n, (lo, hi) in (bounds or {}).items():
        if n in out:
            out[n] = (max(out[n][0], lo), min(out[n][1], hi))
    return out


def _posterior(system: LinearSystem, base: VehicleParams, errors: str,
               pri: Mapping[str, Prior], limits: Mapping[str, tuple[float, float]],
               use_priors: bool) -> tuple[Posterior, Covariance, np.ndarray]:
    """The bounded posterior of ``system`` (:mod:`auv_ident.identify.posterior`) in the
    coefficients' own units, the data's covariance it used, and the data-only estimate.
    The data's information is the sandwich of their own estimate (the meat at its residual):
    how precisely the data fix the coefficients; where they push one past its bound, the
    bound holds it and the note and the equation's R^2 say what that means."""
    theta_d, _ = solve(system)
    scale = system.scale
    names = system.names
    mean = np.array([pri[n].mean for n in names]) * scale
    sd = np.array([pri[n].sd if use_priors else math.inf for n in names]) * scale
    sd = np.where(np.isfinite(sd), sd, 1e150 * np.maximum(scale, 1.0))
    lo = np.array([limits[n][0] for n in names]) * scale
    hi = np.array([limits[n][1] for n in names]) * scale
    floor = (RESIDUAL_FLOOR * math.sqrt(float(np.mean(system.measured ** 2)) + 1e-300)) ** 2
    As = system.A / scale
    resid = system.b - system.regressors @ theta_d
    cv = coefficient_covariance(system, resid, theta_d, base, errors)
    info = information(cv.bread, cv.meat, floor * (As.T @ As))
    post = combine(theta_d * scale, info, mean, sd, lo, hi)
    return Posterior(theta=post.theta / scale, cov=post.cov / np.outer(scale, scale),
                     unbounded=post.unbounded / scale, at_bound=post.at_bound,
                     information=post.information), cv, theta_d


def reduce_system(system: LinearSystem, fixed: Mapping[str, float]) -> LinearSystem:
    """``system`` with the coefficients ``fixed`` (name -> value) moved to ``b``."""
    keep = [k for k, n in enumerate(system.names) if n not in fixed]
    b = system.b.copy()
    for n, v in fixed.items():
        b -= v * system.regressors[:, system.names.index(n)]
    return dataclasses.replace(
        system, names=tuple(system.names[k] for k in keep), A=system.A[:, keep],
        regressors=system.regressors[:, keep], b=b, fixed={**system.fixed, **fixed},
        core=tuple(n for n in system.core if n not in fixed))


def exciting_records(system: LinearSystem) -> dict[str, tuple[str, ...]]:
    """For each coefficient, the records whose own data pass its excitation test."""
    out: dict[str, tuple[str, ...]] = {}
    rows = [system.record_index == i for i in range(len(system.record_names))]
    for name in system.names:
        exc = EXCITATION[name]
        names = []
        for i, rname in enumerate(system.record_names):
            x = system.excitation[rows[i], exc.variable]
            if len(x) and excitation_amplitude(name, x) >= exc.threshold:
                names.append(rname)
        out[name] = tuple(dict.fromkeys(names))
    return out


@one_blas_thread
def identify(records: Sequence[ForceRecord], base: VehicleParams, *,
             equations: Sequence[str] | None = None, fit_offsets: bool = False,
             bounds: Mapping[str, tuple[float, float]] | None = None,
             errors: str = 'hac', partial: bool = False,
             fit_planes: bool = False, use_priors: bool = True,
             structures: bool = True,
             use: Sequence[np.ndarray | None] | None = None) -> Identification:
    """Identify the coefficients of ``equations`` (default: all five) from ``records``.

    Every equation is fitted on all records pooled (each equation holds on every manoeuvre;
    the ones that do not excite a coefficient add little information, not bias), as the
    posterior of the priors and the data inside the physical bounds
    (:mod:`auv_ident.identify.posterior`), with the structure of its quadratic cross-flow term
    chosen by held-out prediction (:func:`choose_structure`).

    Parameters
    ----------
    records
        force records (see :class:`ForceRecord`), one source for all.
    base
        the vehicle the identified values replace (and the fixed CZ0/CM0 come from).
    equations
        names from :data:`EQUATIONS`.
    fit_offsets
        fit CZ0 and CM0 too (else fixed at the base values, as the report).
    fit_planes
        fit the dive plane's CZbar and CMbar too (forces from motion; else fixed
        at the base values, as the report).
    bounds
        name -> (lo, hi) on top of the physical bounds (``{}``: no bounds at all).
    errors
        standard-error method, one of :data:`ERROR_METHODS`.
    partial
        an equation the data cannot identify is left out and said so in
        ``not_identifiable`` (which coefficient, why, what would fix it) instead of
        raising; it raises only when no equation is left.
    use_priors
        the posterior with the file's priors (else the data alone).
    structures
        choose the cross-flow structure by held-out prediction (else the file's).
    use
        per record, the samples the fit may use (held-out data: False), or None.

    Raises
    ------
    NotIdentifiableError
        a coefficient lacks excitation or two cannot be separated
        (with ``partial``: every equation).
    IdentificationError
        bad records, unknown equation or option.
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
        if not any(key in (*e.coefficients, e.offset, e.plane, *QUADRATIC)
                   for e in EQUATIONS.values()):
            raise IdentificationError(f'bound given for unknown coefficient {key!r}')
    fits: dict[str, EquationFit] = {}
    left_out: dict[str, str] = {}
    cache: dict[tuple[int, str], np.ndarray] = {}
    for name in names:
        eq = EQUATIONS[name]
        system = build_system(records, eq, base, fit_offsets, fit_planes, use=use, cache=cache)
        try:
            check_identifiable(system)
        except NotIdentifiableError as exc:
            if not partial:
                raise
            left_out[name] = str(exc)
            continue
        label, scores, system = (choose_structure(records, eq, base, system, fit_offsets,
                                                  fit_planes, use, cache, bounds, use_priors)
                                 if structures else ('file', {}, system))
        fit = fit_equation(system, base, bounds, errors, check=False, use_priors=use_priors)
        fit = widen_to_structures(fit, scores.pop('_systems', {}), base, bounds, errors,
                                  use_priors)
        fit.structure = label
        fit.structures = scores
        fits[name] = fit
        if not fit.identified:
            left_out[name] = fit.why
    if not fits:
        raise NotIdentifiableError('no equation can be identified from these data: '
                                   + '; '.join(f'{k}: {v}' for k, v in left_out.items()))
    result = Identification(fits=fits, base=base, params=base, source=sources.pop(),
                            errors=errors, fit_offsets=fit_offsets, bounds=dict(bounds or {}),
                            not_identifiable=left_out, fit_planes=fit_planes,
                            use=None if use is None else list(use),
                            method={'bounds': 'physical' if bounds is None else (
                                'none' if len(bounds) == 0 else 'physical and given'),
                                'priors': 'file values, width by source' if use_priors
                                else 'none'})
    try:
        result.params = base.replace(**result.written())
    except ValueError as exc:
        raise IdentificationError(f'identified values are not a valid vehicle: {exc}') from None
    return result


#: The quadratic cross-flow term each equation may fit with its linear ones.
QUADRATIC = {'heave': 'Zww', 'pitch': 'Mqq', 'sway': 'Yvv', 'yaw': 'Nrr'}
#: Contiguous folds of the held-out prediction that chooses the structure.
FOLDS = 10
#: A richer structure is chosen only if its held-out error is below the simpler one's by
#: more than this many standard errors of the folds' mean log ratio, and by 1 % at least.
STRUCTURE_Z = 2.0


def structure_candidates(equation: Equation, base: VehicleParams
                         ) -> list[tuple[str, tuple[str, ...], dict[str, float]]]:
    """The structures an equation may have, simplest first: ``(label, fitted quadratic
    terms, terms set)``: ``file`` (the quadratic terms at the file's values), ``linear``
    (without quadratic terms: 0; when the file has some), ``quadratic`` (the equation's
    quadratic cross-flow term fitted with the linear ones, its cross terms such as ``Zqq``,
    ``Mww`` at the file's values; the linear damping term may reach 0 on its bound, which is
    the quadratic-only structure), ``quadratic, cross terms 0`` (the same without them,
    when the file has them) and ``quadratic, cross terms fitted`` (every quadratic term of
    the component fitted, each held by its prior where the data say little)."""
    quad = QUADRATIC.get(equation.name)
    if quad is None:
        return [('file', (), {})]
    terms = [k for k in component_terms(equation) if k in QUADRATIC_TERMS]
    minor = [k for k in terms if k != quad]
    out: list[tuple[str, tuple[str, ...], dict[str, float]]] = [('file', (), {})]
    if any(base.values[k] != 0.0 for k in terms):
        out.append(('linear', (), {k: 0.0 for k in terms}))
    out.append(('quadratic', (quad,), {}))
    if any(base.values[k] != 0.0 for k in minor):
        out.append(('quadratic, cross terms 0', (quad,), {k: 0.0 for k in minor}))
    out.append(('quadratic, cross terms fitted', (quad, *minor), {}))
    return out


def choose_structure(records: Sequence[ForceRecord], equation: Equation, base: VehicleParams,
                     system: LinearSystem, fit_offsets: bool, fit_planes: bool,
                     use: Sequence[np.ndarray | None] | None,
                     cache: dict[tuple[int, str], np.ndarray],
                     bounds: Mapping[str, tuple[float, float]] | None, use_priors: bool
                     ) -> tuple[str, dict[str, Any], LinearSystem]:
    """The structure of ``equation`` that predicts held-out data best
    (:func:`structure_candidates`, scored by :func:`held_out_error` on :data:`FOLDS`
    contiguous folds): the simplest one not worse than the best by a significant margin
    (:data:`STRUCTURE_Z` standard errors of the fold-wise difference and 1 %). Returns the
    label, the scores (``cv_rss`` per structure, ``set``: the terms it sets) and its system.
    """
    cands = structure_candidates(equation, base)
    if len(cands) == 1:
        return 'file', {}, system
    systems: dict[str, LinearSystem] = {}
    folds: dict[str, np.ndarray] = {}
    sets: dict[str, dict[str, float]] = {}
    for label, free, values in cands:
        sysc = system if label == 'file' else build_system(
            records, equation, base, fit_offsets, fit_planes, free=free, values=values,
            use=use, cache=cache)
        systems[label] = sysc
        folds[label] = held_out_error(sysc, base, bounds, use_priors)
        sets[label] = values
    best = min(folds, key=lambda k: float(folds[k].sum()))
    chosen = best
    scale = float(np.sum(system.measured ** 2)) + 1e-300
    for label, _, _ in cands:
        if label == best or not_worse(folds[label], folds[best], scale):
            chosen = label
            break
    plausible = [label for label, _, _ in cands
                 if label == best or not_worse(folds[label], folds[best], scale)]
    # structures that predict as the chosen one to rounding have its coefficients
    same = {k for k in plausible
            if abs(float(folds[k].sum() - folds[chosen].sum())) <= 1e-9 * scale}
    scores = {'cv_rss': {k: float(v.sum()) for k, v in folds.items()}, 'folds': FOLDS,
              'set': sets[chosen], 'plausible': plausible,
              '_systems': {k: systems[k] for k in plausible if k not in same}}
    return chosen, scores, systems[chosen]


def widen_to_structures(fit: EquationFit, alternatives: Mapping[str, LinearSystem],
                        base: VehicleParams, bounds: Mapping[str, tuple[float, float]] | None,
                        errors: str, use_priors: bool) -> EquationFit:
    """``fit`` with every coefficient's interval widened to cover its intervals in the
    ``alternatives``: the structures the held-out prediction could not rule out (a
    coefficient fixed in one, such as a quadratic term at its file value, counts with that
    value). The structure is uncertain there, so the interval says so."""
    if not alternatives:
        return fit
    coefs = {c.name: c for c in fit.coefficients}
    lo = {n: c.ci95[0] for n, c in coefs.items()}
    hi = {n: c.ci95[1] for n, c in coefs.items()}
    for system in alternatives.values():
        alt = fit_equation(system, base, bounds, errors, check=False, use_priors=use_priors)
        found = {c.name: c.ci95 for c in alt.coefficients}
        found.update({k: (v, v) for k, v in alt.fixed.items()})
        for n in coefs:
            a, b = found.get(n, (0.0, 0.0) if n in QUADRATIC_TERMS else (lo[n], hi[n]))
            lo[n], hi[n] = min(lo[n], a), max(hi[n], b)
    widened = tuple(c._replace(ci95=(lo[c.name], hi[c.name])) for c in fit.coefficients)
    return dataclasses.replace(fit, coefficients=widened)


def not_worse(simple: np.ndarray, best: np.ndarray, scale: float) -> bool:
    """Whether held-out fold errors ``simple`` are not significantly worse than ``best``:
    the mean log ratio of the folds' errors below 1 % or below :data:`STRUCTURE_Z` of its
    standard error, or the two equal to rounding (``1e-9`` of ``scale``, the measured
    component's sum of squares)."""
    if float(simple.sum() - best.sum()) <= 1e-9 * scale:
        return True
    ratio = np.log(np.maximum(simple, 1e-300) / np.maximum(best, 1e-300))
    mean = float(ratio.mean())
    se = float(np.std(ratio, ddof=1)) / math.sqrt(len(ratio)) if len(ratio) > 1 else 0.0
    return mean <= max(0.01, STRUCTURE_Z * se)


def held_out_error(system: LinearSystem, base: VehicleParams,
                   bounds: Mapping[str, tuple[float, float]] | None, use_priors: bool
                   ) -> np.ndarray:
    """Sum of squared prediction errors of each of :data:`FOLDS` contiguous folds of the
    rows of ``system``, each predicted by the fit to the other folds [(N or N m)^2].

    The fold fits are the regularised normal equations ``(D'A / s^2 + Lambda_0) theta =
    D'b / s^2 + Lambda_0 theta_0`` with ``s^2`` the residual variance of the fit to all rows
    times its correlation time (the data's weight against the priors), coefficients that
    leave their physical bounds fixed on them.
    """
    n, p = system.A.shape
    edges = np.linspace(0, n, FOLDS + 1).astype(int)
    names = system.names
    pri = priors(names, base)
    limits = _limits(names, base, bounds)
    scale = system.scale
    D = system.A / scale
    R = system.regressors / scale
    theta_all = np.linalg.lstsq(D.T @ R, D.T @ system.b, rcond=None)[0]
    resid = system.b - R @ theta_all
    s2 = max(float(resid @ resid) / max(n - p, 1) * correlation_time(resid), 1e-300)
    lam = np.array([1.0 / (pri[k].sd * scale[j]) ** 2 if use_priors else 0.0
                    for j, k in enumerate(names)])
    mean = np.array([pri[k].mean * scale[j] for j, k in enumerate(names)])
    lo = np.array([limits[k][0] * scale[j] for j, k in enumerate(names)])
    hi = np.array([limits[k][1] * scale[j] for j, k in enumerate(names)])
    G = D.T @ R
    h = D.T @ system.b
    out = np.empty(FOLDS)
    for k in range(FOLDS):
        sl = slice(edges[k], edges[k + 1])
        Gk = (G - D[sl].T @ R[sl]) / s2 + np.diag(lam)
        hk = (h - D[sl].T @ system.b[sl]) / s2 + lam * mean
        free = np.ones(p, bool)
        theta = np.zeros(p)
        for _ in range(p + 1):
            theta[free] = np.linalg.lstsq(Gk[np.ix_(free, free)], hk[free]
                                          - Gk[np.ix_(free, ~free)] @ theta[~free],
                                          rcond=None)[0]
            out_lo, out_hi = free & (theta < lo), free & (theta > hi)
            if not (np.any(out_lo) or np.any(out_hi)):
                break
            theta = np.where(out_lo, lo, np.where(out_hi, hi, theta))
            free &= ~(out_lo | out_hi)
        e = system.b[sl] - R[sl] @ theta
        out[k] = float(e @ e)
    return out


@one_blas_thread
def compare_nelder_mead(records: Sequence[ForceRecord], result: Identification,
                        x0: Mapping[str, float] | None = None) -> dict[str, dict[str, Any]]:
    """Run the report's bounded Nelder-Mead on the same data as ``result`` and compare it with
    the data's own least-squares solution (no prior, no physical bound: the two methods on one
    objective).

    For each equation (in its chosen structure): the least-squares and the Nelder-Mead
    coefficients, their largest relative difference and the two sums of squares. The search
    starts from ``x0`` (default: the base vehicle's values, as the report started from its
    prior values) and uses the bounds given to ``result`` (none by default).
    """
    out: dict[str, dict[str, Any]] = {}
    for name, fit in result.fits.items():
        quad = QUADRATIC.get(name)
        free = (quad,) if fit.structure.startswith('quadratic') and quad else ()
        system = build_system(records, fit.equation, result.base, result.fit_offsets,
                              result.fit_planes, free=free,
                              values=fit.structures.get('set', {}), use=result.use)
        lsq, _ = solve(system)
        start = [(x0 or {}).get(c, result.base.values[c]) for c in system.names]
        nm = nelder_mead(system, start, result.bounds)
        rel = np.abs(nm - lsq) / np.maximum(np.abs(lsq), 1e-12)
        out[name] = {'names': list(system.names), 'least_squares': lsq.tolist(),
                     'nelder_mead': nm.tolist(), 'max_relative_difference': float(rel.max()),
                     'sum_of_squares_least_squares': system.sum_of_squares(lsq),
                     'sum_of_squares_nelder_mead': system.sum_of_squares(nm)}
    return out
