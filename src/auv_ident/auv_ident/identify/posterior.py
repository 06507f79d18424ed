"""The fit as the posterior of the priors and the data, inside the physical bounds.

The data give an estimate ``theta_d`` of an equation's coefficients (least squares, or
two-stage least squares for forces from motion) whose covariance ``V_d = B^-1 S B^-T`` does
not assume the model is right (a sandwich: ``B = D'A``, ``S = Var(D'e)`` from the residuals,
:mod:`auv_ident.identify.covariance`). Its information ``I_d = B' S^-1 B`` is combined with
the priors ``N(theta_0, diag(s_0^2))`` (:mod:`auv_ident.identify.priors`)::

    P = I_d + Lambda_0,   Lambda_0 = diag(1 / s_0^2)
    theta = argmin (theta - m)' P (theta - m)  subject to  lo <= theta <= hi
    m = P^-1 (I_d theta_d + Lambda_0 theta_0),   Cov(theta) = P^-1

that is regularised least squares with the sandwich's weighting of the moments ``D'(b - A
theta) = 0`` (a generalised method of moments estimate with a Gaussian prior). The bounded
minimum is a bounded-variable least-squares problem on the Cholesky factor of ``P``
(``scipy.optimize.lsq_linear``, ``bvls``). Where the data say nothing (``I_d`` = 0 in some
direction) the posterior is the prior; where they say much, it is the data's estimate with
the sandwich covariance. ``S`` is floored at a residual of ``1e-10`` of the measured force's
rms (rounding), so exact data give the data's estimate and an interval of finite width.

Intervals: Student's t with the covariance's degrees of freedom; for a coefficient stopped on
a bound, the highest-density 95 % of its marginal posterior truncated to the allowed side:
from the bound, where the estimate is, inwards (never of zero width).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from scipy import optimize, stats

#: Residual floor of the meat, relative to the rms of the measured component (rounding).
RESIDUAL_FLOOR = 1e-10


class Posterior(NamedTuple):
    """Posterior of one equation's coefficients (the coefficients' own units)."""

    theta: np.ndarray        # (p,) the bounded posterior estimate
    cov: np.ndarray          # (p, p) posterior covariance P^-1
    unbounded: np.ndarray    # (p,) the posterior mean m without the bounds
    at_bound: np.ndarray     # (p,) bool: stopped on a bound
    information: np.ndarray  # (p,) the data's share of each coefficient's precision, 0..1


def information(bread: np.ndarray, meat: np.ndarray, floor_meat: np.ndarray) -> np.ndarray:
    """``I_d = B' (S + F)^-1 B`` (symmetric), with ``F`` the meat of a rounding-level
    residual (see the module docstring); pseudo-inverse on the eigenvalues."""
    s = 0.5 * (meat + meat.T) + floor_meat
    w, u = np.linalg.eigh(s)
    keep = w > 1e-300
    inv = (u[:, keep] / w[keep]) @ u[:, keep].T
    info = bread.T @ inv @ bread
    out: np.ndarray = 0.5 * (info + info.T)
    return out


def combine(theta_d: np.ndarray, info: np.ndarray, prior_mean: np.ndarray,
            prior_sd: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> Posterior:
    """The bounded posterior of the data's estimate ``theta_d`` with information ``info``
    and independent Gaussian priors (module docstring). All in one consistent scaling."""
    lam = 1.0 / prior_sd ** 2
    P = info + np.diag(lam)
    P = 0.5 * (P + P.T)
    rhs = info @ np.nan_to_num(theta_d) + lam * prior_mean
    cho = np.linalg.cholesky(P)
    m = np.linalg.solve(P, rhs)
    if np.all(m >= lo) and np.all(m <= hi):
        theta, at_bound = m.copy(), np.zeros(len(m), bool)
    else:
        R = cho.T        # P = R' R
        res = optimize.lsq_linear(R, R @ m, bounds=(lo, hi), method='bvls', tol=1e-14)
        theta = np.clip(res.x, lo, hi)
        at_bound = (res.active_mask != 0) | (theta <= lo) | (theta >= hi)
    cov = np.linalg.inv(P)
    cov = 0.5 * (cov + cov.T)
    data_share = 1.0 - lam * np.diag(cov)
    return Posterior(theta=theta, cov=cov, unbounded=m, at_bound=at_bound,
                     information=np.clip(data_share, 0.0, 1.0))


def interval(value: float, unbounded: float, sd: float, dof: float, lo: float, hi: float,
             at_bound: bool) -> tuple[float, float]:
    """95 % interval: ``value +- t_0.975(dof) sd``, or for a coefficient on a bound the
    highest-density 95 % of ``N(unbounded, sd^2)`` truncated to ``[lo, hi]``: from the bound
    (the estimate) inwards, so that it holds the estimate (module docstring)."""
    sd = max(float(sd), 1e-300)
    if not at_bound or lo < unbounded < hi:
        tq = float(stats.t.ppf(0.975, max(dof, 1.0)))
        return value - tq * sd, value + tq * sd
    a, b = (lo - unbounded) / sd, (hi - unbounded) / sd
    dist = stats.truncnorm(a, b, loc=unbounded, scale=sd)
    # the density rises towards the bound it is stopped on: the shortest 95 % ends there
    q = float(dist.ppf(0.05 if unbounded >= hi else 0.95))
    if not math.isfinite(q) or (q >= hi if unbounded >= hi else q <= lo):
        # far past the bound: the truncated normal is an exponential tail of scale
        # sd^2 / distance from the bound, whose 95 % lie within -ln(0.05) scales of it
        d = max(abs(unbounded - (hi if unbounded >= hi else lo)), sd)
        q = (hi - math.log(20.0) * sd * sd / d if unbounded >= hi
             else lo + math.log(20.0) * sd * sd / d)
    return (q, hi) if unbounded >= hi else (lo, q)
