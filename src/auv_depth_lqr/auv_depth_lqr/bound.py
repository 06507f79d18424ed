"""The shortest settling time any depth pilot can reach on a vehicle model: a benchmark bound.

Frames and units: world NED, depth ``z`` positive down [m]; body FRD heave ``w`` [m/s] and
pitch rate ``q`` [rad/s]; pitch ``theta`` positive nose up [rad]; BAR [rad]; time [s].

The kinematic bound ``T_kin = |dz| / (u0 sin(theta_max))`` ignores that the vehicle must
pitch up and down with a plane of finite angle and rate, and that at a steep pitch the
restoring moment eats the plane's authority. :func:`settling_bound` answers the question
for the vehicle's nonlinear model in the vertical plane (:class:`PlaneModel`: the
simulator's 6-DOF model and RK4 with ``v = p = r = phi = psi = 0``, exact kinematics
``z_dot = -u sin(theta) + w cos(theta)``, surge speed held at ``u0``): with a BAR sequence
(zero-order hold on a grid of ``step`` seconds, ``|BAR| <= bar_max``, ``|dBAR/dt| <=
bar_rate``) that keeps ``|theta| <= theta_max`` throughout and ends in the trim at the target
after a ``hold``, how soon can the depth stay within ``+-band`` of the target
(:class:`BoundProblem`)?

For a settling grid point ``n``, :func:`feasible` finds the smallest band ``b(n)`` any plan
keeps the depth in from ``n`` on, by sequential linear programming: the model linearised
along the current trajectory (complex-step Jacobians of the RK4 step), an LP (HiGHS) that
minimises the band plus an exact penalty on the pitch and end excesses within a trust region
on the BAR, each LP plan flown on the nonlinear model with a stabilising feedback, and a
step accepted only when the merit the nonlinear model shows falls by at least a tenth of what
the LP predicted (otherwise the trust region shrinks). Every plan is checked on the nonlinear
model (pitch and end within :data:`TOLERANCE`): ``b(n)`` is reached. Its smallness is local:
the SLP can stop at a local minimum. The search therefore works from the best plan found so
far, resampled in time and cut in its middle to each candidate's length: a bisection on a grid
of ``2 step`` (an LP of half the size), then on the ``step`` grid from the coarse plan, then
one grid point at a time downwards while a plan settles, the last failure from every start
and continued until its band stops shrinking. The settling time is interpolated between the
last grid point ``n - 1`` whose band is wider than ``band`` and the first ``n`` whose band is
within it, linearly in the band each reaches: ``T = step (n - 1 + (b(n-1) - band) / (b(n-1)
- b(n)))``. A threshold on the grid alone jumps by a whole step when ``b(n-1)`` crosses
``band`` (the A18M's 40 -> 10 m climb at 2 m/s reaches 0.1013 m one step early: a change of
the model's last digits could move a grid time by 0.2 s); the interpolation moves with
``b``, continuously, and an SLP stopped a few millimetres short of ``b``'s minimum moves it by
hundredths of a second. No plan on the grid settles before the grid time ``n step``
(:attr:`SettlingBound.grid_time`, as far as the local search finds the least ``b(n-1)``), and
``T`` lies less than one step below it.

The bound ignores the plane's lag, the surge speed's variation and any feedback margin, so a
real pilot can only approach it; the ratio of a pilot's settling time to it measures how much
of the plane's authority the pilot leaves unused. Results are kept per process, by model and
arguments.
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

__all__ = ['TOLERANCE', 'BoundProblem', 'Plan', 'PlaneModel', 'SettlingBound', 'feasible',
           'settling_bound']

TOLERANCE = 1e-3
"""Largest excess a plan may show on the nonlinear model: 1 mrad of pitch over
``theta_max``; at the end of the hold 1 mm/s of heave, 1 mrad/s of pitch rate, 1 mrad of
pitch and of BAR from the trim. (The band is kept exactly: it is what is minimised.) The LP
aims at a quarter of it, the merit counts excesses beyond half of it."""
_H = 1e-30
"""Complex step [-]."""
_PLANE = np.array([8, 10, 2, 4])
"""Indices of ``(w, q, z, theta)`` in the model's 15-state vector."""
_ACCEPT, _EXPAND = 0.1, 0.75
"""Shares of the LP's predicted decrease of the merit above which the nonlinear model's
decrease accepts a step, and expands the trust region."""
_WEIGHT = 100.0
"""Merit of the pitch and end excesses [m of band per rad, per m/s, per rad/s]. Relaxing the
pitch limit by ``d`` at one grid point gains at most ``u0 step d`` of depth (0.4 m per rad at
2 m/s and 0.2 s), so the penalty is exact: no plan buys band with pitch."""
_WINDOW = 5
"""LPs over which a start's progress is judged."""
_CONVERGED = 5e-4
"""Merit decrease over :data:`_WINDOW` LPs [m] under which the smallest band counts as
found."""
_PIVOTS = 10
"""Iterations per LP column after which HiGHS's simplex counts as stalled and the LP is
solved again by its interior-point method (with crossover). The simplex takes about half an
iteration per column; on a degenerate LP (a plan that already meets every row, merit 0, on
the A18M's foreign plant of :func:`auv_depth_lqr.closed_loop.foreign_plant`) it can cycle
without end. An iteration limit, unlike a time limit, gives the same answer on every
machine."""


