"""The linear regressions: pool records into ``b = A theta``, check identifiability, solve.

Every regression is linear in its coefficients (see :mod:`auv_ident.identify.regressors`), so
the sum of squares ``J(theta) = |b - A theta|^2`` is a quadratic form in ``theta``: it has one
minimum (unique when ``A`` has full column rank), found exactly by a linear least-squares
solve; there are no local minima for a Nelder-Mead search (the report's ``fminsearchbnd``) to
avoid. :func:`nelder_mead` runs that search on the same data so the two can be compared. The
terms of the equation's component that are not fitted (``CZ0`` and ``CM0`` unless fitted, as
the report does; the vehicle file's cross-flow drag) are moved to ``b`` with their base
values (reported under ``fixed``).

For forces from motion the design is the projection of the regressors on lead/lag
instruments (two-stage least squares): ``theta = (D'A)^-1 D'b``.
"""
from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Mapping, Sequence

import numpy as np
from scipy import optimize

from auv_ident.errors import IdentificationError, NotIdentifiableError
from auv_ident.identify.equations import EXCITATION, Equation, excitation_amplitude
from auv_ident.identify.records import ForceRecord, check_record
from auv_ident.identify.regressors import (
    component_terms,
    filtered,
    unbiased_basis,
    unbiased_columns,
)
from auv_sim.params import VehicleParams

#: Column-scaled condition number above which an equation is declared not identifiable.
COND_MAX = 1.0e3


@dataclasses.dataclass
class LinearSystem:
    """``b = A theta`` of one equation, pooled over records (rows with finite ``b`` only)."""

    equation: Equation
    names: tuple[str, ...]           # fitted coefficients, columns of A
    A: np.ndarray                    # (n, p) design the solve uses (= regressors, or their
    #                                  projection on the instruments for motion data)
    regressors: np.ndarray           # (n, p) regressors as measured
    b: np.ndarray                    # (n,) measured component minus the fixed terms
    measured: np.ndarray             # (n,) measured component (the force itself)
    fixed: dict[str, float]          # coefficients moved to b with their base values
    t: np.ndarray                    # (n,) stamps [s]
    record_index: np.ndarray         # (n,) index of the record each row comes from
    record_names: tuple[str, ...]
    excitation: np.ndarray           # (n, 6) nu as filtered like A, for excitation checks
    instrumented: bool = False       # A is the instrument projection (two-stage LS)
    rows: np.ndarray | None = None   # (n,) sample index of each row in its record
    records: tuple[ForceRecord, ...] = ()
    #: the names the identifiability checks apply to (the others, such as the quadratic
    #: cross-flow terms, are held by their priors where the data say little)
    core: tuple[str, ...] = ()
    #: what :func:`build_system` was given to keep between calls on the same records (the
    #: filtered columns; the covariance keeps the noise propagation's differences there)
    cache: dict[tuple[int, str], np.ndarray] | None = dataclasses.field(
        default=None, repr=False, compare=False)

    @functools.cached_property
    def scale(self) -> np.ndarray:
        """:func:`column_scale` of ``A`` (computed once; read only)."""
        return column_scale(self.A)

    def sum_of_squares(self, theta: np.ndarray) -> float:
        """The report's objective ``J(theta) = sum (b - A theta)^2`` [N^2 or (N m)^2]."""
        r = self.b - self.A @ theta
        return float(r @ r)


