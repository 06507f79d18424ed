"""Fitted effects in words: "current 0.30 m/s towards 030 deg", "the model's CZuw is 30 %
low", "..., after re-fitting CZuw, CMuq"."""
from __future__ import annotations

import math

import numpy as np

from auv_gap.fit import FitResult


def interval(lo: float, hi: float, digits: int = 3, sep: str = ' to ') -> str:
    """``lo`` and ``hi`` with as many significant digits (at least ``digits``) as it takes to
    print them apart: an interval never reads as a point ("3.33-3.33")."""
    for d in range(digits, 10):
        a, b = f'{lo:.{d}g}', f'{hi:.{d}g}'
        if a != b or lo == hi:
            return f'{a}{sep}{b}'
    return f'{lo:.10g}{sep}{hi:.10g}'


def _coefficients(fit: FitResult, idx: list[int]) -> tuple[list[str], list[str]]:
    """Texts of the identified coefficients (those the free run kept) that differ from the
    file value, and the names of every identified coefficient."""
    texts, names = [], []
    for i in idx:
        _, p = fit.effects.params[i]
        if not fit.active[i]:
            continue
        names.append(p.name)
        f = float(fit.values[i])
        if abs(f - 1.0) >= 0.005:
            how = 'low' if f > 1.0 else 'high'
            texts.append(f"the model's {p.name} is {abs(f - 1.0) * 100:.0f} % {how} (the "
                         f'logs give {f:.2f} x its value, 95 % interval '
                         f'{interval(fit.lo95[i], fit.hi95[i], sep="-")})')
    return texts, names


def _current(values: np.ndarray) -> str:
    n, e, d = (float(v) for v in values)
    speed = math.hypot(n, e)
    towards = math.degrees(math.atan2(e, n)) % 360.0
    return (f'a current of {speed:.2f} m/s towards {towards:03.0f} deg (north {n:+.2f}, '
            f'east {e:+.2f}, down {d:+.3f} m/s)')


def describe(fit: FitResult) -> str:
    """The fitted effect set in words, with values, units and 95 % intervals."""
    parts: list[str] = []
    after: list[str] = []
    k = 0
    for name, effect in zip(fit.effects.names, fit.effects.effects):
        n = len(effect.parameters(fit.effects.vehicle))
        idx = list(range(k, k + n))
        k += n
        if name == 'coefficients':
            texts, names = _coefficients(fit, idx)
            if len(fit.effects.names) > 1:
                after = names
                parts.extend(texts)
            else:
                parts.extend(texts or ["the model's vertical-plane coefficients re-fitted "
                                       '(none off by 0.5 % or more)'])
            continue
        if name == 'current':
            parts.append(_current(fit.values[idx]))
            continue
        vals = []
        for i in idx:
            _, p = fit.effects.params[i]
            if fit.active[i]:
                unit = '' if p.unit == '-' else f' {p.unit}'
                vals.append(f'{p.name} = {fit.values[i]:.4g}{unit} (95 % interval '
                            f'{interval(fit.lo95[i], fit.hi95[i], 4)})')
        parts.append(f'{name} ' + ', '.join(vals) if vals else name)
    text = '; '.join(parts)
    if after:
        text += ', after re-fitting ' + ', '.join(after)
    return text
