"""Identification of the hydrodynamic coefficients (report section 2) by linear least squares.

Every regression of the report is linear in its coefficients. With the hydrodynamic force
``tau_H`` (body FRD, about the body origin; N and N m) and the velocities through the water
``nu = (u, v, w, p, q, r)`` (body FRD; m/s, rad/s), ``qs = 1/2 rho S_ref`` and ``L = L_ref``::

    surge  X = -Ksh qs C_XF(Re) u|u|,  C_XF = 0.075 / (log10(Re) - 2)^2,
                                        Re = max(|u| L / nu_w, 1e5)
    heave  Z = qs   (CZ0 u|u| + CZuw u w + CZuq L u q)
    pitch  M = qs L (CM0 u|u| + CMuw u w + CMuq L u q)
    sway   Y = qs   (CYuv u v + CYur L u r)
    yaw    N = qs L (CNuv u v + CNur L u r)

plus the vehicle file's quadratic cross-flow drag (``Zww w|w| + Zqq q|q|`` in heave, ``Mww``,
``Mqq`` in pitch, ``Yvv``, ``Yrr`` in sway, ``Nvv``, ``Nrr`` in yaw; dimensional, see
:mod:`auv_sim.params`), which is known from the base vehicle and moved to ``b`` as a fixed term
(reported under ``fixed``) when it is not zero.

so each equation is ``b = A theta`` with known columns ``A`` and the sum of squares
``J(theta) = |b - A theta|^2`` is a quadratic form in ``theta``: it has one minimum (unique
when ``A`` has full column rank), found exactly by a linear least-squares solve; there are no
local minima for a Nelder-Mead search (the report's ``fminsearchbnd``) to avoid.
:func:`nelder_mead` runs that search on the same data so the two can be compared. ``CZ0`` and
``CM0`` are moved to ``b`` with their base values (as the report does) unless fitted.

Statistics per equation. The estimate is ``theta = (D'A)^-1 D'b`` (``D = A`` for least
squares; for forces from motion ``D`` is the projection of ``A`` on lead/lag instruments,
two-stage least squares), so ``theta - theta_0 = (D'A)^-1 D'e`` with the equation error ``e``
and the sandwich covariance ``(D'A)^-1 S (D'A)^-T``, ``S = Var(D'e)``. ``errors='hac'`` (the
default) estimates ``S`` so that it holds for the coloured, filtered errors of this problem:

* forces from motion whose records carry a :class:`NoisePropagation` (see
  :mod:`auv_ident.motion`): ``e`` is, to first order, a known linear filter of the white
  sensor noise on the logged state (the Savitzky-Golay derivative in ``M nu_dot``, the
  consistent low-pass on the other wrenches and on the regressors, all through their local
  sensitivities), so ``S = sum_c sigma_c^2 w_c' w_c`` exactly, with ``w_c`` the design pushed
  back through that filter (its adjoint) and ``sigma_c`` estimated from each logged channel.
  This first-order (delta-method) covariance holds at the noise-free design; the design's
  own noise, amplified by the derivative's adjoint, would overstate it (by up to 1.7x for
  the weakly excited sway pair), so the design is first low-passed by the record's kernel
  (:data:`DESIGN_SMOOTHING_PASSES` times: -3 dB near 0.4 Hz for the 1 s window, above the
  manoeuvres' dynamics) and the bread uses the same design.
  A lag-window estimate cannot do this: the derivative noise is a difference, its spectrum
  vanishes at frequency zero, and the sum of its autocovariances (large, of both signs over
  the filter window) cancels to a small ``S`` that a truncated sum estimates with an error
  far larger than itself. It is used only when this noise model accounts for the residual
  (observed / predicted residual variance at most :data:`NOISE_RATIO_MAX`), else:
* a flat-top (trapezoidal) lag window (Politis and Romano): full weight up to the lag ``m``
  beyond which the autocorrelations of ``D_t e_t`` are insignificant (Politis' empirical
  rule, ``m`` at least the filter length, the known dependence of filtered errors), tapered
  to zero at ``2 m``; it has no bias for errors of finite memory, unlike the Newey-West
  (Bartlett) weights that shrink the negative lobes of the filtered errors and so
  overstate ``S``. If the flat-top matrix is not positive semi-definite, the Bartlett window
  of the same length is used instead.

The columns of a record with a noise model are corrected for the mean shift the noise
gives a nonlinear column (``E[(u + n)|u + n|] = u|u| + sigma_u^2`` away from u = 0; see
:func:`_unbiased_columns`), and :mod:`auv_ident.motion` does the same for the other
wrenches: without it, the errors-in-variables bias of Ksh is a third of its (small) standard
error at the realistic noise level and grows linearly with the noise.

Other methods: ``'iid'`` ``sigma^2 (A'A)^-1``; ``'ess'`` that times ``n / n_eff`` with the
integrated residual autocorrelation time; ``'jackknife'`` a delete-a-block jackknife.
95 % intervals from Student's t with the effective sample size; R^2; NRMSE = rms(residual) /
(max - min of the measured force); the condition number of the column-scaled regressor and
the coefficients' correlation matrix. Data that cannot identify a coefficient raise
:class:`~auv_ident.errors.NotIdentifiableError` naming it and the manoeuvre that would
excite it.

Assumed: no water current during the manoeuvres (the velocities over ground are the
velocities through the water), as in the report.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

import numpy as np
from scipy import optimize, stats

from auv_ident.errors import IdentificationError, NotIdentifiableError
from auv_sim.model import RE_MIN
from auv_sim.params import VehicleParams

#: Body-FRD wrench components (index into a 6-vector of forces/moments).
AXES = ('X', 'Y', 'Z', 'K', 'M', 'N')
#: Velocity components (index into ``nu``).
NU_NAMES = ('u', 'v', 'w', 'p', 'q', 'r')
ERROR_METHODS = ('hac', 'jackknife', 'ess', 'iid')
#: Contiguous blocks of the delete-a-block jackknife.
JACKKNIFE_BLOCKS = 40
#: Column-scaled condition number above which an equation is declared not identifiable.
COND_MAX = 1.0e3
#: Largest ratio of the observed to the sensor-noise-predicted residual variance for which
#: the sensor-noise propagation gives the covariance (above it, part of the residual is not
#: white sensor noise: model error, coloured noise; the lag window is used instead).
NOISE_RATIO_MAX = 1.5
#: Politis' rule: autocorrelations below ``POLITIS_C sqrt(log10(n) / n)`` are insignificant.
POLITIS_C = 2.0


class Equation(NamedTuple):
    """One regression: the wrench component it fits and the coefficients it identifies."""

    name: str                        # 'surge', 'heave', 'pitch', 'sway', 'yaw'
    axis: int                        # index of the fitted component in the body wrench
    unit: str                        # unit of that component
    coefficients: tuple[str, ...]    # always fitted
    offset: str | None               # CZ0 / CM0: fixed from the base, or fitted on request
    figure: int                      # the report's figure showing this fit


EQUATIONS: dict[str, Equation] = {
    'surge': Equation('surge', 0, 'N', ('Ksh',), None, 2),
    'heave': Equation('heave', 2, 'N', ('CZuw', 'CZuq'), 'CZ0', 3),
    'pitch': Equation('pitch', 4, 'N m', ('CMuw', 'CMuq'), 'CM0', 4),
    'sway': Equation('sway', 1, 'N', ('CYuv', 'CYur'), None, 5),
    'yaw': Equation('yaw', 5, 'N m', ('CNuv', 'CNur'), None, 6),
}


#: The vehicle file's quadratic cross-flow drag in each equation (dimensional, Prestero's
#: ``Zww w|w| + Zqq q|q|`` ...): known terms, moved to ``b`` with their base values.
CROSSFLOW: dict[str, tuple[str, str]] = {
    'heave': ('Zww', 'Zqq'), 'pitch': ('Mww', 'Mqq'), 'sway': ('Yvv', 'Yrr'),
    'yaw': ('Nvv', 'Nrr'),
}


class Excitation(NamedTuple):
    """What must vary for a coefficient to be identifiable, and which manoeuvre does it."""

    variable: int       # index into nu
    what: str           # e.g. 'pitch rate q'
    scale: float        # display factor (rad/s -> deg/s)
    unit: str           # display unit
    threshold: float    # minimum 99th percentile of |x - median(x)| (|x| for Ksh), SI
    manoeuvre: str


_DEG = 180.0 / math.pi
_MANOEUVRE_PITCH = 'fly the pitch mission (plane doublets)'
_MANOEUVRE_YAW = 'fly the yaw "Dieudonnee" mission (helm doublets)'
EXCITATION: dict[str, Excitation] = {
    'Ksh': Excitation(0, 'forward speed |u|', 1.0, 'm/s', 0.3,
                      'fly the surge mission (thrust steps)'),
    'CZ0': Excitation(0, 'forward speed u', 1.0, 'm/s', 0.2,
                      'fly at several speeds (thrust steps, as in the surge or pitch mission)'),
    'CM0': Excitation(0, 'forward speed u', 1.0, 'm/s', 0.2,
                      'fly at several speeds (thrust steps, as in the surge or pitch mission)'),
    'CZuw': Excitation(2, 'heave velocity w', 1.0, 'm/s', 0.005, _MANOEUVRE_PITCH),
    'CMuw': Excitation(2, 'heave velocity w', 1.0, 'm/s', 0.005, _MANOEUVRE_PITCH),
    'CZuq': Excitation(4, 'pitch rate q', _DEG, 'deg/s', math.radians(0.2), _MANOEUVRE_PITCH),
    'CMuq': Excitation(4, 'pitch rate q', _DEG, 'deg/s', math.radians(0.2), _MANOEUVRE_PITCH),
    'CYuv': Excitation(1, 'sway velocity v', 1.0, 'm/s', 0.005, _MANOEUVRE_YAW),
    'CNuv': Excitation(1, 'sway velocity v', 1.0, 'm/s', 0.005, _MANOEUVRE_YAW),
    'CYur': Excitation(5, 'yaw rate r', _DEG, 'deg/s', math.radians(0.2), _MANOEUVRE_YAW),
    'CNur': Excitation(5, 'yaw rate r', _DEG, 'deg/s', math.radians(0.2), _MANOEUVRE_YAW),
}

#: Physical sign bounds (``--bounds``): drag and the damping derivatives cannot change sign.
SIGN_BOUNDS: dict[str, tuple[float, float]] = {
    'Ksh': (0.0, math.inf),
    'CZuw': (-math.inf, 0.0),
    'CMuq': (-math.inf, 0.0),
    'CYuv': (-math.inf, 0.0),
    'CNur': (-math.inf, 0.0),
}


@dataclasses.dataclass(frozen=True)
class NoisePropagation:
    """How white sensor noise on the logged state enters a wrench reconstructed from motion.

    The reconstruction is ``tau = M (h * nu) - kappa * tau_other(x)`` (``*``: convolution)
    with the Savitzky-Golay derivative weights ``h`` and the consistent low-pass ``kappa``
    (:attr:`ForceRecord.kernel`); noise ``n`` on the state ``x`` changes it, to first order,
    by ``M (h * n_nu) - kappa * (J n)`` with ``J`` the Jacobian of ``tau_other``.

    Attributes:
        sigma: (12,) standard deviation of the white noise on each logged state channel
            ``x, y, z [m], phi, theta, psi [rad], u, v, w [m/s], p, q, r [rad/s]``.
        other_jacobian: (N, 6, 12) ``d tau_other / d x`` at every sample (body FRD wrench
            [N, N m] per unit of each state channel), ``tau_other`` = Coriolis + restoring +
            actuator wrench.
        mass: (6, 6) mass matrix ``M`` (rigid body plus added mass) [kg, kg m, kg m^2].
        derivative_kernel: (window,) convolution weights ``h`` of the derivative [1/s].
    """

    sigma: np.ndarray
    other_jacobian: np.ndarray
    mass: np.ndarray
    derivative_kernel: np.ndarray


@dataclasses.dataclass(frozen=True)
class ForceRecord:
    """One continuous, uniformly sampled stretch of a log, ready for the regressions.

    Attributes:
        name: where it comes from (bag name), for reports and provenance.
        t: header stamps (N,) [s].
        nu: body-FRD velocities (N, 6) ``u, v, w [m/s], p, q, r [rad/s]`` as logged.
        tau: hydrodynamic wrench (N, 6) body FRD ``X, Y, Z [N], K, M, N [N m]``; NaN rows are
            not used (the ends of a filtered record).
        source: ``'forces'`` (the /auv/hydrodynamic_forces topic) or ``'motion'``
            (reconstructed from the logged motion, see :mod:`auv_ident.motion`).
        kernel: FIR weights (odd length, sum 1) already applied to ``tau``; the regressors are
            filtered with the same weights so the filtered equation stays exact. None: no
            filtering.
        noise: how sensor noise propagates into ``tau`` (forces from motion), for the
            standard errors; None: unknown.
    """

    name: str
    t: np.ndarray
    nu: np.ndarray
    tau: np.ndarray
    source: str = 'forces'
    kernel: np.ndarray | None = None
    noise: NoisePropagation | None = None


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

    def sum_of_squares(self, theta: np.ndarray) -> float:
        """The report's objective ``J(theta) = sum (b - A theta)^2`` [N^2 or (N m)^2]."""
        r = self.b - self.A @ theta
        return float(r @ r)


