"""How a logged signal was sampled: its own update rate and its resolution.

A logger that writes every sensor on every row repeats a slow sensor's value (a 1 Hz DVL on
2 Hz rows: each value on two rows) and prints values in steps (depth in 0.1 m steps). Taken
as data, a repeated value is a signal that stood still and then jumped; a quantised one has
no noise between its steps (second differences of zero), which a noise estimate takes for a
perfect sensor. The map says both (``rate:``, ``resolution:``, see
:mod:`auv_logs.mapping`); this module finds a signal's fresh samples, brings them onto
the time base, and recognises either pattern in a log whose map does not declare it (said
in the import report with the map key to declare it).

Quantisation noise: a value rounded to steps of ``q`` carries an error uniform on
``[-q/2, q/2]``, of standard deviation ``q / sqrt(12)`` (Widrow and Kollar 2008,
Quantization Noise, ch. 4): the least noise that signal can have.
"""
from __future__ import annotations

import math

import numpy as np

#: A signal repeating its value on more than this share of consecutive samples is noted as
#: slower than the log or quantised.
REPEAT_SHARE = 0.3
#: A signal is taken as quantised when at least this share of its nonzero steps are whole
#: multiples (to 2 % of the step) of its smallest step, with at least :data:`QUANTISED_MIN`
#: steps.
QUANTISED_SHARE = 0.95
QUANTISED_MIN = 20


def quantisation_sigma(step: float) -> float:
    """Standard deviation [unit of ``step``] of the rounding error of values logged in steps
    of ``step``: ``step / sqrt(12)``."""
    return step / math.sqrt(12.0)


def fresh_samples(t: np.ndarray, v: np.ndarray, rate: float) -> np.ndarray:
    """Indices of the samples of a signal updated at ``rate`` [Hz] that carry a new value:
    a value that differs from the previous one, or the first after ``1.5 / rate`` seconds
    without a new value (a sensor that read the same twice). Non-finite samples are never
    fresh."""
    keep = np.zeros(len(t), bool)
    last_t, last_v = -math.inf, math.nan
    hold = 1.5 / rate
    for i in range(len(t)):
        if not np.isfinite(v[i]):
            continue
        if v[i] != last_v or t[i] - last_t >= hold:
            keep[i] = True
            last_t, last_v = float(t[i]), float(v[i])
    return np.flatnonzero(keep)


def onto(t_src: np.ndarray, v_src: np.ndarray, at: np.ndarray, rate: float) -> np.ndarray:
    """A signal's fresh samples ``(t_src [s], v_src)`` at stamps ``at`` [s]: linear
    interpolation between consecutive fresh samples at most ``2 / rate`` seconds apart, the
    last one held for ``1 / rate`` seconds after it; NaN elsewhere (no value is made up
    across a gap the sensor left)."""
    out = np.full(at.shape, np.nan)
    if len(t_src) == 0:
        return out
    j = np.searchsorted(t_src, at, side='right') - 1
    inside = (j >= 0) & (j < len(t_src) - 1)
    jj = np.clip(j, 0, max(len(t_src) - 2, 0))
    if len(t_src) >= 2:
        t0, t1 = t_src[jj], t_src[jj + 1]
        close = inside & (t1 - t0 <= 2.0 / rate + 1e-9)
        frac = np.where(close, (at - t0) / np.where(t1 > t0, t1 - t0, 1.0), 0.0)
        out[close] = (v_src[jj] + frac * (v_src[jj + 1] - v_src[jj]))[close]
    last = (j == len(t_src) - 1) & (at - t_src[-1] <= 1.0 / rate + 1e-9)
    out[last] = v_src[-1]
    return out


def repeat_share(v: np.ndarray) -> float:
    """Share of consecutive finite samples with exactly the same value."""
    ok = np.isfinite(v[1:]) & np.isfinite(v[:-1])
    if not np.any(ok):
        return 0.0
    return float(np.mean(v[1:][ok] == v[:-1][ok]))


def logged_step(v: np.ndarray) -> float | None:
    """The step of a quantised signal (its smallest nonzero change, when nearly every change
    is a whole multiple of it: see :data:`QUANTISED_SHARE`), or None."""
    d = np.abs(np.diff(v[np.isfinite(v)]))
    d = d[d > 0]
    if d.size < QUANTISED_MIN:
        return None
    q = float(np.min(d))
    if q <= 1e-12 * max(float(np.max(np.abs(v[np.isfinite(v)]))), 1.0):
        return None
    ratio = d / q
    whole = np.abs(ratio - np.round(ratio)) <= 0.02
    return q if float(np.mean(whole)) >= QUANTISED_SHARE else None
