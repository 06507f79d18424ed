"""Splitting a log into continuous segments: never interpolate across a gap.

A state sample is *usable* when every mapped state signal is there (finite, and for a signal
held from another topic, no older than the map's ``max_age``), the vehicle is submerged
(``z >= surface_depth`` when the map sets one) and the propeller runs (held thrust
``|T| >= thrust_off`` when set). Segments are the runs of usable samples with no time step
longer than ``max_gap`` [s] (default: 3 median sample periods); runs shorter than
``min_duration`` [s] are left out. Because the consumers split their input at pauses of more
than :data:`GAP_SPLIT` sample periods (and interpolate shorter ones), the
last samples of a segment are left out when needed so that consecutive segments are more than
that many periods apart; every sample left out is counted in the notes.

Resampling (only when the map asks, ``time: {grid: PERIOD}``): each segment's state onto
``t0 + k PERIOD`` by linear interpolation between its own samples (roll and yaw unwrapped
first, wrapped back to (-pi, pi] after); never across segments.
"""
from __future__ import annotations

import numpy as np

#: A pause in the state stream longer than this many median sample periods splits the log
#: for every consumer of a log (identification, gap diagnosis).
GAP_SPLIT = 5.0
#: Default largest step inside a segment, in median sample periods.
DEFAULT_GAP_PERIODS = 3.0
#: A step departing from the median step by more than this share of it breaks a uniformly
#: sampled stretch (the identification's derivative filter needs uniform samples).
UNIFORM_TOLERANCE = 0.25
#: Rows departing from the mean step by more than this share of it, in at least
#: :data:`JITTER_SHARE` of the steps, jitter (see :func:`spacing_jitter`).
JITTER_MEAN = 0.1
JITTER_SHARE = 0.25


def spacing_jitter(t: np.ndarray, tolerance: float = UNIFORM_TOLERANCE) -> str | None:
    """Why stamps ``t`` [s] (increasing) are not uniformly sampled, or None.

    A logger that writes rows at uneven intervals (a 2 Hz log whose rows alternate 0.39 and
    0.61 s apart) leaves no stretch uniform enough for a derivative filter, however long the
    segment: a quarter or more of the steps departing from the median step by more than
    ``tolerance`` of it (the rule by which the identification splits a log into uniformly
    sampled stretches), or from the mean step by more than :data:`JITTER_MEAN` of it (taken
    as uniform, the rows would sit that far from their stamps). The sentence names the
    spacing found and the fix, resampling onto a grid (``time: {grid: PERIOD}`` in the map,
    at the mean step).
    """
    d = np.diff(np.asarray(t, float))
    d = d[d > 0]
    if d.size < 4:
        return None
    med = float(np.median(d))
    d = d[d <= DEFAULT_GAP_PERIODS * med]          # gaps split segments anyway
    mean = float(np.mean(d))
    off_median = float(np.mean(np.abs(d - med) > tolerance * med))
    off_mean = float(np.mean(np.abs(d - mean) > JITTER_MEAN * mean))
    if max(off_median, off_mean) < JITTER_SHARE:
        return None
    lo, hi = (float(v) for v in np.quantile(d, [0.05, 0.95]))
    return (f'row spacing jitter: steps of {lo:.3g} to {hi:.3g} s around a mean of '
            f'{mean:.3g} s ({off_mean:.0%} depart from it by more than {JITTER_MEAN:.0%}, '
            f'{off_median:.0%} from the median {med:.3g} s by more than {tolerance:.0%}), so no '
            'stretch is uniformly sampled; resample onto a uniform grid with time: {grid: '
            f'{_round_period(mean):g}}} in the map')


def _round_period(p: float) -> float:
    """A period [s] rounded to two significant digits (a grid the user would write)."""
    if p <= 0:
        return p
    digits = 1 - int(np.floor(np.log10(p)))
    return float(round(p, digits))


def split(t: np.ndarray, usable: np.ndarray, *, max_gap: float | None,
          min_duration: float) -> tuple[list[slice], list[str]]:
    """Segments of stamps ``t`` [s] (N, increasing) where ``usable`` (N, bool) holds.

    Returns the slices (into ``t``) and one note per rule that removed samples.
    """
    n = len(t)
    notes: list[str] = []
    if n < 2:
        return [], ['fewer than 2 samples']
    period = float(np.median(np.diff(t)))
    gap = max_gap if max_gap is not None else DEFAULT_GAP_PERIODS * period
    cut = np.zeros(n, bool)
    cut[1:] = np.diff(t) > gap
    if np.any(cut):
        notes.append(f'{int(np.count_nonzero(cut))} time gap(s) longer than {gap:.3g} s: split '
                     'there (not interpolated)')
    runs: list[slice] = []
    start: int | None = None
    for i in range(n):
        if not usable[i] or cut[i]:
            if start is not None:
                runs.append(slice(start, i))
            start = i if usable[i] else None
        elif start is None:
            start = i
    if start is not None:
        runs.append(slice(start, n))
    kept = [r for r in runs if t[r.stop - 1] - t[r.start] >= min_duration]
    short = len(runs) - len(kept)
    if short:
        dropped = sum(r.stop - r.start for r in runs if r not in kept)
        notes.append(f'{short} stretch(es) shorter than {min_duration:g} s left out '
                     f'({dropped} samples)')
    separation = GAP_SPLIT * period
    trimmed = 0
    out: list[slice] = []
    for k, r in enumerate(kept):
        stop = r.stop
        if k + 1 < len(kept):
            nxt = t[kept[k + 1].start]
            while stop > r.start and nxt - t[stop - 1] <= separation:
                stop -= 1
                trimmed += 1
        if stop - r.start >= 2:
            out.append(slice(r.start, stop))
    if trimmed:
        notes.append(f'{trimmed} sample(s) at segment ends left out so that segments are more '
                     f'than {GAP_SPLIT:g} periods ({separation:.3g} s) apart')
    return out, notes


def resample(t: np.ndarray, state: np.ndarray, period: float) -> tuple[np.ndarray, np.ndarray]:
    """One segment's state (N x 12, NED/FRD, rad) at stamps ``t`` [s] onto the uniform grid
    ``t[0] + k period`` [s] up to ``t[-1]``, by linear interpolation (see module docstring)."""
    n = int(np.floor((t[-1] - t[0]) / period + 1e-9)) + 1
    grid = t[0] + period * np.arange(n)
    out = np.empty((n, state.shape[1]))
    for k in range(state.shape[1]):
        col = np.unwrap(state[:, k]) if k in (3, 5) else state[:, k]
        out[:, k] = np.interp(grid, t, col)
        if k in (3, 5):
            out[:, k] = np.angle(np.exp(1j * out[:, k]))
    return grid, out
