"""Gain schedule over surge speed: one discrete LQR per speed, trim and feed-forward series.

Frames and units (Fossen): world NED (z down, depth) [m]; body FRD; pitch ``theta`` nose up
[rad]; heave ``w`` [m/s], pitch rate ``q`` [rad/s], surge ``u`` [m/s]; BAR [rad]. Design
state ``X = (w, q, z, theta, xi)`` with ``xi = int (z - z_ref) dt`` [m s]. With a plane-rate
design (``R_rate`` of :meth:`GainSchedule.design`) a second gain is designed on the state
augmented by the plane, ``(w, q, z, theta, xi, BAR)``, whose input is the plane's rate
``BAR_dot`` [rad/s] (:func:`~auv_depth_lqr.lqr.input_rate_system`). The vehicle model
supplies ``linearize(u0) -> (x_e, u_e, A, B)``: trim state ``x_e = (w_e, 0, z_any, theta_e,
0)``, trim input ``u_e = BAR_e`` and the Jacobians ``A`` (5, 5), ``B`` (5, 1) at that trim.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from auv_depth_lqr.errors import DesignError
from auv_depth_lqr.limits import Limits
from auv_depth_lqr.lqr import as_matrix, check_controllable, input_rate_system, lqrd
from auv_depth_lqr.validate import finite
from auv_depth_lqr.weights import DEFAULT_WEIGHTS

__all__ = [
    'N_FF',
    'N_STATES',
    'GainSchedule',
    'Linearize',
    'Matrix',
    'OperatingPoint',
    'check_linearization',
    'disturbance_map',
    'feedforward',
    'feedforward_series',
    'steady_matrix',
]

N_STATES = 5
"""Number of design states ``(w, q, z, theta, xi)``."""

Linearize = Callable[[float], tuple[ArrayLike, float, ArrayLike, ArrayLike]]
"""``linearize(u0) -> (x_e, u_e, A, B)`` about the trim at surge speed ``u0`` [m/s]."""

Matrix = NDArray[np.float64]


N_FF = 4
"""Orders of the feed-forward series: vertical speed and its first three derivatives."""


class OperatingPoint(NamedTuple):
    """Gain, trim and feed-forward at one surge speed (designed or interpolated).

    The feed-forward of a reference with vertical speed ``v(t)`` is the series
    ``X_ref = X_e + sum_k F[k, :3] v^(k)`` on ``(w, q, theta)`` and
    ``BAR_ff = BAR_e + sum_k F[k, 3] v^(k)`` for ``k = 0..3`` (``v^(k)`` the k-th time
    derivative): the exact trajectory of the linear model for polynomial profiles of
    degree <= 3 and its slow-manifold expansion otherwise (see :func:`feedforward_series`).
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
    P: Matrix = np.zeros((2, 4))
    """Heave and pitch rows of the linear model (2, 4) over ``(w, q, theta, BAR)``:
    ``(w_dot, q_dot) = P (w - w_e, q, theta - theta_e, BAR - BAR_e)`` [m/s^2, rad/s^2]
    (the depth column is zero)."""
    D: Matrix = np.zeros((4, 2))
    """Steady trim shift (4, 2) per unit constant disturbance: a disturbance ``d`` of the
    heave and pitch accelerations [m/s^2, rad/s^2] moves the level trim ``(w, q, theta,
    BAR)`` by ``D d`` (``P (shift) + d = 0`` with the depth rate kept zero)."""
    learned: bool = False
    """Whether the model was corrected by what the pilot learned of its plant
    (:meth:`auv_depth_lqr.learning.PlantEstimator.correct`): its series is then not the
    design's interpolated between grid speeds."""
    K_rate: Matrix = np.zeros(0)
    """Plane-rate gain (6,) on ``(X - X_ref, BAR - BAR_ff)``: the plane's rate command is
    ``BAR_ff_dot - K_rate (X - X_ref, BAR - BAR_ff)`` [rad/s]; empty without a plane-rate
    design."""

    def rows_at(self, u: float) -> Matrix:
        """:attr:`P` at the measured surge ``u`` [m/s] off this point's ``u0``: the heave and
        pitch terms scale with the speed, the plane's with its square, the hydrostatic
        ``theta`` column not at all (2, 4) [same units as :attr:`P`]."""
        speed = u / self.u0
        rows: Matrix = self.P * np.array([speed, speed, 1.0, speed ** 2])
        return rows


def steady_matrix(A: Matrix, B: Matrix, u0: float) -> Matrix:
    """The steady-motion rows of the linear model (4, 4) over ``(w, q, theta, BAR)``:
    heave and pitch accelerations, ``theta_dot = q`` and the depth rate (see
    :func:`feedforward_series`). DesignError when singular (no steady climb at ``u0``)."""
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
    return M


def disturbance_map(A: Matrix, B: Matrix, u0: float) -> tuple[Matrix, Matrix]:
    """``(P, D)`` of :class:`OperatingPoint`: the heave and pitch rows of the model over
    ``(w, q, theta, BAR)`` (2, 4), and the level trim's shift per unit constant heave and
    pitch disturbance (4, 2): ``M shift = -(d, 0, 0)``, ``M`` of :func:`steady_matrix`."""
    cols = [0, 1, 3]
    P = np.zeros((2, 4))
    P[:, :3], P[:, 3] = A[:2][:, cols], B[:2, 0]
    rhs = np.zeros((4, 2))
    rhs[0, 0] = rhs[1, 1] = -1.0
    D: Matrix = np.asarray(np.linalg.solve(steady_matrix(A, B, u0), rhs), dtype=np.float64)
    return P, D


