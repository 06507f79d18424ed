"""LQR weights of the depth pilot: the diagonal continuous cost and its named presets.

Design state ``X = (w, q, z, theta, xi)`` (heave [m/s] and pitch rate [rad/s] in the body
frame FRD, depth [m] NED down, pitch [rad] nose up, integrated depth error [m s]) and input
BAR [rad]. The vehicle's own weights are derived from its file by
:func:`auv_depth_lqr.tuning.derive_tuning`; :data:`DEFAULT_WEIGHTS` are the A18M's.
"""
from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from auv_depth_lqr.errors import DesignError

__all__ = ['DEFAULT_WEIGHTS', 'PRESETS', 'Weights', 'preset']

Matrix = NDArray[np.float64]


class Weights(NamedTuple):
    """Diagonal LQR weights of the continuous cost ``int (X'QX + R BAR^2) dt``."""

    Q: tuple[float, float, float, float, float]
    """Diagonal of Q for ``(w, q, z, theta, xi)`` [s/m^2, s/rad^2, 1/(m^2 s), 1/(rad^2 s),
    1/(m^2 s^3)]."""
    R: float
    """Weight of BAR [1/(rad^2 s)]."""

    def matrices(self) -> tuple[Matrix, Matrix]:
        """``(Q, R)`` as a (5, 5) diagonal matrix and a (1, 1) matrix."""
        return np.diag(np.asarray(self.Q, dtype=float)), np.array([[float(self.R)]])


# Bryson-style start (each entry 1 / acceptable excursion^2), then tuned on the report's model
# scaled with speed and checked on the nonlinear 6-DOF A18M model (closed loop with the BAR
# angle/rate limits and the reference governor, bench/bench_closed_loop.py): the pitch-rate and
# pitch terms dominate the depth term, so a depth error is removed by a well-damped attitude
# change, never by a pitch oscillation. The manoeuvre itself is flown by the governor's
# feed-forward; the feedback only corrects model error, so its depth weight stays moderate:
# a 9x larger depth weight (0.1 m) gained under 1 % of settling time on the A18M and raised the
# pitch-rate activity after settling. Closed-loop poles at 1-3 m/s on the A18M: damping ratio
# >= 0.76, depth mode ~0.25 rad/s at 2 m/s, integral mode ~0.07 rad/s (checked in the tests).
DEFAULT_WEIGHTS = Weights(
    Q=(
        1.0 / 0.1**2,     # w: 0.1 m/s heave excursion; damps the heave (angle-of-attack) mode
        1.0 / 0.03**2,    # q: 0.03 rad/s (1.7 deg/s) pitch rate: the anti-porpoising term
        1.0 / 0.3**2,     # z: 0.3 m depth error (away from the governed reference)
        1.0 / 0.06**2,    # theta: 0.06 rad (3.3 deg) pitch away from the feed-forward attitude
        1.0 / 4.5**2,     # xi: 4.5 m s integrated depth error; slow trim-bias removal only
    ),
    R=1.0 / 0.1**2,       # BAR: 0.1 rad (5.7 deg) of plane for the excursions above
)
"""Default weights for "depth without pitch oscillation" (see the comments in the source)."""

PRESETS: Mapping[str, Weights] = MappingProxyType({
    'default': DEFAULT_WEIGHTS,
    # Report section 4.4 ("default values provided"): Q = diag(1e-6, 1, 100, 10, 0.1), R = 1e9.
    'report_4_4': Weights(Q=(1e-6, 1.0, 100.0, 10.0, 0.1), R=1e9),
    # Report section 5 ("best result"): Q = diag(1e8, 1e8, 350, 450, 1e-5), R = 1e8.
    'report_5': Weights(Q=(1e8, 1e8, 350.0, 450.0, 1e-5), R=1e8),
})
"""Named weight sets: ``'default'`` and the report's two tunings for reproduction."""


def preset(name: str) -> Weights:
    """The weights called ``name`` in :data:`PRESETS`; :class:`DesignError` if unknown."""
    try:
        return PRESETS[name]
    except KeyError:
        known = ', '.join(sorted(PRESETS))
        raise DesignError(f'unknown weight preset {name!r}; known presets: {known}') from None