class CoefficientEstimate(NamedTuple):
    """One identified coefficient (dimensionless, as in the vehicle file)."""

    name: str
    value: float
    std_error: float
    ci95: tuple[float, float]
    base: float                 # value in the base vehicle file
    at_bound: bool              # the bounded solve stopped on a bound (SE then not meaningful)
    records: tuple[str, ...]    # records whose data excite it


@dataclasses.dataclass
class EquationFit:
    """The solved regression of one equation, with its statistics and fit series."""

    equation: Equation
    coefficients: tuple[CoefficientEstimate, ...]
    fixed: dict[str, float]
    r2: float
    nrmse: float
    rmse: float                 # [N or N m]
    condition_number: float     # of the column-scaled regressor
    correlation: np.ndarray     # (p, p) coefficient correlation
    n_samples: int
    n_effective: float
    hac_lags: int
    errors: str
    t: np.ndarray
    measured: np.ndarray
    fitted: np.ndarray
    record_index: np.ndarray
    record_names: tuple[str, ...]
    covariance: str = ''        # how S of the 'hac' sandwich was estimated
    noise_ratio: float = math.nan  # observed / sensor-noise-predicted residual variance

    def value(self, name: str) -> float:
        """Identified value of a coefficient of this equation."""
        for c in self.coefficients:
            if c.name == name:
                return c.value
        raise KeyError(name)


