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
* a reference governor that turns a large depth change into a smooth vertical-speed profile
  whose steady climb/dive needs at most ``margin * theta_max`` pitch and ``margin * bar_max``
  BAR, with model-based feed-forward of the trim for that vertical speed, so big steps settle
  near the kinematic bound ``|dz| / (u sin(theta_max))`` without stall or porpoising.

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

from auv_depth_lqr.errors import DesignError, InvalidInputError
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
# scaled with speed (closed loop with the BAR angle/rate limits and the reference governor):
# the pitch-rate and pitch terms dominate the depth term, so the depth error is removed by a
# well-damped attitude change, never by a pitch oscillation. Closed-loop poles at
# 0.5-3 m/s: damping ratio >= 0.7 (checked in the tests).
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
    integral_bar_max: float = math.radians(8.0)
    """Largest BAR share of the integral term ``|K_xi xi|`` [rad]: bounds the integrator to
    what trim errors can need (8 deg, assumed: ~2x the report's trim BAR)."""

    def __post_init__(self) -> None:
        for name in ('bar_max', 'bar_rate_max', 'theta_max', 'integral_bar_max'):
            _finite(f'Limits.{name}', getattr(self, name), positive=True)
        if self.theta_max >= math.pi / 2:
            raise DesignError(f'Limits.theta_max must be < pi/2 rad, got {self.theta_max!r}')


@dataclass(frozen=True)
class GovernorSettings:
    """Reference governor: how a depth step becomes a vertical-speed profile.

    The governed reference ``z_r`` moves towards the commanded depth with a speed ``v_r``
    that obeys ``|v_r| <= v_lim`` (from the pitch and BAR limits, see
    :meth:`GainSchedule.vertical_speed_bounds`), an acceleration of at most ``accel_max``
    reached in ``jerk_time``, and brakes on a square-root profile ending in an exponential
    approach (see :meth:`DepthController._govern`).
    """

    margin: float = 0.9
    """Fraction of ``theta_max``, ``bar_max`` and ``u sin(theta_max)`` that the steady climb or
    dive of the reference may use; the rest is left to the feedback [-]."""
    accel_max: float = 0.07
    """Vertical acceleration of the reference [m/s^2]; it sets the pitch rate in the
    transitions, ``~ accel_max / u`` [rad/s]."""
    jerk_time: float = 3.0
    """Time over which the reference acceleration may go from 0 to ``accel_max`` [s]
    (jerk limit ``accel_max / jerk_time``); it keeps the demanded pitch rate continuous,
    which the pitch dynamics (time constants of 1-2 s) can follow."""
    approach_time: float = 3.0
    """Time constant of the final exponential approach [s]."""
    integrate_within: float = 0.5
    """The depth integrator runs only while ``|z - z_r|`` is at most this [m]."""
    integrate_below_speed: float = 0.05
    """The depth integrator runs only while ``|v_r|`` is at most this [m/s]: the manoeuvre
    itself is flown on the feed-forward and the proportional feedback, so transient tracking
    errors of a long climb do not wind the integrator up."""
    pitch_rate_bar_share: float = 0.9
    """Fraction of ``margin * bar_max`` that the feed-forward of the reference may use in the
    transitions (trim + steady climb + pitch rate); the rest is left to the feedback [-]."""

    def __post_init__(self) -> None:
        margin = _finite('GovernorSettings.margin', self.margin, positive=True)
        if margin > 1.0:
            raise DesignError(f'GovernorSettings.margin must be in (0, 1], got {margin!r}')
        _finite('GovernorSettings.accel_max', self.accel_max, positive=True)
        _finite('GovernorSettings.approach_time', self.approach_time, positive=True)
        _finite('GovernorSettings.jerk_time', self.jerk_time, positive=True)
        _finite('GovernorSettings.integrate_within', self.integrate_within, positive=True)
        _finite('GovernorSettings.integrate_below_speed', self.integrate_below_speed,
                positive=True)
        share = _finite('GovernorSettings.pitch_rate_bar_share', self.pitch_rate_bar_share,
                        positive=True)
        if share > 1.0:
            raise DesignError(
                f'GovernorSettings.pitch_rate_bar_share must be in (0, 1], got {share!r}')


