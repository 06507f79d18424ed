"""Covariance of the estimated coefficients: four estimators of the sandwich.

The estimate is ``theta = (D'A)^-1 D'b`` (``D = A`` for least squares; for forces from motion
``D`` is the projection of ``A`` on lead/lag instruments, two-stage least squares), so
``theta - theta_0 = (D'A)^-1 D'e`` with the equation error ``e`` and the sandwich covariance
``(D'A)^-1 S (D'A)^-T``, ``S = Var(D'e)``. ``errors='hac'`` (the default) estimates ``S`` so
that it holds for the coloured, filtered errors of this problem:

* forces from motion whose records carry a
  :class:`~auv_ident.identify.records.NoisePropagation` (see
  :mod:`auv_ident.motion`): ``e`` is, to first order, a known linear filter of the white
  sensor noise on the logged state (the Savitzky-Golay derivative in ``M nu_dot``, the
  consistent low-pass on the other wrenches and on the regressors, all through their local
  sensitivities), so ``S = sum_c sigma_c^2 w_c' w_c`` exactly, with ``w_c`` the design pushed
  back through that filter (its adjoint) and ``sigma_c`` estimated from each logged channel.
  This first-order (delta-method) covariance holds at the noise-free design; the design's
  own noise, amplified by the derivative's adjoint, would overstate it (by up to 1.7x for
  the weakly excited sway pair), so the design is first low-passed by the record's kernel
  (:data:`DESIGN_SMOOTHING_PASSES` times: -3 dB near 0.4 Hz for the 1 s window, above the
  manoeuvres' dynamics) and the bread uses the same design.
  A lag-window estimate cannot do this: the derivative noise is a difference, its spectrum
  vanishes at frequency zero, and the sum of its autocovariances (large, of both signs over
  the filter window) cancels to a small ``S`` that a truncated sum estimates with an error
  far larger than itself. It is used only when this noise model accounts for the residual
  (observed / predicted residual variance at most :data:`NOISE_RATIO_MAX`), else:
* a flat-top (trapezoidal) lag window (Politis and Romano): full weight up to the lag ``m``
  beyond which the autocorrelations of ``D_t e_t`` are insignificant (Politis' empirical
  rule, ``m`` at least the filter length, the known dependence of filtered errors), tapered
  to zero at ``2 m``; it has no bias for errors of finite memory, unlike the Newey-West
  (Bartlett) weights that shrink the negative lobes of the filtered errors and so
  overstate ``S``. If the flat-top matrix is not positive semi-definite, the Bartlett window
  of the same length is used instead.

The columns of a record with a noise model are corrected for the mean shift the noise
gives a nonlinear column (``E[(u + n)|u + n|] = u|u| + sigma_u^2`` away from u = 0; see
:func:`auv_ident.identify.regressors.unbiased_columns`), and :mod:`auv_ident.motion` does
the same for the other wrenches: without it, the errors-in-variables bias of Ksh is a third
of its (small) standard error at the realistic noise level and grows linearly with the noise.

Other methods: ``'iid'`` ``sigma^2 (A'A)^-1``; ``'ess'`` that times ``n / n_eff`` with the
integrated residual autocorrelation time; ``'jackknife'`` a delete-a-block jackknife.
Which is used: ``'hac'`` unless the caller asks for another (``auv ident --errors``).
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np

from auv_ident.identify.records import ForceRecord
from auv_ident.identify.regression import LinearSystem
from auv_ident.identify.regressors import (
    as_slice,
    basis_differences,
    gradient_differences,
    hydro_gradient,
)
from auv_sim.params import VehicleParams

ERROR_METHODS = ('hac', 'jackknife', 'ess', 'iid')
#: Contiguous blocks of the delete-a-block jackknife.
JACKKNIFE_BLOCKS = 40
#: Largest ratio of the observed to the sensor-noise-predicted residual variance for which
#: the sensor-noise propagation gives the covariance (above it, part of the residual is not
#: white sensor noise: model error, coloured noise; the lag window is used instead).
NOISE_RATIO_MAX = 1.5
#: Politis' rule: autocorrelations below ``POLITIS_C sqrt(log10(n) / n)`` are insignificant.
POLITIS_C = 2.0
#: Passes of a record's kernel that smooth the design before the noise propagation.
DESIGN_SMOOTHING_PASSES = 2


def _autocorrelation(e: np.ndarray, max_lag: int) -> np.ndarray:
    """Sample autocorrelation of ``e`` for lags 0..max_lag (FFT)."""
    n = len(e)
    e = e - e.mean()
    nfft = 1 << (2 * n - 1).bit_length()
    f = np.fft.rfft(e, nfft)
    acov = np.fft.irfft(f * np.conj(f), nfft)[:max_lag + 1]
    return acov / acov[0] if acov[0] > 0 else np.zeros(max_lag + 1)


def correlation_time(e: np.ndarray) -> float:
    """Integrated autocorrelation time ``tau = 1 + 2 sum_k rho_k`` [samples], the sum taken up
    to the first non-positive ``rho_k`` (initial positive sequence); >= 1."""
    if len(e) < 4:
        return 1.0
    rho = _autocorrelation(e, min(len(e) - 1, max(10, len(e) // 4)))
    neg = np.flatnonzero(rho[1:] <= 0)
    k = int(neg[0]) if len(neg) else len(rho) - 1
    return max(1.0, 1.0 + 2.0 * float(np.sum(rho[1:k + 1])))


def _lag_window_meat(g: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """``S = sum_{|k|<=L} weights[|k|] sum_t g_t g_{t+k}'`` for ``g`` (n, p) and lag weights
    (L+1,) (FFT cross-covariances)."""
    n, p = g.shape
    lags = len(weights) - 1
    nfft = 1 << (n + lags).bit_length()
    G = np.fft.rfft(g, nfft, axis=0)
    S = np.empty((p, p))
    for i in range(p):
        for j in range(i, p):
            cc = np.fft.irfft(np.conj(G[:, i]) * G[:, j], nfft)  # cc[k] = sum_t g_i,t g_j,t+k
            pos = cc[:lags + 1]
            neg = cc[::-1][:lags]  # lags -1..-L
            s = weights[0] * pos[0] + np.dot(weights[1:], pos[1:]) + np.dot(weights[1:], neg)
            S[i, j] = S[j, i] = s
    return S


def _hac_meat(g: np.ndarray, lags: int) -> np.ndarray:
    """Newey-West ``S = sum_{|k|<=L} (1 - |k|/(L+1)) sum_t g_t g_{t-k}'``."""
    return _lag_window_meat(g, 1.0 - np.arange(lags + 1) / (lags + 1.0))


