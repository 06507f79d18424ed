"""Root finding for the reference governor: the largest root of an increasing function."""
from __future__ import annotations

import math
from collections.abc import Callable

__all__ = ['largest_root_below']


def largest_root_below(f: Callable[[float], float], lo: float, hi: float, f_lo: float,
                        f_hi: float, guess: float | None = None, tol: float = 1e-6) -> float:
    """Largest ``x`` in ``[lo, hi]`` with ``f(x) <= 0`` for an increasing ``f`` with
    ``f(lo) < 0 < f(hi)``, to ``tol`` times the bracket (regula falsi, Illinois variant:
    a handful of evaluations where bisection needs twenty). A ``guess`` inside the bracket
    (the last sample's root) is tried first, with a point just beside it."""
    width = tol * (hi - lo)
    if guess is not None and lo < guess < hi:
        for x in (guess, guess + 1e-4 * (hi - lo)):
            x = min(x, hi - 0.5 * width)
            fx = f(x)
            if fx > 0.0:
                hi, f_hi = x, fx
                break
            lo, f_lo = x, fx
    side = 0
    for _ in range(60):
        if hi - lo <= width:
            break
        if math.isfinite(f_hi) and math.isfinite(f_lo):
            x = hi - f_hi * (hi - lo) / (f_hi - f_lo)
            x = min(max(x, lo + 0.5 * width), hi - 0.5 * width)
        else:  # an endless stop on one side: bisect
            x = 0.5 * (lo + hi)
        fx = f(x)
        if fx > 0.0:
            hi, f_hi = x, fx
            if side == 1:
                f_lo *= 0.5
            side = 1
        else:
            lo, f_lo = x, fx
            if fx > -1e-6:  # within a micrometre of the target: done
                break
            if side == -1:
                f_hi *= 0.5
            side = -1
    return lo

