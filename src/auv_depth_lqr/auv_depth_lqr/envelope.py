"""Pitch envelope protection of the depth pilot: the plane command of the depth loop is kept
within the commands a pitch-hold law aiming at the pitch limits would give. Clock- and ROS-free.

Frames and units (Fossen): pitch ``theta`` positive nose up [rad], pitch rate ``q`` [rad/s]
(body FRD), dive-plane (BAR) angle [rad], positive pitching the nose down (``docs/model.md``):
the pitch acceleration per BAR ``M_bar = dq_dot/dBAR`` is negative.

The selector, standard in flight control (envelope protection by min/max selection)::

    BAR = min(max(BAR_depth, BAR_hold(+theta_up)), BAR_hold(-theta_down))

``BAR_hold(theta_t)`` is the command of a pitch-hold law towards ``theta_t``: more BAR (nose
down) than ``BAR_hold(+theta_up)`` keeps the nose below ``+theta_up``, less than
``BAR_hold(-theta_down)`` keeps it above ``-theta_down`` (both ``theta_lim`` unless they
give way, below). The law is incremental (incremental nonlinear dynamic inversion): from the
BAR held over the last sample ``BAR_prev`` and the pitch acceleration it gave, measured
``q_dot_m = (q - q_prev) / Ts``,

    BAR_hold(theta_t) = BAR_prev + g (q_dot_d - q_dot_m) / M_bar,
    q_dot_d = M_bar (-K_theta (theta_stop - theta_t) - K_q q),

so it needs of the model only the plane's effectiveness ``M_bar`` (at the measured speed) and
the LQR's own attitude gains ``K_theta``, ``K_q``: whatever else the model gets wrong (a
buoyancy, a trim moment, a Munk moment, a plane weaker than designed) is in the measured
``q_dot_m``, so the law holds the limit without knowing it (it integrates: at rest on the
limit ``q_dot_m = q_dot_d = 0``).

``theta_stop`` (:func:`stop_pitch`) is where the pitch would stop if the plane swung over to
brake now, which is what makes the law hold a hard pitch-rate kick: the plane's rate limit
is in it. Until the plane has swung from ``BAR_prev`` to the far end, ``t_r = Ts + (bar_max
+- BAR_prev) / bar_rate_max``, the rotation goes on, its measured acceleration fading
linearly; then the plane stops it at ``a = BRAKE_SHARE |M_bar| bar_max`` over the braking
distance ``q_b^2 / (2 a)``. Each side counts only a rotation towards it.

With the thrust held, the speed falls in a climb or dive whose weight less buoyancy acts
against the propeller (a buoyant vehicle diving), and the plane's authority falls with its
square: below some speed no plane holds the limit, and the hydrostatic and Munk moments take
the pitch beyond it, out of reach of any plane. So a side's limit gives way (set to the
present pitch, then towards level at ``RELIEF_RATE``) while the pitch is on that side
(beyond ``RELIEF_BAND``) and the plane that holds the present attitude once the motion has
settled (:func:`settled_plane`), scaled to the speed the vehicle is heading for by ``(u /
u_heading)^2``, is more than ``hold_bar``; it comes back at the same rate otherwise. A
shallower climb or dive lets the speed recover: the pilot flies the best it can within the
limits. The settled plane, low-passed over ``RELIEF_FILTER``, counts the heave that is still
settling: in the rotation into a dive the vehicle has not yet bent its path, and the angle
of attack of that moment (its Munk moment) would ask for a plane the steady dive does not
need. The plane of the present motion, the settling not counted, gives way too, but only in
a rotation towards that side past the reference's pitch ``theta_ref``: an overshoot, not a
manoeuvre the pilot flies, whose swing the hold law then stops (a pitch-rate kick on a small
vehicle whose plane rate bounds its loop; an unstable vehicle's overshoot in a current).
"""
from __future__ import annotations

import math
from typing import NamedTuple

__all__ = ['EnvelopeBounds', 'Heave', 'PitchEnvelope', 'settled_plane', 'stop_pitch']

BRAKE_SHARE = 0.5
"""Share of the plane's full pitch acceleration ``|M_bar| bar_max`` counted on to stop a
rotation [-] (the rest holds the moments the plane is already holding, assumed)."""

HOLD_GAIN = 0.5
"""Share ``g`` of the pitch-acceleration error the incremental hold law corrects per sample
[-] (below 1: a plane delay or lag, or a plane weaker than the model's, stays stable)."""

RELIEF_RATE = math.radians(1.0)
"""Rate [rad/s] at which a side's pitch limit gives way while the plane could not hold it at
the speed the vehicle is heading for, and comes back otherwise (1 deg/s, assumed: slower than
the pitch dynamics, faster than the speed's)."""

RELIEF_FILTER = 2.0
"""Time constant [s] of the low-pass on the settled plane of the relief (its heave
acceleration is differenced from the measured heave, whose noise it carries; 2 s, assumed:
longer than a sensor's noise, shorter than the speed's fall)."""