class OperatingPoint(NamedTuple):
    """Gain and trim at one surge speed (designed or interpolated)."""

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
    dw_dq: float
    """Heave that accompanies a sustained pitch rate, per unit pitch rate [(m/s) / (rad/s)]."""
    dbar_dq: float
    """BAR that sustains a pitch rate, per unit pitch rate [rad / (rad/s)]."""


def _steady_climb(A: Matrix, B: Matrix, u0: float) -> tuple[float, float, float]:
    """Steady ``(dw, dtheta, dbar)`` per unit vertical speed from the linear model.

    Solves ``w_dot = 0, q_dot = 0, z_dot = 1`` with ``q = 0`` and the integrator untouched,
    i.e. rows (w, q, z) and columns (w, theta, BAR). Depth dependence of the forces
    (column z of rows w, q) is neglected; it is zero in a model without depth effects.
    """
    M = np.array([
        [A[0, 0], A[0, 3], B[0, 0]],
        [A[1, 0], A[1, 3], B[1, 0]],
        [A[2, 0], A[2, 3], B[2, 0]],
    ])
    if abs(np.linalg.det(M)) < 1e-12 * max(1.0, float(np.max(np.abs(M)))) ** 3:
        raise DesignError(
            f'the linear model at u0={u0:g} m/s has no steady climb: heave, pitch and depth '
            f'rows are singular in (w, theta, BAR): {M.tolist()}')
    dw, dtheta, dbar = np.linalg.solve(M, np.array([0.0, 0.0, 1.0]))
    return float(dw), float(dtheta), float(dbar)


