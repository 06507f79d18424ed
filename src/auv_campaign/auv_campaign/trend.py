"""Drift and step tests of one quantity across the missions of a campaign.

Data: the estimates ``y_i`` of a quantity (an effect parameter, a coefficient) at mission
times ``x_i``, with standard errors ``s_i`` from their 95 % intervals
(``s = (hi - lo) / (2 * 1.96)``); weights ``w_i = 1 / s_i^2``. Three models are fitted by
weighted least squares:

* constant: ``y = m``, residual ``chi0 = sum w (y - m)^2``;
* drift: ``y = a + b x`` (weighted linear trend), ``chi1``;
* step: ``y = m1`` for the first ``k`` missions, ``m2`` after (a single change point; the
  weighted likelihood ratio ``chi0 - chi_s(k)`` maximised over ``k``, the CUSUM-of-squares
  form of the Gaussian change-point test), ``chi_s``.

Significance is by permutation: the missions' ``(y, s)`` pairs are exchangeable in time under
"no change", so the observed ``chi0 - chi1`` (trend) and ``max_k (chi0 - chi_s(k))`` (step)
are compared with their values over ``permutations`` random reorderings. This stays valid when
the intervals are too narrow or too wide by a common factor (over- or under-dispersion), where
a chi-square reference would not. A quantity is ``stable`` when neither p-value is below
``alpha``; otherwise ``drift`` or ``step``, whichever of the significant models has the lower
Bayesian information criterion (``chi / phi + k ln n``, ``k`` = 2 for the drift, 3 for the
step with its location, ``phi`` the dispersion of the better model, at least 1).
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from scipy import stats

Z95 = 1.959963984540054
SECONDS_PER_DAY = 86400.0
MIN_MISSIONS = 4


def standard_error(ci95: Sequence[float]) -> float:
    """Standard error of a symmetric-normal 95 % interval ``(lo, hi)``."""
    return (float(ci95[1]) - float(ci95[0])) / (2.0 * Z95)


def _step_chi(y: np.ndarray, w: np.ndarray, min_seg: int) -> np.ndarray:
    """Residual chi-square of the best split after each ``k`` (rows: series; columns:
    ``k = min_seg .. n - min_seg``)."""
    W = np.cumsum(w, axis=-1)
    WY = np.cumsum(w * y, axis=-1)
    tot_w, tot_wy = W[..., -1:], WY[..., -1:]
    tot_wyy = np.sum(w * y * y, axis=-1, keepdims=True)
    n = y.shape[-1]
    k = np.arange(min_seg, n - min_seg + 1)
    W1, WY1 = W[..., k - 1], WY[..., k - 1]
    W2, WY2 = tot_w - W1, tot_wy - WY1
    chi: np.ndarray = tot_wyy - WY1 ** 2 / W1 - WY2 ** 2 / W2
    return chi


def _trend_stat(x: np.ndarray, y: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``chi0 - chi1`` = ``b^2 Sxx`` of the weighted linear fit (rows: series)."""
    sw = np.sum(w, axis=-1, keepdims=True)
    xm = np.sum(w * x, axis=-1, keepdims=True) / sw
    ym = np.sum(w * y, axis=-1, keepdims=True) / sw
    sxx = np.sum(w * (x - xm) ** 2, axis=-1)
    sxy = np.sum(w * (x - xm) * (y - ym), axis=-1)
    out: np.ndarray = sxy ** 2 / sxx
    return out