def build_system(records: Sequence[ForceRecord], equation: Equation, base: VehicleParams,
                 fit_offset: bool = False, fit_plane: bool = False, *,
                 free: Sequence[str] = (), values: Mapping[str, float] | None = None,
                 use: Sequence[np.ndarray | None] | None = None,
                 cache: dict[tuple[int, str], np.ndarray] | None = None) -> LinearSystem:
    """Pool the records into ``b = A theta`` for ``equation``.

    The offset coefficient (CZ0, CM0) is a column when ``fit_offset``, else its base value
    times its column is subtracted from the measured component (report 2.2). With
    ``fit_plane`` the dive plane's coefficient (CZbar, CMbar) is a column too, the record's
    plane wrench per unit coefficient (:attr:`ForceRecord.plane_unit`), and the plane wrench
    the reconstruction subtracted with the base value is added back to the measured component
    (forces from motion only). ``free`` names more of the component's terms to fit (the
    quadratic cross-flow drag); ``values`` overrides the base value of terms that stay fixed
    (a structure without the quadratic terms: 0). ``use`` (per record, a boolean mask of its
    samples or None for all) keeps the others out of the system (held-out data); ``cache``
    keeps the filtered columns of every term between calls on the same records.
    """
    hydro = equation.coefficients if (equation.offset is None or not fit_offset) else (
        (equation.offset, *equation.coefficients))
    terms = component_terms(equation)
    for name in free:
        if name not in terms:
            raise IdentificationError(f'{name} is not a term of the {equation.name} equation')
    hydro = (*hydro, *(n for n in free if n not in hydro))
    plane = equation.plane if fit_plane else None
    names = (*hydro, plane) if plane is not None else hydro
    if plane is not None and base.values[plane] == 0.0:
        raise IdentificationError(f'fitting {plane} needs a non-zero {plane} in the base '
                                  f'vehicle (its sign and rough size): the plane column comes '
                                  f'from it')
    value_of = {**base.values, **(values or {})}
    fixed = {} if (equation.offset is None or fit_offset) else {
        equation.offset: value_of[equation.offset]}
    # the model's other terms on this component are known (not fitted): moved to b like
    # the offset, when the base vehicle (or ``values``) has them
    fixed.update({k: value_of[k] for k in terms
                  if k not in names and k not in fixed and value_of[k] != 0.0})
    fixed = {k: v for k, v in fixed.items() if v != 0.0 or k == equation.offset}
    parts_a, parts_b, parts_m, parts_t, parts_i, parts_x = [], [], [], [], [], []
    parts_z: list[np.ndarray] = []
    parts_r: list[np.ndarray] = []
    for i, rec in enumerate(records):
        check_record(rec)
        all_cols = _term_columns(i, rec, equation, base, cache)
        stacked = np.column_stack([all_cols[:, terms.index(k)] for k in (*hydro, *fixed)])
        meas = rec.tau[:, equation.axis]
        if plane is not None:
            if rec.plane_unit is None:
                raise IdentificationError(
                    f'{rec.name}: fitting {plane} needs forces from motion (the force topic '
                    f'carries the hydrodynamic wrench without the plane\'s)')
            column = rec.plane_unit[:, equation.axis]
            stacked = np.column_stack([stacked[:, :len(hydro)], column,
                                       stacked[:, len(hydro):]])
            meas = meas + base.values[plane] * column
        ok = np.isfinite(meas)
        if use is not None and use[i] is not None:
            ok &= np.asarray(use[i], bool)
        if rec.kernel is not None:
            # instruments: the filtered regressors one window before and after (noise-free
            # parts only: their noise windows do not overlap those of row t)
            lag = len(rec.kernel)
            k = len(names)
            inst = np.full((len(meas), 2 * k), np.nan)
            if len(meas) > 4 * lag:
                inst[2 * lag:-2 * lag, :k] = 0.5 * (stacked[lag:-3 * lag, :k]
                                                    + stacked[3 * lag:-lag, :k])
                inst[2 * lag:-2 * lag, k:] = 0.5 * (stacked[:-4 * lag, :k]
                                                    + stacked[4 * lag:, :k])
            ok &= np.all(np.isfinite(inst), axis=1)
            parts_z.append(inst[ok])
        a = stacked[ok, :len(names)]
        b = meas[ok].copy()
        for j, (_name, value) in enumerate(fixed.items()):
            b -= value * stacked[ok, len(names) + j]
        parts_a.append(a)
        parts_b.append(b)
        parts_m.append(meas[ok])
        parts_t.append(rec.t[ok])
        parts_i.append(np.full(int(ok.sum()), i))
        parts_r.append(np.flatnonzero(ok))
        parts_x.append(_filtered_nu(i, rec, cache)[ok])
    if not parts_a:
        raise IdentificationError('no data: give at least one record')
    A = np.concatenate(parts_a)
    design = A
    if parts_z:
        if len(parts_z) != len(parts_a):
            raise IdentificationError('records mix filtered and unfiltered forces; use one')
        Z = np.concatenate(parts_z)
        if len(Z) > 0:
            zs = column_scale(Z)
            design = (Z / zs) @ np.linalg.lstsq(Z / zs, A, rcond=None)[0]
    return LinearSystem(
        equation=equation, names=tuple(names), A=design, regressors=A,
        b=np.concatenate(parts_b), measured=np.concatenate(parts_m), fixed=fixed,
        t=np.concatenate(parts_t), record_index=np.concatenate(parts_i),
        record_names=tuple(r.name for r in records), excitation=np.concatenate(parts_x),
        instrumented=bool(parts_z), rows=np.concatenate(parts_r), records=tuple(records),
        core=tuple(n for n in names if n not in free), cache=cache)