@dataclasses.dataclass
class Identification:
    """Result of :func:`identify`: per-equation fits and the identified vehicle."""

    fits: dict[str, EquationFit]
    base: VehicleParams
    params: VehicleParams
    source: str
    errors: str
    fit_offsets: bool
    bounds: dict[str, tuple[float, float]]

    @property
    def coefficients(self) -> dict[str, CoefficientEstimate]:
        """Every identified coefficient by name."""
        return {c.name: c for fit in self.fits.values() for c in fit.coefficients}

    def values(self) -> dict[str, float]:
        """Identified values by name."""
        return {name: c.value for name, c in self.coefficients.items()}


# ------------------------------------------------------------------------------------------
# regressors


def surge_regressor(u: np.ndarray, params: VehicleParams) -> np.ndarray:
    """Column of Ksh: ``-qs C_XF(Re) u|u|`` [N] with ``Re = max(|u| L_ref / nu_w, 1e5)``."""
    qs = 0.5 * params.rho * params.S_ref
    re = np.maximum(np.abs(u) * params.L_ref / params.nu_water, RE_MIN)
    cxf = 0.075 / (np.log10(re) - 2.0) ** 2
    column: np.ndarray = -qs * cxf * u * np.abs(u)
    return column


def regressor_columns(equation: Equation, nu: np.ndarray, params: VehicleParams
                      ) -> dict[str, np.ndarray]:
    """Columns of every coefficient of ``equation`` (offset included) for velocities ``nu``.

    ``nu`` is (N, 6) body FRD [m/s, rad/s]; columns are in N (forces) or N m (moments).
    """
    u, v, w, q, r = nu[:, 0], nu[:, 1], nu[:, 2], nu[:, 4], nu[:, 5]
    qs = 0.5 * params.rho * params.S_ref
    L = params.L_ref
    if equation.name == 'surge':
        return {'Ksh': surge_regressor(u, params)}
    if equation.name in ('heave', 'pitch'):
        k = qs if equation.name == 'heave' else qs * L
        c0, cw, cq = ('CZ0', 'CZuw', 'CZuq') if equation.name == 'heave' else (
            'CM0', 'CMuw', 'CMuq')
        xw, xq = CROSSFLOW[equation.name]
        return {c0: k * u * np.abs(u), cw: k * u * w, cq: k * L * u * q,
                xw: w * np.abs(w), xq: q * np.abs(q)}
    if equation.name in ('sway', 'yaw'):
        k = qs if equation.name == 'sway' else qs * L
        cv, cr = ('CYuv', 'CYur') if equation.name == 'sway' else ('CNuv', 'CNur')
        xv, xr = CROSSFLOW[equation.name]
        return {cv: k * u * v, cr: k * L * u * r, xv: v * np.abs(v), xr: r * np.abs(r)}
    raise IdentificationError(f'unknown equation {equation.name!r} (known: {list(EQUATIONS)})')


