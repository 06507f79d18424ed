"""The pilot's tuned settings derived from the vehicle file: one place, one rule per setting.

The pilot was tuned on the A18M (``config/a18m.yaml``, ``bench/bench_closed_loop.py``). Its
tuned numbers are carried to another vehicle by similarity: each is written as a
dimensionless constant times the vehicle's own scale of that quantity, and the constants are
the A18M's tuned values divided by the A18M's scales, so the A18M gets back exactly the
numbers it was tuned with and a geometrically similar vehicle gets the same closed loop in
its own units.

Scales (SI units):

* length ``L = L_ref`` [m] (the vehicle file's reference length, the hull length);
* speed ``sqrt(g L)`` [m/s], time ``sqrt(L / g)`` [s], acceleration ``g`` [m/s^2]: the
  vertical plane's dynamics are the balance of the hydrodynamic moments (``~ rho L^3 u^2``)
  and the hydrostatic restoring moment (``~ m g z_g``, ``m ~ rho L^3``, ``z_g ~ L``), whose
  ratio is the Froude number ``u^2 / (g L)``: a vehicle scaled geometrically by ``k`` and
  flown at ``sqrt(k)`` times the speed has the same motion at ``k`` times the lengths and
  ``sqrt(k)`` times the times (Froude scaling);
* angles: the plane's travel ``bar_max`` [rad] (vehicle file) and the pitch limit
  ``theta_max`` [rad] (pilot setting), already dimensionless.

Angles are not scaled by similarity but by the limits, so a vehicle with a smaller plane
travel (REMUS 100: 13.6 deg) spends its plane in the same proportion.

No ROS import here.
"""
from __future__ import annotations

import math
from typing import NamedTuple

from auv_depth_lqr.errors import DesignError
from auv_depth_lqr.governor import GovernorSettings
from auv_depth_lqr.weights import Weights
from auv_sim.params import VehicleParams

__all__ = ['Scales', 'Tuning', 'derive_tuning', 'scales']

# The A18M's scales the constants below are normalised by (config/a18m.yaml, pilot default).
_A18M_L = 4.6                           # m
_A18M_G = 9.81                          # m/s^2
_A18M_BAR_MAX = 0.4363                  # rad
_A18M_THETA_MAX = math.radians(25.0)    # rad
_A18M_SPEED = math.sqrt(_A18M_G * _A18M_L)      # m/s
_A18M_TIME = math.sqrt(_A18M_L / _A18M_G)       # s

# Bryson's rule: each weight is 1 / (acceptable excursion)^2; the excursions as fractions of
# the vehicle's scales (the A18M's tuned excursion / the A18M's scale, see the comments).
W_EXCURSION = 0.1 / _A18M_SPEED         # heave, of sqrt(g L): 0.1 m/s on the A18M
Q_EXCURSION = 0.03 * _A18M_TIME         # pitch rate, of 1 / sqrt(L/g): 0.03 rad/s
Z_EXCURSION = 0.3 / _A18M_L             # depth, of L: 0.3 m
THETA_EXCURSION = 0.06 / _A18M_THETA_MAX    # pitch, of theta_max: 0.06 rad (3.4 deg)
XI_EXCURSION = 4.5 / (_A18M_L * _A18M_TIME)  # integrated depth, of L sqrt(L/g): 4.5 m s
BAR_EXCURSION = 0.1 / _A18M_BAR_MAX     # plane, of bar_max: 0.1 rad (5.7 deg)

# Reference governor.
ACCEL_SHARE = 0.2 / _A18M_G             # vertical acceleration, of g: 0.2 m/s^2
APPROACH_LENGTHS = 8.0 / _A18M_L        # landing time constant x speed, of L: 8 m
LANDING_PITCH = 0.12 / 8.0              # landing length / approach length [rad]: 0.015
LAG_LENGTHS = 0.5 / _A18M_L             # reference lead over the vehicle, of L: 0.5 m
INTEGRATE_LENGTHS = 0.2 / _A18M_L       # integrator band about the reference, of L: 0.2 m
DISTURBANCE_TIMES = 3.0 / _A18M_TIME    # disturbance estimate's time constant, of sqrt(L/g): 3 s
SURGE_HORIZON_TIMES = 10.0 / _A18M_TIME  # surge speed prediction horizon, of sqrt(L/g): 10 s

# Pitch-sensor offset estimate (auv_depth_lqr.attitude): forgetting time, of sqrt(L/g): 20 s,
# the time to run ~9 hull lengths at the A18M's Froude speed share (2 m/s): long enough to
# average a 0.05 m depth noise to 3e-4 rad, short against a depth change of a few minutes.
PITCH_OFFSET_TIMES = 20.0 / _A18M_TIME

# Plane-authority measure (auv_depth_lqr.authority): trailing window, of sqrt(L/g): 20 s, five
# landing time constants (4 s at 2 m/s) so that the hold's attitude motion averages out, short
# against a mission leg.
AUTHORITY_TIMES = 20.0 / _A18M_TIME

# Safe plane without state: a gentle nose-up climb.
SAFE_BAR_SHARE = 0.12 / _A18M_BAR_MAX   # of bar_max, nose up: 0.12 rad on the A18M


class Scales(NamedTuple):
    """The vehicle's scales the settings are derived from."""

    length: float
    """Reference length ``L_ref`` [m]."""
    speed: float
    """Froude speed scale ``sqrt(g L)`` [m/s]."""
    time: float
    """Froude time scale ``sqrt(L / g)`` [s]."""
    gravity: float
    """Acceleration of gravity ``g`` [m/s^2]."""
    bar_max: float
    """Plane travel [rad]."""
    theta_max: float
    """Pitch limit [rad]."""


