"""The true effect sizes of a simulated plant against a gap diagnosis's 95 % intervals (shared
by the gap benchmarks)."""
from __future__ import annotations

from typing import Any


def truth_in_intervals(report: dict[str, Any], truth: dict[str, dict[str, float]]
                       ) -> list[tuple[str, float, float, float]]:
    """``(key, true value, lo, hi)`` for every parameter of ``truth`` (``{effect: {parameter:
    value}}``) whose effect the best candidate of ``report`` (the report.json document) names,
    with that candidate's 95 % interval ``[lo, hi]``; ``key`` is the report's parameter key
    (``name``, or ``effect.name`` when the candidate names several effects). Empty when there
    is no best candidate."""
    best = report['best']
    if not best:
        return []
    entry = next(c for c in report['candidates'] if c['effect'] == best)
    named = best.split('+')
    out = []
    for effect, fields in truth.items():
        if effect not in named:
            continue
        for name, value in fields.items():
            key = name if len(named) == 1 else f'{effect}.{name}'
            lo, hi = entry['ci95'][key]
            out.append((key, value, lo, hi))
    return out
