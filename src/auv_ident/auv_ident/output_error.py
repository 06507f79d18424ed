"""Output error: the vertical-plane coefficients fitted to the free-run prediction of the
logged depth, pitch and speed, where the equation error's derivatives are poor.

Equation error fits ``M nu_dot - tau_other`` against the model's terms. On a slow or coarse
log (2 Hz rows, depth in 0.1 m steps, a 1 Hz DVL repeated on every row, heave and pitch rate
derived by differencing) the derivative and the regressors carry errors that bias it (errors
in variables) and its window removes the fast part of the manoeuvres. The simulation error
does not differentiate: the model, run from a state at the start of each segment with the
logged commands (:mod:`auv_ident.freerun`, the simulator's RK4 and actuator model), must
reproduce what was measured. Multiple shooting: the windows that are not held out are cut
into segments of at most two e-folding times of an unstable vertical-plane mode (at most
30 s), every segment's initial state (depth, pitch, surge, heave and pitch rate) is fitted
with the coefficients, so a segment is an independent short free run and an unstable vehicle
does not diverge; at most :data:`WINDOWS_MAX` segments, evenly spread, are used.

Minimised (``scipy.optimize.least_squares``, trust-region reflective, inside the physical
bounds of :mod:`auv_ident.identify.physics`)::

    sum_windows sum_samples sum_channels ((y_model - y_logged) / sigma_c)^2
        + sum_k ((theta_k - theta_0k) / s_0k)^2

over the measured channels ``c`` among depth, pitch, surge (and heave and pitch rate when
measured, not derived), with the file's priors ``N(theta_0, s_0^2)``
(:mod:`auv_ident.identify.priors`). ``sigma_c`` starts at the log's noise level (with the
quantisation step over sqrt(12) as a floor) and is set to each channel's residual rms for a
second pass, so no channel dominates by its units. The Jacobian is by forward differences,
all perturbed runs in one parallel batch.

Covariance (does not assume the model is right): ``H^-1 (G + Lambda_0) H^-1`` with ``H`` the
Gauss-Newton matrix (priors included) and ``G`` the sum over windows of the outer products
of each window's score (a cluster sandwich, windows as clusters), or the model-based ``G``
(residual variance times its correlation time), whichever is larger per coefficient;
Student's t with the windows less one as degrees of freedom.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence

import numpy as np
from scipy import optimize, sparse

from auv_contract.blas import one_blas_thread
from auv_ident.freerun import (
    FreeRuns,
    Window,
    parameter_vector,
    shooting_segments,
    window_length,
)
from auv_ident.identify.covariance import correlation_time
from auv_ident.identify.physics import constraint
from auv_ident.identify.posterior import interval
from auv_ident.identify.priors import priors
from auv_ident.identify.records import LoggedRun
from auv_ident.motion import noise_sigma
from auv_sim.params import VehicleParams

#: Initial-state channels fitted per window: z, theta, u, w, q (indices into the state).
FITTED_STATES = (2, 4, 6, 8, 10)
#: Output channels compared when measured: z, theta, u, w, q.
OUTPUTS = (2, 4, 6, 8, 10)
CHANNEL_NAMES = {2: 'z', 4: 'theta', 6: 'u', 8: 'w', 10: 'q', 5: 'psi'}
#: Floors of the channel weights (m, rad, m/s, m/s, rad/s).
SIGMA_FLOOR = {2: 1e-3, 4: math.radians(0.01), 6: 1e-3, 8: 1e-3, 10: math.radians(0.01)}
#: e-folding times of an unstable mode a shooting segment spans at most (an initial-state
#: error grows about e^2 = 7-fold over it; the validation's windows span 4).
SHOOTING_FOLDS = 2.0
#: Fewest log rows a shooting segment must hold (four per fitted initial state): fewer, and
#: the initial states absorb what the coefficients should explain (an open-loop-unstable
#: vehicle's short segments on a slow log).
ROWS_MIN = 20
#: Most windows an output-error fit uses (evenly spread over a long log): its cost grows
#: with them, the coefficients' information far less once there are tens.
WINDOWS_MAX = 60
#: Below this log rate [Hz] the equation error's derivative window is too long.
RATE_MIN_HZ = 5.0
#: A channel is quantised when its smallest non-zero step is at least this many times its
#: white-noise level, on at least half of the samples unchanged from the last.
QUANTISED_REPEAT = 0.3


class OutputErrorImpossible(ValueError):
    """The log cannot inform an output-error fit (the message says why)."""


@dataclasses.dataclass
class OutputErrorFit:
    """Result of :func:`refine`: coefficients (the vehicle file's units) and the fit."""

    names: tuple[str, ...]
    values: dict[str, float]
    std_error: dict[str, float]
    ci95: dict[str, tuple[float, float]]
    at_bound: dict[str, bool]
    informed: dict[str, float]
    start: dict[str, float]           # the values it started from
    rms: dict[str, float]             # residual rms per output channel (its units)
    rms_start: dict[str, float]       # the same with the starting values
    windows: int
    samples: int
    evaluations: int
    why: str                          # why output error was used


def quantisation_step(x: np.ndarray) -> float:
    """The step of a quantised signal (its smallest non-zero change, when at least
    :data:`QUANTISED_REPEAT` of its samples repeat the previous one), else 0."""
    d = np.abs(np.diff(np.asarray(x, float)))
    if len(d) < 10:
        return 0.0
    if np.mean(d == 0.0) < QUANTISED_REPEAT:
        return 0.0
    nz = d[d > 0]
    return float(np.min(nz)) if len(nz) else 0.0


def needs_output_error(logs: Sequence[LoggedRun]) -> str:
    """Why the equation error's derivatives are poor on ``logs`` (empty: they are not):
    a log slower than :data:`RATE_MIN_HZ`, heave velocity or pitch rate derived by
    differencing, a quantised depth or pitch, a surge speed repeated on several rows."""
    reasons = []
    rates = [1.0 / float(np.median(np.diff(lg.t))) for lg in logs if len(lg.t) > 2]
    if rates and min(rates) < RATE_MIN_HZ:
        reasons.append(f'rows at {min(rates):.3g} Hz (the derivative window of equation error '
                       f'is then {5 / min(rates):.3g} s or more)')
    derived = sorted({c for lg in logs for c in ('w', 'q') if not lg.is_measured(c)})
    if derived:
        reasons.append(f'{" and ".join(derived)} derived by differencing (not measured)')
    for c, what in ((2, 'depth'), (4, 'pitch'), (6, 'surge speed')):
        steps = [quantisation_step(lg.state[:, c]) for lg in logs]
        step = max(steps) if steps else 0.0
        if step > 0.0:
            unit = 'm' if c != 4 else 'deg'
            shown = step if c != 4 else math.degrees(step)
            reasons.append(f'{what} quantised or repeated ({shown:.3g} {unit} steps)')
    return '; '.join(reasons)


def channel_sigma(logs: Sequence[LoggedRun], c: int) -> float:
    """Starting weight of output channel ``c``: its white-noise level, the quantisation step
    over sqrt(12) as a floor."""
    vals = []
    for lg in logs:
        if len(lg.t) > 8:
            vals.append(float(noise_sigma(lg.state[:, c:c + 1])[0]))
            vals.append(quantisation_step(lg.state[:, c]) / math.sqrt(12.0))
    return max([*vals, SIGMA_FLOOR[c]])


class ShootingProblem:
    """The multiple-shooting least-squares problem of :func:`refine` (coefficients ``names``
    and every window's initial depth, pitch, surge, heave velocity and pitch rate)."""

    def __init__(self, runs: FreeRuns, params: VehicleParams, names: Sequence[str],
                 outputs: Sequence[int], sigma: Mapping[int, float],
                 prior_mean: np.ndarray, prior_sd: np.ndarray) -> None:
        self.runs = runs
        self.params = params
        self.names = tuple(names)
        self.outputs = tuple(outputs)
        self.sigma = dict(sigma)
        self.prior_mean = prior_mean
        self.prior_sd = prior_sd
        self.nw = len(runs.windows)
        self.p = len(self.names)
        self.X0 = runs.initial_states()
        self.meas = [runs.logs[w.record].state[w.i0:w.i1] for w in runs.windows]
        sizes = [len(m) * len(self.outputs) for m in self.meas]
        self.offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(int)
        self.evaluations = 0

    def split(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Coefficients (p,) and initial states (nw, 5) of a parameter vector."""
        return z[:self.p], z[self.p:].reshape(self.nw, len(FITTED_STATES))

    def start(self, theta: np.ndarray) -> np.ndarray:
        """The parameter vector with ``theta`` and the logged initial states."""
        return np.concatenate([theta, self.X0[:, list(FITTED_STATES)].ravel()])

    def residuals(self, Z: np.ndarray) -> np.ndarray:
        """Weighted residuals (nv, n_data + p) of parameter vectors ``Z`` (nv, p + 5 nw):
        window by window, channel by channel, then the prior rows."""
        Z = np.atleast_2d(Z)
        nv = Z.shape[0]
        self.evaluations += nv
        P = np.empty((nv, len(self.params.as_array())))
        X0 = np.repeat(self.X0[None], nv, axis=0)
        for v in range(nv):
            theta, x0 = self.split(Z[v])
            P[v] = parameter_vector(self.params, dict(zip(self.names, theta)))
            X0[v][:, list(FITTED_STATES)] = x0
        pred = self.runs.run(P, X0)
        parts = []
        for j in range(self.nw):
            for c in self.outputs:
                r = (pred[j][:, :, c] - self.meas[j][None, :, c]) / self.sigma[c]
                parts.append(np.where(np.isfinite(r), r, 1e3))
        parts.append((Z[:, :self.p] - self.prior_mean) / self.prior_sd)
        return np.concatenate(parts, axis=1)

    def rows_of_window(self, j: int) -> slice:
        """The data rows of window ``j`` in the residual vector."""
        return slice(int(self.offsets[j]), int(self.offsets[j + 1]))

    def jacobian(self, z: np.ndarray, r0: np.ndarray | None = None) -> sparse.csr_matrix:
        """Forward-difference Jacobian (sparse): one run per coefficient and one per fitted
        initial channel (all windows' at once: each window's rows depend on its own only)."""
        m = len(FITTED_STATES)
        steps = 1e-6 * np.maximum(np.abs(z), 1e-3)
        Z = np.repeat(z[None], 1 + self.p + m, axis=0)
        for k in range(self.p):
            Z[1 + k, k] += steps[k]
        for c in range(m):
            Z[1 + self.p + c, self.p + c::m] += steps[self.p + c::m]
        R = self.residuals(Z)
        base = R[0] if r0 is None else r0
        n = R.shape[1]
        rows, cols, vals = [], [], []
        for k in range(self.p):
            rows.append(np.arange(n))
            cols.append(np.full(n, k))
            vals.append((R[1 + k] - base) / steps[k])
        for c in range(m):
            d = R[1 + self.p + c] - base
            for j in range(self.nw):
                sl = self.rows_of_window(j)
                rows.append(np.arange(sl.start, sl.stop))
                cols.append(np.full(sl.stop - sl.start, self.p + j * m + c))
                vals.append(d[sl] / steps[self.p + j * m + c])
        return sparse.csr_matrix((np.concatenate(vals), (np.concatenate(rows),
                                                          np.concatenate(cols))),
                                 shape=(n, len(z)))


@one_blas_thread
def refine(logs: Sequence[LoggedRun], windows: Sequence[Window], params: VehicleParams,
           base: VehicleParams, names: Sequence[str], why: str,
           bounds: Mapping[str, tuple[float, float]] | None = None,
           use_priors: bool = True,
           tracks: dict[tuple[float, ...], np.ndarray] | None = None) -> OutputErrorFit:
    """Fit the coefficients ``names`` to the free-run prediction of the windows that are not
    held out (module docstring), starting from ``params`` (the equation error's values);
    ``base`` gives the priors and the signs; ``tracks``: the actuator positions kept between
    free runs of ``logs`` (:class:`~auv_ident.freerun.FreeRuns`).

    Raises
    ------
    ValueError
        no window to fit, or no measured output channel.
    """
    fit_windows = [w for w in windows if not w.held_out]
    if not fit_windows:
        raise ValueError('no window of the log is left for the output-error fit')
    shoot, why_len = window_length(base, logs, folds=SHOOTING_FOLDS)
    period = max(float(np.median(np.diff(lg.t))) for lg in logs if len(lg.t) > 1)
    if shoot / period < ROWS_MIN:
        raise OutputErrorImpossible(
            f'output error needs {ROWS_MIN} rows per shooting segment for its 5 initial '
            f'states; the {shoot:.2g} s segments ({why_len}) hold {shoot / period:.0f} at '
            f'{1.0 / period:.3g} Hz')
    fit_windows = shooting_segments(fit_windows, logs, shoot)
    if len(fit_windows) > WINDOWS_MAX:    # evenly spread over the log
        pick = np.round(np.linspace(0, len(fit_windows) - 1, WINDOWS_MAX)).astype(int)
        fit_windows = [fit_windows[i] for i in pick]
    outputs = [c for c in OUTPUTS if all(lg.is_measured(CHANNEL_NAMES[c]) for lg in logs)]
    if 2 not in outputs and 4 not in outputs:
        raise ValueError('output error needs the depth or the pitch measured')
    runs = FreeRuns(logs, fit_windows, params, tracks=tracks)
    pri = priors(list(names), base)
    limits = {n: (constraint(n, base).lo, constraint(n, base).hi) for n in names}
    for n, (b_lo, b_hi) in (bounds or {}).items():
        if n in limits:
            limits[n] = (max(limits[n][0], b_lo), min(limits[n][1], b_hi))
    mean = np.array([pri[n].mean for n in names])
    sd = np.array([pri[n].sd if use_priors else 1e12 * max(abs(pri[n].mean), 1.0)
                   for n in names])
    theta0 = np.array([params.values[n] for n in names])
    lo = np.array([limits[n][0] for n in names])
    hi = np.array([limits[n][1] for n in names])
    span = np.maximum(np.abs(theta0), 1e-6)
    theta0 = np.clip(theta0, lo + 1e-9 * span, hi - 1e-9 * span)
    sigma = {c: channel_sigma(logs, c) for c in outputs}
    prob = ShootingProblem(runs, params, names, outputs, sigma, mean, sd)
    z = prob.start(theta0)
    nz = len(z)
    lo_z = np.concatenate([lo, np.full(nz - len(names), -np.inf)])
    hi_z = np.concatenate([hi, np.full(nz - len(names), np.inf)])
    rms_start = _channel_rms(prob, z)
    for _ in range(2):   # a second pass with each channel weighted by its residual rms
        res = optimize.least_squares(lambda x: prob.residuals(x[None])[0], z,
                                     jac=lambda x: prob.jacobian(x), bounds=(lo_z, hi_z),
                                     method='trf', x_scale='jac', max_nfev=40,
                                     tr_solver='lsmr', xtol=1e-8, ftol=1e-8)
        z = res.x
        rms = _channel_rms(prob, z)
        prob.sigma = {c: max(rms[CHANNEL_NAMES[c]], SIGMA_FLOOR[c]) for c in outputs}
    r = prob.residuals(z[None])[0]
    J = prob.jacobian(z, r).toarray()
    theta = z[:len(names)]
    cov, dof = _covariance(prob, J, r)
    p = len(names)
    se = np.sqrt(np.maximum(np.diag(cov)[:p], 0.0))
    se = np.maximum(se, 1e-12 * np.maximum(np.abs(theta), 1e-300))
    near = 1e-3 * np.minimum(se, sd)     # on a bound to well within its uncertainty
    at_bound = (theta <= lo + near) | (theta >= hi - near)
    theta = np.where(at_bound & (theta <= lo + near), lo, np.where(at_bound, hi, theta))
    ci = {}
    for k, n in enumerate(names):
        ci[n] = interval(float(theta[k]), float(theta[k]), float(se[k]), dof,
                         float(lo[k]), float(hi[k]), bool(at_bound[k]))
    informed = {n: float(np.clip(1.0 - (se[k] / sd[k]) ** 2, 0.0, 1.0))
                for k, n in enumerate(names)}
    return OutputErrorFit(
        names=tuple(names), values={n: float(theta[k]) for k, n in enumerate(names)},
        std_error={n: float(se[k]) for k, n in enumerate(names)}, ci95=ci,
        at_bound={n: bool(at_bound[k]) for k, n in enumerate(names)}, informed=informed,
        start={n: float(v) for n, v in zip(names, theta0)},
        rms=_channel_rms(prob, z), rms_start=rms_start, windows=len(fit_windows),
        samples=sum(len(m) for m in prob.meas), evaluations=prob.evaluations, why=why)


def _channel_rms(prob: ShootingProblem, z: np.ndarray) -> dict[str, float]:
    """Residual rms per output channel (its units) of parameter vector ``z``."""
    r = prob.residuals(z[None])[0]
    out = {}
    for k, c in enumerate(prob.outputs):
        vals = []
        for j in range(prob.nw):
            rows = prob.rows_of_window(j)
            n = len(prob.meas[j])
            vals.append(r[rows][k * n:(k + 1) * n] * prob.sigma[c])
        v = np.concatenate(vals)
        out[CHANNEL_NAMES[c]] = float(np.sqrt(np.mean(v * v)))
    return out


def _covariance(prob: ShootingProblem, J: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, float]:
    """The sandwich covariance of the module docstring and its degrees of freedom."""
    p = prob.p
    n_data = len(r) - p
    H = J.T @ J
    lam = np.zeros_like(H)
    lam[np.arange(p), np.arange(p)] = 1.0 / prob.prior_sd ** 2
    ridge = 1e-12 * max(float(np.max(np.diag(H))), 1e-300)
    Hinv = np.linalg.inv(H + ridge * np.eye(len(H)))
    G = np.zeros_like(H)
    for j in range(prob.nw):
        rows = prob.rows_of_window(j)
        g = J[rows].T @ r[rows]
        G += np.outer(g, g)
    Jd = J[:n_data]
    rd = r[:n_data]
    dof_res = max(n_data - J.shape[1], 1)
    taus = [correlation_time(rd[prob.rows_of_window(j)]) for j in range(prob.nw)]
    kappa = float(rd @ rd) / dof_res * float(np.mean(taus))
    cluster = Hinv @ (G + lam) @ Hinv.T
    model = Hinv @ (kappa * (Jd.T @ Jd) + lam) @ Hinv.T
    sd = np.sqrt(np.maximum(np.maximum(np.diag(cluster), np.diag(model)), np.diag(Hinv)))
    sd_m = np.sqrt(np.maximum(np.diag(model), 1e-300))
    cov = model / np.outer(sd_m, sd_m) * np.outer(sd, sd)
    dof = float(max(prob.nw - 1, 1))
    if not np.all(np.isfinite(cov)):
        cov = np.where(np.isfinite(cov), cov, 0.0)
    return cov, dof
