"""Identification results and their reporting: coefficients with 95 % intervals, per-equation
fit statistics, and the JSON summary (``report.json``).

Intervals are Student's t with the effective sample size (or the jackknife's blocks less one)
as degrees of freedom: ``theta +- t_0.975(dof) SE``.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any, NamedTuple

import numpy as np
from scipy import stats

from auv_ident.identify.equations import AXES, Equation
from auv_sim.params import VehicleParams


def t_interval(value: float, std_error: float, dof: float) -> tuple[float, float]:
    """95 % interval ``value +- t_0.975(dof) std_error`` (Student's t, ``dof`` at least 1)."""
    tq = float(stats.t.ppf(0.975, max(dof, 1.0)))
    return value - tq * std_error, value + tq * std_error


class CoefficientEstimate(NamedTuple):
    """One identified coefficient (dimensionless, or dimensional for the cross-flow terms,
    as in the vehicle file)."""

    name: str
    value: float
    std_error: float
    ci95: tuple[float, float]
    base: float                 # value in the base vehicle file
    at_bound: bool              # stopped on its physical bound (interval: truncated)
    records: tuple[str, ...]    # records whose data excite it
    prior_sd: float = math.nan  # standard deviation of its prior (mean: ``base``)
    informed: float = 1.0       # the data's share of its posterior precision, 0..1
    note: str = ''              # on its bound, or left at its prior: what and why
    bounds: tuple[float, float] = (-math.inf, math.inf)  # its physical range
    method: str = 'equation error'  # 'equation error' or 'output error'

    @property
    def at_prior(self) -> bool:
        """Left at its prior: the data did not inform it."""
        return self.note.startswith('left at')


@dataclasses.dataclass
class EquationFit:
    """The solved regression of one equation, with its statistics and fit series."""

    equation: Equation
    coefficients: tuple[CoefficientEstimate, ...]
    fixed: dict[str, float]
    r2: float
    nrmse: float
    rmse: float                 # [N or N m]
    condition_number: float     # of the column-scaled regressor
    correlation: np.ndarray     # (p, p) coefficient correlation
    n_samples: int
    n_effective: float
    hac_lags: int
    errors: str
    t: np.ndarray
    measured: np.ndarray
    fitted: np.ndarray
    record_index: np.ndarray
    record_names: tuple[str, ...]
    covariance: str = ''        # how S of the 'hac' sandwich was estimated
    noise_ratio: float = math.nan  # observed / sensor-noise-predicted residual variance
    #: the data alone (unbounded least squares, no prior): for the Nelder-Mead comparison
    data_only: dict[str, float] = dataclasses.field(default_factory=dict)
    #: the structure fitted (``file``: the quadratic terms at the file's values; ``linear``:
    #: without them; ``quadratic``: fitted with the linear ones) and the held-out scores
    structure: str = 'file'
    structures: dict[str, Any] = dataclasses.field(default_factory=dict)
    #: False: not identified (R^2 < 0, ...); its coefficients stay at the base, ``why``
    identified: bool = True
    why: str = ''

    def value(self, name: str) -> float:
        """Identified value of a coefficient of this equation."""
        for c in self.coefficients:
            if c.name == name:
                return c.value
        raise KeyError(name)


@dataclasses.dataclass
class Identification:
    """Result of :func:`identify`: per-equation fits and the identified vehicle."""

    fits: dict[str, EquationFit]
    base: VehicleParams
    params: VehicleParams
    source: str
    errors: str
    fit_offsets: bool
    bounds: dict[str, tuple[float, float]]
    #: equations left out: name -> what is not identifiable, why and what would fix it
    not_identifiable: dict[str, str] = dataclasses.field(default_factory=dict)
    #: the dive plane's CZbar and CMbar fitted too (else fixed at the base values)
    fit_planes: bool = False

    #: what the fit was: physical bounds, priors, how the derivatives were handled
    method: dict[str, Any] = dataclasses.field(default_factory=dict)
    #: per record, the samples the fit used (None: all)
    use: list[np.ndarray | None] | None = None

    @property
    def coefficients(self) -> dict[str, CoefficientEstimate]:
        """Every coefficient of an identified equation by name."""
        return {c.name: c for fit in self.fits.values() if fit.identified
                for c in fit.coefficients}

    def values(self) -> dict[str, float]:
        """Identified values by name."""
        return {name: c.value for name, c in self.coefficients.items()}

    def written(self) -> dict[str, float]:
        """The values written to the vehicle file: the identified coefficients and the
        terms a chosen structure sets (the quadratic terms of a linear structure: 0)."""
        out = self.values()
        for fit in self.fits.values():
            if fit.identified:
                out.update(fit.structures.get('set', {}))
        return out



def summary(result: Identification) -> dict[str, Any]:
    """A JSON-ready summary of ``result`` (the body of ``report.json``)."""
    eqs: dict[str, Any] = {}
    for name, fit in result.fits.items():
        eqs[name] = {
            'component': AXES[fit.equation.axis], 'unit': fit.equation.unit,
            'r2': fit.r2, 'nrmse': fit.nrmse, 'rmse': fit.rmse,
            'condition_number': fit.condition_number,
            'correlation': {'names': [c.name for c in fit.coefficients],
                            'matrix': fit.correlation.tolist()},
            'samples': fit.n_samples, 'effective_samples': fit.n_effective,
            'hac_lags': fit.hac_lags, 'covariance': fit.covariance,
            'noise_ratio': fit.noise_ratio if math.isfinite(fit.noise_ratio) else None,
            'fixed': fit.fixed, 'figure': fit.equation.figure,
            'structure': fit.structure, 'structures': fit.structures,
            'identified': fit.identified, **({'why': fit.why} if fit.why else {}),
        }
    coefs = {
        c.name: {'value': c.value, 'std_error': c.std_error, 'ci95': list(c.ci95),
                 'base': c.base,
                 'relative_change': (c.value - c.base) / c.base if c.base else None,
                 'at_bound': c.at_bound, 'records': list(c.records),
                 'prior_sd': c.prior_sd, 'informed': c.informed, 'at_prior': c.at_prior,
                 'bounds': list(c.bounds), 'method': c.method,
                 **({'note': c.note} if c.note else {})}
        for c in result.coefficients.values()}
    return {'source': result.source, 'errors': result.errors, 'fit_offsets': result.fit_offsets,
            'fit_planes': result.fit_planes,
            'bounds': {k: list(v) for k, v in result.bounds.items()},
            'method': result.method,
            'coefficients': coefs, 'equations': eqs,
            **({'not_identifiable': dict(result.not_identifiable)}
               if result.not_identifiable else {})}

