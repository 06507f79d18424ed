"""The pilot's design (gain schedule and surge length) kept on disk between starts.

A pilot's design depends only on its vehicle file and its settings, yet takes most of a
node's start (108 trims, 36 discrete LQR designs: ~1 s of CPU, more than a loaded machine
gives it in the seconds a start may take). :func:`cached_design` keeps it in the cache of
:mod:`auv_sim.disk_cache` (``~/.cache/auv`` by default, ``$AUV_CACHE_DIR`` to move it, empty
to turn it off; ``rm -rf ~/.cache/auv`` clears it), keyed by the vehicle's parameters as
loaded, the gain-scheduling grid [m/s], the weights ``Q``, ``R`` (and ``R_rate`` of a plane-rate
design), the sample period [s] and
the source of ``auv_sim`` and ``auv_depth_lqr`` (the trim, the model, the design code): a
changed vehicle file, setting or line of code gives a new key. Values are stored exactly (JSON
floats in their shortest round-trip form), so a cached design equals the one computed afresh,
number for number; an entry that does not decode to a whole, finite schedule of the key's
sample period is ignored and the design computed again.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from auv_depth_lqr.schedule import N_FF, N_STATES, GainSchedule, Matrix
from auv_sim.disk_cache import cached
from auv_sim.params import VehicleParams

__all__ = ['DESIGN_KIND', 'DESIGN_PACKAGES', 'cached_design', 'design_data',
           'design_from_data', 'design_inputs']

DESIGN_KIND = 'pilot-design'
"""Kind (file prefix) of the pilot's design entries."""
DESIGN_PACKAGES = ('auv_sim', 'auv_depth_lqr')
"""The packages whose code the design runs (trim and model, design)."""

Design = tuple[GainSchedule, float]
"""A gain schedule and the surge length [m] of :func:`auv_depth_lqr.surge.surge_length`."""


def design_inputs(params: VehicleParams, speeds: Sequence[float], Q: Matrix, R: Matrix,
                  Ts: float, R_rate: Matrix | None = None) -> dict[str, Any]:
    """What the design depends on besides the code, as JSON data (the cache key's inputs).

    Parameters
    ----------
    params : VehicleParams
        The vehicle as loaded (every value of its file; not its name or path).
    speeds : sequence of float
        The gain-scheduling grid asked for [m/s] (before the untrimmable speeds are dropped).
    Q, R : ndarray
        Continuous weights (5, 5) and (1, 1).
    Ts : float
        Sample period [s].
    R_rate : ndarray, optional
        Weight (1, 1) of the plane's rate of a plane-rate design; None without.

    Returns
    -------
    dict
        JSON-serialisable inputs.
    """
    rate = {} if R_rate is None else {'R_rate': np.asarray(R_rate, dtype=float).tolist()}
    return {**rate,
            'vehicle': {name: float(value) for name, value in sorted(params.values.items())},
            'speeds': [float(u) for u in speeds],
            'Q': np.asarray(Q, dtype=float).tolist(), 'R': np.asarray(R, dtype=float).tolist(),
            'Ts': float(Ts)}


def design_data(design: Design) -> dict[str, Any]:
    """A design as JSON data (exact floats)."""
    schedule, surge = design
    arrays = {name: np.asarray(getattr(schedule, name), dtype=float).tolist()
              for name in ('speeds', 'K', 'w_e', 'theta_e', 'bar_e', 'F', 'P', 'D', 'Q', 'R',
                           'K_rate', 'R_rate')}
    return {**arrays, 'Ts': float(schedule.Ts), 'surge_length': float(surge)}


def _array(data: dict[str, Any], name: str, shape: tuple[int, ...]) -> Matrix:
    """``data[name]`` as a finite float array of ``shape``; ValueError otherwise."""
    out = np.array(data[name], dtype=np.float64)
    if out.shape != shape or not np.all(np.isfinite(out)):
        raise ValueError(f'{name}: not a finite array of shape {shape}')
    return out


def design_from_data(data: dict[str, Any], Ts: float) -> Design:
    """:func:`design_data`'s inverse, checked.

    Parameters
    ----------
    data : dict
        As :func:`design_data` wrote it.
    Ts : float
        The sample period the design must have [s].

    Returns
    -------
    tuple of GainSchedule and float
        The schedule and the surge length [m].

    Raises
    ------
    KeyError, TypeError, ValueError
        A missing item, an array of the wrong shape or with a non-finite value, a grid that
        is not strictly increasing and positive, another sample period.
    """
    speeds = np.array(data['speeds'], dtype=np.float64)
    g = speeds.shape[0] if speeds.ndim == 1 else 0
    if g == 0 or not np.all(np.isfinite(speeds)) or speeds[0] <= 0.0 \
            or np.any(np.diff(speeds) <= 0.0):
        raise ValueError('speeds: not a strictly increasing grid of positive speeds')
    if float(data['Ts']) != float(Ts):
        raise ValueError('another sample period')
    surge = float(data['surge_length'])
    if not math.isfinite(surge):
        raise ValueError('surge_length: not finite')
    rated = len(data['K_rate']) > 0  # a plane-rate design's gains, or none
    schedule = GainSchedule(
        speeds=speeds, K=_array(data, 'K', (g, N_STATES)), w_e=_array(data, 'w_e', (g,)),
        theta_e=_array(data, 'theta_e', (g,)), bar_e=_array(data, 'bar_e', (g,)),
        F=_array(data, 'F', (g, N_FF, 4)), Ts=float(Ts), P=_array(data, 'P', (g, 2, 4)),
        D=_array(data, 'D', (g, 4, 2)), Q=_array(data, 'Q', (N_STATES, N_STATES)),
        R=_array(data, 'R', (1, 1)),
        K_rate=_array(data, 'K_rate', (g, N_STATES + 1)) if rated
        else np.zeros((0, N_STATES + 1)),
        R_rate=_array(data, 'R_rate', (1, 1)) if rated else np.zeros((0, 0)))
    return schedule, surge


def cached_design(params: VehicleParams, speeds: Sequence[float], Q: Matrix, R: Matrix,
                  Ts: float, compute: Callable[[], Design], R_rate: Matrix | None = None
                  ) -> Design:
    """The pilot's design from the cache, or ``compute()`` (then stored).

    Parameters
    ----------
    params, speeds, Q, R, Ts, R_rate
        What the design depends on (:func:`design_inputs`).
    compute : callable
        Computes the design from these (:func:`auv_depth_lqr.pilot.build_controller`); its
        errors pass through and nothing is stored.

    Returns
    -------
    tuple of GainSchedule and float
        The gain schedule and the surge length [m].
    """
    return cached(DESIGN_KIND, design_inputs(params, speeds, Q, R, Ts, R_rate), DESIGN_PACKAGES,
                  compute, design_data, lambda data: design_from_data(data, Ts))
