"""The stop planner of the reference governor: how far a vertical motion runs before it stops.

Travel frame: distance ``P`` [m], speed ``V`` [m/s], acceleration ``A`` [m/s^2], jerk ``J``
[m/s^3], all along the direction of travel (NED down for a dive, up for a climb). A vehicle
whose BAR -> vertical-speed series is stable stops by holding its plane at the braking end
(:func:`series_map`); an open-loop-unstable one (e.g. the REMUS 100) stops kinematically
(:func:`kinematic_map`). :func:`stop_distance` gives the distance of the planned stop.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from scipy.linalg import expm

__all__ = ['MAX_BRAKE_STEPS', 'Brake', 'kinematic_map', 'series_map', 'stable_series',
           'stop_distance']


def _hurwitz(coefficients: Sequence[float]) -> bool:
    """Whether ``c_0 + c_1 s + ... + c_n s^n`` (``c_n != 0``) has all roots in Re < 0."""
    return bool(np.all(np.real(np.roots(list(coefficients)[::-1])) < 0.0))


class Brake(NamedTuple):
    """Travel-frame stop of the reference (see
    :meth:`auv_depth_lqr.governor.ReferenceGovernor.limits_toward`).

    Over one sample, ``(P, V, A, J)`` (distance [m], speed [m/s], acceleration [m/s^2], jerk
    [m/s^3] along the travel) maps exactly to ``phi (P, V, A, J) + gam U`` under the series
    model ``b_0 V + b_1 A + b_2 J + b_3 J' = U`` with the input ``U = travel (BAR - bar_e)``
    [rad] held; ``phi`` row-major 4 x 4, ``gam`` 4. When the third-order model is not
    stable, the highest stable truncation is used (the lower orders follow the input
    faster).
    """

    phi: tuple[float, ...]
    gam: tuple[float, ...]
    u_brake: float
    """Input of the braking end of the BAR budget [rad]."""
    u_release: float
    """Input the release moves towards [rad]."""
    du: float
    """Largest change of the input over one sample [rad] (the BAR rate limit)."""
    landing: float
    """Time constant of the landing [s]."""
    v_land: float
    """Speed at which the landing starts [m/s]."""

    @classmethod
    def build(cls, b: Sequence[float], u_brake: float, u_release: float, du: float,
              landing: float, v_land: float, ts: float) -> Brake:
        """The stop model of the series coefficients ``b = (b_0, b_1, b_2, b_3)``."""
        phi, gam = series_map(b, ts)
        return cls(phi, gam, u_brake, u_release, max(du, 1e-9), landing, v_land)

    def advance(self, state: tuple[float, float, float, float], u: float
                ) -> tuple[float, float, float, float]:
        """``(P, V, A, J)`` one sample later with the input ``u`` held [rad]."""
        m, g = self.phi, self.gam
        p, v, a, j = state
        return (m[0] * p + m[1] * v + m[2] * a + m[3] * j + g[0] * u,
                m[4] * p + m[5] * v + m[6] * a + m[7] * j + g[1] * u,
                m[8] * p + m[9] * v + m[10] * a + m[11] * j + g[2] * u,
                m[12] * p + m[13] * v + m[14] * a + m[15] * j + g[3] * u)


def series_map(b: Sequence[float], ts: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """``(phi, gam)`` of :class:`Brake`: the exact one-sample map of the series model with
    coefficients ``b = (b_0, b_1, b_2, b_3)`` at sample time ``ts`` [s]."""
    M = np.zeros((5, 5))
    M[0, 1] = M[1, 2] = M[2, 3] = 1.0
    tau = 0.1 * ts  # fast lag that stands for a dropped order [s]
    if b[3] != 0.0 and _hurwitz(b[:4]):
        M[3, 1:4] = [-b[0] / b[3], -b[1] / b[3], -b[2] / b[3]]
        M[3, 4] = 1.0 / b[3]
    elif b[2] != 0.0 and _hurwitz(b[:3]):  # J follows (U - b0 V - b1 A) / b2
        M[3, 1:4] = [-b[0] / (b[2] * tau), -b[1] / (b[2] * tau), -1.0 / tau]
        M[3, 4] = 1.0 / (b[2] * tau)
    elif b[1] != 0.0:  # A follows (U - b0 V) / b1
        M[2, 3] = 0.0
        M[2, 1:3] = [-b[0] / (b[1] * tau), -1.0 / tau]
        M[2, 4] = 1.0 / (b[1] * tau)
    E = expm(M * ts)
    return tuple(float(x) for x in E[:4, :4].ravel()), tuple(float(x) for x in E[:4, 4])


def stable_series(b: Sequence[float]) -> bool:
    """Whether holding the plane stops the vertical motion: the first-order truncation
    ``b_0 + b_1 s`` of the series is Hurwitz (``b_0``, ``b_1`` of one sign)."""
    return b[1] != 0.0 and _hurwitz(b[:2])


def kinematic_map(tau: float, ts: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """``(phi, gam)`` of the kinematic stop of an open-loop-unstable vehicle.

    A vehicle that is unstable in pitch and heave (the Munk moment beyond the restoring and
    fin moments, e.g. the REMUS 100) does not stop when its plane is held at the braking end:
    it pitches over ever faster, and a stop planned on its series diverges. Its reference
    instead stops kinematically: the acceleration ``A`` [m/s^2] follows the commanded one
    ``U`` as a critically damped second-order lag of time constant ``tau`` [s]
    (``A'' = (U - A) / tau^2 - 2 A' / tau``), the feedback stabilising the vehicle along it.
    """
    M = np.zeros((5, 5))
    M[0, 1] = M[1, 2] = M[2, 3] = 1.0
    M[3, 2], M[3, 3], M[3, 4] = -1.0 / tau**2, -2.0 / tau, 1.0 / tau**2
    E = expm(M * ts)
    return tuple(float(x) for x in E[:4, :4].ravel()), tuple(float(x) for x in E[:4, 4])


MAX_BRAKE_STEPS = 2000
"""Longest stop the planner follows, in samples; a stop that is not over by then is taken
to be infinitely long (the reference then brakes at once)."""


def _toward(u: float, target: float, du: float) -> float:
    """``u`` moved by at most ``du`` towards ``target``."""
    return min(target, u + du) if u < target else max(target, u - du)


def _release(state: tuple[float, float, float, float], u: float, brake: Brake
             ) -> tuple[float, float]:
    """Distance [m] and speed [m/s] at the end of the release from ``(P, V, A, J)`` with
    input ``u`` [rad]: the input moves at its rate limit towards ``brake.u_release`` until
    the acceleration reaches ``-v_land / landing`` (interpolated within the sample), or
    until the motion stops (speed 0: the release came too late to land)."""
    a_end = -brake.v_land / brake.landing
    for _ in range(MAX_BRAKE_STEPS):
        if state[2] >= a_end:
            return state[0], state[1]
        u = _toward(u, brake.u_release, brake.du)
        nxt = brake.advance(state, u)
        if nxt[1] <= 0.0:  # released too late: the motion stops (and would turn) here
            f = state[1] / (state[1] - nxt[1])
            return state[0] + f * (nxt[0] - state[0]), 0.0
        if nxt[2] >= a_end:
            f = (a_end - state[2]) / (nxt[2] - state[2])
            return state[0] + f * (nxt[0] - state[0]), state[1] + f * (nxt[1] - state[1])
        state = nxt
    return math.inf, state[1]


def stop_distance(v: float, a: float, j: float, u_now: float, brake: Brake,
                   hint: list[int] | None = None) -> float:
    """Distance [m] to the target of the stop from speed ``v`` [m/s], acceleration ``a``
    [m/s^2], jerk ``j`` [m/s^3] (along the travel) and feed-forward input ``u_now`` [rad].

    The stop moves the BAR at its rate limit to the braking end of the budget and holds it
    there (:meth:`Brake.advance`, sample by sample), then releases (:func:`_release`);
    the release ends at the speed ``v_land`` (the switch is found by bisection over the
    samples and interpolated): the start of the exponential landing ``e(t) = e_0
    exp(-t / landing)`` of length ``v_land * landing``. A motion already slower than
    ``v_land`` lands at once; one that brakes harder than it needs releases at once.
    Negative for a motion away from the target (the same stop, mirrored, without a landing).
    ``hint`` (a one-element list), if given, is where the search for the switch starts and
    receives the switch found: the stop of the next sample switches about one sample earlier.
    """
    if v < 0.0 or (v == 0.0 and a < 0.0):
        mirrored = brake._replace(v_land=0.0, u_brake=-brake.u_release,
                                  u_release=-brake.u_brake)
        return -stop_distance(-v, -a, -j, -u_now, mirrored)
    landing, v_land = brake.landing, brake.v_land
    if v <= v_land:
        return v * landing
    # Brake-hold states, built only as far as the search for the switch needs them; the
    # hold ends (index n) when the speed is down to v_land.
    states = [((0.0, v, a, j), u_now)]
    end: list[int] = []

    def last(k: int) -> int:
        """Build the states up to ``k``; the highest valid index at most ``k``."""
        while len(states) <= k and not end:
            if len(states) > MAX_BRAKE_STEPS:
                raise OverflowError
            state, u = states[-1]
            u = _toward(u, brake.u_brake, brake.du)
            state = brake.advance(state, u)
            states.append((state, u))
            if state[1] <= v_land:
                end.append(len(states) - 1)
        return min(k, len(states) - 1)

    def outcome(k: int) -> tuple[float, float]:
        p_r, v_r = _release(*states[k], brake)
        return p_r + max(min(v_r, v_land), 0.0) * landing, v_r

    # The release at k ends faster than v_land for k < k*, slower from k* on: find k*.
    try:
        start = last(0 if hint is None else max(hint[0], 0))
        out = outcome(start)
        step = 1
        if out[1] > v_land:  # switch later: gallop up
            lo, lo_out = start, out
            while True:
                hi = last(lo + step)
                if hi == lo:  # the hold is over and still too fast: release at its end
                    return lo_out[0]
                hi_out = outcome(hi)
                if hi_out[1] <= v_land:
                    break
                lo, lo_out, step = hi, hi_out, 2 * step
        else:  # switch earlier: gallop down
            hi, hi_out = start, out
            while True:
                if hi == 0:
                    return hi_out[0]  # braking harder than needed already: release at once
                lo = max(hi - step, 0)
                lo_out = outcome(lo)
                if lo_out[1] > v_land:
                    break
                hi, hi_out, step = lo, lo_out, 2 * step
    except OverflowError:
        return math.inf
    while hi - lo > 1:
        mid = (lo + hi) // 2
        out = outcome(mid)
        if out[1] > v_land:
            lo, lo_out = mid, out
        else:
            hi, hi_out = mid, out
    if hint is not None:
        hint[0] = lo
    f = (lo_out[1] - v_land) / (lo_out[1] - hi_out[1])
    return lo_out[0] + f * (hi_out[0] - lo_out[0])

