"""Figures of merit of a depth manoeuvre (pure): settling, overshoot, pitch, plane use.

Inputs are time series sampled at any rate: time ``t`` [s], depth ``z`` [m, NED down],
pitch ``theta`` [rad, nose up], pitch rate ``q`` [rad/s], dive-plane angle ``bar`` [rad].
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np


class StepMetrics(NamedTuple):
    """Figures of a depth step from ``z_start`` to ``z_target`` commanded at ``t_command``.

    ``settling_time`` [s] is the time after the command from which depth stays within
    ``+-band`` of the target to the end of the record (``nan`` if it never settles);
    ``overshoot`` [m] is the largest excursion past the target; ``peak_pitch`` [rad] the
    largest ``|theta|``; ``rms_q_settled`` [rad/s] the RMS pitch rate after settling;
    ``bar_saturation_time`` [s] the time spent with ``|bar|`` within 1e-3 rad of the limit.
    """

    z_start: float
    z_target: float
    settling_time: float
    overshoot: float
    peak_pitch: float
    rms_q_settled: float
    bar_saturation_time: float
    kinematic_bound: float

    def as_dict(self) -> dict[str, float]:
        """JSON-ready figures, with degrees added for the angles."""
        d = {k: float(v) for k, v in self._asdict().items()}
        d['peak_pitch_deg'] = math.degrees(self.peak_pitch)
        d['rms_q_settled_deg_s'] = math.degrees(self.rms_q_settled)
        d['settling_over_kinematic_bound'] = self.settling_time / self.kinematic_bound \
            if self.kinematic_bound > 0 else math.nan
        return d


def kinematic_bound(dz: float, u0: float, theta_max: float) -> float:
    """Shortest time [s] to change depth by ``dz`` [m] at speed ``u0`` [m/s] and pitch limit
    ``theta_max`` [rad]: ``|dz| / (u0 sin(theta_max))``."""
    return abs(dz) / (abs(u0) * math.sin(theta_max))


def step_metrics(t: np.ndarray, z: np.ndarray, theta: np.ndarray, q: np.ndarray,
                 bar: np.ndarray, z_target: float, t_command: float = 0.0, band: float = 0.1,
                 bar_max: float = math.inf, u0: float = 2.0,
                 theta_max: float = math.radians(25.0)) -> StepMetrics:
    """Figures of a depth step (see :class:`StepMetrics`)."""
    t = np.asarray(t, dtype=float)
    after = t >= t_command - 1e-9
    if not np.any(after):
        raise ValueError(f'no samples at or after the command time {t_command} s')
    t, z, theta, q, bar = (np.asarray(a, dtype=float)[after] for a in (t, z, theta, q, bar))
    z_start = float(z[0])
    direction = math.copysign(1.0, z_target - z_start)
    outside = np.abs(z - z_target) > band
    if outside[-1]:
        settle_index = None
    else:
        last_out = np.flatnonzero(outside)
        settle_index = int(last_out[-1]) + 1 if last_out.size else 0
    settling = float(t[settle_index] - t_command) if settle_index is not None else math.nan
    overshoot = float(max(0.0, np.max(direction * (z - z_target))))
    if settle_index is not None and settle_index < len(q) - 1:
        rms_q = float(np.sqrt(np.mean(q[settle_index:] ** 2)))
    else:
        rms_q = math.nan
    dt = np.diff(t, append=t[-1])
    saturated = np.abs(bar) >= bar_max - 1e-3 if math.isfinite(bar_max) else np.zeros_like(bar,
                                                                                          bool)
    return StepMetrics(z_start=z_start, z_target=float(z_target), settling_time=settling,
                       overshoot=overshoot, peak_pitch=float(np.max(np.abs(theta))),
                       rms_q_settled=rms_q, bar_saturation_time=float(np.sum(dt[saturated])),
                       kinematic_bound=kinematic_bound(z_target - z_start, u0, theta_max))
