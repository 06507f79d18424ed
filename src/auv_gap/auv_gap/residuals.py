"""Residual tests: is anything left in a candidate's held-out residuals?

A candidate explains the gap only if what it leaves behind looks like sensor noise: no
autocorrelation (Ljung-Box), no mean, and no correlation with the inputs or with the
operating point (depth, speed, pitch, heave velocity, pitch rate; for the free-run errors
also heave and pitch acceleration, where an inertia error shows; not for the equation errors,
whose noise is the measured acceleration's own). Structure left over names
where the rest of the gap is: which equation, and what it follows ("follows depth").

The residuals are equation errors of the held-out windows (``M nu_dot - tau`` per body
equation over its noise level, and the depth-kinematics error), one-step residuals in the
sense of Ljung (1999, System Identification, sec. 16.6). They are taken at a spacing no
shorter than the smoothing filter, so that sensor noise alone gives nearly independent
samples. The tests still allow for autocorrelation:

* Ljung-Box ``Q = n (n + 2) sum_k rho_k^2 / (n - k)``, chi-square with ``h`` degrees of
  freedom (Ljung and Box 1978), autocorrelations pooled over the windows;
* the mean against its standard error with the effective sample size
  ``n_eff = n / (1 + 2 sum_k rho_k)`` (lags up to ``h``, positive sum only);
* cross-correlation with each signal at lags of +-``max_lag`` samples, its null variance by
  Bartlett's formula ``var r_xy(k) = (1/n) sum_j rho_xx(j) rho_yy(j)`` (Box, Jenkins and
  Reinsel 2008, sec. 11.1.3): the effective sample size ``n / sum_j rho_xx(j) rho_yy(j)``
  of an autocorrelated signal against an autocorrelated residual. No pre-whitening.

All tests of one diagnosis share the family-wise level ``alpha`` (Bonferroni).
"""
from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np
from scipy import stats

#: Family-wise level of all residual tests of a diagnosis.
ALPHA = 0.01
#: Ljung-Box lags.
LB_LAGS = 10
#: Cross-correlation lags (samples each way).
XC_LAGS = 5

#: How a residual that follows a signal is described.
FOLLOWS = {'z': 'depth', 'u': 'speed', 'theta': 'pitch', 'w': 'heave velocity',
           'q': 'pitch rate', 'w_dot': 'heave acceleration', 'q_dot': 'pitch acceleration',
           'bar_command': 'the plane command', 'bar_command_rate': 'the plane command rate',
           'thrust_command': 'the thrust command'}


@dataclasses.dataclass(frozen=True)
class Finding:
    """One residual test: equation, test (``ljung_box``, ``mean``, ``xcorr:<signal>``), its
    statistic, p-value (one test, before the Bonferroni correction), and the text naming the
    structure when it is significant."""

    equation: str
    test: str
    statistic: float
    p_value: float
    n_eff: float
    text: str


def _acf(pieces: Sequence[np.ndarray], h: int) -> tuple[np.ndarray, int]:
    """Autocorrelation (lags 0..h) pooled over pieces (each centred on the pooled mean)."""
    allv = np.concatenate(pieces)
    mu = float(np.mean(allv))
    c = [p - mu for p in pieces]
    c0 = float(sum(float(p @ p) for p in c))
    rho = np.zeros(h + 1)
    if c0 <= 0:
        return rho, allv.size
    for k in range(h + 1):
        rho[k] = sum(float(p[k:] @ p[:p.size - k]) for p in c if p.size > k) / c0
    return rho, allv.size


def ljung_box(pieces: Sequence[np.ndarray], lags: int = LB_LAGS) -> tuple[float, float]:
    """Ljung-Box ``Q`` over ``lags`` lags of a residual given as time-ordered pieces, and its
    p-value (chi-square, ``lags`` degrees of freedom)."""
    rho, n = _acf(pieces, lags)
    k = np.arange(1, lags + 1)
    q = float(n * (n + 2) * np.sum(rho[1:] ** 2 / (n - k)))
    return q, float(stats.chi2.sf(q, lags))


