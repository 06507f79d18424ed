"""The shortest settling time any depth pilot can reach on a vehicle model: a benchmark bound.

Frames and units: world NED, depth ``z`` positive down [m]; body FRD heave ``w`` [m/s] and
pitch rate ``q`` [rad/s]; pitch ``theta`` positive nose up [rad]; BAR [rad]; time [s].

The kinematic bound ``T_kin = |dz| / (u0 sin(theta_max))`` ignores that the vehicle must
pitch up and down with a plane of finite angle and rate, and that at a steep pitch the
restoring moment eats the plane's authority. :func:`settling_bound` answers the question
exactly for the vehicle's nonlinear model in the vertical plane (:class:`PlaneModel`: the
simulator's 6-DOF model and RK4 with ``v = p = r = phi = psi = 0``, exact kinematics
``z_dot = -u sin(theta) + w cos(theta)``, surge speed held at ``u0``): the
smallest time ``T`` for which some BAR sequence (zero-order hold on a grid of ``step``
seconds, ``|BAR| <= bar_max``, ``|dBAR/dt| <= bar_rate``) keeps ``|theta| <= theta_max``
throughout and the depth within ``+-band`` of the target from ``T`` on, ending in the trim at
the target. Each candidate ``T`` is a feasibility problem solved by sequential linear
programming (the model linearised along the current trajectory with complex-step Jacobians
of the RK4 step, a trust region on the BAR, HiGHS); ``T`` is found by bisection on the grid.

The bound ignores the plane's lag, the surge speed's variation and any feedback margin, so a
real pilot can only approach it; the ratio of a pilot's settling time to it measures how much
of the plane's authority the pilot leaves unused.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import scipy.sparse as sp
from scipy.linalg import solve_discrete_are
from scipy.optimize import linprog

from auv_depth_lqr.errors import DesignError
from auv_sim.environment import Environment
from auv_sim.model import NX, surge_held_steps
from auv_sim.params import VehicleParams
from auv_sim.trim import VerticalPlane

__all__ = ['PlaneModel', 'SettlingBound', 'feasible', 'settling_bound']

_H = 1e-30
"""Complex step [-]."""
_PLANE = np.array([8, 10, 2, 4])
"""Indices of ``(w, q, z, theta)`` in the model's 15-state vector."""


@dataclasses.dataclass(frozen=True)
class SettlingBound:
    """Result of :func:`settling_bound`."""

    settling_time: float
    """Shortest time after the command from which the depth stays within the band [s]."""
    kinematic_bound: float
    """``|dz| / (u0 sin(theta_max))`` [s]."""
    t: np.ndarray
    """Grid times (n + 1,) [s]."""
    states: np.ndarray
    """Model states ``(w, q, z, theta)`` on the grid (n + 1, 4) [m/s, rad/s, m, rad]."""
    bar: np.ndarray
    """BAR held over each grid step (n,) [rad]."""