def feedforward_series(A: Matrix, B: Matrix, u0: float) -> Matrix:
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
    M = steady_matrix(A, B, u0)
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
    P: Matrix = field(repr=False, default_factory=lambda: np.zeros((0, 2, 4)))
    """Heave and pitch rows of the model (g, 2, 4), see :class:`OperatingPoint`."""
    D: Matrix = field(repr=False, default_factory=lambda: np.zeros((0, 4, 2)))
    """Trim shift per unit disturbance (g, 4, 2), see :class:`OperatingPoint`."""
    Q: Matrix = field(repr=False, default_factory=lambda: np.zeros((0, 0)))
    """State weight used in the design (5, 5)."""
    R: Matrix = field(repr=False, default_factory=lambda: np.zeros((0, 0)))
    """Input weight used in the design (1, 1)."""
    K_rate: Matrix = field(repr=False, default_factory=lambda: np.zeros((0, N_STATES + 1)))
    """Plane-rate gains (g, 6) on ``(X - X_ref, BAR - BAR_ff)``, see
    :class:`OperatingPoint`; no rows without a plane-rate design."""
    R_rate: Matrix = field(repr=False, default_factory=lambda: np.zeros((0, 0)))
    """Weight of the plane's rate used in the plane-rate design (1, 1); empty without."""

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
        R_rate: ArrayLike | None = None,
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
        R_rate : array_like, optional
            Weight (1, 1) of the plane's rate [1 / ((rad/s)^2 s)]. When given, a second gain
            per speed (:attr:`K_rate`) is designed on the state augmented by the plane
            (:func:`~auv_depth_lqr.lqr.input_rate_system`), its input the plane's rate, with
            the weights ``diag(Q, R)`` on ``(X, BAR)`` and ``R_rate`` on the rate.

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
        ts = finite('Ts', Ts, positive=True)
        grid = np.array([finite('speed', s, positive=True) for s in speeds], dtype=float)
        if grid.size == 0 or np.any(np.diff(grid) <= 0.0):
            raise DesignError(
                f'speeds must be a non-empty, strictly increasing list of m/s, got {list(speeds)}')
        q_mat = as_matrix('Q', Q, (N_STATES, N_STATES), '(5, 5)')
        r_mat = as_matrix('R', R, (1, 1), '(1, 1)')
        r_rate = None if R_rate is None else as_matrix('R_rate', R_rate, (1, 1), '(1, 1)')
        q_aug = np.zeros((N_STATES + 1, N_STATES + 1))
        q_aug[:N_STATES, :N_STATES], q_aug[N_STATES, N_STATES] = q_mat, r_mat[0, 0]
        rate_gains: list[Matrix] = []
        rows: list[list[float]] = []
        gains: list[Matrix] = []
        series: list[Matrix] = []
        maps: list[tuple[Matrix, Matrix]] = []
        for u0 in grid:
            x_e, u_e, A, B = check_linearization(linearize, float(u0))
            try:
                check_controllable(A, B)
            except DesignError as exc:
                raise type(exc)(f'at u0={u0:g} m/s: {exc}') from None
            result = lqrd(A, B, q_mat, r_mat, ts)
            series.append(feedforward_series(A, B, float(u0)))
            maps.append(disturbance_map(A, B, float(u0)))
            gains.append(result.K[0])
            if r_rate is not None:
                rate_gains.append(lqrd(*input_rate_system(A, B), q_aug, r_rate, ts).K[0])
            rows.append([float(x_e[0]), float(x_e[3]), float(u_e)])
        table = np.array(rows)
        return cls(speeds=grid, K=np.array(gains), w_e=table[:, 0], theta_e=table[:, 1],
                   bar_e=table[:, 2], F=np.array(series), Ts=ts,
                   P=np.array([m[0] for m in maps]), D=np.array([m[1] for m in maps]),
                   Q=q_mat, R=r_mat,
                   K_rate=np.array(rate_gains).reshape(-1, N_STATES + 1),
                   R_rate=np.zeros((0, 0)) if r_rate is None else r_rate)

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
        known = self.P.shape[0] == self.speeds.size
        P = interp(self.P) if known else np.zeros((2, 4))
        D = interp(self.D) if known else np.zeros((4, 2))
        K_rate = interp(self.K_rate) if self.K_rate.shape[0] == self.speeds.size \
            else np.zeros(0)
        return OperatingPoint(
            u0=uc, K=interp(self.K), w_e=float(interp(self.w_e)),
            theta_e=float(interp(self.theta_e)), bar_e=float(interp(self.bar_e)),
            dw_dv=float(F[0, 0]), dtheta_dv=float(F[0, 2]), dbar_dv=float(F[0, 3]), F=F, P=P, D=D,
            K_rate=K_rate)

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



def feedforward(op: OperatingPoint, u: float, v: float, a: float, j: float,
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
