"""Fitting effects to a log: equation error first, free-run (output) error to refine.

Both fits are bounded nonlinear least squares in scaled parameters ``s = (p - absent) /
scale`` (:func:`scipy.optimize.least_squares`, trust-region reflective):

* equation error: residuals ``e_k / sigma_k`` of the six equations at the equation samples
  of the training windows (``sigma_k`` the noise of equation ``k`` propagated from the
  sensor noise through the derivative filter and the mass matrix);
* free-run error: ``(y_model - y_log) / s_c`` over the training windows for the states
  ``z, theta, u, w, q, v, r`` with fixed channel scales ``s_c``; the Jacobian's columns are
  free runs of perturbed models, run in one parallel batch.

Intervals (95 %) come from the bias-reduced cluster-robust covariance (CR2) with the windows
as clusters (residuals inside a window are strongly correlated; windows are independent runs)
and Student's t with the Bell-McCaffrey degrees of freedom of each parameter (``G - 1`` for
``G`` equally informative windows, fewer when a few windows carry the information); a
free-run interval is widened to cover the equation-error estimate (two estimators with
different systematic errors: initial-state smoothing for the free run, derivative filtering
for the equation).
A parameter whose residual sensitivity is negligible is "not identifiable from these data": it
is held at its "absent" value and its interval is its whole range. Of several parameters, those
whose free-run interval covers their "absent" value are dropped after the free-run fit and the
rest refitted, so a candidate pays only for the parameters it uses.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np
from scipy import optimize, stats

from auv_gap.catalogue import Perturbation
from auv_gap.problem import CH_INDEX, EffectSet, Problem

#: A parameter moved by one typical size must change the equation-error chi-square by more
#: than this (squared norm of its Jacobian column) to count as identifiable.
IDENTIFIABLE_CHI2 = 0.1
BAD_RESIDUAL = 1e3


@dataclasses.dataclass
class FitResult:
    """Fitted parameters of an effect set (all parameters, set order), which of them the
    data identify, their 95 % intervals, and the fit stage that produced them."""

    effects: EffectSet
    values: np.ndarray
    active: np.ndarray
    lo95: np.ndarray
    hi95: np.ndarray
    stage: str
    #: per parameter: the fit's own interval excludes the "absent" value (before any
    #: widening to cover another estimator); None: use ``lo95``/``hi95``
    significant: np.ndarray | None = None

    @property
    def absent_values(self) -> np.ndarray:
        """The "absent" value of every parameter."""
        return self.effects.absent

    @property
    def n_active(self) -> int:
        """Number of identified parameters."""
        return int(self.active.sum())


def cluster_covariance(J: np.ndarray, r: np.ndarray, clusters: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Cluster-robust covariance of least-squares parameters (windows as clusters) and, per
    parameter, the degrees of freedom of its t reference.

    The bias-reduced linearisation CR2 (Bell and McCaffrey 2002)::

        V = B^-1 [sum_g J_g^T A_g r_g r_g^T A_g J_g] B^-1,  B = J^T J,
        A_g = (I - H_gg)^(-1/2),  H_gg = J_g B^-1 J_g^T

    (exactly unbiased for independent equal-variance residuals; ``A_g`` through the thin SVD
    of ``J_g B^-1/2``, whose rank is at most the number of parameters), with the
    Bell-McCaffrey degrees of freedom of each parameter ``k``: ``(tr G^T G)^2 / tr (G^T G)^2``,
    column ``g`` of ``G`` being ``(I - H)_{:, g} A_g J_g B^-1 e_k``. Equally informative
    clusters give about ``G - 1``; a parameter that only a few windows inform (a plane delay
    seen in the windows with doublets) gets fewer, and a wider t quantile: with few, unequally
    informative clusters the plain ``G - 1`` under-covers (Imbens and Kolesar 2016, Pustejovsky
    and Tipton 2018).

    With no more clusters than parameters (short logs: one training window) the clusters'
    scores, which sum to ``J^T r = 0`` at the least-squares optimum, span fewer directions
    than there are parameters and CR2 gives some a variance of zero (a single cluster: zero
    for all): an interval "3.33-3.33". There each variance is at least the model-based one, ``s^2
    (J^T J)^-1`` with ``s^2 = r^T r / (n - p)``, times ``n / n_eff`` for the residuals'
    correlation within clusters (lag-1, ``n_eff = n (1 - rho) / (1 + rho)``), and the degrees
    of freedom stay ``G - 1`` (at least 1: a t quantile of 12.7 for one window).
    """
    ids = np.unique(clusters)
    p = J.shape[1]
    if not np.any(J):
        # the residuals do not depend on the parameters at all: nothing is identified
        return np.diag(np.full(p, np.inf)), np.ones(p)
    B = J.T @ J
    w, U = np.linalg.eigh(B)
    w = np.maximum(w, w.max() * 1e-14 if w.size else 0.0)
    b_inv = (U / w) @ U.T
    b_isqrt = (U / np.sqrt(w)) @ U.T
    meat = np.zeros((p, p))
    cols = []  # per cluster: (rows, A_g J_g B^-1) for the degrees of freedom
    for c in ids:
        m = np.flatnonzero(clusters == c)
        Jg = J[m]
        Ug, sg, _ = np.linalg.svd(Jg @ b_isqrt, full_matrices=False)
        fac = 1.0 / np.sqrt(np.maximum(1.0 - sg ** 2, 1e-12)) - 1.0

        def adjust(v: np.ndarray, Ug: np.ndarray = Ug, fac: np.ndarray = fac) -> np.ndarray:
            out: np.ndarray = v + Ug @ (fac[:, None] * (Ug.T @ v))
            return out

        u = Jg.T @ adjust(r[m][:, None])[:, 0]
        meat += np.outer(u, u)
        cols.append((m, adjust(Jg @ b_inv)))
    V = b_inv @ meat @ b_inv
    df = np.empty(p)
    for k in range(p):
        G = np.zeros((J.shape[0], len(cols)))
        for j, (m, AJ) in enumerate(cols):
            v = AJ[:, k]                      # A_g J_g B^-1 e_k on the rows of cluster g
            G[m, j] += v
            G[:, j] -= J @ (b_inv @ (J[m].T @ v))   # minus H[:, g] v
        gtg = G.T @ G
        tr = float(np.trace(gtg))
        tr2 = float(np.sum(gtg * gtg))
        df[k] = tr * tr / tr2 if tr2 > 0 else float(len(ids) - 1)
    if len(ids) <= p:
        V = V + np.diag(np.maximum(np.diag(_model_covariance(J, r, clusters, b_inv))
                                   - np.diag(V), 0.0))
    return V, np.clip(df, 1.0, max(len(ids) - 1, 1))