def _steady_pitch_rate(A: Matrix, B: Matrix, u0: float) -> tuple[float, float]:
    """Heave and BAR ``(dw, dbar)`` per unit pitch rate held at constant pitch angle.

    Solves ``w_dot = 0, q_dot = 0`` for ``(w, BAR)`` with ``q = 1`` (rows and columns w, q;
    input BAR); the pitch-angle terms are accounted for by :func:`_steady_climb`.
    """
    M = np.array([[A[0, 0], B[0, 0]], [A[1, 0], B[1, 0]]])
    if abs(np.linalg.det(M)) < 1e-12 * max(1.0, float(np.max(np.abs(M)))) ** 2:
        raise DesignError(
            f'the linear model at u0={u0:g} m/s cannot hold a pitch rate: heave and pitch '
            f'rows are singular in (w, BAR): {M.tolist()}')
    dw, dbar = np.linalg.solve(M, -np.array([A[0, 1], A[1, 1]]))
    return float(dw), float(dbar)


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
    dw_dv: Matrix
    """Steady heave per vertical speed (g,) [-]."""
    dtheta_dv: Matrix
    """Steady pitch per vertical speed (g,) [rad s/m]."""
    dbar_dv: Matrix
    """Steady BAR per vertical speed (g,) [rad s/m]."""
    dw_dq: Matrix
    """Heave per sustained pitch rate (g,) [m/rad]."""
    dbar_dq: Matrix
    """BAR per sustained pitch rate (g,) [s]."""
    Ts: float
    """Sample period the gains were designed for [s]."""
    Q: Matrix = field(repr=False, default_factory=lambda: np.zeros((0, 0)))
    """State weight used in the design (5, 5)."""
    R: Matrix = field(repr=False, default_factory=lambda: np.zeros((0, 0)))
    """Input weight used in the design (1, 1)."""

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
        for u0 in grid:
            x_e, u_e, A, B = check_linearization(linearize, float(u0))
            try:
                check_controllable(A, B)
            except DesignError as exc:
                raise type(exc)(f'at u0={u0:g} m/s: {exc}') from None
            result = lqrd(A, B, q_mat, r_mat, ts)
            dw, dtheta, dbar = _steady_climb(A, B, float(u0))
            dw_q, dbar_q = _steady_pitch_rate(A, B, float(u0))
            gains.append(result.K[0])
            rows.append(
                [float(x_e[0]), float(x_e[3]), float(u_e), dw, dtheta, dbar, dw_q, dbar_q])
        table = np.array(rows)
        return cls(
            speeds=grid, K=np.array(gains), w_e=table[:, 0], theta_e=table[:, 1],
            bar_e=table[:, 2], dw_dv=table[:, 3], dtheta_dv=table[:, 4], dbar_dv=table[:, 5],
            dw_dq=table[:, 6], dbar_dq=table[:, 7], Ts=ts, Q=q_mat, R=r_mat)

    def at(self, u: float) -> OperatingPoint:
        """Gain and trim at surge speed ``u`` [m/s], linear in ``u``, clamped to the grid."""
        uc = float(np.clip(u, self.speeds[0], self.speeds[-1]))

        def interp(values: Matrix) -> float:
            return float(np.interp(uc, self.speeds, values))

        K = np.array([interp(self.K[:, i]) for i in range(self.K.shape[1])])
        return OperatingPoint(
            u0=uc, K=K, w_e=interp(self.w_e), theta_e=interp(self.theta_e),
            bar_e=interp(self.bar_e), dw_dv=interp(self.dw_dv),
            dtheta_dv=interp(self.dtheta_dv), dbar_dv=interp(self.dbar_dv),
            dw_dq=interp(self.dw_dq), dbar_dq=interp(self.dbar_dq))

    @staticmethod
    def vertical_speed_bounds(
        op: OperatingPoint, u: float, limits: Limits, margin: float
    ) -> tuple[float, float]:
        """Range ``(v_lo, v_hi)`` of steady vertical speeds [m/s] the reference may ask for.

        The steady climb/dive at ``v`` needs pitch ``theta_e + dtheta_dv v`` and BAR
        ``bar_e + dbar_dv v``; both must stay within ``margin`` times their limits, and
        ``|v| <= margin * u * sin(theta_max)`` (the kinematic bound at the measured speed).
        ``v_lo <= 0 <= v_hi``; both are 0 when the trim itself violates a limit or ``u <= 0``.
        """
        v_kin = margin * max(u, 0.0) * math.sin(limits.theta_max)
        lo, hi = -v_kin, v_kin
        for centre, slope, bound in (
            (op.theta_e, op.dtheta_dv, margin * limits.theta_max),
            (op.bar_e, op.dbar_dv, margin * limits.bar_max),
        ):
            if abs(centre) >= bound:
                return 0.0, 0.0
            if slope != 0.0:
                ends = sorted(((bound - centre) / slope, (-bound - centre) / slope))
                lo, hi = max(lo, ends[0]), min(hi, ends[1])
        return min(lo, 0.0), max(hi, 0.0)


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
    def _govern(self, op: OperatingPoint, u: float, z_cmd: float) -> tuple[float, float, float]:
        """Advance the governed reference one sample: new ``(z_r, v_r, a_r)``.

        ``v_r`` heads for the braking profile ``sign(e) (sqrt(2 a_max |e| + (a_max c)^2)
        - a_max c)`` with ``c = T_a + jerk_time / 2`` (``e = z_cmd - z_r``; ``~ |e| / c`` near
        the target, decelerating at most ``a_max``), clipped to the vertical speeds whose
        steady climb/dive respects the pitch and BAR limits; its rate ``a_r`` is limited to
        ``+-accel_max``, to what the BAR share can sustain as pitch rate
        ``q = dtheta_dv a_r``, and changes by at most ``accel_max / jerk_time`` per second.
        """
        settings, lim, ts = self.governor, self.limits, self.Ts
        assert self._z_r is not None
        v_prev = self._v_r
        error = z_cmd - self._z_r
        a_max = settings.accel_max
        # Braking profile: ~ sqrt(2 a |e|) far away, ~ |e| / c near, where the stopping
        # distance v^2 / (2 a) + c v with c = T_a + jerk_time / 2 covers the jerk-limited
        # onset of the deceleration; the profile never needs more than a_max.
        a_c = a_max * (settings.approach_time + 0.5 * settings.jerk_time)
        v_goal = math.copysign(math.sqrt(2.0 * a_max * abs(error) + a_c * a_c) - a_c, error)
        v_lo, v_hi = GainSchedule.vertical_speed_bounds(op, u, lim, settings.margin)
        v_goal = min(max(v_goal, v_lo), v_hi)

        # Acceleration interval: +-a_max, and |bar_e + dbar_dv v + dbar_dq dtheta_dv a| within
        # the BAR share for the feed-forward (the interval always keeps a = 0 so the reference
        # can coast).
        a_lo, a_hi = -a_max, a_max
        budget = settings.pitch_rate_bar_share * settings.margin * lim.bar_max
        centre = op.bar_e + op.dbar_dv * v_prev
        slope = op.dbar_dq * op.dtheta_dv
        if slope != 0.0:
            ends = sorted(((budget - centre) / slope, (-budget - centre) / slope))
            a_lo, a_hi = max(a_lo, min(ends[0], 0.0)), min(a_hi, max(ends[1], 0.0))
        # Speed loop of the reference (time constant jerk_time / 2), then the jerk limit.
        a_goal = min(max((v_goal - v_prev) / (0.5 * settings.jerk_time), a_lo), a_hi)
        jerk = a_max / settings.jerk_time * ts
        a_r = min(max(a_goal, self._a_r - jerk), self._a_r + jerk)
        v_r = v_prev + a_r * ts
        z_r = self._z_r + 0.5 * (v_prev + v_r) * ts
        self._a_r = a_r
        return z_r, v_r, a_r

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

        ts, lim = self.Ts, self.limits
        op = self.design.at(u)

        if self._z_r is None:
            self._z_r, self._v_r = z, 0.0
        z_r, v_r, a_r = self._govern(op, u, z_cmd)

        # Feed-forward of the reference manoeuvre (steady climb at v_r, pitch rate for a_r)
        # and the LQR correction around it.
        q_ff = op.dtheta_dv * a_r
        x = np.array([w, q, z, theta, self._xi])
        x_ref = np.array([
            op.w_e + op.dw_dv * v_r + op.dw_dq * q_ff,
            q_ff,
            z_r,
            op.theta_e + op.dtheta_dv * v_r,
            0.0,
        ])
        bar_ff = op.bar_e + op.dbar_dv * v_r + op.dbar_dq * q_ff
        bar_linear = bar_ff - float(op.K @ (x - x_ref))

        # Angle limit, then rate limit.
        bar_cmd = min(max(bar_linear, -lim.bar_max), lim.bar_max)
        if self._bar_prev is not None:
            slew = lim.bar_rate_max * ts
            bar_cmd = min(max(bar_cmd, self._bar_prev - slew), self._bar_prev + slew)

        # Anti-windup (conditional integration): integrate only while the governed reference
        # is (nearly) at rest and the depth is near it, and not when the command is limited
        # and integrating would push it further into the limit; then clamp the integrator's
        # share of the command.
        k_xi = float(op.K[4])
        increment = (z - z_r) * ts
        pushes = -k_xi * increment  # effect of this increment on the command [rad]
        limited = bar_linear - bar_cmd
        winds_up = abs(limited) > 1e-12 and pushes * limited > 0.0
        near = (abs(v_r) <= self.governor.integrate_below_speed
                and abs(z - z_r) <= self.governor.integrate_within)
        if near and not winds_up:
            self._xi += increment
        if k_xi != 0.0:
            xi_max = lim.integral_bar_max / abs(k_xi)
            self._xi = min(max(self._xi, -xi_max), xi_max)

        self._z_r, self._v_r, self._bar_prev = z_r, v_r, bar_cmd
        return bar_cmd


def _input(name: str, value: object) -> float:
    """A finite float run-time input, else :class:`InvalidInputError` naming it."""
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise InvalidInputError(f'{name} must be a number, got {value!r}') from None
    if not math.isfinite(number):
        raise InvalidInputError(f'{name} must be finite, got {value!r}')
    return number