class Tuning(NamedTuple):
    """The derived settings of one vehicle (see :func:`derive_tuning`)."""

    weights: Weights
    """LQR weights (Bryson's rule on the excursions of the module docstring)."""
    governor: GovernorSettings
    """Reference-governor settings with the derived lengths and acceleration."""
    safe_bar: float
    """Safe plane angle without state [rad] (nose up)."""
    pitch_offset_time: float = 20.0
    """Forgetting time of the pitch-sensor offset estimate [s]
    (:class:`auv_depth_lqr.attitude.PitchOffsetEstimator`)."""
    authority_window: float = 20.0
    """Trailing window of the plane-authority measure [s]
    (:class:`auv_depth_lqr.authority.AuthorityMonitor`)."""


def scales(params: VehicleParams, theta_max: float, bar_max: float | None = None) -> Scales:
    """The vehicle's :class:`Scales`; ``bar_max`` [rad] defaults to the vehicle file's."""
    length, g = float(params.L_ref), float(params.g)
    return Scales(length=length, speed=math.sqrt(g * length), time=math.sqrt(length / g),
                  gravity=g, bar_max=float(params.bar_max if bar_max is None else bar_max),
                  theta_max=float(theta_max))


def derive_tuning(params: VehicleParams, theta_max: float,
                  bar_max: float | None = None) -> Tuning:
    """The pilot's tuned settings for a vehicle, from its length, gravity, plane and pitch
    limits (see the module docstring for the scales).

    LQR weights (Bryson's rule, 1 / excursion^2) for ``(w, q, z, theta, xi)`` and BAR:

    * heave ``w``: ``0.01489 sqrt(g L)`` [m/s] (0.1 m/s on the A18M);
    * pitch rate ``q``: ``0.02054 / sqrt(L/g)`` [rad/s] (0.03 rad/s);
    * depth ``z``: ``0.06522 L`` [m] (0.3 m);
    * pitch ``theta``: ``0.1375 theta_max`` [rad] (0.06 rad at 25 deg);
    * integrated depth ``xi``: ``1.4286 L sqrt(L/g)`` [m s] (4.5 m s);
    * plane BAR: ``0.2292 bar_max`` [rad] (0.1 rad at 25 deg travel).

    Reference governor (:class:`GovernorSettings`):

    * ``accel_max = 0.02039 g`` [m/s^2] (0.2 m/s^2): Froude-similar vehicles turn their
      flight path with the same acceleration at their similar speeds;
    * ``approach_length = 1.739 L`` [m] (8 m): the landing's time constant is
      ``approach_length / u``, the time to run 1.74 hull lengths;
    * ``landing_distance = 0.015 approach_length`` [m] (0.12 m): the landing starts at the
      vertical speed ``0.015 u``, i.e. 0.015 rad (0.86 deg) of flight path at any speed;
    * ``max_lag = 0.1087 L`` [m] (0.5 m) and ``integrate_within = 0.04348 L`` [m] (0.2 m);
    * ``disturbance_time = 4.380 sqrt(L/g)`` [s] (3 s): time constant of the disturbance
      estimate (:meth:`auv_depth_lqr.controller.DepthController.step`).
    * ``surge_horizon = 14.60 sqrt(L/g)`` [s] (10 s): how far ahead the surge speed a stop
      is planned at is predicted (:class:`auv_depth_lqr.surge.SurgeTrend`); the surge time
      constant itself is the vehicle's (:func:`auv_depth_lqr.surge.surge_length`, set by
      :func:`auv_depth_lqr.pilot.build_controller`).

    Pitch-sensor offset estimate: ``pitch_offset_time = 29.20 sqrt(L/g)`` [s] (20 s)
    (:class:`auv_depth_lqr.attitude.PitchOffsetEstimator`).

    Plane-authority measure (:class:`auv_depth_lqr.authority.AuthorityMonitor`):
    ``authority_window = 29.20 sqrt(L/g)`` [s] (20 s).

    Safe BAR: ``0.275 bar_max`` [rad] (0.12 rad) to the side whose moment pitches the nose
    up (the sign of ``-CMbar``: a negative ``CMbar`` makes a negative BAR nose up).

    Raises
    ------
    DesignError
        ``bar_max`` not finite or below 1e-6 rad.
    """
    s = scales(params, theta_max, bar_max)
    # below a micro-radian of travel the BAR weight 1 / (0.2292 bar_max)^2 overflows
    if not (math.isfinite(s.bar_max) and s.bar_max >= 1e-6):
        raise DesignError(f'bar_max = {s.bar_max!r} rad must be finite and at least 1e-6 rad')
    weights = Weights(
        Q=(1.0 / (W_EXCURSION * s.speed) ** 2,
           1.0 / (Q_EXCURSION / s.time) ** 2,
           1.0 / (Z_EXCURSION * s.length) ** 2,
           1.0 / (THETA_EXCURSION * s.theta_max) ** 2,
           1.0 / (XI_EXCURSION * s.length * s.time) ** 2),
        R=1.0 / (BAR_EXCURSION * s.bar_max) ** 2)
    approach = APPROACH_LENGTHS * s.length
    governor = GovernorSettings(
        accel_max=ACCEL_SHARE * s.gravity,
        approach_length=approach,
        landing_distance=LANDING_PITCH * approach,
        max_lag=LAG_LENGTHS * s.length,
        integrate_within=INTEGRATE_LENGTHS * s.length,
        disturbance_time=DISTURBANCE_TIMES * s.time,
        surge_horizon=SURGE_HORIZON_TIMES * s.time)
    nose_up = -1.0 if float(params.CMbar) <= 0.0 else 1.0
    return Tuning(weights, governor, nose_up * SAFE_BAR_SHARE * s.bar_max,
                  PITCH_OFFSET_TIMES * s.time, AUTHORITY_TIMES * s.time)