def _term_columns(i: int, rec: ForceRecord, equation: Equation, base: VehicleParams,
                  cache: dict[tuple[int, str], np.ndarray] | None) -> np.ndarray:
    """Filtered, noise-corrected columns (N, k) of every term of the equation's component
    (:func:`component_terms` order) for record ``i``, from ``cache`` when there."""
    key = (i, equation.name)
    if cache is not None and key in cache:
        return cache[key]
    basis = None
    if cache is not None:   # every term at once, each equation takes its own
        basis = cache.get((i, '_unbiased basis'))
        if basis is None:
            basis = cache[(i, '_unbiased basis')] = unbiased_basis(rec, base)
    cols = unbiased_columns(equation, rec, base, basis)
    out = filtered(np.column_stack([cols[k] for k in component_terms(equation)]), rec.kernel)
    if cache is not None:
        cache[key] = out
    return out


def _filtered_nu(i: int, rec: ForceRecord, cache: dict[tuple[int, str], np.ndarray] | None
                 ) -> np.ndarray:
    """The record's velocities filtered like its regressors, from ``cache`` when there."""
    key = (i, '_nu')
    if cache is not None and key in cache:
        return cache[key]
    out = filtered(rec.nu, rec.kernel)
    if cache is not None:
        cache[key] = out
    return out


#: Share of the samples with an actuator at its limit above which it is named as a reason.
SATURATED_SHARE = 0.2
#: The actuator whose motion excites each equation's coefficients (index into bar, helm,
#: thrust) and its name.
_DRIVER = {'surge': (2, 'propeller'), 'heave': (0, 'plane'), 'pitch': (0, 'plane'),
           'sway': (1, 'rudder'), 'yaw': (1, 'rudder')}
#: Log rate [Hz] at which the derivative window is its nominal 1 s (at least 5 samples).
RATE_FOR_WINDOW_HZ = 5.0


def _sample_period(system: LinearSystem) -> float:
    dts = [float(np.median(np.diff(r.t))) for r in system.records if len(r.t) > 1]
    return max(dts) if dts else math.nan


def _window_s(system: LinearSystem) -> float:
    """Longest derivative/low-pass window of the records [s] (0 without filtering)."""
    ws = [len(r.kernel) * float(np.median(np.diff(r.t))) for r in system.records
          if r.kernel is not None and len(r.t) > 1]
    return max(ws) if ws else 0.0