class PlaneModel:
    """The vertical plane at surge speed ``u0`` [m/s], stepped by the simulator's RK4.

    The state ``X = (w, q, z, theta)`` [m/s, rad/s, m, rad] is the vertical-plane part of the
    model's 15-state vector (:data:`auv_sim.model.STATE_NAMES`; ``v = p = r = phi = psi = 0``),
    and one step is :func:`auv_sim.model.surge_held_steps`: the model's own RK4, wrench kernel
    and actuator model, with the surge speed held at ``u0`` by a perfect speed loop (the
    constraint force of :func:`auv_sim.model.surge_held_dynamics`, which gives the heave and
    pitch rows ``M_wq [w_dot, q_dot] = [Z, M]`` of :class:`auv_sim.trim.VerticalPlane`). The
    BAR is held over a step exactly: the plane starts the step at its command, where the
    actuator model's rate is zero (for ``|bar| <= bar_max``, which every plan keeps; beyond
    it the plane would move to the limit). Complex-capable (complex-step Jacobians).
    """

    def __init__(self, params: VehicleParams, u0: float, step: float) -> None:
        self.plane = VerticalPlane(params)
        self.u0, self.h = u0, step
        calm = Environment()
        self.P = self.plane.params.as_array()
        self.env, self.prof = calm.env_vector(), calm.profile()

    def step(self, X: np.ndarray, bar: complex) -> np.ndarray:
        """``X`` one RK4 step of ``h`` [s] later with ``bar`` [rad] held (NaN where the step
        turns non-finite)."""
        dtype = np.result_type(X.dtype, np.asarray(bar).dtype)
        x = np.zeros(NX, dtype=dtype)
        x[_PLANE] = X
        x[6] = self.u0
        x[12] = bar
        cmd = np.zeros(3, dtype=dtype)
        cmd[0] = bar
        if surge_held_steps(0.0, x, cmd, self.P, self.env, self.prof, self.h, 1) != -1:
            return np.full(4, np.nan, dtype=dtype)
        out: np.ndarray = x[_PLANE]
        return out

    def simulate(self, X0: np.ndarray, bars: np.ndarray) -> np.ndarray:
        """States (n + 1, 4) from ``X0`` under the BAR sequence ``bars`` (n,) [rad]."""
        out = [X0]
        X = X0
        for b in bars:
            X = self.step(X, b).real
            out.append(X)
        return np.array(out)

    def jacobians(self, X: np.ndarray, bar: float) -> tuple[np.ndarray, np.ndarray]:
        """Jacobians (4, 4) and (4,) of :meth:`step` in ``X`` and ``bar`` (complex step)."""
        A = np.empty((4, 4))
        for j in range(4):
            Xc = X.astype(complex)
            Xc[j] += 1j * _H
            A[:, j] = self.step(Xc, bar).imag / _H
        B = self.step(X.astype(complex), bar + 1j * _H).imag / _H
        return A, B


class _Rows:
    """Inequality rows ``sum_j a_j x_j <= b`` of an LP, collected one by one (sparse)."""

    def __init__(self) -> None:
        self.rows: list[int] = []
        self.cols: list[int] = []
        self.vals: list[float] = []
        self.bounds: list[float] = []

    def add(self, entries: list[tuple[int, float]], bound: float) -> None:
        """One row: ``entries`` are ``(column, coefficient)``."""
        row = len(self.bounds)
        for col, v in entries:
            self.rows.append(row)
            self.cols.append(col)
            self.vals.append(v)
        self.bounds.append(bound)

    def matrix(self, n_columns: int) -> sp.csr_matrix:
        """The rows as a sparse matrix with ``n_columns`` columns."""
        return sp.csr_matrix((self.vals, (self.rows, self.cols)),
                             shape=(len(self.bounds), n_columns))


def _stabilising_gain(model: PlaneModel, X: np.ndarray, bar: float) -> np.ndarray:
    """Discrete LQR gain (4,) of the model's step at ``(X, bar)``: the rollout's feedback.

    Weights per unit excursion: 0.1 m/s heave, 0.05 rad/s pitch rate, 1 m depth, 0.1 rad
    pitch, 0.1 rad BAR (it only has to keep the rollout near the LP's plan).
    """
    A, B = model.jacobians(X, bar)
    Q = np.diag([1 / 0.1**2, 1 / 0.05**2, 1.0, 1 / 0.1**2])
    R = np.array([[1 / 0.1**2]])
    b = B.reshape(4, 1)
    P = solve_discrete_are(A, b, Q, R)
    gain: np.ndarray = np.linalg.solve(R + b.T @ P @ b, b.T @ P @ A)[0]
    return gain


def _rollout(model: PlaneModel, X0: np.ndarray, plan: np.ndarray, planned: np.ndarray,
             gain: np.ndarray, bar_max: float, rate: float, bar_trim: float
             ) -> tuple[np.ndarray, np.ndarray]:
    """BAR sequence and nonlinear states when the LP's plan is flown with feedback on the
    departure from its planned states (``planned``: X_1..X_n), within the BAR's angle and
    per-step ``rate``. On an open-loop-unstable vehicle the open-loop plan would diverge
    from its prediction (by e^(lambda t)); the feedback keeps the rollout on the plan, and the
    BAR sequence it applies is itself a plan that the bound's conditions are checked on."""
    n = plan.size
    bars = np.empty(n)
    X = X0.copy()
    out = [X0]
    prev = bar_trim
    for k in range(n):
        ref = X0 if k == 0 else planned[k - 1]
        b = float(plan[k] - gain @ (X - ref))
        b = min(max(b, -bar_max, prev - rate), bar_max, prev + rate)
        bars[k] = prev = b
        X = model.step(X, b).real
        out.append(X)
    return bars, np.array(out)


