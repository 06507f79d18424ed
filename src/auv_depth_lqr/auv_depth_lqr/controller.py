"""The discrete depth controller as a pure object: gain-scheduled LQR with integral action.

Frames and units (Fossen): world frame NED, z positive down (z is depth) [m]; body frame FRD;
pitch ``theta`` positive nose up [rad]; heave ``w`` [m/s] and pitch rate ``q`` [rad/s] in the
body frame; surge ``u`` [m/s]; dive-plane (BAR) angle [rad]. The vertical speed
``v = z_dot`` is positive downwards, so a climb has ``v < 0`` and needs ``theta > 0``.

Design state (as in the report, section 3.4) ``X = (w, q, z, theta, xi)`` with
``xi = int (z - z_ref) dt`` [m s], input ``BAR`` [rad]. The vehicle model supplies
``linearize(u0) -> (x_e, u_e, A, B)``: trim state ``x_e = (w_e, 0, z_any, theta_e, 0)``,
trim input ``u_e = BAR_e`` and the Jacobians ``A`` (5, 5), ``B`` (5, 1) at that trim.

Beyond the report, :class:`DepthController` adds

* gain scheduling on the surge speed (:class:`GainSchedule`: one discrete LQR per speed,
  gains and trim interpolated linearly in ``u``, clamped at the ends of the grid);
* integral action on the depth error with anti-windup (conditional integration plus a clamp
  of the integrator's share of the command);
* BAR angle and rate limits on the output command;
* a reference governor (:class:`GovernorSettings`) that turns a depth change into a
  near time-optimal vertical-speed profile (continuous jerk) whose steady climb/dive needs
  at most ``margin * theta_max`` pitch, whose feed-forward BAR stays within the plane's
  angle and rate, whose stop holds the plane at its braking end, and which ends on a short
  exponential landing, so the attitude is quiet once settled;
* model-based feed-forward of the whole manoeuvre: the linear model's exact trajectory for
  the profile (a series in the derivatives of the vertical speed, :class:`OperatingPoint`),
  with the exact depth kinematics ``z_dot = -u sin(theta) + w cos(theta)``;
* pitch envelope protection: the depth feedback may not ask for more than
  ``pitch_guard * theta_max`` (a current or a wrong speed can make the vehicle lag the plan);
* for a vehicle that is open-loop unstable in pitch/heave (its BAR -> vertical-speed series is
  not stable, e.g. the REMUS 100), a kinematic stop of the reference (``kinematic_stop``,
  :func:`_kinematic_map`) instead of the held-plane stop, which would diverge.

No ROS import here: the depth-pilot node converts messages and calls :meth:`DepthController.step`.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import NamedTuple, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.linalg import expm

from auv_depth_lqr.errors import ControllerError, DesignError, InvalidInputError
from auv_depth_lqr.lqr import _matrix, check_controllable, lqrd

__all__ = [
    'DEFAULT_WEIGHTS',
    'N_STATES',
    'PRESETS',
    'THETA_MAX_DEFAULT',
    'DepthController',
    'DepthState',
    'GainSchedule',
    'GovernorSettings',
    'Limits',
    'Linearize',
    'OperatingPoint',
    'PlaneState',
    'Weights',
    'check_linearization',
    'preset',
]

N_STATES = 5
"""Number of design states ``(w, q, z, theta, xi)``."""

THETA_MAX_DEFAULT = math.radians(25.0)
"""Default pitch limit [rad] (25 deg = 0.436 rad): the usual attitude limit of torpedo AUVs
of this class (sonar geometry, stall margin of the hull); assumed, adjust per vehicle."""

Linearize = Callable[[float], tuple[ArrayLike, float, ArrayLike, ArrayLike]]
"""``linearize(u0) -> (x_e, u_e, A, B)`` about the trim at surge speed ``u0`` [m/s]."""

Matrix = NDArray[np.float64]


class DepthState(Protocol):
    """What the controller reads from a vehicle state (``auv_msgs/VehicleState`` fits)."""

    @property
    def z(self) -> float:
        """Depth, NED down [m]."""

    @property
    def theta(self) -> float:
        """Pitch, positive nose up [rad]."""

    @property
    def w(self) -> float:
        """Body FRD heave velocity [m/s]."""

    @property
    def q(self) -> float:
        """Body FRD pitch rate [rad/s]."""

    @property
    def u(self) -> float:
        """Body FRD surge velocity [m/s]."""


class PlaneState(NamedTuple):
    """A minimal vertical-plane state satisfying :class:`DepthState`."""

    z: float
    """Depth, NED down [m]."""
    theta: float
    """Pitch, positive nose up [rad]."""
    w: float
    """Heave velocity, body FRD [m/s]."""
    q: float
    """Pitch rate, body FRD [rad/s]."""
    u: float
    """Surge velocity, body FRD [m/s]."""


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


def _finite(name: str, value: object, positive: bool = False) -> float:
    """``value`` as a finite float (and > 0 if ``positive``), else :class:`DesignError`."""
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise DesignError(f'{name} must be a number, got {value!r}') from None
    if not math.isfinite(number) or (positive and number <= 0.0):
        need = 'finite and > 0' if positive else 'finite'
        raise DesignError(f'{name} must be {need}, got {value!r}')
    return number


@dataclass(frozen=True)
class Limits:
    """Physical limits the command and the motion must respect."""

    bar_max: float = math.radians(25.0)
    """BAR angle limit, symmetric [rad] (25 deg: mechanical stop, assumed for the A18M)."""
    bar_rate_max: float = math.radians(20.0)
    """BAR slew-rate limit [rad/s] (20 deg/s: typical fin servo, assumed)."""
    theta_max: float = THETA_MAX_DEFAULT
    """Pitch limit for large depth changes, symmetric [rad] (default 25 deg = 0.436 rad)."""
    integral_bar_share: float = 0.32
    """Largest share of ``bar_max`` the integral term ``|K_xi xi|`` may command [-]: bounds
    the integrator to what trim errors can need (0.32: 8 deg of a 25 deg plane, ~2x the
    report's trim BAR; a fraction, so that it scales with the vehicle's plane)."""

    @property
    def integral_bar_max(self) -> float:
        """Largest BAR of the integral term [rad]: ``integral_bar_share * bar_max``."""
        return self.integral_bar_share * self.bar_max

    def __post_init__(self) -> None:
        for name in ('bar_max', 'bar_rate_max', 'theta_max', 'integral_bar_share'):
            _finite(f'Limits.{name}', getattr(self, name), positive=True)
        if self.integral_bar_share > 1.0:
            raise DesignError(f'Limits.integral_bar_share must be in (0, 1], got '
                              f'{self.integral_bar_share!r}')
        if self.theta_max >= math.pi / 2:
            raise DesignError(f'Limits.theta_max must be < pi/2 rad, got {self.theta_max!r}')


@dataclass(frozen=True)
class GovernorSettings:
    """Reference governor: how a depth step becomes a flyable vertical-speed profile.

    The governed reference ``(z_r, v_r, a_r, j_r, s_r)`` (depth [m], vertical speed [m/s],
    acceleration [m/s^2], jerk [m/s^3], snap [m/s^4], NED down) is a near time-optimal
    motion to the commanded depth, re-planned every sample (:meth:`DepthController._govern`),
    that ends on a short exponential landing. Its feed-forward BAR is the vehicle's linear
    model series ``bar_e + b_0 v + b_1 a + b_2 j + b_3 s`` (:class:`OperatingPoint`), and
    the reference is built so that this BAR is one the plane can fly:

    * ``|v_r|``: steady climbs/dives whose pitch stays within ``margin * theta_max`` and BAR
      within ``margin * bar_max`` (:meth:`GainSchedule.vertical_speed_bounds`);
    * the feed-forward BAR within ``bar_margin * bar_max`` and moving at most at
      ``bar_rate_margin`` times the plane's rate: it bounds the pitch-up (the restoring
      moment of a steep climb eats the plane's authority) and shapes the stop;
    * a stop holds the feed-forward BAR at ``brake_bar_share`` of that budget on the
      braking side (the vehicle pitches back at the rate the plane allows), then releases
      it towards the landing's BAR (plus ``release_bar_share`` of the room beyond) so that
      the landing starts with the attitude at rest (see :func:`_stop_distance`);
    * the speed-up: ``|a_r| <= accel_max``, ``|j_r| <= accel_max / jerk_time``.

    The reference never overshoots the commanded depth; it waits for a vehicle that falls
    more than ``max_lag`` behind it. The defaults were chosen on the A18M model at 1.5-3 m/s
    (``bench/bench_closed_loop.py``) against the settling, overshoot and quiet-attitude
    targets; the time-optimal bound of :mod:`auv_depth_lqr.bound` is about 10 % faster.
    """

    margin: float = 0.97
    """Fraction of ``theta_max`` and ``u sin(theta_max)`` that the steady climb or dive of the
    reference may use; the rest is left to the feedback [-]."""
    bar_margin: float = 0.98
    """Fraction of ``bar_max`` that the feed-forward BAR of the reference may use [-]."""
    accel_max: float = 0.2
    """Largest vertical acceleration of the reference [m/s^2]; it bounds the pitch rate of
    the transitions, ``~ accel_max / u`` [rad/s] (0.05 rad/s = 2.9 deg/s at 2 m/s)."""
    jerk_time: float = 1.0
    """Shortest time for the reference acceleration to go from 0 to ``accel_max`` [s]
    (jerk limit ``accel_max / jerk_time``); it bounds the pitch acceleration."""
    approach_length: float = 8.0
    """Distance run through the water during one time constant of the final exponential
    approach (the landing) [m]: the time constant is ``approach_length / u`` [s] (4 s at
    2 m/s), so it follows the vehicle's attitude dynamics, which scale with ``1 / u``. The
    pitch left to take out once the vehicle is within a +-0.1 m band, and the pitch rate
    that takes it out, shrink with it: this keeps the attitude quiet once the depth has
    settled."""
    landing_distance: float = 0.12
    """Length of the landing [m]: the stop ends on it at the speed
    ``landing_distance / approach time`` [m/s], i.e. with the same pitch above the trim
    at any speed."""
    integrate_within: float = 0.2
    """The depth integrator runs only while ``|z - z_r|`` is at most this [m]."""
    integrate_below_speed: float = 0.005
    """The depth integrator runs only while ``|v_r|`` is at most this [m/s]: the manoeuvre
    itself is flown on the feed-forward and the proportional feedback, so transient tracking
    errors of a climb or of its final approach do not wind the integrator up."""
    brake_bar_share: float = 0.9
    """Fraction of the feed-forward BAR budget (``bar_margin * bar_max``) that a planned stop
    may use; the rest is left to the feedback, which must absorb the tracking errors of the
    braking, where they become overshoot [-]."""
    release_bar_share: float = 0.1
    """How far beyond the landing's BAR (about the trim) the release of a stop moves the
    feed-forward BAR, as a fraction of the room to the other end of the budget [-]."""
    bar_rate_margin: float = 0.9
    """Fraction of the BAR rate limit that the feed-forward BAR of the reference may use
    [-]; the stop is planned with the BAR moving at that rate."""
    jerk_bar_share: float = 0.28
    """Fraction of ``bar_margin * bar_max`` that the jerk term ``b_2 j`` of the speed-up may
    use; it bounds the jerk (the pitch acceleration) of the speed-up [-]."""
    max_lag: float = 0.5
    """Largest distance [m] by which the governed reference may lead the vehicle in the
    direction of travel; when the vehicle falls further behind (a current, a speed lower
    than assumed) the reference waits for it instead of winding up the depth error."""
    pitch_guard: float = 0.97
    """Fraction of ``theta_max`` beyond which the depth feedback may not ask for more pitch:
    the pitch command ``theta_ref + (depth and integral terms) / K_theta`` of the LQR is
    clipped there (pitch envelope protection; inactive in normal flight) [-]."""

    def __post_init__(self) -> None:
        for name in ('margin', 'bar_margin', 'brake_bar_share', 'pitch_guard',
                     'jerk_bar_share', 'bar_rate_margin'):
            value = _finite(f'GovernorSettings.{name}', getattr(self, name), positive=True)
            if value > 1.0:
                raise DesignError(f'GovernorSettings.{name} must be in (0, 1], got {value!r}')
        share = _finite('GovernorSettings.release_bar_share', self.release_bar_share)
        if not 0.0 <= share < 1.0:
            raise DesignError(f'GovernorSettings.release_bar_share must be in [0, 1), got '
                              f'{share!r}')
        for name in ('accel_max', 'approach_length', 'jerk_time', 'landing_distance',
                     'integrate_within',
                     'integrate_below_speed', 'max_lag'):
            _finite(f'GovernorSettings.{name}', getattr(self, name), positive=True)


N_FF = 4
"""Orders of the feed-forward series: vertical speed and its first three derivatives."""


class OperatingPoint(NamedTuple):
    """Gain, trim and feed-forward at one surge speed (designed or interpolated).

    The feed-forward of a reference with vertical speed ``v(t)`` is the series
    ``X_ref = X_e + sum_k F[k, :3] v^(k)`` on ``(w, q, theta)`` and
    ``BAR_ff = BAR_e + sum_k F[k, 3] v^(k)`` for ``k = 0..3`` (``v^(k)`` the k-th time
    derivative): the exact trajectory of the linear model for polynomial profiles of
    degree <= 3 and its slow-manifold expansion otherwise (see :func:`_feedforward_series`).
    """

    u0: float
    """Surge speed of the design [m/s]."""
    K: Matrix
    """Discrete LQR gain (5,) on ``X - X_ref``; the command is ``BAR_ff - K (X - X_ref)``."""
    w_e: float
    """Trim heave [m/s]."""
    theta_e: float
    """Trim pitch [rad]."""
    bar_e: float
    """Trim BAR [rad]."""
    dw_dv: float
    """Change of steady heave per unit steady vertical speed [(m/s) / (m/s)]."""
    dtheta_dv: float
    """Change of steady pitch per unit steady vertical speed [rad / (m/s)], < 0 normally."""
    dbar_dv: float
    """Change of steady BAR per unit steady vertical speed [rad / (m/s)]."""
    F: Matrix
    """Feed-forward series (4, 4): row ``k`` holds ``(w, q, theta, BAR)`` per unit
    ``v^(k)`` [m/s, rad/s, rad, rad per m s^(k-1)]; row 0 is ``(dw_dv, 0, dtheta_dv,
    dbar_dv)``."""


def _feedforward_series(A: Matrix, B: Matrix, u0: float) -> Matrix:
    """Feed-forward series ``F`` (4, 4) of the linear model (see :class:`OperatingPoint`).

    With ``dX = sum_k X_k v^(k)`` (``X_k`` over ``(w, q, theta)``) and
    ``dBAR = sum_k b_k v^(k)``, the model ``dX_dot = A dX + B dBAR`` with
    ``z_dot = v`` holds term by term when, for ``k = 0, 1, ...``::

        A_wq X_k + B_wq b_k = X_{k-1}[w, q]      (heave and pitch rows)
        X_k[q]              = X_{k-1}[theta]     (theta_dot = q)
        A_z X_k + B_z b_k   = 1 if k == 0 else 0 (depth row: z_dot = v)

    with ``X_{-1} = 0``: one 4 x 4 solve per order. ``k = 0`` is the steady climb; the
    series is the model's slow manifold, accurate while the profile is slower than the
    zeros of BAR -> depth (time scale ~ 1 / |zero|, 0.6 s for the A18M at 2 m/s).
    Depth dependence of the forces (column z) is neglected; it is zero without depth effects.
    """
    cols = [0, 1, 3]
    M = np.zeros((4, 4))
    M[0, :3], M[0, 3] = A[0, cols], B[0, 0]
    M[1, :3], M[1, 3] = A[1, cols], B[1, 0]
    M[2, 1] = 1.0
    M[3, :3], M[3, 3] = A[2, cols], B[2, 0]
    if abs(np.linalg.det(M)) < 1e-12 * max(1.0, float(np.max(np.abs(M)))) ** 4:
        raise DesignError(
            f'the linear model at u0={u0:g} m/s has no steady climb: heave, pitch and depth '
            f'rows are singular in (w, q, theta, BAR): {M.tolist()}')
    F = np.zeros((N_FF, 4))
    previous = np.zeros(4)
    for k in range(N_FF):
        rhs = np.array([previous[0], previous[1], previous[2], 1.0 if k == 0 else 0.0])
        F[k] = np.linalg.solve(M, rhs)
        previous = F[k]
    return F


@dataclass(frozen=True)
class GainSchedule:
    """Discrete LQR gains and trims on a grid of surge speeds, interpolated in ``u``.

    Build it with :meth:`design`; :meth:`at` returns the :class:`OperatingPoint` for a
    measured surge speed, linearly interpolated and clamped to the grid ends.
    """

    speeds: Matrix
    """Grid of surge speeds, strictly increasing (g,) [m/s]."""
    K: Matrix
    """Gains (g, 5), one row per speed, for ``BAR = BAR_ff - K (X - X_ref)``."""
    w_e: Matrix
    """Trim heave (g,) [m/s]."""
    theta_e: Matrix
    """Trim pitch (g,) [rad]."""
    bar_e: Matrix
    """Trim BAR (g,) [rad]."""
    F: Matrix
    """Feed-forward series (g, 4, 4), see :class:`OperatingPoint`."""
    Ts: float
    """Sample period the gains were designed for [s]."""
    Q: Matrix = field(repr=False, default_factory=lambda: np.zeros((0, 0)))
    """State weight used in the design (5, 5)."""
    R: Matrix = field(repr=False, default_factory=lambda: np.zeros((0, 0)))
    """Input weight used in the design (1, 1)."""

    @property
    def dw_dv(self) -> Matrix:
        """Steady heave per vertical speed (g,) [-]."""
        return self.F[:, 0, 0]

    @property
    def dtheta_dv(self) -> Matrix:
        """Steady pitch per vertical speed (g,) [rad s/m]."""
        return self.F[:, 0, 2]

    @property
    def dbar_dv(self) -> Matrix:
        """Steady BAR per vertical speed (g,) [rad s/m]."""
        return self.F[:, 0, 3]

    @classmethod
    def design(
        cls,
        linearize: Linearize,
        speeds: Sequence[float] = (0.5, 1.0, 1.5, 2.0, 2.5, 3.0),
        Q: ArrayLike | None = None,
        R: ArrayLike | None = None,
        Ts: float = 0.1,
    ) -> GainSchedule:
        """Design one discrete LQR (:func:`~auv_depth_lqr.lqr.lqrd`) per surge speed.

        Parameters
        ----------
        linearize : callable
            ``linearize(u0) -> (x_e, u_e, A, B)``, see the module docstring.
        speeds : sequence of float
            Surge speeds of the grid [m/s], > 0 and strictly increasing.
        Q, R : array_like, optional
            Continuous weights for ``(w, q, z, theta, xi)`` (5, 5) and BAR (1, 1); both
            default to :data:`DEFAULT_WEIGHTS`. Use e.g. ``*PRESETS['report_5'].matrices()``.
        Ts : float
            Sample period of the controller [s].

        Raises
        ------
        DesignError
            Bad grid, bad linearisation output, bad weights, or no steady climb solution.
        NotControllableError
            If the model is not controllable at a grid speed (the speed is named).
        """
        if (Q is None) != (R is None):
            raise DesignError('give both Q and R, or neither (then DEFAULT_WEIGHTS is used)')
        if Q is None or R is None:
            Q, R = DEFAULT_WEIGHTS.matrices()
        ts = _finite('Ts', Ts, positive=True)
        grid = np.array([_finite('speed', s, positive=True) for s in speeds], dtype=float)
        if grid.size == 0 or np.any(np.diff(grid) <= 0.0):
            raise DesignError(
                f'speeds must be a non-empty, strictly increasing list of m/s, got {list(speeds)}')
        q_mat = _matrix('Q', Q, (N_STATES, N_STATES), '(5, 5)')
        r_mat = _matrix('R', R, (1, 1), '(1, 1)')
        rows: list[list[float]] = []
        gains: list[Matrix] = []
        series: list[Matrix] = []
        for u0 in grid:
            x_e, u_e, A, B = check_linearization(linearize, float(u0))
            try:
                check_controllable(A, B)
            except DesignError as exc:
                raise type(exc)(f'at u0={u0:g} m/s: {exc}') from None
            result = lqrd(A, B, q_mat, r_mat, ts)
            series.append(_feedforward_series(A, B, float(u0)))
            gains.append(result.K[0])
            rows.append([float(x_e[0]), float(x_e[3]), float(u_e)])
        table = np.array(rows)
        return cls(speeds=grid, K=np.array(gains), w_e=table[:, 0], theta_e=table[:, 1],
                   bar_e=table[:, 2], F=np.array(series), Ts=ts, Q=q_mat, R=r_mat)

    def weights(self, u: float) -> tuple[float, int, int, float]:
        """``(u_c, i, j, s)``: ``u`` [m/s] clamped to the grid and the interpolation between
        grid points ``i`` and ``j`` with weight ``s`` on ``j``."""
        uc = float(np.clip(u, self.speeds[0], self.speeds[-1]))
        i = int(np.clip(np.searchsorted(self.speeds, uc) - 1, 0, max(self.speeds.size - 2, 0)))
        if self.speeds.size == 1:
            return uc, i, i, 0.0
        j = i + 1
        return uc, i, j, float((uc - self.speeds[i]) / (self.speeds[j] - self.speeds[i]))

    def at(self, u: float) -> OperatingPoint:
        """Gain and trim at surge speed ``u`` [m/s], linear in ``u``, clamped to the grid."""
        uc, i, j, s = self.weights(u)

        def interp(values: Matrix) -> Matrix:
            out: Matrix = (1.0 - s) * values[i] + s * values[j]
            return out

        F = interp(self.F)
        return OperatingPoint(
            u0=uc, K=interp(self.K), w_e=float(interp(self.w_e)),
            theta_e=float(interp(self.theta_e)), bar_e=float(interp(self.bar_e)),
            dw_dv=float(F[0, 0]), dtheta_dv=float(F[0, 2]), dbar_dv=float(F[0, 3]), F=F)

    @staticmethod
    def climb_speed(op: OperatingPoint, u: float, v_lin: float) -> float:
        """Vertical speed [m/s, down] of the model's steady climb at linear speed ``v_lin``.

        The steady climb of the linear model at ``v_lin`` has pitch ``theta_e + dtheta_dv
        v_lin`` and heave ``w_e + dw_dv v_lin``; with the exact kinematics its vertical speed
        is ``-u sin(theta) + w cos(theta)`` (equal to ``v_lin`` to first order).
        """
        theta = op.theta_e + op.dtheta_dv * v_lin
        w = op.w_e + op.dw_dv * v_lin
        return -u * math.sin(theta) + w * math.cos(theta)

    @staticmethod
    def linear_speed(op: OperatingPoint, u: float, v: float) -> float:
        """Inverse of :meth:`climb_speed`: the linear-model speed whose exact climb is ``v``.

        Newton iterations from ``v``; the map is monotone for pitches within +-90 deg.
        """
        v_lin = v
        for _ in range(4):
            theta = op.theta_e + op.dtheta_dv * v_lin
            w = op.w_e + op.dw_dv * v_lin
            slope = ((-u * math.cos(theta) - w * math.sin(theta)) * op.dtheta_dv
                     + op.dw_dv * math.cos(theta))
            if slope == 0.0:
                break
            v_lin -= (-u * math.sin(theta) + w * math.cos(theta) - v) / slope
        return v_lin

    @staticmethod
    def vertical_speed_bounds(
        op: OperatingPoint, u: float, limits: Limits, margin: float
    ) -> tuple[float, float]:
        """Range ``(v_lo, v_hi)`` of steady vertical speeds [m/s] the reference may ask for.

        The steady climb/dive at linear speed ``v_lin`` needs pitch ``theta_e + dtheta_dv
        v_lin`` and BAR ``bar_e + dbar_dv v_lin``; both must stay within ``margin`` times
        their limits; the bounds on ``v_lin`` are mapped to true vertical speeds with the
        exact kinematics (:meth:`climb_speed`) and also kept within
        ``margin * u * sin(theta_max)``. ``v_lo <= 0 <= v_hi``; both are 0 when the trim
        itself violates a limit or ``u <= 0``.
        """
        if u <= 0.0:
            return 0.0, 0.0
        v_kin = margin * u * math.sin(limits.theta_max)
        lo, hi = -math.inf, math.inf
        for centre, slope, bound in (
            (op.theta_e, op.dtheta_dv, margin * limits.theta_max),
            (op.bar_e, op.dbar_dv, margin * limits.bar_max),
        ):
            if abs(centre) >= bound:
                return 0.0, 0.0
            if slope != 0.0:
                ends = sorted(((bound - centre) / slope, (-bound - centre) / slope))
                lo, hi = max(lo, ends[0]), min(hi, ends[1])
        v_lo = -v_kin if math.isinf(lo) else max(-v_kin, GainSchedule.climb_speed(op, u, lo))
        v_hi = v_kin if math.isinf(hi) else min(v_kin, GainSchedule.climb_speed(op, u, hi))
        return min(v_lo, 0.0), max(v_hi, 0.0)


def check_linearization(
    linearize: Linearize, u0: float
) -> tuple[Matrix, float, Matrix, Matrix]:
    """Call ``linearize(u0)``; check and return ``(x_e (5,), u_e, A (5, 5), B (5, 1))``.

    Raises :class:`DesignError` naming the returned item whose shape or values are wrong.
    """
    out = linearize(u0)
    try:
        x_e, u_e, A, B = out
    except (TypeError, ValueError):
        raise DesignError(
            f'linearize({u0:g}) must return (x_e, u_e, A, B), got {type(out).__name__}') from None
    x = np.asarray(x_e, dtype=float).reshape(-1)
    a = np.asarray(A, dtype=float)
    b = np.asarray(B, dtype=float)
    if b.ndim == 1:
        b = b.reshape(-1, 1)
    ue = np.asarray(u_e, dtype=float).reshape(-1)
    for name, arr, shape in (('x_e', x, (N_STATES,)), ('A', a, (N_STATES, N_STATES)),
                             ('B', b, (N_STATES, 1)), ('u_e', ue, (1,))):
        if arr.shape != shape:
            raise DesignError(
                f'linearize({u0:g}) returned {name} of shape {arr.shape}, expected {shape}')
        if not np.all(np.isfinite(arr)):
            raise DesignError(f'linearize({u0:g}) returned non-finite {name}: {arr.tolist()}')
    return x, float(ue[0]), a, b


class DepthController:
    """Sampled depth pilot: BAR command from the vertical-plane state and a depth reference.

    Call :meth:`step` once per sample period ``Ts`` with the latest state and the commanded
    depth; the returned BAR angle is to be held (zero-order hold) until the next call.

    Parameters
    ----------
    design : GainSchedule
        Gains and trims on a speed grid, designed for the same ``Ts``.
    limits : Limits
        BAR angle/rate limits, pitch limit, integrator bound.
    Ts : float
        Sample period [s]; must equal ``design.Ts``.
    governor : GovernorSettings, optional
        Reference-governor settings.

    Raises
    ------
    DesignError
        If ``Ts`` differs from the design's, or the trim BAR or pitch at a grid speed is
        already beyond the limits (the vehicle cannot hold depth there: shrink the grid).
    """

    def __init__(
        self,
        design: GainSchedule,
        limits: Limits | None = None,
        Ts: float | None = None,
        governor: GovernorSettings | None = None,
    ) -> None:
        self.design = design
        self.limits = limits if limits is not None else Limits()
        self.governor = governor if governor is not None else GovernorSettings()
        ts = design.Ts if Ts is None else _finite('Ts', Ts, positive=True)
        if abs(ts - design.Ts) > 1e-9 * design.Ts:
            raise DesignError(
                f'Ts={ts:g} s differs from the sample period of the gain design '
                f'({design.Ts:g} s); redesign the schedule for this Ts')
        self.Ts = ts
        for u0, bar_e, theta_e in zip(design.speeds, design.bar_e, design.theta_e):
            if abs(bar_e) >= self.limits.bar_max or abs(theta_e) >= self.limits.theta_max:
                raise DesignError(
                    f'trim at u0={u0:g} m/s (BAR_e={bar_e:.4g} rad, theta_e={theta_e:.4g} rad)'
                    f' is beyond the limits (bar_max={self.limits.bar_max:.4g} rad, '
                    f'theta_max={self.limits.theta_max:.4g} rad); remove this speed from the '
                    'grid')
        # One-sample maps of the stop model at the grid speeds, interpolated like the gains.
        # An open-loop-unstable vehicle (no stable series at some grid speed) cannot stop by
        # holding its plane: its stop is planned kinematically (see _kinematic_map).
        self.kinematic_stop = not all(_stable_series([float(x) for x in design.F[k, :, 3]])
                                      for k in range(design.speeds.size))
        self._stop_tau = 0.5 * self.governor.jerk_time
        self._stop_maps = [
            _kinematic_map(self._stop_tau, ts) if self.kinematic_stop
            else _series_map([float(x) for x in design.F[k, :, 3]], ts)
            for k in range(design.speeds.size)]
        self.reset()

    # -- state -----------------------------------------------------------------------------
    def reset(self, bar_previous: float | None = None) -> None:
        """Forget the integrator, the governed reference and the previous command.

        Parameters
        ----------
        bar_previous : float, optional
            Current BAR angle [rad]. If given, the first command after the reset is
            rate-limited from it; if omitted, the first command is only angle-limited.
        """
        self._xi = 0.0
        self._z_r: float | None = None
        self._v_r = 0.0
        self._a_r = 0.0
        self._j_r = 0.0
        self._s_r = 0.0
        self._landing: tuple[float, float] | None = None
        self._switch_hint = [0]
        self._s_root: float | None = None
        self._bar_prev = None if bar_previous is None else _finite('bar_previous', bar_previous)

    @property
    def integrator(self) -> float:
        """Integrated depth error ``xi`` [m s]."""
        return self._xi

    @property
    def governed_reference(self) -> tuple[float, float] | None:
        """Governed depth and vertical speed ``(z_r [m], v_r [m/s])`` seen by the LQR."""
        return None if self._z_r is None else (self._z_r, self._v_r)

    # -- one sample ------------------------------------------------------------------------
    def _limits_toward(self, op: OperatingPoint, u: float, travel: float, landing: float
                       ) -> tuple[float, float, _Brake]:
        """Limits of the reference for a motion in ``travel`` (+1 down, -1 up).

        Returns ``(v_cap, jerk, brake)``: the steady vertical speed it may reach [m/s, > 0,
        along ``travel``], the jerk limit of its speed-up [m/s^3] and the model of its stop
        (:class:`_Brake`, :func:`_stop_distance`). In the travel frame (speed ``V``,
        acceleration ``A``, jerk ``J``, snap ``S``, all along ``travel``) the feed-forward
        input ``U = travel (BAR - bar_e)`` of the series is ``b_0 V + b_1 A + b_2 J + b_3 S``
        (linear kinematics). A stop moves that input at ``bar_rate_margin`` times the plane's
        rate to the braking end of ``brake_bar_share * bar_margin * bar_max`` and holds it,
        then releases it at the same rate towards the landing's input plus
        ``release_bar_share`` of the room beyond it, until the deceleration is down to that of
        the landing (time constant ``landing`` [s]). The speed-up jerk is at most
        ``accel_max / jerk_time`` and ``b_2 jerk`` at most ``jerk_bar_share`` of the budget.
        """
        settings, lim = self.governor, self.limits
        b = op.F[:, 3]
        budget = settings.bar_margin * lim.bar_max
        jerk = settings.accel_max / settings.jerk_time
        if b[2] != 0.0:
            jerk = min(jerk, settings.jerk_bar_share * budget / abs(float(b[2])))
        v_lo, v_hi = GainSchedule.vertical_speed_bounds(op, u, lim, settings.margin)
        v_cap = v_hi if travel > 0.0 else -v_lo
        v_land = settings.landing_distance / landing
        share = settings.brake_bar_share * budget
        sign = 1.0 if float(b[1]) >= 0.0 else -1.0
        u_brake = -sign * share - travel * op.bar_e
        u_other = sign * share - travel * op.bar_e
        b0, b1 = float(b[0]), float(b[1])
        u_land = b0 * v_land - b1 * v_land / landing  # the landing's input at its start
        u_release = u_land + settings.release_bar_share * (u_other - u_land)
        du = settings.bar_rate_margin * lim.bar_rate_max * self.Ts
        if self.kinematic_stop:
            # Input: the commanded acceleration along the travel [m/s^2], moved no faster than
            # the jerk limit. The stop brakes at the deceleration that the braking share of
            # the plane's room (about the trim, on the side where b_1 (-travel a) lies) holds,
            # at most accel_max.
            side = -travel * (1.0 if b1 >= 0.0 else -1.0)
            room = max(budget - side * op.bar_e, 0.0)
            a_stop = settings.accel_max if b1 == 0.0 else min(
                settings.accel_max, settings.brake_bar_share * room / abs(b1))
            u_brake, u_other = -a_stop, a_stop
            u_land = -v_land / landing
            u_release = u_land + settings.release_bar_share * (u_other - u_land)
            du = jerk * self.Ts
        _, i, j, w = self.design.weights(u)
        (phi_i, gam_i), (phi_j, gam_j) = self._stop_maps[i], self._stop_maps[j]
        brake = _Brake(tuple((1.0 - w) * x + w * y for x, y in zip(phi_i, phi_j)),
                       tuple((1.0 - w) * x + w * y for x, y in zip(gam_i, gam_j)),
                       u_brake, u_release, max(du, 1e-9), landing, v_land)
        return v_cap, jerk, brake

    def _govern(self, op: OperatingPoint, u: float, z_cmd: float
                ) -> tuple[float, float, float, float, float]:
        """Advance the governed reference one sample: new ``(z_r, v_r, a_r, j_r, s_r)``.

        A time-optimal point-to-point motion, re-planned at every sample (so it follows a
        new command, a new speed or a reference held back by the vehicle). The snap ``s_r``
        [m/s^4], constant over the sample, moves the jerk towards the speed-up profile: the
        acceleration goes towards ``sqrt(2 jerk dv + (jerk c)^2) - jerk c`` (``dv`` the speed
        still to gain up to ``v_cap``, ``c = jerk_time / 2``) at most at the jerk limit. The
        feed-forward BAR ``bar_e + b_0 v_lin + b_1 a + b_2 j + b_3 s`` stays inside
        ``bar_margin * bar_max`` and moves at most at ``bar_rate_margin`` times the plane's
        rate, so the reference is one the plane can fly. If the stop from the state after the
        sample (:func:`_stop_distance`) would pass the target, the snap is instead the largest
        one whose stop ends on the target (regula falsi from the last sample's root; the rate
        limit gives way before the target does): the reference brakes as late as the plane
        allows and never overshoots.
        """
        settings, lim, ts = self.governor, self.limits, self.Ts
        assert self._z_r is not None
        # The landing's time constant is fixed per command (at the speed of its first sample):
        # a landing that changed with every wobble of the measured speed would re-plan itself.
        if self._landing is None or self._landing[0] != z_cmd:
            self._landing = (z_cmd, settings.approach_length / max(u, 0.1))
        error = z_cmd - self._z_r
        travel = 1.0 if error > 0.0 or (error == 0.0 and self._v_r > 0.0) else -1.0
        E, V = travel * error, travel * self._v_r
        A, J = travel * self._a_r, travel * self._j_r
        if E < 1e-3 and abs(V) < 1e-3 and abs(A) < 2e-3 and abs(J) < 2e-3:
            return z_cmd, 0.0, 0.0, 0.0, 0.0
        v_cap, jerk, brake = self._limits_toward(op, u, travel, self._landing[1])
        landing, v_land = brake.landing, brake.v_land
        if 0.0 < V <= v_land * (1.0 + 1e-6) and V * landing * (1.0 + 1e-6) >= E:
            # Final approach: the exponential e(t) = E exp(-t / landing).
            e1 = E * math.exp(-ts / landing)
            v1 = e1 / landing
            return (z_cmd - travel * e1, travel * v1, -travel * v1 / landing,
                    travel * v1 / landing**2, -travel * v1 / landing**3)
        b = [float(x) for x in op.F[:, 3]]
        # Feed-forward input U = b0 V + b1 A + b2 J + b3 S at the end of the sample, linear
        # in the snap S held over it; BAR = bar_e + travel U (exact kinematics in b0's term).
        _, v0, a0, j0 = _constant_snap(V, A, J, 0.0, ts)
        lin0 = travel * GainSchedule.linear_speed(op, u, travel * v0)
        centre = b[0] * lin0 + b[1] * a0 + b[2] * j0
        slope = b[3] + b[2] * ts + b[1] * ts * ts / 2.0 + b[0] * ts ** 3 / 6.0
        budget = settings.bar_margin * lim.bar_max
        u_hi, u_lo = budget - travel * op.bar_e, -budget - travel * op.bar_e
        s_cap = settings.accel_max / ts ** 2
        if slope != 0.0 and not self.kinematic_stop:
            ends = sorted(((u_lo - centre) / slope, (u_hi - centre) / slope))
            s_lo, s_hi = ends
            s_floor = s_lo
            lin_prev = travel * GainSchedule.linear_speed(op, u, self._v_r)
            u_prev = b[0] * lin_prev + b[1] * A + b[2] * J + b[3] * travel * self._s_r
            rate = sorted(((u_prev - brake.du - centre) / slope,
                           (u_prev + brake.du - centre) / slope))
            if rate[0] <= s_hi and rate[1] >= s_lo:
                s_lo, s_hi = max(s_lo, rate[0]), min(s_hi, rate[1])
        else:
            s_lo = s_floor = -s_cap
            s_hi = s_cap
        if self.kinematic_stop:
            # The series of an unstable vehicle lets profiles that grow at its unstable rates
            # through the plane budget at no cost: bound the reference's jerk (twice the
            # speed-up's) and, beyond accel_max, turn its acceleration back.
            j_lim = 2.0 * jerk
            k_lo, k_hi = (-j_lim - J) / ts, (j_lim - J) / ts
            if settings.accel_max < A:
                k_hi = min(k_hi, (-j_lim - J) / ts + 1e-9)
            elif -settings.accel_max > A:
                k_lo = max(k_lo, (j_lim - J) / ts - 1e-9)
            s_lo, s_hi = max(s_lo, k_lo), min(s_hi, k_hi)
            if s_lo > s_hi:
                s_lo = s_hi = min(max(0.0, k_lo), k_hi)
            s_floor = max(s_floor, k_lo)
        # Speed-up: the jerk goes towards what brings the acceleration to a_goal.
        dv = v_cap - V - 0.5 * A * settings.jerk_time  # the jerk lags jerk_time behind
        lag = 0.5 * settings.jerk_time * jerk
        a_goal = math.copysign(math.sqrt(2.0 * jerk * abs(dv) + lag * lag) - lag, dv)
        a_goal = min(a_goal, settings.accel_max)
        j_goal = (a_goal - A) / settings.jerk_time
        j_goal = max(j_goal, -jerk) if A < 0.0 else min(max(j_goal, -jerk), jerk)
        s = min(max((j_goal - J) / ts, s_lo), s_hi)

        hint = self._switch_hint
        hint[0] = max(hint[0] - 1, 0)

        def overshoot(s_try: float) -> float:
            dz, v1, a1, j1 = _constant_snap(V, A, J, s_try, ts)
            u1 = (a1 + 2.0 * self._stop_tau * j1 + self._stop_tau ** 2 * s_try
                  if self.kinematic_stop else b[0] * v1 + b[1] * a1 + b[2] * j1 + b[3] * s_try)
            return dz + _stop_distance(v1, a1, j1, u1, brake, hint) - E

        f_hi = overshoot(s)
        if f_hi > 0.0:
            lo, hi = s_lo, s
            f_lo = overshoot(lo)
            if f_lo >= 0.0 and s_floor < s_lo:
                lo, hi = s_floor, s_lo  # the rate limit gives way before the target does
                f_lo, f_hi = overshoot(lo), f_lo
            s = lo if f_lo >= 0.0 else _largest_root_below(overshoot, lo, hi, f_lo, f_hi,
                                                           self._s_root)
            self._s_root = s
        dz, v1, a1, j1 = _constant_snap(V, A, J, s, ts)
        if v1 > v_cap:  # the speed-up's momentum: never beyond the climb/dive bound
            v1, a1, j1 = v_cap, min(a1, 0.0), min(j1, 0.0)
        return (self._z_r + travel * dz, travel * v1, travel * a1, travel * j1, travel * s)

    def feedforward(self, op: OperatingPoint, u: float, v: float, a: float, j: float,
                    snap: float = 0.0) -> tuple[Matrix, float]:
        """Reference ``(w, q, theta)`` [m/s, rad/s, rad] and BAR [rad] of a vertical motion.

        ``v`` [m/s] is the true vertical speed (exact kinematics, see
        :meth:`GainSchedule.linear_speed`); ``a``, ``j``, ``snap`` its derivatives
        [m/s^2, m/s^3, m/s^4]. Uses the series of :class:`OperatingPoint`.
        """
        orders = np.array([GainSchedule.linear_speed(op, u, v), a, j, snap])
        total = orders @ op.F
        x_ref = np.array([op.w_e + total[0], total[1], op.theta_e + total[2]])
        return x_ref, op.bar_e + float(total[3])

    def step(self, state: DepthState, z_ref: float) -> float:
        """BAR command [rad] for this sample.

        Parameters
        ----------
        state : DepthState
            Measured ``z`` [m, NED down], ``theta`` [rad, nose up], ``w`` [m/s], ``q``
            [rad/s], ``u`` [m/s] (e.g. an ``auv_msgs/VehicleState``).
        z_ref : float
            Commanded depth [m, positive down].

        Returns
        -------
        float
            BAR angle [rad], within ``+-bar_max`` and within ``bar_rate_max * Ts`` of the
            previous command.

        Raises
        ------
        InvalidInputError
            If ``z_ref`` or a state field is missing or not finite; the controller's internal
            state is left unchanged.
        """
        z_cmd = _input('depth reference z_ref [m]', z_ref)
        z = _input('state.z [m]', getattr(state, 'z', None))
        theta = _input('state.theta [rad]', getattr(state, 'theta', None))
        w = _input('state.w [m/s]', getattr(state, 'w', None))
        q = _input('state.q [rad/s]', getattr(state, 'q', None))
        u = _input('state.u [m/s]', getattr(state, 'u', None))

        ts, lim, settings = self.Ts, self.limits, self.governor
        op = self.design.at(u)

        if self._z_r is None:
            self._z_r, self._v_r, self._a_r, self._j_r, self._s_r = z, 0.0, 0.0, 0.0, 0.0
        z_r, v_r, a_r, j_r, s_r = self._govern(op, u, z_cmd)
        # The reference waits for a vehicle that falls behind it by more than max_lag.
        if v_r != 0.0:
            travel = math.copysign(1.0, v_r)
            if travel * (z_r - z) > settings.max_lag:
                z_r = z + travel * settings.max_lag

        # Feed-forward of the reference manoeuvre and the LQR correction around it.
        wqt, bar_ff = self.feedforward(op, u, v_r, a_r, j_r, s_r)
        x = np.array([w, q, z, theta, self._xi])
        x_ref = np.array([wqt[0], wqt[1], z_r, wqt[2], 0.0])
        error = x - x_ref
        K = op.K
        depth_terms = float(K[2] * error[2] + K[4] * error[4])
        # Pitch envelope protection: the depth and integral terms act like a pitch command
        # theta_ref - depth_terms / K_theta for the attitude loop; clip that command.
        k_theta = float(K[3])
        if k_theta != 0.0:
            theta_lim = settings.pitch_guard * lim.theta_max
            theta_cmd = x_ref[3] - depth_terms / k_theta
            clipped = min(max(theta_cmd, -theta_lim), theta_lim)
            depth_terms = k_theta * (x_ref[3] - clipped)
        bar_linear = bar_ff - float(K[0] * error[0] + K[1] * error[1] + K[3] * error[3]) \
            - depth_terms

        if not (math.isfinite(bar_linear) and math.isfinite(z_r) and math.isfinite(v_r)):
            # min/max would turn a NaN into a limit: refuse instead; the state is left as is
            raise ControllerError(
                f'the controller produced a non-finite command (BAR {bar_linear}, reference '
                f'z {z_r} m, v {v_r} m/s) from z={z} m, theta={theta} rad, w={w} m/s, '
                f'q={q} rad/s, u={u} m/s, z_ref={z_cmd} m')
        # Angle limit, then rate limit.
        bar_cmd = min(max(bar_linear, -lim.bar_max), lim.bar_max)
        if self._bar_prev is not None:
            slew = lim.bar_rate_max * ts
            bar_cmd = min(max(bar_cmd, self._bar_prev - slew), self._bar_prev + slew)

        # Anti-windup (conditional integration): integrate only while the governed reference
        # is (nearly) at rest and the depth is near it, and not when the command is limited
        # and integrating would push it further into the limit; then clamp the integrator's
        # share of the command.
        k_xi = float(K[4])
        increment = (z - z_r) * ts
        pushes = -k_xi * increment  # effect of this increment on the command [rad]
        limited = bar_linear - bar_cmd
        winds_up = abs(limited) > 1e-12 and pushes * limited > 0.0
        near = (abs(v_r) <= settings.integrate_below_speed
                and abs(z - z_r) <= settings.integrate_within)
        if near and not winds_up:
            self._xi += increment
        if k_xi != 0.0:
            xi_max = lim.integral_bar_max / abs(k_xi)
            self._xi = min(max(self._xi, -xi_max), xi_max)

        self._z_r, self._v_r, self._a_r, self._j_r, self._s_r = z_r, v_r, a_r, j_r, s_r
        self._bar_prev = bar_cmd
        return bar_cmd


def _largest_root_below(f: Callable[[float], float], lo: float, hi: float, f_lo: float,
                        f_hi: float, guess: float | None = None, tol: float = 1e-6) -> float:
    """Largest ``x`` in ``[lo, hi]`` with ``f(x) <= 0`` for an increasing ``f`` with
    ``f(lo) < 0 < f(hi)``, to ``tol`` times the bracket (regula falsi, Illinois variant:
    a handful of evaluations where bisection needs twenty). A ``guess`` inside the bracket
    (the last sample's root) is tried first, with a point just beside it."""
    width = tol * (hi - lo)
    if guess is not None and lo < guess < hi:
        for x in (guess, guess + 1e-4 * (hi - lo)):
            x = min(x, hi - 0.5 * width)
            fx = f(x)
            if fx > 0.0:
                hi, f_hi = x, fx
                break
            lo, f_lo = x, fx
    side = 0
    for _ in range(60):
        if hi - lo <= width:
            break
        if math.isfinite(f_hi) and math.isfinite(f_lo):
            x = hi - f_hi * (hi - lo) / (f_hi - f_lo)
            x = min(max(x, lo + 0.5 * width), hi - 0.5 * width)
        else:  # an endless stop on one side: bisect
            x = 0.5 * (lo + hi)
        fx = f(x)
        if fx > 0.0:
            hi, f_hi = x, fx
            if side == 1:
                f_lo *= 0.5
            side = 1
        else:
            lo, f_lo = x, fx
            if fx > -1e-6:  # within a micrometre of the target: done
                break
            if side == -1:
                f_hi *= 0.5
            side = -1
    return lo


def _constant_snap(v: float, a: float, j: float, s: float, t: float
                   ) -> tuple[float, float, float, float]:
    """Distance [m], speed [m/s], acceleration [m/s^2] and jerk [m/s^3] after ``t`` [s] at
    constant snap ``s`` [m/s^4]."""
    t2 = t * t
    return (v * t + a * t2 / 2.0 + j * t2 * t / 6.0 + s * t2 * t2 / 24.0,
            v + a * t + j * t2 / 2.0 + s * t2 * t / 6.0, a + j * t + s * t2 / 2.0, j + s * t)


def _hurwitz(coefficients: Sequence[float]) -> bool:
    """Whether ``c_0 + c_1 s + ... + c_n s^n`` (``c_n != 0``) has all roots in Re < 0."""
    return bool(np.all(np.real(np.roots(list(coefficients)[::-1])) < 0.0))


class _Brake(NamedTuple):
    """Travel-frame stop of the reference (see :meth:`DepthController._limits_toward`).

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
              landing: float, v_land: float, ts: float) -> _Brake:
        """The stop model of the series coefficients ``b = (b_0, b_1, b_2, b_3)``."""
        phi, gam = _series_map(b, ts)
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


def _series_map(b: Sequence[float], ts: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """``(phi, gam)`` of :class:`_Brake`: the exact one-sample map of the series model with
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


def _stable_series(b: Sequence[float]) -> bool:
    """Whether holding the plane stops the vertical motion: the first-order truncation
    ``b_0 + b_1 s`` of the series is Hurwitz (``b_0``, ``b_1`` of one sign)."""
    return b[1] != 0.0 and _hurwitz(b[:2])


def _kinematic_map(tau: float, ts: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
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


_MAX_BRAKE_STEPS = 2000
"""Longest stop the planner follows, in samples; a stop that is not over by then is taken
to be infinitely long (the reference then brakes at once)."""


def _toward(u: float, target: float, du: float) -> float:
    """``u`` moved by at most ``du`` towards ``target``."""
    return min(target, u + du) if u < target else max(target, u - du)


def _release(state: tuple[float, float, float, float], u: float, brake: _Brake
             ) -> tuple[float, float]:
    """Distance [m] and speed [m/s] at the end of the release from ``(P, V, A, J)`` with
    input ``u`` [rad]: the input moves at its rate limit towards ``brake.u_release`` until
    the acceleration reaches ``-v_land / landing`` (interpolated within the sample), or
    until the motion stops (speed 0: the release came too late to land)."""
    a_end = -brake.v_land / brake.landing
    for _ in range(_MAX_BRAKE_STEPS):
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


def _stop_distance(v: float, a: float, j: float, u_now: float, brake: _Brake,
                   hint: list[int] | None = None) -> float:
    """Distance [m] to the target of the stop from speed ``v`` [m/s], acceleration ``a``
    [m/s^2], jerk ``j`` [m/s^3] (along the travel) and feed-forward input ``u_now`` [rad].

    The stop moves the BAR at its rate limit to the braking end of the budget and holds it
    there (:meth:`_Brake.advance`, sample by sample), then releases (:func:`_release`);
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
        return -_stop_distance(-v, -a, -j, -u_now, mirrored)
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
            if len(states) > _MAX_BRAKE_STEPS:
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


def _input(name: str, value: object) -> float:
    """A finite float run-time input, else :class:`InvalidInputError` naming it."""
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise InvalidInputError(f'{name} must be a number, got {value!r}') from None
    if not math.isfinite(number):
        raise InvalidInputError(f'{name} must be finite, got {value!r}')
    return number


