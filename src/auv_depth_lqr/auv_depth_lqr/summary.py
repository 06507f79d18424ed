"""JSON-ready summary of one depth-loop design (trim, model, gain, closed-loop poles).

Used by ``auv design``. Pure: no ROS import, no file I/O.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from auv_depth_lqr.errors import DesignError
from auv_depth_lqr.lqr import controllability, lqrd
from auv_depth_lqr.schedule import Linearize, check_linearization
from auv_depth_lqr.weights import DEFAULT_WEIGHTS

__all__ = ['STATE_NAMES', 'design_summary']

STATE_NAMES = ('w', 'q', 'z', 'theta', 'xi')
"""Design states: heave [m/s], pitch rate [rad/s], depth [m], pitch [rad], int(z - z_ref) [m s]."""


def _poles(values: NDArray[np.complex128], discrete: bool, ts: float) -> list[dict[str, float]]:
    """Poles sorted by real part, each with natural frequency [rad/s] and damping ratio.

    Discrete poles are mapped to the s-plane with ``s = ln(z) / Ts`` for the frequency and
    damping; a pole at ``z = 0`` (deadbeat) gets frequency ``inf`` and damping 1.
    """
    rows = []
    for p in sorted(values, key=lambda c: (c.real, c.imag)):
        p = complex(p)
        if discrete:
            s = complex(math.log(abs(p)), math.atan2(p.imag, p.real)) / ts if p != 0 else None
        else:
            s = p
        if s is None:
            wn, zeta = math.inf, 1.0
        else:
            wn = abs(s)
            zeta = -s.real / wn if wn > 0.0 else 1.0
        rows.append({'re': p.real, 'im': p.imag, 'wn': wn, 'zeta': zeta})
    return rows


def design_summary(
    linearize: Linearize,
    u0: float,
    Q: ArrayLike | None = None,
    R: ArrayLike | None = None,
    Ts: float = 0.1,
) -> dict[str, Any]:
    """Trim, linear model, discrete LQR gain and closed-loop poles at surge speed ``u0``.

    Parameters
    ----------
    linearize : callable
        ``linearize(u0) -> (x_e, u_e, A, B)`` (see :mod:`auv_depth_lqr.controller`).
    u0 : float
        Surge speed of the trim [m/s], > 0.
    Q, R : array_like, optional
        Continuous weights (5, 5) and (1, 1); default :data:`DEFAULT_WEIGHTS`.
    Ts : float
        Sample period [s].

    Returns
    -------
    dict
        JSON-serialisable (floats, lists, strings only)::

            {"u0": m/s, "Ts": s, "states": [...], "input": "bar",
             "trim": {"w": m/s, "q": rad/s, "theta": rad, "bar": rad},
             "A": 5x5, "B": 5x1, "Q": 5x5, "R": 1x1, "K": 1x5 (u = bar_e - K (x - x_e)),
             "controllability": {"rank": int, "condition": float},
             "poles_continuous": [{"re", "im", "wn", "zeta"}],   # eig(A - B K)
             "poles_discrete": [{"re", "im", "wn", "zeta"}],     # eig(Phi - Gamma K)
             "min_damping": float}

        ``poles_continuous`` applies the discrete gain as continuous feedback (valid when
        ``Ts`` is small against the loop's time constants); ``poles_discrete`` are the
        sampled loop's, with ``wn`` and ``zeta`` of their s-plane equivalents ``ln(z)/Ts``.
        ``condition`` is ``null`` when the controllability matrix is singular.

    Raises
    ------
    DesignError
        On a bad speed, linearisation, weights or sample period.
    """
    speed = float(u0)
    if not (math.isfinite(speed) and speed > 0.0):
        raise DesignError(f'u0 must be finite and > 0 m/s, got {u0!r}')
    if (Q is None) != (R is None):
        raise DesignError('give both Q and R, or neither (then DEFAULT_WEIGHTS is used)')
    if Q is None or R is None:
        Q, R = DEFAULT_WEIGHTS.matrices()
    x_e, u_e, A, B = check_linearization(linearize, speed)
    result = lqrd(A, B, Q, R, Ts)
    ctrb = controllability(A, B)
    cont = np.linalg.eigvals(A - B @ result.K).astype(np.complex128)
    poles_c = _poles(cont, discrete=False, ts=float(Ts))
    poles_d = _poles(result.E, discrete=True, ts=float(Ts))
    return {
        'u0': speed,
        'Ts': float(Ts),
        'states': list(STATE_NAMES),
        'input': 'bar',
        'trim': {'w': float(x_e[0]), 'q': float(x_e[1]), 'theta': float(x_e[3]),
                 'bar': float(u_e)},
        'A': A.tolist(),
        'B': B.tolist(),
        'Q': np.asarray(Q, dtype=float).reshape(5, 5).tolist(),
        'R': np.asarray(R, dtype=float).reshape(1, 1).tolist(),
        'K': result.K.tolist(),
        'controllability': {
            'rank': ctrb.rank,
            'condition': ctrb.condition if math.isfinite(ctrb.condition) else None,
        },
        'poles_continuous': poles_c,
        'poles_discrete': poles_d,
        'min_damping': min(p['zeta'] for p in poles_d),
    }
