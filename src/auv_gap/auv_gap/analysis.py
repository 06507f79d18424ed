"""Where the gap lies: free-run and equation-error summaries of the nominal model.

Everything here describes the nominal model against the log, before any effect is fitted:
per-state free-run RMS, per-equation RMS, the dominant equation, the windows where the
depth error is largest, operating-regime bins, the frequency band of the residual and its
correlation with inputs and states at lags (a peak against the BAR rate at a lag points to a
delay).
"""
from __future__ import annotations

import itertools
from typing import Any

import numpy as np
from scipy.signal import savgol_filter, welch

from auv_gap.problem import EQ_ROWS, EQUATIONS, Problem

#: An equation (or state) whose nominal RMS exceeds its noise level by this factor has a gap.
GAP_FACTOR = 1.5
MAX_LAG = 5.0  # s, correlation lags
#: Fewest equation samples of a log piece whose spectrum is taken.
MIN_SPECTRUM = 64


def dominant_equation(eq_rms: np.ndarray, sigma: np.ndarray) -> str | None:
    """The body equation with the largest RMS relative to its noise, if it exceeds it."""
    ratio = eq_rms[:5] / sigma[:5]
    k = int(np.argmax(ratio))
    return EQUATIONS[k] if ratio[k] > GAP_FACTOR else None


def regimes(pr: Problem, residual: np.ndarray, act_bar: np.ndarray, bins: int = 4
            ) -> dict[str, Any]:
    """RMS and mean of ``residual`` (at the equation samples) in quantile bins of speed u
    [m/s], depth z [m], pitch theta [deg] and plane angle BAR [deg]."""
    xs = pr.eq_state
    signals = {'speed_mps': xs[:, 6], 'depth_m': xs[:, 2], 'pitch_deg': np.degrees(xs[:, 4]),
               'plane_deg': np.degrees(act_bar)}
    out: dict[str, Any] = {}
    for name, sig in signals.items():
        edges = np.unique(np.quantile(sig, np.linspace(0, 1, bins + 1)))
        rows = []
        for a, b in itertools.pairwise(edges):
            m = (sig >= a) & ((sig < b) | (b == edges[-1]))
            if m.sum() < 5:
                continue
            rows.append({'lo': float(a), 'hi': float(b), 'n': int(m.sum()),
                         'rms': float(np.sqrt(np.mean(residual[m] ** 2))),
                         'mean': float(np.mean(residual[m]))})
        out[name] = rows
    return out


def _pieces(pr: Problem, values: np.ndarray) -> list[np.ndarray]:
    """Split equation-sample values into per-log, time-ordered pieces."""
    return [values[pr.eq_log == li] for li in range(len(pr.logs))]


def expected_noise_psd(pr: Problem, row: int, fs: float, nperseg: int, seed: int = 0
                       ) -> np.ndarray:
    """Welch PSD (``nperseg // 2 + 1`` frequencies) of the equation error ``row`` (index of
    :data:`EQUATIONS`) that sensor noise alone gives, by simulating the noise through the same
    derivative filter and decimation, over enough samples for eight segments whatever the
    length of the logs."""
    rng = np.random.default_rng(seed)
    nwin = max(s.length for s in pr.smoothed)
    every = max(1, int(round(1.0 / (fs * pr.period))))
    n = min(max(8 * nperseg * every, 4 * nwin), 200_000)
    acc = None
    for _ in range(3):
        noise = rng.standard_normal((n, 12)) * pr.noise
        d = savgol_filter(noise, nwin, 3, deriv=1, delta=pr.period, axis=0)
        e = (d[:, 6:12] @ pr.M.T)[:, EQ_ROWS[row]] if row < 5 else d[:, 2] - noise[:, 8]
        _, p = welch(e[::every], fs=fs, nperseg=nperseg)
        acc = p if acc is None else acc + p
    assert acc is not None
    psd: np.ndarray = acc / 3.0
    return psd