@dataclasses.dataclass(frozen=True)
class SettlingBound:
    """Result of :func:`settling_bound` (its arrays are read-only: results are shared)."""

    settling_time: float
    """Shortest settling time [s]: between :attr:`grid_time` less one step and
    :attr:`grid_time`, linear in the band reached there (:attr:`earlier_band`) and at
    :attr:`grid_time` (:attr:`band_reached`)."""
    grid_time: float
    """First grid time from which a plan keeps the depth within the band [s]."""
    kinematic_bound: float
    """``|dz| / (u0 sin(theta_max))`` [s]."""
    t: np.ndarray
    """Grid times (n + 1,) [s]."""
    states: np.ndarray
    """Model states ``(w, q, z, theta)`` on the grid (n + 1, 4) [m/s, rad/s, m, rad] of the
    plan that settles at :attr:`grid_time`."""
    bar: np.ndarray
    """BAR held over each grid step (n,) [rad]."""
    band_reached: float
    """Largest ``|z - z1|`` of that plan from :attr:`grid_time` on [m] (at most the band)."""
    earlier_band: float
    """Smallest such band found for a plan settling one grid step earlier [m] (more than the
    band; ``inf`` when that step is before the start)."""
    solves: int
    """Number of SLP runs (starts) the search made."""


_CACHE: dict[tuple[object, ...], SettlingBound] = {}
"""Bounds computed in this process, by model and arguments (tests and benchmarks ask for the
same change several times); at most :data:`_CACHE_SIZE`, the oldest dropped first."""
_CACHE_SIZE = 256


def clear_cache() -> None:
    """Forget the bounds computed in this process (a benchmark timing the search itself)."""
    _CACHE.clear()


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
        out = np.empty((bars.size + 1, 4))
        out[0] = X = X0
        for k, b in enumerate(bars):
            out[k + 1] = X = self.step(X, b).real
        return out

    def jacobians(self, X: np.ndarray, bar: float) -> tuple[np.ndarray, np.ndarray]:
        """Jacobians (4, 4) and (4,) of :meth:`step` in ``X`` and ``bar`` (complex step)."""
        A = np.empty((4, 4))
        for j in range(4):
            Xc = X.astype(complex)
            Xc[j] += 1j * _H
            A[:, j] = self.step(Xc, bar).imag / _H
        B = self.step(X.astype(complex), bar + 1j * _H).imag / _H
        return A, B


