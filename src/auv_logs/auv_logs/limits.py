"""Logged actuator values outside the vehicle file's limits: used as logged, and reported.

The actuator model (:func:`auv_sim.model.actuator_rates`) saturates a command at the vehicle
file's ``bar_max``, ``helm_max``, ``thrust_min``/``thrust_max``. For a *logged* command that
would alter the data without a word (a plant logging 29-44 N of thrust against a file's
9.3 N gives a wrong drag coefficient with a tight interval). So before logs are reconstructed
or simulated, the limits are widened to cover what was logged, and every value outside the
file's limits is counted and reported (channel, count, range, the file's limit).
"""
from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np

from auv_sim.params import VehicleParams

#: Channel -> (lower limit name or None for -upper, upper limit name, unit).
LIMITS = {'bar': (None, 'bar_max', 'rad'), 'helm': (None, 'helm_max', 'rad'),
          'thrust': ('thrust_min', 'thrust_max', 'N')}


def as_logged(params: VehicleParams,
              commands: Iterable[Mapping[str, tuple[np.ndarray, np.ndarray]]]
              ) -> tuple[VehicleParams, dict[str, dict[str, Any]]]:
    """``params`` with the actuator limits widened to the logged commands of every log in
    ``commands`` (channel -> (stamps [s], values [rad or N])), and per channel with values
    outside the file's limits: ``count``, ``total``, ``min``, ``max`` (logged) and ``limits``
    (the file's)."""
    lo_seen: dict[str, float] = {}
    hi_seen: dict[str, float] = {}
    out_count: dict[str, int] = {}
    total: dict[str, int] = {}
    for cmds in commands:
        for ch, (lo_name, hi_name, _) in LIMITS.items():
            if ch not in cmds or len(cmds[ch][1]) == 0:
                continue
            v = np.asarray(cmds[ch][1], float)
            hi = params.values[hi_name]
            lo = params.values[lo_name] if lo_name else -hi
            out_count[ch] = out_count.get(ch, 0) + int(np.count_nonzero((v < lo) | (v > hi)))
            total[ch] = total.get(ch, 0) + len(v)
            lo_seen[ch] = min(lo_seen.get(ch, np.inf), float(np.min(v)))
            hi_seen[ch] = max(hi_seen.get(ch, -np.inf), float(np.max(v)))
    changes: dict[str, float] = {}
    report: dict[str, dict[str, Any]] = {}
    for ch, (lo_name, hi_name, unit) in LIMITS.items():
        if not out_count.get(ch):
            continue
        hi = params.values[hi_name]
        lo = params.values[lo_name] if lo_name else -hi
        report[ch] = {'count': out_count[ch], 'total': total[ch], 'min': lo_seen[ch],
                      'max': hi_seen[ch], 'limits': [lo, hi], 'unit': unit}
        if lo_name is None:
            changes[hi_name] = max(hi, abs(lo_seen[ch]), abs(hi_seen[ch]))
        else:
            changes[lo_name] = min(lo, lo_seen[ch])
            changes[hi_name] = max(hi, hi_seen[ch])
    return params.replace(**changes), report


def describe(report: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """One line per channel of :func:`as_logged`'s report."""
    return [f'{ch}: {r["count"]} of {r["total"]} logged commands outside the vehicle file\'s '
            f'limits [{r["limits"][0]:.4g}, {r["limits"][1]:.4g}] {r["unit"]} (logged '
            f'{r["min"]:.4g} .. {r["max"]:.4g}); used as logged, not clipped'
            for ch, r in report.items()]