def flat_top_lag(g: np.ndarray, minimum: int = 1) -> int:
    """Politis' empirical bandwidth for the flat-top window on ``g`` (n, p) [samples]: the
    smallest ``m >= minimum`` after which ``K = max(5, sqrt(log10 n))`` consecutive
    autocorrelations of every column are below ``POLITIS_C sqrt(log10(n) / n)``; at most
    ``n / 8``."""
    n = len(g)
    cap = max(1, n // 8)
    if n < 16:
        return min(max(minimum, 1), cap)
    K = max(5, int(math.sqrt(math.log10(n))))
    thr = POLITIS_C * math.sqrt(math.log10(n) / n)
    m_hat = min(max(minimum, 1), cap)
    for j in range(g.shape[1]):
        rho = _autocorrelation(g[:, j], min(n - 1, cap + K))
        big = np.abs(rho) >= thr
        big[0] = True
        # first m with K insignificant autocorrelations after it
        run = np.convolve(big[1:].astype(float), np.ones(K), mode='valid')  # lags m+1..m+K
        ok = np.flatnonzero(run[m_hat:] == 0)
        m_j = m_hat + int(ok[0]) if len(ok) else cap
        m_hat = max(m_hat, min(m_j, cap))
    return m_hat


def _flat_top_meat(g: np.ndarray, m: int) -> np.ndarray:
    """Flat-top (trapezoid) lag window: weight 1 up to lag ``m``, ``2 - k/m`` to ``2 m``."""
    k = np.arange(2 * m + 1)
    return _lag_window_meat(g, np.clip(2.0 - k / m, 0.0, 1.0))


def _record_rows(record_index: np.ndarray, i: int) -> slice | np.ndarray | None:
    """The rows of record ``i`` among a system's pooled rows (``record_index`` (n,)): a slice
    when they are contiguous (as :func:`~auv_ident.identify.regression.build_system` pools
    them), so that selecting them takes no copy, else a boolean mask (n,); None when the
    record has no row."""
    sel: np.ndarray = record_index == i
    idx = np.flatnonzero(sel)
    if not len(idx):
        return None
    rows = as_slice(idx)
    return rows if isinstance(rows, slice) else sel


def sensor_noise_meat(system: LinearSystem, design: np.ndarray, resid: np.ndarray,
                      theta: np.ndarray, base: VehicleParams,
                      full: Sequence[np.ndarray | None] | None = None
                      ) -> tuple[np.ndarray, float] | None:
    """``S = Var(D'e)`` propagated from the white sensor noise (see :class:`NoisePropagation`)
    and the ratio of the observed to the predicted residual variance; None when a record
    has no noise model.

    With the equation's wrench component ``a``, noise ``n_c`` on state channel ``c`` gives
    ``e = M_ac (h * n_c) - kappa * (G_c n_c)``, ``G_c`` the sensitivity of the other wrenches
    plus the fitted hydrodynamic model; so ``D'e = sum_c sum_j n_c,j w_c,j`` with
    ``w_c = M_ac (h~ * d) - G_c (kappa * d)`` (``h~`` reversed, ``d`` the design rows, zero
    where unused) and ``S = sum_c sigma_c^2 w_c' w_c``. ``full``: per record, ``d`` when
    already at hand (the design's rows in place among the record's samples, zero elsewhere).
    """
    p = design.shape[1]
    S = np.zeros((p, p))
    predicted = 0.0
    axis = system.equation.axis
    for i, rec in enumerate(system.records):
        sel = _record_rows(system.record_index, i)
        if sel is None:
            continue
        nm = rec.noise
        if nm is None or rec.kernel is None or system.rows is None:
            return None
        N = len(rec.t)
        rows = system.rows[sel]
        given = None if full is None else full[i]
        if given is None:
            d = np.zeros((N, p))
            d[rows] = design[sel]
        else:
            d = given
        kappa = rec.kernel
        h = nm.derivative_kernel
        kd = np.column_stack([np.convolve(d[:, j], kappa, mode='same') for j in range(p)])
        hd = np.column_stack([np.convolve(d[:, j], h[::-1], mode='same') for j in range(p)])
        G = nm.other_jacobian[:, axis, :].copy()
        coef = dict(zip(system.names, theta))
        coef.update(system.fixed)
        G[:, 6:12] += hydro_gradient(system.equation, rec.nu, coef, base,
                                     _gradient_differences(system, i, rec, base))
        # the channels summed in closed form: with s_c = sigma_c^2 (0 for a channel without
        # noise), sum_c s_c w_c' w_c = a hd'hd - hd' g1 kd - kd' g1 hd + kd' g2 kd and the
        # predicted variance conv(g2, kappa^2) - 2 conv(g1, h kappa) + a h'h, with
        # a = sum_c s_c M_ac^2, g1 = sum_c s_c M_ac G_c, g2 = sum_c s_c G_c^2
        s2 = np.where(nm.sigma[:12] <= 0.0, 0.0, nm.sigma[:12]) ** 2
        m_a = np.concatenate([np.zeros(6), nm.mass[axis, :6]])
        a = float(np.sum(s2 * m_a ** 2))
        g1 = G @ (s2 * m_a)
        g2 = (G * G) @ s2
        cross = hd.T @ (g1[:, None] * kd)
        S += a * (hd.T @ hd) - cross - cross.T + kd.T @ (g2[:, None] * kd)
        # residual variance the noise predicts at each sample
        var_t = (np.convolve(g2, kappa ** 2, mode='same')
                 - 2.0 * np.convolve(g1, h * kappa, mode='same') + a * float(h @ h))
        predicted += float(np.sum(var_t[rows]))
    observed = float(resid @ resid)
    ratio = observed / predicted if predicted > 0 else math.inf
    return S, ratio


def _gradient_differences(system: LinearSystem, i: int, rec: ForceRecord,
                          base: VehicleParams) -> tuple[np.ndarray, np.ndarray]:
    """:func:`gradient_differences` of record ``i`` of ``system`` for ``base``; the
    differences of every term (:func:`basis_differences`, which do not depend on the
    coefficients, and which every equation takes its terms from) kept in the system's cache
    when it has one."""
    key, key_h = (i, '_basis differences'), (i, '_basis steps')
    cache = system.cache
    if cache is not None and key in cache and key_h in cache:
        return gradient_differences(system.equation, rec.nu, base, (cache[key], cache[key_h]))
    full = basis_differences(rec.nu, base)
    if cache is not None:
        cache[key], cache[key_h] = full
    return gradient_differences(system.equation, rec.nu, base, full)


def _block_jackknife(design: np.ndarray, regressors: np.ndarray, b: np.ndarray,
                     blocks: int = JACKKNIFE_BLOCKS) -> tuple[np.ndarray, int]:
    """Delete-a-block jackknife covariance of ``theta = (D'A)^-1 D'b`` (D: design, A:
    regressors; D = A for least squares, the instrument projection for two-stage LS) over
    contiguous blocks of rows; returns it and the number of blocks."""
    n, p = design.shape
    blocks = int(max(2, min(blocks, n // max(10 * p, 1))))
    edges = np.linspace(0, n, blocks + 1).astype(int)
    G = design.T @ regressors
    h = design.T @ b
    thetas = np.empty((blocks, p))
    for k in range(blocks):
        sl = slice(edges[k], edges[k + 1])
        Gb = G - design[sl].T @ regressors[sl]
        hb = h - design[sl].T @ b[sl]
        thetas[k] = np.linalg.solve(Gb, hb)
    dev = thetas - thetas.mean(axis=0)
    return (blocks - 1.0) / blocks * (dev.T @ dev), blocks


def _smoothed_design(system: LinearSystem, design: np.ndarray
                     ) -> tuple[np.ndarray, list[np.ndarray | None]] | None:
    """The design with its noise filtered out, for the first-order (delta-method) covariance,
    which holds at the noise-free design: each record's rows low-passed by its kernel
    (normalised at the ends of the used rows); None if a record has no kernel. Returned with
    each record's smoothed rows in place among its samples (N, p), zero where unused (None for
    a record without rows)."""
    out = np.empty_like(design)
    full: list[np.ndarray | None] = []
    for i, rec in enumerate(system.records):
        sel = _record_rows(system.record_index, i)
        if sel is None:
            full.append(None)
            continue
        if rec.kernel is None or system.rows is None:
            return None
        rows = system.rows[sel]
        N = len(rec.t)
        used = np.zeros(N, bool)
        used[rows] = True
        d = np.zeros((N, design.shape[1]))
        d[rows] = design[sel]
        norm = np.convolve(used.astype(float), rec.kernel, mode='same')
        divisor = np.where(used, norm, 1.0)[:, None]
        for _ in range(DESIGN_SMOOTHING_PASSES):
            d = np.column_stack([np.convolve(d[:, j], rec.kernel, mode='same')
                                 for j in range(d.shape[1])])
            d = np.where(used[:, None], d / divisor, 0.0)
        out[sel] = d[rows]
        full.append(d)
    return (out, full) if system.records else None


def _hac_covariance(system: LinearSystem, As: np.ndarray, resid: np.ndarray,
                    theta: np.ndarray, base: VehicleParams, xtx: np.ndarray,
                    taus: Sequence[tuple[int, int | np.integer[Any], float]]
                    ) -> tuple[np.ndarray, np.ndarray, int, str, float]:
    """The ``'hac'`` sandwich ``(D'A)^-1 S (D'A)^-T`` of the column-scaled design ``As``
    (see the module docstring): ``S`` from the sensor-noise propagation when every record has
    a noise model that accounts for the residual, else from the flat-top lag window.

    Returns the bread ``D'A`` and the meat ``S`` (scaled coefficients), the largest lag
    window used [samples] (0 for the propagation), a description and the observed /
    predicted residual variance.
    """
    n, p = As.shape
    smoothed = _smoothed_design(system, As)
    smooth = None if smoothed is None else smoothed[0]
    propagated = None if smoothed is None else sensor_noise_meat(
        system, smoothed[0], resid, theta, base, smoothed[1])
    ratio = math.nan
    if propagated is not None and smooth is not None:
        meat, ratio = propagated
        if ratio <= NOISE_RATIO_MAX:
            bread = smooth.T @ (system.regressors / system.scale)
            return (bread, meat, 0,
                    f'sensor-noise propagation (residual variance {ratio:.2f} x predicted)',
                    ratio)
    meat = np.zeros((p, p))
    lags = 0
    g = As * resid[:, None]
    for i, _m, _ in taus:
        sel = system.record_index == i
        rec = system.records[i] if system.records else None
        memory = len(rec.kernel) - 1 if rec is not None and rec.kernel is not None else 1
        m_i = flat_top_lag(g[sel], memory)
        part = _flat_top_meat(g[sel], m_i)
        if np.min(np.linalg.eigvalsh(part)) < 0.0:
            part = _hac_meat(g[sel], 2 * m_i)
        lags = max(lags, 2 * m_i)
        meat += part
    dof = max(n - p, 1)
    why = '' if math.isnan(ratio) else (
        f'; residual variance {ratio:.3g} x the sensor-noise prediction')
    return (xtx, meat * (n / dof), lags, f'flat-top lag window, {lags} lags{why}', ratio)


class Covariance(NamedTuple):
    """Covariance of one equation's coefficients and how it was estimated."""

    scaled: np.ndarray      # (p, p) covariance of the coefficients times their column norms
    bread: np.ndarray       # (p, p) B = D'A of the scaled problem: scaled = B^-1 S B^-T
    meat: np.ndarray        # (p, p) S = Var(D'e) of the scaled problem
    n_effective: float      # effective sample size (records' lengths over their residual
    #                         correlation times)
    dof: float              # degrees of freedom of Student's t for the intervals
    lags: int               # largest lag window used [samples] (0: none)
    method: str             # how S was estimated ('iid', 'ess', 'jackknife' or the 'hac' way)
    noise_ratio: float      # observed / sensor-noise-predicted residual variance (NaN: none)


def coefficient_covariance(system: LinearSystem, resid: np.ndarray, theta: np.ndarray,
                           base: VehicleParams, errors: str) -> Covariance:
    """Covariance of the coefficients ``theta`` of ``system`` with residual ``resid`` by the
    method ``errors`` (one of :data:`ERROR_METHODS`, see the module docstring), for the
    column-scaled problem (divide by the outer product of :func:`column_scale` of
    ``system.A`` for the coefficients' own)."""
    A, b = system.A, system.b
    n, p = A.shape
    scale = system.scale
    As = A / scale
    xtx = As.T @ As
    dof = max(n - p, 1)
    sigma2 = float(resid @ resid) / dof
    # correlation times per record (the records are independent of each other)
    taus = []
    for i in range(len(system.record_names)):
        sel = system.record_index == i
        if np.count_nonzero(sel) > 3:
            tau_i = correlation_time(resid[sel])
            taus.append((i, np.count_nonzero(sel), tau_i))
    n_eff = sum(m / t for _, m, t in taus) if taus else float(n)
    tdof = n_eff - p
    lags = 0
    method = errors
    noise_ratio = math.nan
    bread = xtx
    if errors == 'iid':
        meat = sigma2 * xtx
        n_eff = float(n)
    elif errors == 'ess':
        meat = sigma2 * xtx * (n / n_eff)
    elif errors == 'jackknife':
        cov_j, blocks = _block_jackknife(As, system.regressors / scale, b)
        meat = xtx @ cov_j @ xtx
        tdof = blocks - 1.0
    else:
        bread, meat, lags, method, noise_ratio = _hac_covariance(system, As, resid, theta,
                                                                 base, xtx, taus)
    bread_inv = np.linalg.pinv(bread)
    cov_s = bread_inv @ meat @ bread_inv.T
    return Covariance(scaled=cov_s, bread=bread, meat=meat, n_effective=float(n_eff),
                      dof=float(tdof), lags=lags, method=method, noise_ratio=noise_ratio)