RELIEF_BAND = 0.2
"""A side's limit gives way only while the pitch is beyond this share of ``theta_lim`` on
that side [-]."""


def stop_pitch(theta: float, q: float, qdot: float, reaction: float, decel: float,
               side: float) -> float:
    """Pitch [rad, nose up] at which a rotation towards ``side`` (+1 nose up, -1 nose down)
    stops if the plane starts swinging over now.

    For ``reaction`` [s] the rotation goes on, its acceleration ``qdot`` [rad/s^2] fading
    linearly to zero (the plane swinging over): rate ``q_b = q + qdot reaction / 2``, pitch
    ``theta_b = theta + q reaction + qdot reaction^2 / 3``; a rotation still towards
    ``side`` then stops over ``q_b^2 / (2 decel)`` (``decel`` [rad/s^2, > 0]). Without a
    rotation towards ``side``, the farther of ``theta`` and ``theta_b`` on that side.

    Parameters
    ----------
    theta, q, qdot : float
        Pitch [rad], pitch rate [rad/s] and pitch acceleration [rad/s^2], nose up positive.
    reaction : float
        Time until the plane brakes [s].
    decel : float
        Pitch deceleration of the braking plane [rad/s^2, > 0].
    side : float
        +1 (the upper limit) or -1 (the lower).

    Returns
    -------
    float
        The stopping pitch [rad].
    """
    q_b = q + 0.5 * qdot * reaction
    theta_b = theta + q * reaction + qdot * reaction ** 2 / 3.0
    if side * q_b <= 0.0:
        return side * max(side * theta, side * theta_b)
    return theta_b + q_b * abs(q_b) / (2.0 * decel)


class Heave(NamedTuple):
    """The measured heave and the linear model's heave terms at the measured speed (the
    rows of :attr:`auv_depth_lqr.schedule.OperatingPoint.P`), for :func:`settled_plane`."""

    w: float
    """Measured heave [m/s, body FRD, down]."""
    z_w: float
    """Heave acceleration per heave [1/s]."""
    z_q: float
    """Heave acceleration per pitch rate [m/s^2 per rad/s]."""
    z_bar: float
    """Heave acceleration per BAR [m/s^2 per rad]."""
    m_w: float
    """Pitch acceleration per heave [rad/s^2 per m/s] (the Munk moment's share)."""


def settled_plane(bar: float, q: float, qdot: float, wdot: float, m_q: float, m_bar: float,
                  heave: Heave) -> float:
    """The BAR [rad] that holds the present pitch once the pitch rate and the heave have
    settled, from the accelerations measured with ``bar`` [rad] held.

    The linear model's pitch and heave rows, with everything they do not know in the
    measured accelerations ``qdot`` [rad/s^2] and ``wdot`` [m/s^2]: at the same pitch with
    ``q`` [rad/s] gone to zero, the heave changed by ``dw`` and the plane by ``db``,

        M_w dw + M_bar db = -(qdot - M_q q)
        Z_w dw + Z_bar db = -(wdot - Z_q q),

    and the plane is ``bar + db``. ``m_q`` [1/s] and ``m_bar`` [rad/s^2 per rad, < 0] are the
    pitch row's damping and plane terms. Without heave coupling (``m_w`` 0) this is ``bar -
    (qdot - M_q q) / M_bar``, the plane of the present motion; so it is too where the two rows
    leave ``dw`` undetermined (``M_w Z_bar - M_bar Z_w`` zero).
    """
    r_q = -(qdot - m_q * q)
    r_w = -(wdot - heave.z_q * q)
    det = heave.m_w * heave.z_bar - m_bar * heave.z_w
    if abs(det) <= 1e-9 * abs(m_bar * heave.z_w):
        return bar + r_q / m_bar
    return bar + (heave.m_w * r_w - heave.z_w * r_q) / det


class EnvelopeBounds(NamedTuple):
    """The selector's bounds of one sample [rad]."""

    low: float
    """``BAR_hold(+theta_up)``: the least BAR (nose up) that keeps the nose below the upper
    limit."""
    high: float
    """``BAR_hold(-theta_down)``: the most BAR (nose down) that keeps the nose above the
    lower limit."""