def band(pr: Problem, residual: np.ndarray, row: int) -> tuple[list[float] | None, dict[str, Any]]:
    """Frequency band [Hz] holding the central 80 % of the residual's power above the noise
    expectation, or None when the excess is under a quarter of the noise power. Spectra are
    taken per log piece (Welch, one segment length for all: the shortest piece of at least
    :data:`MIN_SPECTRUM` samples) and averaged; pieces shorter are left out, whatever their
    order."""
    fs = 1.0 / pr.eq_step
    pieces = [p for p in _pieces(pr, residual) if p.size >= MIN_SPECTRUM]
    if not pieces:
        return None, {}
    nperseg = int(min(min(p.size for p in pieces), 1024))
    psd = None
    for p in pieces:
        f, q = welch(p - 0.0, fs=fs, nperseg=nperseg, detrend=False)
        psd = q if psd is None else psd + q
    assert psd is not None
    psd /= len(pieces)
    noise = expected_noise_psd(pr, row, fs, nperseg)
    excess = np.clip(psd - noise, 0.0, None)
    info = {'f': f, 'psd': psd, 'noise': noise}
    if excess.sum() < 0.25 * noise.sum():
        return None, info
    cum = np.cumsum(excess) / excess.sum()
    lo = float(f[np.searchsorted(cum, 0.1)])
    hi = float(f[min(np.searchsorted(cum, 0.9), f.size - 1)])
    return [lo, hi], info


def correlations(pr: Problem, residual: np.ndarray, signals: dict[str, np.ndarray]
                 ) -> list[dict[str, Any]]:
    """Peak normalised cross-correlation of ``residual`` with each signal over lags of
    +-MAX_LAG s; a positive lag means the signal leads the residual."""
    dt = pr.eq_step
    nlag = int(round(MAX_LAG / dt))
    res_p = [p - p.mean() for p in _pieces(pr, residual)]
    out = []
    for name, sig in signals.items():
        sig_p = [s - s.mean() for s in _pieces(pr, sig)]
        best = (0.0, 0.0)
        curve = []
        for lag in range(-nlag, nlag + 1):
            num = 0.0
            d1 = 0.0
            d2 = 0.0
            for r, s in zip(res_p, sig_p):
                if r.size <= abs(lag) + 2:
                    continue
                if lag >= 0:
                    a, b = r[lag:], s[:r.size - lag]
                else:
                    a, b = r[:lag], s[-lag:]
                num += float(a @ b)
                d1 += float(a @ a)
                d2 += float(b @ b)
            c = num / np.sqrt(d1 * d2) if d1 > 0 and d2 > 0 else 0.0
            curve.append(c)
            if abs(c) > abs(best[0]):
                best = (c, lag * dt)
        out.append({'signal': name, 'peak_corr': float(best[0]), 'lag_s': float(best[1]),
                    'curve': curve, 'lags': [k * dt for k in range(-nlag, nlag + 1)]})
    return out


def segments(pr: Problem, windows: list[int], rms_z: np.ndarray, top: int = 5
             ) -> list[dict[str, Any]]:
    """The ``top`` windows with the largest nominal free-run depth RMS, largest first: times
    ``t0``, ``t1`` [s] since the start of their log (:attr:`GapLog.origin`), the log's
    name."""
    order = np.argsort(-np.where(np.isfinite(rms_z), rms_z, np.inf))[:top]
    out = []
    for i in order:
        w = pr.windows[windows[i]]
        lg = pr.logs[w.log]
        out.append({'t0': w.t0 - lg.origin, 't1': w.t1 - lg.origin, 'rms_z': float(rms_z[i]),
                    'log': lg.name.split('#')[0]})
    return out


def time_origin(pr: Problem) -> dict[str, Any]:
    """What the report's times count from: each log's start (its first stamp) and that
    instant in UTC where known, per log name."""
    out: dict[str, Any] = {}
    for lg in pr.logs:
        out.setdefault(lg.name.split('#')[0], {'stamp_s': lg.origin, 'utc': lg.origin_utc})
    return {'times': 'seconds since the start of each log', 'logs': out}