def feasible(model: PlaneModel, X0: np.ndarray, trim: np.ndarray, bar_trim: float, z1: float,
              n_settle: int, bars: np.ndarray, limits: tuple[float, float, float, float],
              iterations: int = 25) -> tuple[bool, np.ndarray]:
    """Sequential LP: is there a BAR sequence of ``bars.size`` steps that keeps the depth in
    the band from step ``n_settle`` on? Returns ``(found, bars)``."""
    bar_max, rate, theta_max, band = limits
    n = bars.size
    gain = _stabilising_gain(model, X0, float(bars[0]))
    rho = 0.5  # trust region on the BAR [rad]
    nx = 4 * n
    nv = nx + n + 1  # X_1..X_n, BAR_0..BAR_{n-1}, slack

    def ix(k: int, i: int) -> int:
        return 4 * (k - 1) + i

    for _ in range(iterations):
        Xn = model.simulate(X0, bars)
        rows, cols, vals, beq = [], [], [], []
        r = 0
        for k in range(n):
            A, B = model.jacobians(Xn[k], bars[k])
            c = Xn[k + 1] - A @ Xn[k] - B * bars[k]
            for i in range(4):
                row = [(ix(k + 1, i), 1.0), (nx + k, -float(B[i]))]
                if k > 0:
                    row += [(ix(k, j), -float(A[i, j])) for j in range(4)]
                    beq.append(float(c[i]))
                else:
                    beq.append(float(c[i] + A[i] @ Xn[0]))
                for col, value in row:
                    rows.append(r)
                    cols.append(col)
                    vals.append(value)
                r += 1
        a_eq = sp.csr_matrix((vals, (rows, cols)), shape=(r, nv))
        rows_ub = _Rows()
        add = rows_ub.add

        s = nv - 1
        for k in range(1, n + 1):
            add([(ix(k, 3), 1.0), (s, -1.0)], theta_max)
            add([(ix(k, 3), -1.0), (s, -1.0)], theta_max)
            if k >= n_settle:
                add([(ix(k, 2), 1.0), (s, -1.0)], z1 + band)
                add([(ix(k, 2), -1.0), (s, -1.0)], -(z1 - band))
        add([(nx, 1.0)], bar_trim + rate)
        add([(nx, -1.0)], -bar_trim + rate)
        for k in range(1, n):
            add([(nx + k, 1.0), (nx + k - 1, -1.0)], rate)
            add([(nx + k, -1.0), (nx + k - 1, 1.0)], rate)
        for i in (0, 1, 3):  # end in the trim (w, q, theta) and at the trim BAR
            add([(ix(n, i), 1.0), (s, -1.0)], trim[i])
            add([(ix(n, i), -1.0), (s, -1.0)], -trim[i])
        add([(nx + n - 1, 1.0), (s, -1.0)], bar_trim)
        add([(nx + n - 1, -1.0), (s, -1.0)], -bar_trim)
        a_ub = rows_ub.matrix(nv)
        bub = rows_ub.bounds
        bounds = [(None, None)] * nx + [
            (max(-bar_max, b - rho), min(bar_max, b + rho)) for b in bars] + [(0.0, None)]
        cost = np.zeros(nv)
        cost[-1] = 1.0
        res = linprog(cost, A_ub=a_ub, b_ub=np.array(bub), A_eq=a_eq, b_eq=np.array(beq),
                      bounds=bounds, method='highs')
        if res.status != 0:
            rho *= 0.5
            continue
        plan = np.clip(res.x[nx:nx + n], -bar_max, bar_max)
        bars, Xs = _rollout(model, X0, plan, res.x[:nx].reshape(n, 4), gain, bar_max, rate,
                            bar_trim)
        violation = max(float(np.max(np.abs(Xs[n_settle:, 2] - z1))) - band,
                        float(np.max(np.abs(Xs[:, 3]))) - theta_max, 0.0)
        if res.x[-1] < 1e-7 and violation < 1e-3:
            return True, bars
        if res.x[-1] > 1e-3 and rho < 0.05:
            return False, bars
        rho = max(0.7 * rho, 0.01)
    return False, bars