class PitchEnvelope:
    """The pitch-hold bounds of the selector, sample by sample (see the module docstring).

    Parameters
    ----------
    theta_lim : float
        Pitch limit the hold law aims at [rad, > 0], symmetric.
    bar_rate : float
        The plane's rate limit [rad/s, > 0].
    Ts : float
        Sample period [s].
    """

    def __init__(self, theta_lim: float, bar_rate: float, Ts: float) -> None:
        self.theta_lim = theta_lim
        self.bar_rate = bar_rate
        self.Ts = Ts
        self.reset()

    def reset(self) -> None:
        """Forget the last pitch rate (the next sample has no measured acceleration) and
        restore the limits."""
        self._q_prev: float | None = None
        self._w_prev: float | None = None
        self._settled: float | None = None
        self.up = self.theta_lim
        """Present upper pitch limit [rad] (``theta_lim`` unless it gives way)."""
        self.down = self.theta_lim
        """Present lower pitch limit, as a magnitude [rad]."""
        self.active = 0
        """Side the last :meth:`select` held: +1 the upper limit (nose up), -1 the lower,
        0 none (the depth command went through)."""

    def bounds(self, theta: float, q: float, bar_prev: float | None, m_bar: float,
               m_q: float, k_theta: float, k_q: float, bar_max: float, slowing: float = 1.0,
               hold_bar: float = math.inf, heave: Heave | None = None,
               theta_ref: float | None = None) -> EnvelopeBounds | None:
        """The bounds ``(BAR_hold(+theta_up), BAR_hold(-theta_down))`` [rad] this sample, or
        None when they cannot be formed (first sample, no previous BAR, ``m_bar`` not < 0).

        Parameters
        ----------
        theta, q : float
            Measured pitch [rad, nose up] and pitch rate [rad/s].
        bar_prev : float or None
            BAR [rad] commanded over the last sample.
        m_bar : float
            Pitch acceleration per BAR at the measured speed [rad/s^2 per rad, < 0].
        m_q : float
            Pitch acceleration per pitch rate at the measured speed (damping) [1/s].
        k_theta, k_q : float
            The LQR's gains on pitch [rad/rad] and pitch rate [rad/(rad/s)].
        bar_max : float
            BAR angle limit [rad].
        slowing : float
            ``u / u_heading`` [-]: how far the speed is heading down (1: not falling; <= 0:
            heading to a standstill).
        hold_bar : float
            Most plane [rad] holding the attitude may take at the speed heading for.
        heave : Heave or None
            The measured heave and the model's heave terms: the relief counts the heave
            still settling (:func:`settled_plane`); None: it does not.
        theta_ref : float or None
            The reference's pitch [rad, nose up]; None: no rotation counts as an overshoot.

        Returns
        -------
        EnvelopeBounds or None
            ``low <= high`` [rad].
        """
        q_prev, self._q_prev = self._q_prev, q
        w_prev, self._w_prev = self._w_prev, (None if heave is None else heave.w)
        if q_prev is None or bar_prev is None or not m_bar < 0.0:
            return None
        qdot_m = (q - q_prev) / self.Ts
        decel = BRAKE_SHARE * abs(m_bar) * bar_max
        up = stop_pitch(theta, q, qdot_m, self.Ts + (bar_max - bar_prev) / self.bar_rate,
                        decel, 1.0)
        down = stop_pitch(theta, q, qdot_m, self.Ts + (bar_max + bar_prev) / self.bar_rate,
                          decel, -1.0)

        def hold(theta_stop: float, target: float) -> float:
            qdot_d = m_bar * (-k_theta * (theta_stop - target) - k_q * q)
            return bar_prev + HOLD_GAIN * (qdot_d - qdot_m) / m_bar

        low, high = hold(up, self.up), hold(down, -self.down)
        # the plane of the present motion and the plane that holds the present attitude once
        # it has settled, at the speed the vehicle is heading for
        scale = slowing ** 2 if slowing > 0.0 else math.inf
        now = bar_prev - (qdot_m - m_q * q) / m_bar
        settled = now if heave is None or w_prev is None else settled_plane(
            bar_prev, q, qdot_m, (heave.w - w_prev) / self.Ts, m_q, m_bar, heave)
        band = RELIEF_BAND * self.theta_lim
        step = RELIEF_RATE * self.Ts
        if self._settled is None:
            self._settled = settled
        else:
            self._settled += self.Ts / (RELIEF_FILTER + self.Ts) * (settled - self._settled)
        for side in (1.0, -1.0):
            # a rotation towards this side past the reference's pitch: not one the pilot flies
            overshoot = side * q > 0.0 and theta_ref is not None and \
                side * (theta - theta_ref) > 0.0
            short = side * theta > band and (side * self._settled * scale > hold_bar or (
                overshoot and side * now * scale > hold_bar))
            if side > 0.0:
                self.up = self._relieved(self.up, theta, short, step)
            else:
                self.down = self._relieved(self.down, -theta, short, step)
        if low > high:  # a rotation so fast that both cannot hold: the side it runs to wins
            if q > 0.0:
                high = low
            else:
                low = high
        return EnvelopeBounds(low, high)

    def _relieved(self, limit: float, pitch: float, short: bool, step: float) -> float:
        """A side's ``limit`` [rad]: from the side's ``pitch`` [rad] one ``step`` towards level
        if the plane falls ``short``, else one back towards ``theta_lim``."""
        if short:
            return max(min(limit, pitch) - step, 0.0)
        return min(limit + step, self.theta_lim)

    def select(self, bar_depth: float, bounds: EnvelopeBounds | None) -> float:
        """``bar_depth`` [rad] within ``bounds`` (unchanged without bounds); sets
        :attr:`active`."""
        self.active = 0
        if bounds is None:
            return bar_depth
        if bar_depth < bounds.low:
            self.active = 1
            return bounds.low
        if bar_depth > bounds.high:
            self.active = -1
            return bounds.high
        return bar_depth