@dataclasses.dataclass(frozen=True)
class BoundProblem:
    """One depth change on one model: what a plan must do, and the rollout's feedback.

    A plan of ``n_settle + n_hold`` grid steps starts at ``start`` (the trim at the start
    depth), keeps ``|bar| <= bar_max`` [rad], ``|bar_k - bar_(k-1)| <= bar_step`` [rad] (the
    first change from ``bar_trim``), ``|theta| <= theta_max`` [rad] on every grid point, the
    depth within ``band`` [m] of ``end[2]`` from grid point ``n_settle`` on, and ends in
    ``end`` (the trim at the target: ``w``, ``q``, ``theta``) with the BAR at ``bar_trim``.
    """

    model: PlaneModel
    start: np.ndarray
    """Initial state ``(w, q, z, theta)`` [m/s, rad/s, m, rad]."""
    end: np.ndarray
    """Trim state at the target ``(w, q, z1, theta)``."""
    bar_trim: float
    bar_max: float
    bar_step: float
    theta_max: float
    band: float
    n_hold: int
    """Grid steps the depth must stay in the band after settling."""
    gain: np.ndarray
    """Feedback (4,) [rad per unit state] with which a plan is flown (:meth:`rollout`)."""

    @classmethod
    def build(cls, params: VehicleParams, z0: float, z1: float, u0: float, theta_max: float,
              bar_max: float, bar_rate: float, band: float, step: float,
              hold: float) -> BoundProblem:
        """The problem of ``z0 -> z1`` [m] at ``u0`` [m/s]; raises DesignError without a trim
        at ``u0``."""
        model = PlaneModel(params, u0, step)
        try:
            trim = model.plane.trim(u0)
        except Exception as exc:  # TrimError and numerical failures alike
            raise DesignError(f'settling_bound: no trim at u0={u0} m/s: {exc}') from None
        start = np.array([trim.w, 0.0, z0, trim.theta])
        return cls(model=model, start=start, end=np.array([trim.w, 0.0, z1, trim.theta]),
                   bar_trim=trim.bar, bar_max=bar_max, bar_step=bar_rate * step,
                   theta_max=theta_max, band=band, n_hold=int(math.ceil(hold / step - 1e-9)),
                   gain=_stabilising_gain(model, start, trim.bar))

    def judge(self, n_settle: int, states: np.ndarray, bars: np.ndarray,
              margin: float = 0.0) -> tuple[float, float, float]:
        """A plan's band, other violations and merit.

        Returns
        -------
        tuple
            ``(reached, violation, merit)``: the largest ``|z - z1|`` [m] from grid point
            ``n_settle`` on; the largest excess of ``|theta|`` over ``theta_max`` [rad] and
            of the end's heave [m/s], pitch rate [rad/s], pitch [rad] and BAR [rad] over the
            trim's; and ``reached`` plus :data:`_WEIGHT` times the sum of those excesses
            beyond ``margin`` (the SLP's merit).
        """
        reached = float(np.max(np.abs(states[n_settle:, 2] - self.end[2])))
        excess = np.concatenate([
            np.abs(states[1:, 3]) - self.theta_max,
            np.abs(states[-1, [0, 1, 3]] - self.end[[0, 1, 3]]),
            [abs(bars[-1] - self.bar_trim)]])
        violation = max(float(np.max(excess)), 0.0)
        merit = reached + _WEIGHT * float(np.sum(np.maximum(excess - margin, 0.0)))
        return reached, violation, merit

    def rollout(self, plan: np.ndarray, reference: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
        """BAR sequence (N,) and nonlinear states (N + 1, 4) when ``plan`` (N,) [rad] is flown
        with feedback on the departure from ``reference`` (N + 1, 4; row 0 unused), within
        the BAR's angle and rate. On an open-loop-unstable vehicle an open-loop plan diverges
        from its prediction (by ``e^(lambda t)``); the feedback keeps the rollout near it,
        and the BAR sequence it applies is itself a plan, checked as such."""
        n = plan.size
        bars = np.empty(n)
        out = np.empty((n + 1, 4))
        out[0] = X = self.start
        prev = self.bar_trim
        for k in range(n):
            ref = self.start if k == 0 else reference[k]
            b = float(plan[k] - self.gain @ (X - ref))
            b = min(max(b, -self.bar_max, prev - self.bar_step), self.bar_max,
                    prev + self.bar_step)
            bars[k] = prev = b
            out[k + 1] = X = self.model.step(X, b).real
        return bars, out


@dataclasses.dataclass(frozen=True)
class Plan:
    """A BAR sequence flown on the nonlinear model, judged for one settling index."""

    n_settle: int
    bar: np.ndarray
    """BAR (N,) [rad], ``N = n_settle + n_hold``."""
    states: np.ndarray
    """States (N + 1, 4) [m/s, rad/s, m, rad]."""
    reached: float
    """Largest ``|z - z1|`` from grid point :attr:`n_settle` on [m]."""
    violation: float
    """Largest excess over the pitch limit and the end's trim (:meth:`BoundProblem.judge`)."""

    def settles(self, problem: BoundProblem) -> bool:
        """Within the band and every other limit (to :data:`TOLERANCE`)."""
        return self.reached <= problem.band and self.violation <= TOLERANCE


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


class _Rows:
    """Inequality rows ``A x <= b`` of an LP, added in blocks of equal structure (sparse)."""

    def __init__(self) -> None:
        self.rows: list[np.ndarray] = []
        self.cols: list[np.ndarray] = []
        self.vals: list[np.ndarray] = []
        self.bounds: list[np.ndarray] = []
        self.count = 0

    def add(self, terms: list[tuple[np.ndarray | int, float]], bound: np.ndarray | float,
            m: int) -> None:
        """``m`` rows ``sum_j c_j x[col_j[i]] <= bound[i]``; ``terms`` are ``(col_j, c_j)``,
        each column an array (m,) or one index for every row."""
        rows = self.count + np.arange(m)
        for col, coefficient in terms:
            self.rows.append(rows)
            self.cols.append(np.broadcast_to(np.asarray(col), (m,)))
            self.vals.append(np.full(m, coefficient))
        self.bounds.append(np.broadcast_to(np.asarray(bound, dtype=float), (m,)))
        self.count += m

    def matrix(self, n_columns: int) -> sp.csr_matrix:
        """The rows as a sparse matrix with ``n_columns`` columns."""
        return sp.csr_matrix((np.concatenate(self.vals),
                              (np.concatenate(self.rows), np.concatenate(self.cols))),
                             shape=(self.count, n_columns))


class _Linearised:
    """The LP of one SLP iteration around a rollout ``(states, bars)``.

    Columns: states ``X_1..X_N`` (4N), BAR ``b_0..b_(N-1)`` (N), the band ``beta``, then
    non-negative slacks: pitch ``s_k`` (N), end (heave, pitch rate, pitch, BAR). Rows:
    ``X_(k+1) = A_k X_k + B_k b_k + c_k`` (the linearised RK4 step, exact at the rollout),
    ``|z_k - z1| <= beta`` from ``k = n_settle`` on, ``|theta_k| <= theta_max + m + s_k``,
    the BAR rate, and the end in the trim within ``m`` plus its slacks, with ``m`` half of
    :data:`TOLERANCE` (room for the linearisation's error). Cost: ``beta`` plus
    :data:`_WEIGHT` times the sum of the slacks (an exact penalty: the weight is above what a
    radian of pitch limit is worth in metres of band).
    """

    def __init__(self, problem: BoundProblem, n_settle: int, states: np.ndarray,
                 bars: np.ndarray) -> None:
        p = problem
        N = bars.size
        A = np.empty((N, 4, 4))
        B = np.empty((N, 4))
        for k in range(N):
            A[k], B[k] = p.model.jacobians(states[k], float(bars[k]))
        nx = 4 * N
        ib, ibeta, ith, iend = nx, nx + N, nx + N + 1, nx + 2 * N + 1
        self.n_columns = iend + 4
        c = states[1:] - np.einsum('kij,kj->ki', A, states[:-1]) - B * bars[:, None]
        c[0] += A[0] @ states[0]
        r4 = np.arange(nx)
        kk, ii, jj = np.meshgrid(np.arange(1, N), np.arange(4), np.arange(4), indexing='ij')
        self.a_eq = sp.csr_matrix(
            (np.concatenate([np.ones(nx), -B.reshape(-1), -A[1:].reshape(-1)]),
             (np.concatenate([r4, r4, (4 * kk + ii).ravel()]),
              np.concatenate([r4, ib + r4 // 4, (4 * (kk - 1) + jj).ravel()]))),
            shape=(nx, self.n_columns))
        self.b_eq = c.reshape(-1)
        m = 0.25 * TOLERANCE
        z1 = p.end[2]
        rows = _Rows()
        ks = np.arange(n_settle, N + 1)
        depth = 4 * (ks - 1) + 2
        for sign in (1.0, -1.0):
            rows.add([(depth, sign), (ibeta, -1.0)], sign * z1, ks.size)
        ts = np.arange(N)
        theta = 4 * ts + 3
        for sign in (1.0, -1.0):
            rows.add([(theta, sign), (ith + ts, -1.0)], p.theta_max + m, N)
            rows.add([(ib, sign)], sign * p.bar_trim + p.bar_step, 1)
            rows.add([(ib + ts[1:], sign), (ib + ts[:-1], -sign)], p.bar_step, N - 1)
        last = 4 * (N - 1)
        for j, (col, target) in enumerate(((last, p.end[0]), (last + 1, p.end[1]),
                                           (last + 3, p.end[3]), (ib + N - 1, p.bar_trim))):
            for sign in (1.0, -1.0):
                rows.add([(col, sign), (iend + j, -1.0)], sign * target + m, 1)
        self.a_ub = rows.matrix(self.n_columns)
        self.b_ub = np.concatenate(rows.bounds)
        self.cost = np.zeros(self.n_columns)
        self.cost[ibeta] = 1.0
        self.cost[ith:] = _WEIGHT
        self.problem, self.bars, self.N = p, bars, N

    def solve(self, rho: float) -> tuple[np.ndarray, np.ndarray, float] | None:
        """LP plan within ``rho`` [rad] of the linearisation's BAR: (BAR (N,), states
        (N + 1, 4), predicted merit), or None when HiGHS finds no solution (the dual simplex,
        then, if it stalls past :data:`_PIVOTS` iterations per column, the interior-point
        method; None also when both stop at that limit)."""
        p, N = self.problem, self.N
        lower = np.full(self.n_columns, -np.inf)
        upper = np.full(self.n_columns, np.inf)
        lower[4 * N:5 * N] = np.maximum(-p.bar_max, self.bars - rho)
        upper[4 * N:5 * N] = np.minimum(p.bar_max, self.bars + rho)
        lower[5 * N:] = 0.0
        bounds = np.c_[lower, upper]
        limit = _PIVOTS * self.n_columns
        for method in ('highs', 'highs-ipm'):
            res = linprog(self.cost, A_ub=self.a_ub, b_ub=self.b_ub, A_eq=self.a_eq,
                          b_eq=self.b_eq, bounds=bounds, method=method,
                          options={'maxiter': limit})
            if res.status != 1:  # not stopped at the iteration limit
                break
        if res.status != 0:
            return None
        states = np.vstack([p.start, res.x[:4 * N].reshape(N, 4)])
        return res.x[4 * N:5 * N], states, float(res.fun)


def feasible(problem: BoundProblem, n_settle: int, plan: np.ndarray, reference: np.ndarray,
             rho: float | None = None, iterations: int | None = None, converge: bool = False
             ) -> tuple[bool, Plan]:
    """Sequential LP from one start: the smallest band a plan settling at grid point
    ``n_settle`` reaches; is it within ``problem.band``?

    Parameters
    ----------
    problem
        The depth change and its limits.
    n_settle
        Grid point from which the depth must stay in the band.
    plan, reference
        The start: a BAR sequence (N,) [rad], ``N = n_settle + problem.n_hold``, and the
        states (N + 1, 4) it is flown along (:meth:`BoundProblem.rollout`).
    rho
        Initial trust region on the BAR [rad] (default ``bar_max``).
    iterations
        Most LPs solved (default 100 with ``converge``, else 40).
    converge
        Go on after the band is reached, until the merit stops falling (by less than
        :data:`_CONVERGED` over :data:`_WINDOW` LPs), to measure the smallest band; otherwise
        stop at the first plan that settles (:meth:`Plan.settles`), or when the pace of the
        last :data:`_WINDOW` LPs would not bring the band within the problem's in the LPs
        left.

    Returns
    -------
    tuple
        ``(settles, plan)``: whether the plan found settles, and the last accepted plan (its
        merit, :meth:`BoundProblem.judge`, the smallest seen).
    """
    p = problem
    margin = 0.5 * TOLERANCE
    bars, states = p.rollout(plan, reference)
    reached, violation, merit = p.judge(n_settle, states, bars, margin)
    best = Plan(n_settle, bars, states, reached, violation)
    if best.settles(p) and not converge:
        return True, best
    rho = p.bar_max if rho is None else rho
    iterations = (100 if converge else 40) if iterations is None else iterations
    history = [merit]
    lp = _Linearised(p, n_settle, states, bars)
    for _ in range(iterations):
        solution = lp.solve(rho)
        if solution is None:
            rho *= 0.5
            continue
        lp_bars, lp_states, predicted = solution
        decrease = merit - predicted
        if decrease <= 1e-10 * max(1.0, merit):
            break  # a stationary point of the merit
        new_bars, new_states = p.rollout(lp_bars, lp_states)
        new = p.judge(n_settle, new_states, new_bars, margin)
        ratio = (merit - new[2]) / decrease
        size = float(np.max(np.abs(lp_bars - bars)))
        if ratio >= _ACCEPT:
            bars, states, (reached, violation, merit) = new_bars, new_states, new
            best = Plan(n_settle, bars, states, reached, violation)
            if best.settles(p) and not converge:
                return True, best
            if ratio > _EXPAND and size > 0.9 * rho:
                rho = min(2.0 * rho, 2.0 * p.bar_max)
            lp = _Linearised(p, n_settle, states, bars)
        else:
            rho = 0.5 * min(rho, size)
            if rho < 1e-6:
                break
        history.append(merit)
        if len(history) > _WINDOW:
            gained = history[-1 - _WINDOW] - merit
            if converge and gained < _CONVERGED:
                break
            # at the pace of the last LPs, the band is out of reach of the LPs left
            left = iterations - len(history) + 1
            if not converge and gained * left < _WINDOW * (merit - p.band):
                break
    return best.settles(p), best


def _resampled(plan: Plan, step: float, problem: BoundProblem, n_settle: int
               ) -> tuple[np.ndarray, np.ndarray]:
    """Start for ``n_settle`` on ``problem``'s grid from ``plan`` (on a grid of ``step``
    [s]): its manoeuvre (the steps before it settles) stretched or compressed in time to
    ``n_settle`` steps, its hold resampled to ``problem.n_hold`` steps; the pitch rates
    scaled with the manoeuvre's time."""
    n, N_src = plan.n_settle, plan.bar.size
    N = n_settle + problem.n_hold
    src = np.arange(N_src + 1, dtype=float)  # source grid index of each state
    # new grid index -> source grid index: linear on the manoeuvre and on the hold
    new = np.arange(N + 1, dtype=float)
    hold_scale = (N_src - n) / problem.n_hold
    index = np.where(new <= n_settle, new * n / n_settle,
                     n + (new - n_settle) * hold_scale)
    states = np.column_stack([np.interp(index, src, plan.states[:, i]) for i in range(4)])
    time_scale = np.where(new <= n_settle, n * step / (n_settle * problem.model.h),
                          hold_scale * step / problem.model.h)
    states[:, 1] *= time_scale
    mid = index[:-1] + 0.5 * np.diff(index)
    bars = np.interp(mid - 0.5, np.arange(N_src, dtype=float), plan.bar)
    return bars, states


def _cut(plan: Plan, problem: BoundProblem, n_settle: int) -> tuple[np.ndarray, np.ndarray]:
    """Start for ``n_settle < plan.n_settle`` on the plan's own grid: ``plan`` with the
    missing steps cut out of the middle of its manoeuvre (the steady climb or dive of a long
    change)."""
    d = plan.n_settle - n_settle
    a = plan.n_settle // 2 - d // 2
    N = n_settle + problem.n_hold
    return (np.r_[plan.bar[:a], plan.bar[a + d:]][:N],
            np.vstack([plan.states[:a + 1], plan.states[a + d + 1:]])[:N + 1])


def _reference(problem: BoundProblem, n_settle: int) -> tuple[np.ndarray, np.ndarray]:
    """Start for ``n_settle`` without a plan: the BAR at trim, flown along a smooth depth
    path (quintic) that reaches the target at 80 % of the settling time, the pitch the
    kinematics ``z_dot = -u0 sin(theta - theta_trim)`` ask for (at most 95 % of the limit)."""
    p, h, u0 = problem, problem.model.h, problem.model.u0
    N = n_settle + p.n_hold
    s = np.clip(np.arange(N + 1) / (0.8 * n_settle), 0.0, 1.0)
    z = p.start[2] + (p.end[2] - p.start[2]) * (10 * s**3 - 15 * s**4 + 6 * s**5)
    limit = 0.95 * math.sin(p.theta_max)
    theta = p.start[3] + np.arcsin(np.clip(-np.gradient(z, h) / u0, -limit, limit))
    states = np.column_stack([np.full(N + 1, p.start[0]), np.gradient(theta, h), z, theta])
    return np.full(N, p.bar_trim), states


def _score(plan: Plan) -> float:
    """The band a plan reaches [m], infinite when it breaks another limit."""
    return plan.reached if plan.violation <= TOLERANCE else math.inf


def _try(problem: BoundProblem, n_settle: int, best: Plan, step: float,
         cut: bool = True) -> tuple[Plan, int]:
    """Every start for ``n_settle`` from ``best`` (a plan on a grid of ``step`` [s]) until
    one settles: ``best`` resampled in time, and (``cut``) cut in its middle when it is on
    the same grid and longer. Returns (the plan that settles, or the one that reaches the
    smallest band; the starts run)."""
    starts = [_resampled(best, step, problem, n_settle)]
    if cut and step == problem.model.h and n_settle < best.n_settle:
        starts.append(_cut(best, problem, n_settle))
    least: Plan | None = None
    for plan, reference in starts:
        _, found = feasible(problem, n_settle, plan, reference, 0.1 * problem.bar_max)
        if least is None or _score(found) < _score(least):
            least = found
        if found.settles(problem):
            break
    assert least is not None
    return least, len(starts)


@dataclasses.dataclass
class _Search:
    """The shortest settling index on one grid: bisection, then steps down one at a time from
    the best plan until a step fails from every start."""

    problem: BoundProblem
    best: Plan
    step: float
    """Grid [s] of :attr:`best` (a coarser grid's plan seeds a finer search)."""
    solves: int = 0
    cut: bool = True
    """Whether a failure is tried again from :func:`_cut`."""

    def attempt(self, n_settle: int) -> Plan:
        """Try ``n_settle`` from the best plan; keep the plan when it settles."""
        found, runs = _try(self.problem, n_settle, self.best, self.step, self.cut)
        self.solves += runs
        if found.settles(self.problem):
            self.best, self.step = found, self.problem.model.h
        return found

    def bisect(self, lo: int, hi: int) -> int:
        """Bisection between ``lo`` (assumed not to settle) and ``hi`` (:attr:`best` settles
        there); returns the index found."""
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if self.attempt(mid).settles(self.problem):
                hi = mid
            else:
                lo = mid
        return hi

    def finish(self, hi: int) -> tuple[int, float, float]:
        """From ``hi`` (where :attr:`best` settles) step down while a plan one step earlier
        settles: from every start, then the one that reaches the smallest band continued
        until its band stops shrinking. Then the smallest band at the index found. Returns
        (index, band reached one step earlier [m], band reached [m])."""
        p, rho = self.problem, 0.1 * self.problem.bar_max
        earlier = math.inf
        while hi > 1:
            below = self.attempt(hi - 1)
            if not below.settles(p):
                _, below = feasible(p, hi - 1, below.bar, below.states, rho, converge=True)
                self.solves += 1
                if not below.settles(p):
                    earlier = _score(below)
                    break
                self.best = below
            hi -= 1
        _, at = feasible(p, hi, self.best.bar, self.best.states, rho, converge=True)
        self.solves += 1
        if at.settles(p) and at.reached < self.best.reached:
            self.best = at
        return hi, earlier, self.best.reached


def settling_bound(params: VehicleParams, z0: float, z1: float, u0: float,
                   theta_max: float, bar_max: float | None = None,
                   bar_rate: float | None = None, band: float = 0.1, step: float = 0.2,
                   hold: float = 20.0) -> SettlingBound:
    """Shortest settling time [s] of a depth change ``z0 -> z1`` [m] at ``u0`` [m/s].

    Parameters
    ----------
    params
        The vehicle.
    z0, z1
        Start and target depth [m].
    u0
        Surge speed, held [m/s].
    theta_max
        Bound on ``|theta|`` [rad].
    bar_max, bar_rate
        Plane angle [rad] and rate [rad/s] limits (default: the vehicle file's).
    band
        Settling band [m].
    step
        BAR grid [s]; the time is found on it.
    hold
        How long the depth must stay in the band before the model ends in its trim [s].

    Returns
    -------
    SettlingBound
        The time, the plan that reaches it (checked on the nonlinear model within
        :data:`TOLERANCE`) and by how much one step earlier failed.

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
    key = (params.as_array().tobytes(), z0, z1, u0, theta_max, bar_max, bar_rate, band, step,
           hold)
    if key not in _CACHE:
        if len(_CACHE) >= _CACHE_SIZE:
            del _CACHE[next(iter(_CACHE))]
        _CACHE[key] = _search(params, z0, z1, u0, theta_max, bar_max, bar_rate, band, step,
                              hold)
    return _CACHE[key]


def _search(params: VehicleParams, z0: float, z1: float, u0: float, theta_max: float,
            bar_max: float, bar_rate: float, band: float, step: float, hold: float
            ) -> SettlingBound:
    """:func:`settling_bound` with its arguments checked."""
    problem = BoundProblem.build(params, z0, z1, u0, theta_max, bar_max, bar_rate, band, step,
                                 hold)
    t_kin = abs(z1 - z0) / (u0 * math.sin(theta_max))
    # search horizon: four times the kinematic time plus the vehicle's own time scales (the
    # hull passing its length, the plane reaching its stop), which dominate small changes
    scales = params.L_ref / u0 + bar_max / bar_rate
    ceiling = 4.0 * (t_kin + scales)
    # the search runs first on a grid of twice the step (an LP of half the size), then on the
    # step's grid from the coarse plan
    coarse = BoundProblem.build(params, z0, z1, u0, theta_max, bar_max, bar_rate, band,
                                2.0 * step, hold)
    hi = int(math.ceil((1.5 * t_kin + scales) / (2.0 * step)))
    solves = 0
    found: Plan | None = None
    while 2.0 * step * hi <= ceiling:
        solves += 1
        ok, plan = feasible(coarse, hi, *_reference(coarse, hi))
        if ok:
            found = plan
            break
        hi = int(math.ceil(hi * 1.25))
    if found is None:
        raise DesignError(f'settling_bound: no BAR sequence settles {z0} -> {z1} m at '
                          f'{u0} m/s within {ceiling:.1f} s (4 (T_kin + L/u0 + '
                          f'bar_max/bar_rate))')
    search = _Search(coarse, found, 2.0 * step, solves=solves, cut=False)
    n_coarse = search.bisect(int(math.floor(t_kin / (2.0 * step))), hi)
    fine = _Search(problem, search.best, 2.0 * step, solves=search.solves)
    n, lo = 2 * n_coarse, 0
    while not fine.attempt(n).settles(problem):
        if n * step > ceiling:
            raise DesignError(f'settling_bound: no BAR sequence settles {z0} -> {z1} m at '
                              f'{u0} m/s on the {step} s grid within {ceiling:.1f} s')
        lo, n = n, n + max(1, n // 20)
    if lo:
        n = fine.bisect(lo, n)
    n, earlier, reached = fine.finish(n)
    # the time between the last grid point that cannot reach the band and the first that
    # can, linear in the band each reaches: continuous in the inputs, where the grid time
    # alone jumps by a step when the band one step earlier crosses the problem's
    share = 1.0 if not math.isfinite(earlier) else (earlier - band) / (earlier - reached)
    best = fine.best
    t = np.arange(best.bar.size + 1) * step
    for array in (t, best.states, best.bar):
        array.flags.writeable = False  # shared by every caller of the cache
    return SettlingBound(settling_time=round((n - 1 + share) * step, 9),
                         grid_time=round(n * step, 9), kinematic_bound=t_kin,
                         t=t, states=best.states,
                         bar=best.bar, band_reached=reached, earlier_band=earlier,
                         solves=fine.solves)