def analyse(x: Sequence[float] | np.ndarray, y: Sequence[float] | np.ndarray,
            s: Sequence[float] | np.ndarray, *,
            permutations: int = 999, alpha: float = 0.01, seed: int = 0,
            min_segment: int = 2) -> dict[str, Any]:
    """Drift and single-step tests of ``y`` (errors ``s``) against ``x`` (see module doc).

    ``x`` must be sorted ascending (mission time [s] or mission index). Returns a JSON-ready
    dict: ``n``, ``verdict`` (``stable``, ``drift``, ``step`` or ``too_few``), ``slope`` and
    ``slope_ci95`` (per unit of ``x``), ``p_trend``, ``step_index`` (index of the first
    point after the step), ``before``/``after`` (weighted means and their standard errors),
    ``p_step``, ``dispersion`` (chi-square per degree of freedom of the constant model).
    """
    xa, ya, sa = (np.asarray(v, dtype=np.float64) for v in (x, y, s))
    ok = np.isfinite(xa) & np.isfinite(ya) & np.isfinite(sa) & (sa > 0)
    xa, ya, sa = xa[ok], ya[ok], sa[ok]
    n = int(xa.size)
    base: dict[str, Any] = {'n': n, 'used': np.flatnonzero(ok).tolist()}
    if n < max(MIN_MISSIONS, 2 * min_segment):
        return {**base, 'verdict': 'too_few'}
    if np.any(np.diff(xa) < 0):
        raise ValueError('mission times must be sorted ascending')
    w = 1.0 / sa ** 2
    sw = float(np.sum(w))
    m0 = float(np.sum(w * ya) / sw)
    chi0 = float(np.sum(w * (ya - m0) ** 2))
    xm = float(np.sum(w * xa) / sw)
    sxx = float(np.sum(w * (xa - xm) ** 2))
    if sxx <= 0:
        return {**base, 'verdict': 'too_few'}
    slope = float(np.sum(w * (xa - xm) * (ya - m0)) / sxx)
    chi1 = chi0 - slope ** 2 * sxx
    chis = _step_chi(ya, w, min_segment)
    j = int(np.argmin(chis))
    k = j + min_segment
    chi_s = float(chis[j])
    # permutation reference
    rng = np.random.default_rng(seed)
    order = np.argsort(rng.random((permutations, n)), axis=1)
    yp, wp = ya[order], w[order]
    t_obs = chi0 - chi1
    s_obs = chi0 - chi_s
    t_perm = _trend_stat(xa[None, :], yp, wp)
    s_perm = chi0 - np.min(_step_chi(yp, wp, min_segment), axis=1)
    p_trend = float((1 + np.sum(t_perm >= t_obs * (1 - 1e-12))) / (permutations + 1))
    p_step = float((1 + np.sum(s_perm >= s_obs * (1 - 1e-12))) / (permutations + 1))
    phi1 = max(1.0, chi1 / (n - 2))
    tq = float(stats.t.ppf(0.975, n - 2))
    se_b = math.sqrt(phi1 / sxx)
    w1, w2 = float(np.sum(w[:k])), float(np.sum(w[k:]))
    m1, m2 = float(np.sum(w[:k] * ya[:k]) / w1), float(np.sum(w[k:] * ya[k:]) / w2)
    phis = max(1.0, chi_s / (n - 3))
    result = {
        **base, 'mean': m0, 'dispersion': chi0 / (n - 1),
        'intercept': m0 - slope * xm, 'slope': slope,
        'slope_ci95': [slope - tq * se_b, slope + tq * se_b],
        'p_trend': p_trend, 'chi2_constant': chi0, 'chi2_drift': chi1, 'chi2_step': chi_s,
        'step_index': k,
        'before': {'mean': m1, 'std_error': math.sqrt(phis / w1)},
        'after': {'mean': m2, 'std_error': math.sqrt(phis / w2)},
        'p_step': p_step, 'alpha': alpha, 'permutations': permutations,
    }
    sig_t, sig_s = p_trend < alpha, p_step < alpha
    if not (sig_t or sig_s):
        result['verdict'] = 'stable'
        return result
    phi = max(1.0, min(chi1 / (n - 2), chi_s / (n - 3)))
    bic_drift = chi1 / phi + 2 * math.log(n)
    bic_step = chi_s / phi + 3 * math.log(n)
    result['bic'] = {'drift': bic_drift, 'step': bic_step}
    if sig_t and (not sig_s or bic_drift <= bic_step):
        result['verdict'] = 'drift'
    else:
        result['verdict'] = 'step'
    return result
