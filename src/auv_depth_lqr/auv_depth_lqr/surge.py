"""The surge speed a vehicle with its propeller held is heading for, from its measured trend.

Units: surge speed ``u`` [m/s] (body FRD, through the water when the pilot knows it), time
[s]. With the thrust held, the surge speed follows ``(m - Xudot) u_dot = T - k u |u| + X_h``
(``X_h`` the weight less the buoyancy along the body axis, ``(B - W) sin(theta)``, and the
drag of the lift in a climb or dive). About a speed ``u`` it settles with the time constant
``tau = (m - Xudot) / (2 k u) = surge_length / u``; a positively buoyant A18M diving 10 m
at 2 m/s slows to 1.69 m/s, and its plane with it (authority ~ u^2, 71 %). The first-order
prediction of the speed it is heading for is ``u + tau u_dot``; ``horizon`` seconds ahead,
``u + tau (1 - exp(-horizon / tau)) u_dot``.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from auv_sim.params import VehicleParams

__all__ = ['SurgeTrend', 'surge_length']


def surge_length(params: VehicleParams, speeds: Sequence[float]) -> float:
    """The surge time constant with the thrust held, times the speed [m], of a vehicle file:
    ``(m - Xudot) u / T'(u)`` with ``T(u)`` the thrust of its level trim at ``speeds`` [m/s]
    (the model's own surge drag, :meth:`auv_sim.trim.VerticalPlane.trim`; ``T'`` by finite
    differences over the speeds, ``2 T / u`` at a single speed), the median over the speeds
    (a drag ``k u^2`` gives ``(m - Xudot) / (2 k)`` at every speed). Raises TrimError if the
    vehicle cannot trim at a speed."""
    from auv_sim.trim import VerticalPlane  # the compiled model, only when solved

    plane = VerticalPlane(params)
    u = np.array(sorted(float(x) for x in speeds))
    thrust = np.array([plane.trim(x).thrust for x in u])
    slope = np.gradient(thrust, u) if u.size > 1 else 2.0 * thrust / u
    inertia = float(params.m) - float(params.Xudot)
    return float(np.median(inertia * u / slope))


class SurgeTrend:
    """Measured surge speed [m/s] and the speed it is heading for over a horizon.

    ``u_dot`` is estimated from two cascaded first-order low-passes of ``u`` with the time
    constant ``time`` [s]: ``(u_1 - u_2) / time`` (a filtered derivative: a white 0.01 m/s on
    ``u`` at 10 Hz gives a standard deviation of 1.5 mm/s^2 with ``time`` 1 s, measured).
    The speed ``horizon`` [s] ahead on the first-order response is
    ``u + tau (1 - exp(-horizon / tau)) u_dot``, ``tau = surge_length / u``.

    Parameters
    ----------
    surge_length : float
        The surge time constant times the speed [m] (:func:`surge_length`); 0 turns the
        prediction off (:meth:`update` returns ``u``).
    time : float
        Time constant of each low-pass [s].
    ts : float
        Sample period [s].
    horizon : float
        How far ahead the speed is predicted [s]; ``inf``: the steady speed it tends to.
    """

    def __init__(self, surge_length: float, time: float, ts: float,
                 horizon: float = math.inf) -> None:
        self.surge_length, self.time, self.ts, self.horizon = surge_length, time, ts, horizon
        self.reset()

    def reset(self) -> None:
        """Forget the trend (the next :meth:`update` starts the filters at its speed)."""
        self._u1: float | None = None
        self._u2 = 0.0

    @property
    def rate(self) -> float:
        """Filtered surge acceleration ``u_dot`` [m/s^2] (0 before the first sample)."""
        return 0.0 if self._u1 is None else (self._u1 - self._u2) / self.time

    def update(self, u: float) -> float:
        """Take the speed ``u`` [m/s] measured this sample; the speed it is heading for within
        the horizon [m/s] (``u`` itself when the prediction is off)."""
        if self._u1 is None:
            self._u1 = self._u2 = u
        alpha = self.ts / (self.time + self.ts)
        self._u1 += alpha * (u - self._u1)
        self._u2 += alpha * (self._u1 - self._u2)
        return self.ahead(u, self.horizon)

    def ahead(self, u: float, horizon: float = math.inf) -> float:
        """The speed [m/s] the trend heads for ``horizon`` [s] ahead of the measured ``u``
        [m/s] (``inf``: the speed it settles at, ``u + tau u_dot``), without taking a sample;
        ``u`` itself when the prediction is off."""
        if self.surge_length <= 0.0 or not math.isfinite(u) or u <= 0.0:
            return u
        tau = self.surge_length / u
        return u + tau * (1.0 - math.exp(-horizon / tau)) * self.rate