def saturation_note(system: LinearSystem) -> str:
    """``'; the plane was at its limit in 35 % of the samples ...'`` when the actuator that
    excites the equation sat at its limit in more than :data:`SATURATED_SHARE` of the rows
    used, else ``''``."""
    c, what = _DRIVER[system.equation.name]
    flags = []
    for i, rec in enumerate(system.records):
        if rec.saturated is None or system.rows is None:
            continue
        flags.append(rec.saturated[system.rows[system.record_index == i], c])
    if not flags:
        return ''
    share = float(np.mean(np.concatenate(flags)))
    if share <= SATURATED_SHARE:
        return ''
    return (f'; the {what} was at its limit in {share:.0%} of the samples, where the motion '
            'follows the limit and not the commands (keep the manoeuvres within the limits)')


def _rate_note(system: LinearSystem, name: str, amp: float) -> str:
    """Why a coefficient's excitation is lost to the log rate, or ``''``: its variable varies
    enough as logged (beyond 3 noise standard deviations) but not after the derivative
    window, which at a slow log is longer than 1 s (at least 5 samples)."""
    exc = EXCITATION[name]
    window = _window_s(system)
    dt = _sample_period(system)
    if not (window > 1.5 and math.isfinite(dt)):
        return ''
    raw = []
    sigma = 0.0
    for i, rec in enumerate(system.records):
        if system.rows is None:
            return ''
        raw.append(rec.nu[system.rows[system.record_index == i], exc.variable])
        if rec.noise is not None:
            sigma = max(sigma, float(rec.noise.sigma[6 + exc.variable]))
    amp_raw = excitation_amplitude(name, np.concatenate(raw)) - 3.0 * sigma
    if amp_raw < exc.threshold or amp_raw < 2.0 * amp:
        return ''
    return (f' (as logged it varies by {amp_raw * exc.scale:.3g} {exc.unit} beyond the noise: '
            f'the {window:.2g} s derivative window of this {1.0 / dt:.3g} Hz log removes it; '
            f'log at {RATE_FOR_WINDOW_HZ:g} Hz or faster, or fly slower manoeuvres)')


def check_identifiable(system: LinearSystem) -> None:
    """Raise NotIdentifiableError if a coefficient of ``system`` lacks excitation, or if two
    coefficients cannot be told apart (column-scaled condition number above COND_MAX).

    The message names the coefficient, why (too few samples, too little excitation, two
    coefficients alike), what made it so when the data say (a log rate whose derivative
    window removes the excitation; an actuator at its limit for much of the time), and the
    manoeuvre or rate that would fix it.
    """
    core = system.core or system.names
    p = len(core)
    sat = saturation_note(system)
    if len(system.b) < 10 * p:
        dt = _sample_period(system)
        rate = (f' at {1.0 / dt:.3g} Hz ({10 * p * dt:.3g} s of usable data needed after the '
                'filter edges)' if math.isfinite(dt) else '')
        raise NotIdentifiableError(
            f'{system.equation.name} equation: only {len(system.b)} usable samples for '
            f'{p} coefficient(s) ({", ".join(core)}){rate}; record a longer '
            f'manoeuvre{sat}')
    for name in core:
        exc = EXCITATION[name]
        amp = excitation_amplitude(name, system.excitation[:, exc.variable])
        if amp < exc.threshold:
            kind = 'never exceeds' if name == 'Ksh' else 'never varies by more than'
            raise NotIdentifiableError(
                f'{name}: {exc.what} {kind} {amp * exc.scale:.3g} {exc.unit} in these data '
                f'(99th percentile; needs {exc.threshold * exc.scale:.3g} {exc.unit})'
                f'{_rate_note(system, name, amp)}{sat}; {exc.manoeuvre}')
    cond, corr = conditioning(system.A[:, [system.names.index(n) for n in core]])
    if not math.isfinite(cond) or cond > COND_MAX:
        if p == 1:
            raise NotIdentifiableError(
                f'{core[0]}: its regressor is zero in these data{sat}; '
                f'{EXCITATION[core[0]].manoeuvre}')
        c = np.abs(np.nan_to_num(corr, nan=1.0)) - np.eye(p)
        i, j = np.unravel_index(int(np.argmax(c)), c.shape)
        a, b = core[min(i, j)], core[max(i, j)]
        raise NotIdentifiableError(
            f'{a} and {b} cannot be told apart in these data (regressor condition number '
            f'{cond:.3g} > {COND_MAX:.0f}, correlation {corr[i, j]:+.5f}){sat}; '
            f'{EXCITATION[b].manoeuvre} with varied lengths and speeds')


