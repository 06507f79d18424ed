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
    """One identified coefficient (dimensionless, as in the vehicle file)."""

    name: str
    value: float
    std_error: float
    ci95: tuple[float, float]
    base: float                 # value in the base vehicle file
    at_bound: bool              # the bounded solve stopped on a bound (SE then not meaningful)
    records: tuple[str, ...]    # records whose data excite it


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

    @property
    def coefficients(self) -> dict[str, CoefficientEstimate]:
        """Every identified coefficient by name."""
        return {c.name: c for fit in self.fits.values() for c in fit.coefficients}

    def values(self) -> dict[str, float]:
        """Identified values by name."""
        return {name: c.value for name, c in self.coefficients.items()}



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
        }
    coefs = {
        c.name: {'value': c.value, 'std_error': c.std_error, 'ci95': list(c.ci95),
                 'base': c.base,
                 'relative_change': (c.value - c.base) / c.base if c.base else None,
                 'at_bound': c.at_bound, 'records': list(c.records)}
        for c in result.coefficients.values()}
    return {'source': result.source, 'errors': result.errors, 'fit_offsets': result.fit_offsets,
            'fit_planes': result.fit_planes,
            'bounds': {k: list(v) for k, v in result.bounds.items()},
            'coefficients': coefs, 'equations': eqs,
            **({'not_identifiable': dict(result.not_identifiable)}
               if result.not_identifiable else {})}