def settling_bound(params: VehicleParams, z0: float, z1: float, u0: float,
                   theta_max: float, bar_max: float | None = None,
                   bar_rate: float | None = None, band: float = 0.1, step: float = 0.2,
                   hold: float = 20.0) -> SettlingBound:
    """Shortest settling time [s] of a depth change ``z0 -> z1`` [m] at ``u0`` [m/s].

    ``theta_max`` [rad] bounds ``|theta|``; ``bar_max`` [rad] and ``bar_rate`` [rad/s]
    default to the vehicle file's plane limits; ``band`` [m] is the settling band; ``step``
    [s] the BAR grid; ``hold`` [s] how long the depth must stay in the band before the model
    ends in its trim. Feasibility is checked on the nonlinear model to 1 mm of band and
    1 mrad of pitch; the time is exact to one ``step``.

    Raises
    ------
    DesignError
        Bad arguments, a speed without trim, or no solution within
        ``4 (T_kin + L/u0 + bar_max/bar_rate)``.
    """
    for name, value in (('z0', z0), ('z1', z1), ('u0', u0), ('theta_max', theta_max),
                        ('band', band), ('step', step), ('hold', hold)):
        if not math.isfinite(value):
            raise DesignError(f'settling_bound: {name} must be finite, got {value!r}')
    if u0 <= 0.0 or not 0.0 < theta_max < math.pi / 2 or band <= 0.0 or step <= 0.0 \
            or hold < step:
        raise DesignError(f'settling_bound: need u0 > 0, 0 < theta_max < pi/2, band > 0, '
                          f'step > 0, hold >= step; got u0={u0}, theta_max={theta_max}, '
                          f'band={band}, step={step}, hold={hold}')
    if abs(z1 - z0) <= band:
        raise DesignError(f'settling_bound: the change {z0} -> {z1} m is already within the '
                          f'band of {band} m')
    bar_max = params.bar_max if bar_max is None else bar_max
    bar_rate = params.bar_rate if bar_rate is None else bar_rate
    model = PlaneModel(params, u0, step)
    try:
        trim = model.plane.trim(u0)
    except Exception as exc:  # TrimError and numerical failures alike
        raise DesignError(f'settling_bound: no trim at u0={u0} m/s: {exc}') from None
    X0 = np.array([trim.w, 0.0, z0, trim.theta])
    trim_state = np.array([trim.w, 0.0, z1, trim.theta])
    limits = (bar_max, bar_rate * step, theta_max, band)
    t_kin = abs(z1 - z0) / (u0 * math.sin(theta_max))
    # search horizon: four times the kinematic time plus the vehicle's own time scales (the
    # hull passing its length, the plane reaching its stop), which dominate small changes
    ceiling = 4.0 * (t_kin + params.L_ref / u0 + bar_max / bar_rate)
    n_hold = int(math.ceil(hold / step))
    hi = int(math.ceil(1.5 * t_kin / step))
    found: np.ndarray | None = None
    while hi * step <= ceiling:
        ok, bars = feasible(model, X0, trim_state, trim.bar, z1, hi,
                             np.full(hi + n_hold, trim.bar), limits)
        if ok:
            found = bars
            break
        hi = int(math.ceil(hi * 1.5))
    if found is None:
        raise DesignError(f'settling_bound: no BAR sequence settles {z0} -> {z1} m at '
                          f'{u0} m/s within {ceiling:.1f} s (4 (T_kin + L/u0 + '
                          f'bar_max/bar_rate))')
    lo = int(math.floor(0.5 * t_kin / step))
    while hi - lo > 1:
        mid = (lo + hi) // 2
        start = np.r_[found[:mid], np.full(n_hold, trim.bar)]
        ok, bars = feasible(model, X0, trim_state, trim.bar, z1, mid, start, limits)
        if ok:
            hi, found = mid, bars
        else:
            lo = mid
    states = model.simulate(X0, found)
    return SettlingBound(settling_time=round(hi * step, 9), kinematic_bound=t_kin,
                         t=np.arange(found.size + 1) * step, states=states, bar=found)