def mean_test(pieces: Sequence[np.ndarray], lags: int = LB_LAGS) -> tuple[float, float, float]:
    """``(t, p, n_eff)``: the residual's mean over its standard error with the effective
    sample size (two-sided normal p-value)."""
    rho, n = _acf(pieces, lags)
    n_eff = n / max(1.0, 1.0 + 2.0 * float(np.sum(rho[1:])))
    allv = np.concatenate(pieces)
    sd = float(np.std(allv, ddof=1))
    if sd <= 0:
        return 0.0, 1.0, n_eff
    t = float(np.mean(allv) / (sd / np.sqrt(n_eff)))
    return t, float(2.0 * stats.norm.sf(abs(t))), n_eff


def cross_correlation(res: Sequence[np.ndarray], sig: Sequence[np.ndarray],
                      max_lag: int = XC_LAGS, acf_lags: int = 20
                      ) -> tuple[float, int, float, float]:
    """Largest normalised cross-correlation of residual and signal (pieces alike) over lags
    ``-max_lag..max_lag`` (positive: the signal leads), with its p-value under independence
    (Bartlett's variance, Sidak-corrected over the lags) and the effective sample size.

    Returns ``(r, lag, p, n_eff)``.
    """
    mr = float(np.mean(np.concatenate(res)))
    ms = float(np.mean(np.concatenate(sig)))
    rr = [p - mr for p in res]
    ss = [p - ms for p in sig]
    d1 = sum(float(p @ p) for p in rr)
    d2 = sum(float(p @ p) for p in ss)
    n = sum(p.size for p in rr)
    if d1 <= 0 or d2 <= 0:
        return 0.0, 0, 1.0, float(n)
    best, best_lag = 0.0, 0
    for lag in range(-max_lag, max_lag + 1):
        num = 0.0
        for a, b in zip(rr, ss):
            if a.size <= abs(lag):
                continue
            num += float(a[lag:] @ b[:b.size - lag]) if lag >= 0 else \
                float(a[:lag] @ b[-lag:])
        r = num / np.sqrt(d1 * d2)
        if abs(r) > abs(best):
            best, best_lag = r, lag
    rho_r, _ = _acf(res, acf_lags)
    rho_s, _ = _acf(sig, acf_lags)
    factor = max(1.0, 1.0 + 2.0 * float(np.sum(rho_r[1:] * rho_s[1:])))
    n_eff = n / factor
    z = abs(best) * np.sqrt(n_eff)
    p_one = 2.0 * float(stats.norm.sf(z))
    p = 1.0 - (1.0 - p_one) ** (2 * max_lag + 1)
    return float(best), best_lag, float(p), float(n_eff)


@dataclasses.dataclass(frozen=True)
class Group:
    """Residuals sampled alike: name -> time-ordered pieces (one per held-out window) of a
    normalised residual, the signals at the same samples (keys of :data:`FOLLOWS`), the
    sample spacing ``period`` [s], and ``white``: whether the residual of a right model is
    white (one-step equation errors: Ljung-Box and mean tests apply) or coloured (free-run
    output errors: only the cross-correlations apply, with Bartlett's variance over
    ``acf_lags`` lags)."""

    residuals: dict[str, list[np.ndarray]]
    signals: dict[str, list[np.ndarray]]
    period: float
    white: bool
    acf_lags: int = 20