def _filtered(columns: np.ndarray, kernel: np.ndarray | None) -> np.ndarray:
    """Columns (N, k) filtered by the symmetric FIR ``kernel`` (same length; ends unused)."""
    if kernel is None:
        return columns
    out = np.empty_like(columns)
    for j in range(columns.shape[1]):
        out[:, j] = np.convolve(columns[:, j], kernel, mode='same')
    return out


def _unbiased_columns(equation: Equation, rec: ForceRecord, base: VehicleParams
                      ) -> dict[str, np.ndarray]:
    """Regressor columns of ``rec``; for a record with a noise model (velocities with white
    noise of std ``sigma_c``), less their second-order mean shift from that noise,
    ``1/2 sum_c sigma_c^2 d^2 col / d nu_c^2`` (``(f(nu + s) + f(nu - s) - 2 f(nu)) / 2`` with
    ``s = sigma_c``), the errors-in-variables bias of a nonlinear column such as ``u|u|``."""
    cols = regressor_columns(equation, rec.nu, base)
    if rec.noise is None:
        return cols
    out = {k: v.copy() for k, v in cols.items()}
    for c in range(6):
        s = float(rec.noise.sigma[6 + c])
        if s <= 0.0:
            continue
        up, dn = rec.nu.copy(), rec.nu.copy()
        up[:, c] += s
        dn[:, c] -= s
        cu = regressor_columns(equation, up, base)
        cd = regressor_columns(equation, dn, base)
        for k in out:
            out[k] -= 0.5 * (cu[k] + cd[k] - 2.0 * cols[k])
    return out


def check_record(rec: ForceRecord) -> None:
    """Shapes, finiteness and increasing stamps of a record; IdentificationError if not."""
    n = len(rec.t)
    if rec.nu.shape != (n, 6) or rec.tau.shape != (n, 6):
        raise IdentificationError(f'{rec.name}: expected t (N), nu (N, 6) and tau (N, 6), got '
                                  f'{rec.t.shape}, {rec.nu.shape}, {rec.tau.shape}')
    if n and not np.all(np.isfinite(rec.t)):
        raise IdentificationError(f'{rec.name}: non-finite time stamps')
    back = np.flatnonzero(np.diff(rec.t) <= 0)
    if len(back):
        i = int(back[0]) + 1
        raise IdentificationError(f'{rec.name}: time stamps out of order at sample {i} '
                                  f'({rec.t[i - 1]:.6f} s, then {rec.t[i]:.6f} s)')
    if not np.all(np.isfinite(rec.nu)):
        i = int(np.flatnonzero(~np.all(np.isfinite(rec.nu), axis=1))[0])
        raise IdentificationError(f'{rec.name}: non-finite velocity at t = {rec.t[i]:.3f} s')


def build_system(records: Sequence[ForceRecord], equation: Equation, base: VehicleParams,
                 fit_offset: bool = False) -> LinearSystem:
    """Pool the records into ``b = A theta`` for ``equation``.

    The offset coefficient (CZ0, CM0) is a column when ``fit_offset``, else its base value
    times its column is subtracted from the measured component (report 2.2).
    """
    names = equation.coefficients if (equation.offset is None or not fit_offset) else (
        (equation.offset, *equation.coefficients))
    fixed = {} if (equation.offset is None or fit_offset) else {
        equation.offset: base.values[equation.offset]}
    # the vehicle's cross-flow drag is known (not fitted): moved to b like the offset
    fixed.update({k: base.values[k] for k in CROSSFLOW.get(equation.name, ())
                  if base.values[k] != 0.0})
    parts_a, parts_b, parts_m, parts_t, parts_i, parts_x = [], [], [], [], [], []
    parts_z: list[np.ndarray] = []
    parts_r: list[np.ndarray] = []
    for i, rec in enumerate(records):
        check_record(rec)
        cols = _unbiased_columns(equation, rec, base)
        stacked = _filtered(np.column_stack([cols[k] for k in (*names, *fixed)]), rec.kernel)
        meas = rec.tau[:, equation.axis]
        ok = np.isfinite(meas)
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
        parts_x.append(_filtered(rec.nu, rec.kernel)[ok])
    if not parts_a:
        raise IdentificationError('no data: give at least one record')
    A = np.concatenate(parts_a)
    design = A
    if parts_z:
        if len(parts_z) != len(parts_a):
            raise IdentificationError('records mix filtered and unfiltered forces; use one')
        Z = np.concatenate(parts_z)
        if len(Z) > 0:
            zs = _column_scale(Z)
            design = (Z / zs) @ np.linalg.lstsq(Z / zs, A, rcond=None)[0]
    return LinearSystem(
        equation=equation, names=tuple(names), A=design, regressors=A,
        b=np.concatenate(parts_b), measured=np.concatenate(parts_m), fixed=fixed,
        t=np.concatenate(parts_t), record_index=np.concatenate(parts_i),
        record_names=tuple(r.name for r in records), excitation=np.concatenate(parts_x),
        instrumented=bool(parts_z), rows=np.concatenate(parts_r), records=tuple(records))


# ------------------------------------------------------------------------------------------
# identifiability


def excitation_amplitude(name: str, x: np.ndarray) -> float:
    """The excitation measure of coefficient ``name`` on its variable ``x`` (SI units):
    99th percentile of ``|x|`` for Ksh (speed must be non-zero), else of ``|x - median x|``."""
    if len(x) == 0:
        return 0.0
    if name == 'Ksh':
        return float(np.percentile(np.abs(x), 99.0))
    return float(np.percentile(np.abs(x - np.median(x)), 99.0))


