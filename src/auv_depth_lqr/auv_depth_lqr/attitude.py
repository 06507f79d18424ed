"""Pitch-sensor offset from the depth kinematics: a model-free estimate (pure, no ROS).

Frames and units: world NED (depth ``z`` positive down) [m]; body FRD; pitch ``theta``
positive nose up [rad]; surge ``u`` and heave ``w`` [m/s] in the body frame; time [s].

A pitch sensor that reads ``theta_m = theta + b`` (a mounting misalignment, an AHRS offset)
makes a depth pilot hold the wrong attitude: the LQR regulates the measured pitch, so the
vehicle runs at a flight-path angle ``-b`` off the one it plans, and the depth feedback
balances it only at a steady depth offset ``b K_theta / K_z`` (0.2 m per degree on the A18M
at 2 m/s), which only the slow integrator removes. The dynamics do not see ``b`` (the pitch
stiffness of a torpedo hull is small), but the **kinematics** do, whatever the model:

    z_dot = -u sin(theta) + w cos(theta)                           (vertical plane, no roll)

is exact for the body velocities over ground and, in a horizontal current, for those through
the water. With the measured pitch, ``z_dot = -u sin(theta_m) + w cos(theta_m) + b (u cos
theta_m + w sin theta_m)`` to first order in ``b``. So the difference ``r`` between the
measured depth and the depth integrated from the measured velocities and pitch grows, against
the run ``s = int (u cos theta_m + w sin theta_m) dt`` [m], with slope ``b``:
:class:`PitchOffsetEstimator` fits that line by exponentially weighted least squares
(time constant ``time``), so white depth noise ``sigma`` [m] leaves an error of about
``sigma sqrt(2 / n) / (u time)`` [rad] (``n`` samples per time constant): 3e-4 rad for
0.05 m at 10 Hz, 2 m/s and 20 s.

What else moves ``r`` in proportion to the run is taken as pitch offset too: a vertical
current ``c_v`` [m/s, down] gives ``b = c_v / u``; flying the corrected pitch then holds the
flight path through the water that keeps the depth, which is what the pilot needs. A
depth-sensor scale error or a pitch-sensor scale error shows only while the depth or the
pitch changes and is averaged over ``time``.
"""
from __future__ import annotations

import math
from typing import NamedTuple

from auv_depth_lqr.errors import DesignError

__all__ = ['PitchOffset', 'PitchOffsetEstimator']


class PitchOffset(NamedTuple):
    """The estimator's answer at one sample."""

    offset: float
    """Estimated pitch-sensor offset ``b`` [rad] (measured minus true), 0 until valid."""
    valid: bool
    """Whether the fit spans at least one time constant and is within ``offset_max``."""
    fitted: float
    """The raw fitted slope [rad] (nan before two samples), also when it is not valid."""


class PitchOffsetEstimator:
    """Exponentially weighted line fit of the kinematic depth residual (module docstring).

    ``time`` [s] is the forgetting time constant; ``offset_max`` [rad] the largest offset
    taken as physical (a fit beyond it is reported, not applied: the last valid offset is
    held); ``gap`` [s] the longest interval between samples over which the kinematics are
    integrated (a longer one restarts the fit, holding the last valid offset).
    """

    def __init__(self, time: float, offset_max: float, gap: float) -> None:
        for name, value in (('time', time), ('offset_max', offset_max), ('gap', gap)):
            if not (math.isfinite(value) and value > 0.0):
                raise DesignError(f'pitch offset estimator: {name} = {value!r} must be '
                                  'finite and > 0')
        self.time, self.offset_max, self.gap = float(time), float(offset_max), float(gap)
        self._held = 0.0
        self.restart()

    def restart(self) -> None:
        """Forget the fit (the last valid offset is held until a new fit is valid)."""
        self._last: tuple[float, float, float, float] | None = None  # t, z, z_dot_kin, s_dot
        self._z_kin = 0.0
        self._s = 0.0
        self._elapsed = 0.0
        self._weight = 0.0
        self._mean_s = 0.0
        self._mean_r = 0.0
        self._css = 0.0
        self._csr = 0.0
        self._fitted = math.nan

    @property
    def estimate(self) -> PitchOffset:
        """The offset to subtract from the measured pitch (:class:`PitchOffset`)."""
        valid = bool(self._elapsed >= self.time and self._css > 0.0
                     and abs(self._fitted) <= self.offset_max)
        return PitchOffset(float(self._held), valid, float(self._fitted))

    def update(self, t: float, z: float, theta: float, w: float, u: float) -> PitchOffset:
        """Add the sample at ``t`` [s]: measured depth ``z`` [m], measured pitch ``theta``
        [rad], body heave ``w`` and surge ``u`` [m/s] (over ground, or through the water in a
        horizontal current); returns the estimate after it."""
        z_dot = -u * math.sin(theta) + w * math.cos(theta)
        s_dot = u * math.cos(theta) + w * math.sin(theta)
        last = self._last
        if last is not None and (t <= last[0] or t - last[0] > self.gap):
            if t <= last[0]:
                return self.estimate
            self.restart()
            last = None
        if last is None:
            self._last = (t, z, z_dot, s_dot)
            self._z0 = z
            return self.estimate
        dt = t - last[0]
        self._z_kin += 0.5 * (z_dot + last[2]) * dt  # trapezoid
        self._s += 0.5 * (s_dot + last[3]) * dt
        self._elapsed += dt
        self._last = (t, z, z_dot, s_dot)
        r = (z - self._z0) - self._z_kin
        # Exponentially weighted centred moments (West's update, weights decaying over time).
        decay = math.exp(-dt / self.time)
        weight = decay * self._weight + 1.0
        ds, dr = self._s - self._mean_s, r - self._mean_r
        share = decay * self._weight / weight
        self._mean_s += ds / weight
        self._mean_r += dr / weight
        self._css = decay * self._css + share * ds * ds
        self._csr = decay * self._csr + share * ds * dr
        self._weight = weight
        if self._css > 0.0:
            self._fitted = self._csr / self._css
        estimate = self.estimate
        if estimate.valid:
            self._held = self._fitted
            estimate = estimate._replace(offset=self._held)
        return estimate