def _model_covariance(J: np.ndarray, r: np.ndarray, clusters: np.ndarray, b_inv: np.ndarray
                      ) -> np.ndarray:
    """``s^2 (J^T J)^-1 n / n_eff``: the model-based covariance, inflated for the residuals'
    lag-1 correlation within clusters (see :func:`cluster_covariance`)."""
    n, p = J.shape
    num = den = 0.0
    for c in np.unique(clusters):
        rc = r[clusters == c]
        num += float(np.sum(rc[1:] * rc[:-1])) if rc.size > 1 else 0.0
        den += float(np.sum(rc * rc))
    rho = float(np.clip(num / den, 0.0, 0.95)) if den > 0 else 0.0
    s2 = float(r @ r) / max(n - p, 1)
    out: np.ndarray = s2 * b_inv * (1.0 + rho) / (1.0 - rho)
    return out


def _intervals(es: EffectSet, values: np.ndarray, active: np.ndarray, cov_s: np.ndarray,
               df: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = es.lo.copy(), es.hi.copy()
    idx = np.flatnonzero(active)
    for k, i in enumerate(idx):
        tq = float(stats.t.ppf(0.975, df[k]))
        half = tq * np.sqrt(max(cov_s[k, k], 0.0)) * es.scale[i]
        lo[i] = max(es.lo[i], values[i] - half)
        hi[i] = min(es.hi[i], values[i] + half)
    return lo, hi


class EquationFit:
    """Equation-error fits on the training samples of a :class:`Problem`."""

    def __init__(self, problem: Problem) -> None:
        self.pr = problem
        self.train = ~problem.eq_held
        self.act_nominal: np.ndarray | None = None
        #: effect names -> the set's change at its "absent" values, and whether moving its
        #: parameters changes the actuator model (:func:`_probe_actuators`)
        self._moves_actuators: dict[tuple[str, ...], tuple[Perturbation, bool]] = {}

    def residual(self, es: EffectSet, values: np.ndarray, mask: np.ndarray | None = None,
                 ) -> np.ndarray:
        """Normalised equation errors (n x 6) of the effect set at ``values``."""
        pert = es.perturbation(values)
        act = None
        if es.names not in self._moves_actuators:
            self._moves_actuators[es.names] = _probe_actuators(es)
        nom, probe_moves = self._moves_actuators[es.names]
        if not (probe_moves or _actuators_differ(pert, nom)):
            if self.act_nominal is None:
                self.act_nominal = self.pr.actuators(pert)
            act = self.act_nominal
        # a candidate that changes the mass matrix changes how much of the measured
        # acceleration's noise its equations carry: weighting each equation by its own noise
        # keeps the fit from shrinking the inertia to shed noise (errors in variables)
        sigma = self.pr.eq_sigma if not pert.factors else self.pr.equation_sigma(
            self.pr.model_arrays(pert)[1])
        e: np.ndarray = self.pr.equation_error(pert, act) / sigma
        return e if mask is None else e[mask]

    def cost(self, es: EffectSet, values: np.ndarray, held_out: bool) -> float:
        """Mean squared normalised equation error on training or held-out samples."""
        mask = self.pr.eq_held if held_out else self.train
        return float(np.mean(self.residual(es, values, mask) ** 2))

    def fit(self, es: EffectSet, start: np.ndarray | None = None) -> FitResult:
        """Fit ``es`` by equation error from ``start`` (default: a scan of each single
        parameter's range from the "absent" values)."""
        free = np.ones(len(es.params), dtype=bool)
        x0 = (np.zeros(len(es.params)) if start is None
              else (np.asarray(start) - es.absent) / es.scale)
        if start is None and len(es.params) == 1:
            x0 = self._scan(es)
        for _ in range(3):
            values, J, r = self._solve(es, x0, free)
            strength = np.sum(J ** 2, axis=0)
            weak = strength < IDENTIFIABLE_CHI2
            if not weak.any():
                break
            fi = np.flatnonzero(free)
            free[fi[weak]] = False
            x0 = (values - es.absent) / es.scale
            x0[~free] = 0.0
            if not free.any():
                values = es.absent.copy()
                break
        active = self._generalising(es, values, free)
        values = np.where(active, values, es.absent)
        if active.any():
            values, J, r = self._solve(es, (values - es.absent) / es.scale, active)
            clusters = np.repeat(self.pr.eq_window[self.train], 6)
            cov, df = cluster_covariance(J, r, clusters)
            lo, hi = _intervals(es, values, active, cov, df)
        else:
            lo, hi = es.lo.copy(), es.hi.copy()
        return FitResult(es, values, active, lo, hi, 'equation_error')

    def _generalising(self, es: EffectSet, values: np.ndarray, free: np.ndarray
                      ) -> np.ndarray:
        """Of several fitted parameters, those whose fitted value predicts the held-out
        equation samples better than their "absent" value (the others held at the fit):
        a parameter that makes the held-out equation error larger fits the training samples'
        noise (through terms of higher order, a current across the heading seen only through
        the noise of the derived rates), not the vehicle. The one with the largest held-out
        gain is always kept.

        Parameters
        ----------
        es
            the effect set.
        values
            its fitted parameter values (all parameters, set order; units of each).
        free
            the parameters fitted.

        Returns
        -------
        np.ndarray
            the parameters kept (bool, set order).
        """
        idx = np.flatnonzero(free)
        if idx.size < 2 or not np.any(self.pr.eq_held):
            return free
        held = self.cost(es, values, held_out=True)
        gain = np.empty(idx.size)
        for k, i in enumerate(idx):
            without = values.copy()
            without[i] = es.absent[i]
            gain[k] = self.cost(es, without, held_out=True) - held
        keep = free.copy()
        drop = (gain <= 0.0) & (np.arange(idx.size) != int(np.argmax(gain)))
        keep[idx[drop]] = False
        return keep

    def _scan(self, es: EffectSet) -> np.ndarray:
        """Best start of a one-parameter effect on a geometric grid over its range."""
        lo_s = (es.lo[0] - es.absent[0]) / es.scale[0]
        hi_s = (es.hi[0] - es.absent[0]) / es.scale[0]
        grid = [0.0]
        for k in range(12):
            for sgn in (-1.0, 1.0):
                v = sgn * 2.0 ** (k - 2)
                if lo_s <= v <= hi_s:
                    grid.append(v)
        best, best_cost = 0.0, np.inf
        for v in grid:
            c = float(np.sum(self.residual(es, es.absent + v * es.scale, self.train) ** 2))
            if c < best_cost:
                best, best_cost = v, c
        return np.array([best])

    def _solve(self, es: EffectSet, x0: np.ndarray, free: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        lb = ((es.lo - es.absent) / es.scale)[free]
        ub = ((es.hi - es.absent) / es.scale)[free]
        base = x0.copy()

        def full(s: np.ndarray) -> np.ndarray:
            x = base.copy()
            x[free] = s
            values: np.ndarray = es.absent + x * es.scale
            return values

        def fun(s: np.ndarray) -> np.ndarray:
            return self.residual(es, full(s), self.train).ravel()

        s0 = np.clip(x0[free], lb + 1e-9 * (ub - lb), ub - 1e-9 * (ub - lb))
        sol = optimize.least_squares(fun, s0, bounds=(lb, ub), method='trf', diff_step=1e-3,
                                     x_scale=1.0, max_nfev=60)
        return full(sol.x), sol.jac, sol.fun


def _probe_actuators(es: EffectSet) -> tuple[Perturbation, bool]:
    """The model change of ``es`` at its "absent" values, and whether moving every parameter
    by its scale changes the actuator model (delay, lag, rate)."""
    nom = es.perturbation(es.absent)
    return nom, _actuators_differ(es.perturbation(es.absent + es.scale), nom)


def _actuators_differ(a: Perturbation, b: Perturbation) -> bool:
    """Whether the actuator models (delay, lag, rate) of ``a`` and ``b`` differ."""
    return bool(np.any(a.delay != b.delay) or np.any(a.tau != b.tau)
                or np.any(a.rate != b.rate))


class FreeRunFit:
    """Free-run (output-error) fits and scores of a :class:`Problem`.

    ``scales`` (7) are the channel scales ``s_c`` of :data:`auv_gap.problem.CH_INDEX`.
    """

    def __init__(self, problem: Problem, scales: np.ndarray) -> None:
        self.pr = problem
        self.scales = np.asarray(scales, dtype=np.float64)
        self.train = problem.select(False)
        self.held = problem.select(True)
        rows = problem.window_rows(self.train)
        every = problem.cost_every
        self.pick = np.concatenate([np.arange(r.start, r.stop)[1::every] for r in rows])
        self.clusters = np.concatenate([np.full(len(np.arange(r.start, r.stop)[1::every]), k)
                                        for k, r in enumerate(rows)])

    def residuals(self, es: EffectSet, values_list: Sequence[np.ndarray],
                  windows: Sequence[int] | None = None) -> np.ndarray:
        """Normalised free-run errors (nc x S x 7) on the training windows (or ``windows``)."""
        wins = self.train if windows is None else windows
        out, meas = self.pr.free_run([es.perturbation(v) for v in values_list], wins)
        err = (out[:, :, CH_INDEX] - meas[None, :, CH_INDEX]) / self.scales
        return np.clip(np.where(np.isfinite(err), err, BAD_RESIDUAL), -BAD_RESIDUAL,
                       BAD_RESIDUAL)

    def fit(self, start: FitResult, max_nfev: int = 8, prune: bool = True,
            cover: np.ndarray | None = None) -> FitResult:
        """Refine an equation-error fit by free-run error over the training windows; with
        ``prune``, of several parameters those whose interval covers their "absent" value are
        then dropped and the rest refitted (once); when every interval covers it, the least
        significant parameter (smallest distance from "absent" over its interval's width) is
        dropped and the rest fitted and pruned again. The interval is widened to cover ``cover``
        (default: the equation-error estimate of ``start``)."""
        es, active = start.effects, start.active.copy()
        if not active.any():
            return dataclasses.replace(start, stage='free_run')
        x_start = (start.values - es.absent) / es.scale
        lb = ((es.lo - es.absent) / es.scale)[active]
        ub = ((es.hi - es.absent) / es.scale)[active]
        cache: dict[bytes, np.ndarray] = {}
        h = 0.05

        def full(s: np.ndarray) -> np.ndarray:
            x = x_start.copy()
            x[active] = s
            values: np.ndarray = es.absent + x * es.scale
            return values

        def fun(s: np.ndarray) -> np.ndarray:
            key = s.tobytes()
            if key not in cache:
                cache.clear()
                cache[key] = self.residuals(es, [full(s)])[0][self.pick].ravel()
            return cache[key]

        def jac(s: np.ndarray) -> np.ndarray:
            r0 = fun(s)
            steps = []
            for i in range(s.size):
                si = s.copy()
                step = h if si[i] + h <= ub[i] else -h
                si[i] += step
                steps.append((si, step))
            res = self.residuals(es, [full(si) for si, _ in steps])
            J = np.empty((r0.size, s.size))
            for i, (_, step) in enumerate(steps):
                J[:, i] = (res[i][self.pick].ravel() - r0) / step
            return J

        s0 = np.clip(x_start[active], lb + 1e-9 * (ub - lb), ub - 1e-9 * (ub - lb))
        sol = optimize.least_squares(fun, s0, jac=jac, bounds=(lb, ub), method='trf',
                                     max_nfev=max_nfev, x_scale=1.0)
        values = full(sol.x)
        nch = len(CH_INDEX)
        cov, df = cluster_covariance(sol.jac, sol.fun, np.repeat(self.clusters, nch))
        lo, hi = _intervals(es, values, active, cov, df)
        covers = active & (lo <= es.absent) & (hi >= es.absent)
        if prune and active.sum() >= 2 and covers.any():
            if covers[active].all():
                # none told from "absent" (one poorly seen parameter can widen the others'
                # intervals): drop the least significant and try the rest again
                t = np.where(active, np.abs(values - es.absent) / np.maximum(hi - lo, 1e-300),
                             np.inf)
                drop = np.arange(active.size) == int(np.argmin(t))
            else:
                # drop what the free run cannot tell from "absent", refit the rest once
                drop = covers
            active = active & ~drop
            kept = dataclasses.replace(start, active=active,
                                       values=np.where(active, values, es.absent))
            return self.fit(kept, max_nfev=max(2, max_nfev // 2),
                            prune=bool(covers[start.active].all()),
                            cover=np.where(active, start.values, es.absent))
        significant = active & ((lo > es.absent) | (hi < es.absent))
        # the two fits are different estimators of the same parameters: widen the interval
        # to cover the equation-error estimate, so a disagreement shows as a wider interval
        other = start.values if cover is None else cover
        lo = np.where(active, np.minimum(lo, other), lo)
        hi = np.where(active, np.maximum(hi, other), hi)
        return FitResult(es, values, active, lo, hi, 'free_run', significant)