def check_identifiable(system: LinearSystem) -> None:
    """Raise NotIdentifiableError if a coefficient of ``system`` lacks excitation, or if two
    coefficients cannot be told apart (column-scaled condition number above COND_MAX)."""
    p = len(system.names)
    if len(system.b) < 10 * p:
        raise NotIdentifiableError(
            f'{system.equation.name} equation: only {len(system.b)} usable samples for '
            f'{p} coefficient(s) ({", ".join(system.names)}); record a longer manoeuvre')
    for name in system.names:
        exc = EXCITATION[name]
        amp = excitation_amplitude(name, system.excitation[:, exc.variable])
        if amp < exc.threshold:
            kind = 'never exceeds' if name == 'Ksh' else 'never varies by more than'
            raise NotIdentifiableError(
                f'{name}: {exc.what} {kind} {amp * exc.scale:.3g} {exc.unit} in these data '
                f'(99th percentile; needs {exc.threshold * exc.scale:.3g} {exc.unit}); '
                f'{exc.manoeuvre}')
    cond, corr = _conditioning(system.A)
    if not math.isfinite(cond) or cond > COND_MAX:
        if p == 1:
            raise NotIdentifiableError(
                f'{system.names[0]}: its regressor is zero in these data; '
                f'{EXCITATION[system.names[0]].manoeuvre}')
        c = np.abs(np.nan_to_num(corr, nan=1.0)) - np.eye(p)
        i, j = np.unravel_index(int(np.argmax(c)), c.shape)
        a, b = system.names[min(i, j)], system.names[max(i, j)]
        raise NotIdentifiableError(
            f'{a} and {b} cannot be told apart in these data (regressor condition number '
            f'{cond:.3g} > {COND_MAX:.0f}, correlation {corr[i, j]:+.5f}); '
            f'{EXCITATION[b].manoeuvre} with varied lengths and speeds')


def _column_scale(A: np.ndarray) -> np.ndarray:
    s = np.sqrt(np.sum(A * A, axis=0))
    return np.where(s > 0, s, 1.0)


def _conditioning(A: np.ndarray) -> tuple[float, np.ndarray]:
    """Condition number of the column-scaled ``A`` and the correlation of its LS estimate."""
    As = A / _column_scale(A)
    sv = np.linalg.svd(As, compute_uv=False)
    cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else math.inf
    try:
        cov = np.linalg.inv(As.T @ As)
        d = np.sqrt(np.diag(cov))
        corr = cov / np.outer(d, d)
    except np.linalg.LinAlgError:
        corr = np.full((A.shape[1], A.shape[1]), np.nan)
    return cond, corr


# ------------------------------------------------------------------------------------------
# solving


def solve(system: LinearSystem, bounds: Mapping[str, tuple[float, float]] | None = None
          ) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares coefficients of ``system`` and a mask of those stopped on a bound.

    Unbounded: an SVD least-squares solve of the column-scaled problem. With ``bounds``
    (name -> (lo, hi), missing names unbounded): scipy's bounded-variable least squares
    (``lsq_linear``, method ``bvls``), exact for this convex quadratic problem.
    """
    scale = _column_scale(system.A)
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
    scale = _column_scale(system.A)
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


def _autocorrelation(e: np.ndarray, max_lag: int) -> np.ndarray:
    """Sample autocorrelation of ``e`` for lags 0..max_lag (FFT)."""
    n = len(e)
    e = e - e.mean()
    nfft = 1 << (2 * n - 1).bit_length()
    f = np.fft.rfft(e, nfft)
    acov = np.fft.irfft(f * np.conj(f), nfft)[:max_lag + 1]
    return acov / acov[0] if acov[0] > 0 else np.zeros(max_lag + 1)


def correlation_time(e: np.ndarray) -> float:
    """Integrated autocorrelation time ``tau = 1 + 2 sum_k rho_k`` [samples], the sum taken up
    to the first non-positive ``rho_k`` (initial positive sequence); >= 1."""
    if len(e) < 4:
        return 1.0
    rho = _autocorrelation(e, min(len(e) - 1, max(10, len(e) // 4)))
    neg = np.flatnonzero(rho[1:] <= 0)
    k = int(neg[0]) if len(neg) else len(rho) - 1
    return max(1.0, 1.0 + 2.0 * float(np.sum(rho[1:k + 1])))


def _lag_window_meat(g: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """``S = sum_{|k|<=L} weights[|k|] sum_t g_t g_{t+k}'`` for ``g`` (n, p) and lag weights
    (L+1,) (FFT cross-covariances)."""
    n, p = g.shape
    lags = len(weights) - 1
    nfft = 1 << (n + lags).bit_length()
    G = np.fft.rfft(g, nfft, axis=0)
    S = np.empty((p, p))
    for i in range(p):
        for j in range(i, p):
            cc = np.fft.irfft(np.conj(G[:, i]) * G[:, j], nfft)  # cc[k] = sum_t g_i,t g_j,t+k
            pos = cc[:lags + 1]
            neg = cc[::-1][:lags]  # lags -1..-L
            s = weights[0] * pos[0] + np.dot(weights[1:], pos[1:]) + np.dot(weights[1:], neg)
            S[i, j] = S[j, i] = s
    return S


def _hac_meat(g: np.ndarray, lags: int) -> np.ndarray:
    """Newey-West ``S = sum_{|k|<=L} (1 - |k|/(L+1)) sum_t g_t g_{t-k}'``."""
    return _lag_window_meat(g, 1.0 - np.arange(lags + 1) / (lags + 1.0))