def column_scale(A: np.ndarray) -> np.ndarray:
    """Euclidean norm of each column of ``A`` (1 for a zero column), for scaling."""
    s = np.sqrt(np.sum(A * A, axis=0))
    return np.where(s > 0, s, 1.0)


def conditioning(A: np.ndarray) -> tuple[float, np.ndarray]:
    """Condition number of the column-scaled ``A`` and the correlation of its LS estimate."""
    As = A / column_scale(A)
    sv = np.linalg.svd(As, compute_uv=False)
    cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else math.inf
    try:
        cov = np.linalg.inv(As.T @ As)
        d = np.sqrt(np.diag(cov))
        corr = cov / np.outer(d, d)
    except np.linalg.LinAlgError:
        corr = np.full((A.shape[1], A.shape[1]), np.nan)
    return cond, corr


def solve(system: LinearSystem, bounds: Mapping[str, tuple[float, float]] | None = None
          ) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares coefficients of ``system`` and a mask of those stopped on a bound.

    Unbounded: an SVD least-squares solve of the column-scaled problem. With ``bounds``
    (name -> (lo, hi), missing names unbounded): scipy's bounded-variable least squares
    (``lsq_linear``, method ``bvls``), exact for this convex quadratic problem.
    """
    scale = system.scale
    As = system.A / scale
    lo = np.array([(bounds or {}).get(n, (-math.inf, math.inf))[0] for n in system.names])
    hi = np.array([(bounds or {}).get(n, (-math.inf, math.inf))[1] for n in system.names])
    if bounds and (np.any(np.isfinite(lo)) or np.any(np.isfinite(hi))):
        res = optimize.lsq_linear(As, system.b, bounds=(lo * scale, hi * scale),
                                  method='bvls', tol=1e-12, lsmr_tol='auto')
        theta = res.x / scale
        at_bound = res.active_mask != 0
    else:
        theta = np.linalg.lstsq(As, system.b, rcond=None)[0] / scale
        at_bound = np.zeros(len(theta), bool)
    return theta, at_bound


def nelder_mead(system: LinearSystem, x0: Sequence[float] | None = None,
                bounds: Mapping[str, tuple[float, float]] | None = None,
                xatol: float = 1e-10) -> np.ndarray:
    """The report's method on the same data: bounded Nelder-Mead on ``J(theta)``.

    The search runs on coefficients scaled by their column norms (so one tolerance fits all)
    from ``x0`` (default: zeros), with scipy's ``minimize(method='Nelder-Mead', bounds=...)``;
    the objective is :meth:`LinearSystem.sum_of_squares` evaluated on every sample.
    """
    scale = system.scale
    p = len(system.names)
    start = np.zeros(p) if x0 is None else np.asarray(x0, float) * scale
    lim = [((bounds or {}).get(n, (-math.inf, math.inf))) for n in system.names]
    nm_bounds = [(lo * s if math.isfinite(lo) else None, hi * s if math.isfinite(hi) else None)
                 for (lo, hi), s in zip(lim, scale)]
    f0 = max(system.sum_of_squares(np.zeros(p)), 1e-300)

    def objective(z: np.ndarray) -> float:
        return system.sum_of_squares(z / scale) / f0

    best = start
    for _ in range(3):  # restarts from the last point shrink the simplex anew
        res = optimize.minimize(objective, best, method='Nelder-Mead', bounds=nm_bounds,
                                options={'xatol': xatol, 'fatol': 1e-15, 'maxiter': 20000,
                                         'maxfev': 40000, 'adaptive': True})
        best = res.x
    return np.asarray(best / scale)

