"""The steady climb or dive of a vehicle whose thrust is held: how steep it may be planned.

Frames and units (Fossen): body FRD, surge ``u`` and heave ``w`` [m/s]; pitch ``theta`` nose
up [rad]; BAR [rad]; surge force ``X``, heave force ``Z`` [N], pitch moment ``M`` [N m]; the
vertical speed ``v = z_dot = -u sin(theta) + w cos(theta)`` [m/s] is positive down.

With its propeller held, a vehicle that climbs or dives settles at the speed where the thrust
``T`` balances its drag and the weight less the buoyancy along its axis: a positively
buoyant REMUS 100 diving at 23 deg with the thrust of 1.5 m/s slows to 0.8 m/s, where holding
its trim takes 11 of its 13.6 deg of plane. A dive planned at the pitch limit then leaves no
plane to stop it. :func:`steady_glide` solves that steady motion at a given pitch (surge,
heave and pitch in equilibrium: ``X + T = Z = M = 0``); :func:`glide_cap` walks the pitch
from level towards the limit and returns the fastest steady climb or dive whose plane stays
within a bound, or ``inf`` when the one at the pitch limit itself does (the pitch limit, not
the plane, bounds the motion).
"""
from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

__all__ = ['Force', 'Glide', 'glide_cap', 'steady_glide']

Force = Callable[[float, float, float, float], tuple[float, float, float]]
"""``force(u, w, theta, bar) -> (X [N], Z [N], M [N m])``: the vehicle's surge and heave
force and pitch moment, without the thrust, in a steady straight motion (``q = 0``)."""

_STEP = 1e-6
"""Relative finite-difference step of the Jacobian [-]."""


class Glide(NamedTuple):
    """A steady straight climb or dive with the thrust held."""

    u: float
    """Surge speed [m/s]."""
    w: float
    """Heave speed [m/s]."""
    theta: float
    """Pitch [rad]."""
    bar: float
    """BAR that holds it [rad]."""

    @property
    def vertical_speed(self) -> float:
        """``-u sin(theta) + w cos(theta)`` [m/s, positive down]."""
        return -self.u * math.sin(self.theta) + self.w * math.cos(self.theta)


def steady_glide(force: Force, thrust: float, theta: float, guess: Glide,
                 iterations: int = 12) -> Glide | None:
    """The steady motion at pitch ``theta`` [rad] with the thrust ``thrust`` [N] held.

    Newton's method on ``(u, w, BAR)`` from ``guess`` (finite-difference Jacobian).

    Parameters
    ----------
    force : Force
        The vehicle's forces without the thrust.
    thrust : float
        Held thrust [N].
    theta : float
        Pitch [rad].
    guess : Glide
        Starting point (a neighbouring pitch's glide).
    iterations : int, optional
        Largest number of Newton steps.

    Returns
    -------
    Glide or None
        The glide, or None if Newton's method does not converge to one with ``u > 0``.
    """
    x = np.array([guess.u, guess.w, guess.bar], dtype=np.float64)

    def residual(v: np.ndarray) -> np.ndarray:
        X, Z, M = force(float(v[0]), float(v[1]), theta, float(v[2]))
        return np.array([X + thrust, Z, M])

    scale = np.array([1.0, 1.0, 1.0])
    for _ in range(iterations):
        r = residual(x)
        jac = np.empty((3, 3))
        for j in range(3):
            h = _STEP * max(abs(float(x[j])), 1.0)
            dx = x.copy()
            dx[j] += h
            jac[:, j] = (residual(dx) - r) / h
        try:
            step = np.linalg.solve(jac, -r)
        except np.linalg.LinAlgError:
            return None
        if not np.all(np.isfinite(step)):
            return None
        x = x + step
        if x[0] <= 0.0:
            return None
        if np.all(np.abs(step) <= 1e-9 * np.maximum(np.abs(x), scale)):
            return Glide(float(x[0]), float(x[1]), theta, float(x[2]))
    return None


def glide_cap(force: Force, thrust: float, travel: float, theta_limit: float,
              bar_limit: float, level: Glide, step: float = math.radians(2.5)) -> float:
    """The fastest steady climb or dive with the thrust held whose BAR stays within
    ``bar_limit``, or ``inf`` if the one at the pitch limit does.

    The pitch is walked from level (from the guess ``level``) towards ``-travel *
    theta_limit`` in steps of ``step`` (continuation, each glide from the last); the walk
    ends where the BAR passes out of ``bar_limit`` (the boundary interpolated) or a glide has
    no solution. A level glide beyond the bound is not feasible, but a steeper one may be
    (a buoyant vehicle's climb): the walk goes on.

    Parameters
    ----------
    force, thrust
        As for :func:`steady_glide`.
    travel : float
        +1 for a dive (down), -1 for a climb.
    theta_limit : float
        Pitch limit of the steady motion [rad, > 0].
    bar_limit : float
        Largest BAR the steady motion may hold [rad, > 0].
    level : Glide
        A starting guess of the level glide (``theta`` ignored).
    step : float, optional
        Pitch step [rad].

    Returns
    -------
    float
        Vertical speed along the travel [m/s, >= 0], or ``inf``.
    """
    glide = steady_glide(force, thrust, 0.0, level._replace(theta=0.0))
    if glide is None:
        return 0.0
    feasible = abs(glide.bar) <= bar_limit
    best = max(travel * glide.vertical_speed, 0.0) if feasible else 0.0
    n = max(int(math.ceil(theta_limit / step)), 1)
    for k in range(1, n + 1):
        nxt = steady_glide(force, thrust, -travel * theta_limit * k / n, glide)
        if nxt is None:
            return best
        inside = abs(nxt.bar) <= bar_limit
        if inside != feasible:
            # the boundary between this glide and the last, interpolated
            f = (bar_limit - abs(glide.bar)) / (abs(nxt.bar) - abs(glide.bar))
            edge = travel * ((1.0 - f) * glide.vertical_speed + f * nxt.vertical_speed)
            best = max(best, edge)
            if feasible:
                return best
        if inside:
            best = max(best, travel * nxt.vertical_speed)
        glide, feasible = nxt, inside
    return math.inf if feasible else best