def _group_findings(g: Group) -> list[Finding]:
    findings: list[Finding] = []
    for eq, raw in g.residuals.items():
        # pieces (held-out windows) shorter than LB_LAGS + 3 samples, as the short windows of
        # a vehicle unstable without feedback give: fewer lags, a third of the longest piece
        longest = max((p.size for p in raw), default=0)
        lags = LB_LAGS if longest > LB_LAGS + 2 else max(2, longest // 3)
        keep = [k for k, p in enumerate(raw) if p.size > lags + 2]
        pieces = [raw[k] for k in keep]
        if sum(p.size for p in pieces) < 4 * lags:
            continue
        if g.white:
            q, p = ljung_box(pieces, lags)
            findings.append(Finding(eq, 'ljung_box', q, p, float(sum(x.size for x in pieces)),
                                    f'{eq}: autocorrelated (Ljung-Box Q = {q:.1f} over '
                                    f'{lags} lags)'))
            t, p, n_eff = mean_test(pieces, lags)
            findings.append(Finding(eq, 'mean', t, p, n_eff,
                                    f'{eq}: a constant part is left ({t:+.1f} standard '
                                    'errors)'))
        for name, spieces in g.signals.items():
            r, lag, p, n_eff = cross_correlation(pieces, [spieces[k] for k in keep],
                                                 acf_lags=g.acf_lags)
            what = FOLLOWS.get(name, name)
            when = '' if lag == 0 else f' {abs(lag) * g.period:.3g} s ' + \
                ('later' if lag > 0 else 'earlier')
            grows = 'grows' if r > 0 else 'falls'
            text = (f'{eq}: {grows} with {what}{when} (r = {r:+.2f}, effective n = '
                    f'{n_eff:.0f})')
            findings.append(Finding(eq, f'xcorr:{name}', r, p, n_eff, text))
    return findings


def residual_tests(groups: Sequence[Group], alpha: float = ALPHA
                   ) -> tuple[bool, list[Finding], list[str]]:
    """Run every test on every residual of ``groups``.

    Returns
    -------
    ``(white, findings, left_over)``: whether every test passes at the family-wise level
    ``alpha`` (Bonferroni over all tests), every test's finding, and the texts of the
    significant ones, most significant first ("heave: grows with depth (r = +0.41)").
    With no test possible (every piece too short) ``white`` is False and ``left_over``
    says so.
    """
    findings = [f for g in groups for f in _group_findings(g)]
    if not findings:    # nothing could be tested: not evidence of white residuals
        return False, [], ['the residuals could not be tested (held-out windows too short)']
    level = alpha / max(1, len(findings))
    left = [f.text for f in sorted(findings, key=lambda f: f.p_value) if f.p_value < level]
    return not left, findings, left


def predictive_gain(loss_a: Sequence[np.ndarray], loss_b: Sequence[np.ndarray],
                    lags: int) -> tuple[float, float, float]:
    """Diebold-Mariano test of equal predictive accuracy (Diebold and Mariano 1995): does
    model ``b`` predict held-out data better than model ``a``?

    ``loss_a``, ``loss_b``: per-sample losses (e.g. squared normalised free-run errors summed
    over the channels) of the two models on the same held-out samples, as time-ordered pieces
    (one per held-out window). The loss differential ``d = loss_a - loss_b`` is averaged over
    all samples; its long-run variance is the Newey-West (Bartlett-kernel) estimate with
    ``lags`` lags, autocovariances pooled over the pieces (each piece a run of its own, no
    products across pieces), so a gain carried by one window is weighed against the spread
    of every window's differential rather than against the number of windows.

    Returns ``(t, p, n_eff)``: the mean differential over its standard error, the one-sided
    p-value (normal reference) of "``b`` is no better", and the effective sample size.
    """
    d = [np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64)
         for a, b in zip(loss_a, loss_b)]
    allv = np.concatenate(d)
    n = allv.size
    if n < 2:
        return 0.0, 1.0, float(n)
    mu = float(np.mean(allv))
    c = [p - mu for p in d]
    gamma0 = sum(float(p @ p) for p in c) / n
    if gamma0 <= 0:
        return 0.0, 1.0, float(n)
    lrv = gamma0
    for k in range(1, max(0, lags) + 1):
        gk = sum(float(p[k:] @ p[:p.size - k]) for p in c if p.size > k) / n
        lrv += 2.0 * (1.0 - k / (lags + 1.0)) * gk
    lrv = max(lrv, gamma0 / n)
    t = mu / float(np.sqrt(lrv / n))
    return t, float(stats.norm.sf(t)), n * gamma0 / lrv