def flat_top_lag(g: np.ndarray, minimum: int = 1) -> int:
    """Politis' empirical bandwidth for the flat-top window on ``g`` (n, p) [samples]: the
    smallest ``m >= minimum`` after which ``K = max(5, sqrt(log10 n))`` consecutive
    autocorrelations of every column are below ``POLITIS_C sqrt(log10(n) / n)``; at most
    ``n / 8``."""
    n = len(g)
    cap = max(1, n // 8)
    if n < 16:
        return min(max(minimum, 1), cap)
    K = max(5, int(math.sqrt(math.log10(n))))
    thr = POLITIS_C * math.sqrt(math.log10(n) / n)
    m_hat = min(max(minimum, 1), cap)
    for j in range(g.shape[1]):
        rho = _autocorrelation(g[:, j], min(n - 1, cap + K))
        big = np.abs(rho) >= thr
        big[0] = True
        # first m with K insignificant autocorrelations after it
        run = np.convolve(big[1:].astype(float), np.ones(K), mode='valid')  # lags m+1..m+K
        ok = np.flatnonzero(run[m_hat:] == 0)
        m_j = m_hat + int(ok[0]) if len(ok) else cap
        m_hat = max(m_hat, min(m_j, cap))
    return m_hat


def _flat_top_meat(g: np.ndarray, m: int) -> np.ndarray:
    """Flat-top (trapezoid) lag window: weight 1 up to lag ``m``, ``2 - k/m`` to ``2 m``."""
    k = np.arange(2 * m + 1)
    return _lag_window_meat(g, np.clip(2.0 - k / m, 0.0, 1.0))


def _regressor_gradient(rec: ForceRecord, system: LinearSystem, theta: np.ndarray,
                        base: VehicleParams) -> np.ndarray:
    """``d/d nu`` of ``sum_k theta_k col_k + fixed`` (the model's hydrodynamic component)
    at every sample of ``rec`` (N, 6) [N or N m per m/s or rad/s], central differences."""
    coef = dict(zip(system.names, theta))
    coef.update(system.fixed)
    out = np.zeros((len(rec.t), 6))
    for c in range(6):
        h = 1e-6 * (1.0 + float(np.max(np.abs(rec.nu[:, c]))))
        up, dn = rec.nu.copy(), rec.nu.copy()
        up[:, c] += h
        dn[:, c] -= h
        cu = regressor_columns(system.equation, up, base)
        cd = regressor_columns(system.equation, dn, base)
        out[:, c] = sum(v * (cu[k] - cd[k]) for k, v in coef.items()) / (2.0 * h)
    return out


def sensor_noise_meat(system: LinearSystem, design: np.ndarray, resid: np.ndarray,
                      theta: np.ndarray, base: VehicleParams) -> tuple[np.ndarray, float] | None:
    """``S = Var(D'e)`` propagated from the white sensor noise (see :class:`NoisePropagation`)
    and the ratio of the observed to the predicted residual variance; None when a record
    has no noise model.

    With the equation's wrench component ``a``, noise ``n_c`` on state channel ``c`` gives
    ``e = M_ac (h * n_c) - kappa * (G_c n_c)``, ``G_c`` the sensitivity of the other wrenches
    plus the fitted hydrodynamic model; so ``D'e = sum_c sum_j n_c,j w_c,j`` with
    ``w_c = M_ac (h~ * d) - G_c (kappa * d)`` (``h~`` reversed, ``d`` the design rows, zero
    where unused) and ``S = sum_c sigma_c^2 w_c' w_c``.
    """
    p = design.shape[1]
    S = np.zeros((p, p))
    predicted = 0.0
    axis = system.equation.axis
    for i, rec in enumerate(system.records):
        sel = system.record_index == i
        if not np.any(sel):
            continue
        nm = rec.noise
        if nm is None or rec.kernel is None or system.rows is None:
            return None
        N = len(rec.t)
        rows = system.rows[sel]
        d = np.zeros((N, p))
        d[rows] = design[sel]
        kappa = rec.kernel
        h = nm.derivative_kernel
        kd = np.column_stack([np.convolve(d[:, j], kappa, mode='same') for j in range(p)])
        hd = np.column_stack([np.convolve(d[:, j], h[::-1], mode='same') for j in range(p)])
        G = nm.other_jacobian[:, axis, :].copy()
        G[:, 6:12] += _regressor_gradient(rec, system, theta, base)
        var_t = np.zeros(N)
        for c in range(12):
            sig = float(nm.sigma[c])
            if sig <= 0.0:
                continue
            m_ac = float(nm.mass[axis, c - 6]) if c >= 6 else 0.0
            w = m_ac * hd - G[:, c:c + 1] * kd
            S += sig ** 2 * (w.T @ w)
            # residual variance the noise predicts at each sample
            v = (np.convolve(G[:, c] ** 2, kappa ** 2, mode='same')
                 - 2.0 * m_ac * np.convolve(G[:, c], h * kappa, mode='same')
                 + m_ac ** 2 * float(h @ h))
            var_t += sig ** 2 * v
        predicted += float(np.sum(var_t[rows]))
    observed = float(resid @ resid)
    ratio = observed / predicted if predicted > 0 else math.inf
    return S, ratio


def _block_jackknife(design: np.ndarray, regressors: np.ndarray, b: np.ndarray,
                     blocks: int = JACKKNIFE_BLOCKS) -> tuple[np.ndarray, int]:
    """Delete-a-block jackknife covariance of ``theta = (D'A)^-1 D'b`` (D: design, A:
    regressors; D = A for least squares, the instrument projection for two-stage LS) over
    contiguous blocks of rows; returns it and the number of blocks."""
    n, p = design.shape
    blocks = int(max(2, min(blocks, n // max(10 * p, 1))))
    edges = np.linspace(0, n, blocks + 1).astype(int)
    G = design.T @ regressors
    h = design.T @ b
    thetas = np.empty((blocks, p))
    for k in range(blocks):
        sl = slice(edges[k], edges[k + 1])
        Gb = G - design[sl].T @ regressors[sl]
        hb = h - design[sl].T @ b[sl]
        thetas[k] = np.linalg.solve(Gb, hb)
    dev = thetas - thetas.mean(axis=0)
    return (blocks - 1.0) / blocks * (dev.T @ dev), blocks


#: Passes of a record's kernel that smooth the design before the noise propagation.
DESIGN_SMOOTHING_PASSES = 2


def _smoothed_design(system: LinearSystem, design: np.ndarray) -> np.ndarray | None:
    """The design with its noise filtered out, for the first-order (delta-method) covariance,
    which holds at the noise-free design: each record's rows low-passed by its kernel
    (normalised at the ends of the used rows); None if a record has no kernel."""
    out = np.empty_like(design)
    for i, rec in enumerate(system.records):
        sel = system.record_index == i
        if not np.any(sel):
            continue
        if rec.kernel is None or system.rows is None:
            return None
        rows = system.rows[sel]
        N = len(rec.t)
        mask = np.zeros(N)
        mask[rows] = 1.0
        d = np.zeros((N, design.shape[1]))
        d[rows] = design[sel]
        for _ in range(DESIGN_SMOOTHING_PASSES):
            norm = np.convolve(mask, rec.kernel, mode='same')
            d = np.column_stack([np.convolve(d[:, j], rec.kernel, mode='same')
                                 for j in range(d.shape[1])])
            d[rows] /= norm[rows, None]
            d[mask == 0] = 0.0
        out[sel] = d[rows]
    return out if system.records else None


def _hac_covariance(system: LinearSystem, As: np.ndarray, resid: np.ndarray,
                    theta: np.ndarray, base: VehicleParams, xtx_inv: np.ndarray,
                    taus: Sequence[tuple[int, int | np.integer[Any], float]]
                    ) -> tuple[np.ndarray, int, str, float]:
    """The ``'hac'`` sandwich ``(D'A)^-1 S (D'A)^-T`` of the column-scaled design ``As``
    (see the module docstring): ``S`` from the sensor-noise propagation when every record has
    a noise model that accounts for the residual, else from the flat-top lag window.

    Returns the covariance (scaled coefficients), the largest lag window used [samples] (0
    for the propagation), a description and the observed / predicted residual variance.
    """
    n, p = As.shape
    smooth = _smoothed_design(system, As)
    propagated = None if smooth is None else sensor_noise_meat(system, smooth, resid, theta,
                                                                base)
    ratio = math.nan
    if propagated is not None and smooth is not None:
        meat, ratio = propagated
        if ratio <= NOISE_RATIO_MAX:
            bread = np.linalg.inv(smooth.T @ (system.regressors / _column_scale(system.A)))
            return (bread @ meat @ bread.T, 0,
                    f'sensor-noise propagation (residual variance {ratio:.2f} x predicted)',
                    ratio)
    meat = np.zeros((p, p))
    lags = 0
    g = As * resid[:, None]
    for i, _m, _ in taus:
        sel = system.record_index == i
        rec = system.records[i] if system.records else None
        memory = len(rec.kernel) - 1 if rec is not None and rec.kernel is not None else 1
        m_i = flat_top_lag(g[sel], memory)
        part = _flat_top_meat(g[sel], m_i)
        if np.min(np.linalg.eigvalsh(part)) < 0.0:
            part = _hac_meat(g[sel], 2 * m_i)
        lags = max(lags, 2 * m_i)
        meat += part
    dof = max(n - p, 1)
    why = '' if math.isnan(ratio) else (
        f'; residual variance {ratio:.3g} x the sensor-noise prediction')
    return (xtx_inv @ meat @ xtx_inv * (n / dof), lags,
            f'flat-top lag window, {lags} lags{why}', ratio)


def fit_equation(system: LinearSystem, base: VehicleParams,
                 bounds: Mapping[str, tuple[float, float]] | None = None,
                 errors: str = 'hac', check: bool = True) -> EquationFit:
    """Solve one equation and compute its statistics (see module docstring)."""
    if errors not in ERROR_METHODS:
        raise IdentificationError(f'unknown standard-error method {errors!r} '
                                  f'(known: {", ".join(ERROR_METHODS)})')
    if check:
        check_identifiable(system)
    theta, at_bound = solve(system, bounds)
    A, b = system.A, system.b
    n, p = A.shape
    resid = b - system.regressors @ theta
    fitted = system.measured - resid
    scale = _column_scale(A)
    As = A / scale
    xtx_inv = np.linalg.inv(As.T @ As)
    dof = max(n - p, 1)
    sigma2 = float(resid @ resid) / dof
    # correlation times per record (the records are independent of each other)
    taus = []
    lags = 0
    for i in range(len(system.record_names)):
        sel = system.record_index == i
        if np.count_nonzero(sel) > 3:
            tau_i = correlation_time(resid[sel])
            taus.append((i, np.count_nonzero(sel), tau_i))
    n_eff = sum(m / t for _, m, t in taus) if taus else float(n)
    tdof = n_eff - p
    covariance = errors
    noise_ratio = math.nan
    if errors == 'iid':
        cov_s = sigma2 * xtx_inv
        n_eff = float(n)
    elif errors == 'ess':
        cov_s = sigma2 * xtx_inv * (n / n_eff)
    elif errors == 'jackknife':
        cov_s, blocks = _block_jackknife(As, system.regressors / scale, b)
        tdof = blocks - 1.0
    else:
        cov_s, lags, covariance, noise_ratio = _hac_covariance(system, As, resid, theta,
                                                              base, xtx_inv, taus)
    cov = cov_s / np.outer(scale, scale)
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    tq = float(stats.t.ppf(0.975, max(tdof, 1.0)))
    d = np.sqrt(np.diag(cov_s))
    corr = cov_s / np.outer(d, d) if np.all(d > 0) else np.eye(p)
    cond, _ = _conditioning(A)
    rng = float(np.ptp(system.measured)) if n else 0.0
    tss = float(np.sum((system.measured - system.measured.mean()) ** 2))
    rss = float(resid @ resid)
    rmse = math.sqrt(rss / n) if n else math.nan
    excited = _exciting_records(system)
    coefs = tuple(
        CoefficientEstimate(name=name, value=float(theta[k]), std_error=float(se[k]),
                            ci95=(float(theta[k] - tq * se[k]), float(theta[k] + tq * se[k])),
                            base=float(base.values[name]), at_bound=bool(at_bound[k]),
                            records=excited[name])
        for k, name in enumerate(system.names))
    return EquationFit(
        equation=system.equation, coefficients=coefs, fixed=dict(system.fixed),
        r2=1.0 - rss / tss if tss > 0 else math.nan,
        nrmse=rmse / rng if rng > 0 else math.nan, rmse=rmse, condition_number=cond,
        correlation=corr, n_samples=n, n_effective=float(n_eff), hac_lags=lags,
        errors=errors, t=system.t, measured=system.measured, fitted=fitted,
        record_index=system.record_index, record_names=system.record_names,
        covariance=covariance, noise_ratio=noise_ratio)


def _exciting_records(system: LinearSystem) -> dict[str, tuple[str, ...]]:
    """For each coefficient, the records whose own data pass its excitation test."""
    out: dict[str, tuple[str, ...]] = {}
    for name in system.names:
        exc = EXCITATION[name]
        names = []
        for i, rname in enumerate(system.record_names):
            x = system.excitation[system.record_index == i, exc.variable]
            if len(x) and excitation_amplitude(name, x) >= exc.threshold:
                names.append(rname)
        out[name] = tuple(dict.fromkeys(names))
    return out


def identify(records: Sequence[ForceRecord], base: VehicleParams, *,
             equations: Sequence[str] | None = None, fit_offsets: bool = False,
             bounds: Mapping[str, tuple[float, float]] | None = None,
             errors: str = 'hac') -> Identification:
    """Identify the coefficients of ``equations`` (default: all five) from ``records``.

    Every equation is fitted on all records pooled (each equation holds on every manoeuvre;
    the ones that do not excite a coefficient add little information, not bias).

    Args:
        records: force records (see :class:`ForceRecord`), one source for all.
        base: the vehicle the identified values replace (and the fixed CZ0/CM0 come from).
        equations: names from :data:`EQUATIONS`.
        fit_offsets: fit CZ0 and CM0 too (else fixed at the base values, as the report).
        bounds: name -> (lo, hi) for a bounded solve (e.g. :data:`SIGN_BOUNDS`).
        errors: standard-error method, one of :data:`ERROR_METHODS`.

    Raises:
        NotIdentifiableError: a coefficient lacks excitation or two cannot be separated.
        IdentificationError: bad records, unknown equation or option.
    """
    if not records:
        raise IdentificationError('no data: give at least one record')
    sources = {r.source for r in records}
    if len(sources) != 1:
        raise IdentificationError(f'records mix force sources {sorted(sources)}; use one')
    names = list(EQUATIONS) if equations is None else list(dict.fromkeys(equations))
    for name in names:
        if name not in EQUATIONS:
            raise IdentificationError(f'unknown equation {name!r} (known: {list(EQUATIONS)})')
    for key in (bounds or {}):
        if not any(key in (*e.coefficients, e.offset) for e in EQUATIONS.values()):
            raise IdentificationError(f'bound given for unknown coefficient {key!r}')
    fits: dict[str, EquationFit] = {}
    for name in names:
        system = build_system(records, EQUATIONS[name], base, fit_offsets)
        fits[name] = fit_equation(system, base, bounds, errors)
    values = {c.name: c.value for f in fits.values() for c in f.coefficients}
    try:
        params = base.replace(**values)
    except ValueError as exc:
        raise IdentificationError(f'identified values are not a valid vehicle: {exc}') from None
    return Identification(fits=fits, base=base, params=params, source=sources.pop(),
                          errors=errors, fit_offsets=fit_offsets, bounds=dict(bounds or {}))


def summary(result: Identification) -> dict[str, Any]:
    """A JSON-ready summary of ``result`` (the body of ``report.json``)."""
    eqs: dict[str, Any] = {}
    for name, fit in result.fits.items():
        eqs[name] = {
            'component': AXES[fit.equation.axis], 'unit': fit.equation.unit,
            'r2': fit.r2, 'nrmse': fit.nrmse, 'rmse': fit.rmse,
            'condition_number': fit.condition_number,
            'correlation': {'names': [c.name for c in fit.coefficients],
                            'matrix': fit.correlation.tolist()},
            'samples': fit.n_samples, 'effective_samples': fit.n_effective,
            'hac_lags': fit.hac_lags, 'covariance': fit.covariance,
            'noise_ratio': fit.noise_ratio if math.isfinite(fit.noise_ratio) else None,
            'fixed': fit.fixed, 'figure': fit.equation.figure,
        }
    coefs = {
        c.name: {'value': c.value, 'std_error': c.std_error, 'ci95': list(c.ci95),
                 'base': c.base,
                 'relative_change': (c.value - c.base) / c.base if c.base else None,
                 'at_bound': c.at_bound, 'records': list(c.records)}
        for c in result.coefficients.values()}
    return {'source': result.source, 'errors': result.errors, 'fit_offsets': result.fit_offsets,
            'bounds': {k: list(v) for k, v in result.bounds.items()},
            'coefficients': coefs, 'equations': eqs}


def compare_nelder_mead(records: Sequence[ForceRecord], result: Identification,
                        x0: Mapping[str, float] | None = None) -> dict[str, dict[str, Any]]:
    """Run the report's bounded Nelder-Mead on the same data as ``result`` and compare.

    For each equation: the least-squares and the Nelder-Mead coefficients, their largest
    relative difference and the two sums of squares. The search starts from ``x0`` (default:
    the base vehicle's values, as the report started from its prior values) and uses the
    bounds of ``result`` (unbounded coefficients get none).
    """
    out: dict[str, dict[str, Any]] = {}
    for name, fit in result.fits.items():
        system = build_system(records, fit.equation, result.base, result.fit_offsets)
        lsq = np.array([c.value for c in fit.coefficients])
        start = [(x0 or {}).get(c, result.base.values[c]) for c in system.names]
        nm = nelder_mead(system, start, result.bounds)
        rel = np.abs(nm - lsq) / np.maximum(np.abs(lsq), 1e-12)
        out[name] = {'names': list(system.names), 'least_squares': lsq.tolist(),
                     'nelder_mead': nm.tolist(), 'max_relative_difference': float(rel.max()),
                     'sum_of_squares_least_squares': system.sum_of_squares(lsq),
                     'sum_of_squares_nelder_mead': system.sum_of_squares(nm)}
    return out
