"""Records for the regressions: one uniformly sampled stretch of a log with its hydrodynamic
wrench (from the force topic or reconstructed from the motion) and, for forces from motion,
how white sensor noise propagates into that wrench."""
from __future__ import annotations

import dataclasses

import numpy as np

from auv_ident.errors import IdentificationError


@dataclasses.dataclass(frozen=True)
class NoisePropagation:
    """How white sensor noise on the logged state enters a wrench reconstructed from motion.

    The reconstruction is ``tau = M (h * nu) - kappa * tau_other(x)`` (``*``: convolution)
    with the Savitzky-Golay derivative weights ``h`` and the consistent low-pass ``kappa``
    (:attr:`ForceRecord.kernel`); noise ``n`` on the state ``x`` changes it, to first order,
    by ``M (h * n_nu) - kappa * (J n)`` with ``J`` the Jacobian of ``tau_other``.

    Attributes
    ----------
    sigma
        (12,) standard deviation of the white noise on each logged state channel
        ``x, y, z [m], phi, theta, psi [rad], u, v, w [m/s], p, q, r [rad/s]``.
    other_jacobian
        (N, 6, 12) ``d tau_other / d x`` at every sample (body FRD wrench
        [N, N m] per unit of each state channel), ``tau_other`` = Coriolis + restoring +
        actuator wrench.
    mass
        (6, 6) mass matrix ``M`` (rigid body plus added mass) [kg, kg m, kg m^2].
    derivative_kernel
        (window,) convolution weights ``h`` of the derivative [1/s].
    """

    sigma: np.ndarray
    other_jacobian: np.ndarray
    mass: np.ndarray
    derivative_kernel: np.ndarray


#: Logged state channels (NED/FRD) in the order of ``/auv/state``.
STATE_NAMES = ('x', 'y', 'z', 'phi', 'theta', 'psi', 'u', 'v', 'w', 'p', 'q', 'r')
Series = tuple[np.ndarray, np.ndarray]


@dataclasses.dataclass(frozen=True)
class LoggedRun:
    """What a free run of a model against one stretch of a log needs: the logged state,
    the commands (and measured fin positions) that drive the actuators, and which state
    channels were measured (the others were derived from them or assumed by an import, and
    are not scored against).

    Attributes
    ----------
    t
        stamps (N,) [s].
    state
        (N, 12) ``x, y, z [m] NED, phi, theta, psi [rad], u, v, w [m/s], p, q, r
        [rad/s]`` body FRD, as logged.
    commands
        ``bar``/``helm``/``thrust`` -> (stamps [s], set-points [rad, rad, N]).
    measured
        measured fin positions ``bar``/``helm`` -> (stamps [s], angles [rad]).
    origins
        state channel -> ``measured``, ``derived`` or ``assumed``.
    """

    t: np.ndarray
    state: np.ndarray
    commands: dict[str, Series]
    measured: dict[str, Series] = dataclasses.field(default_factory=dict)
    origins: dict[str, str] = dataclasses.field(default_factory=dict)

    def is_measured(self, channel: str) -> bool:
        """The channel was logged by a sensor (not derived, not assumed)."""
        return self.origins.get(channel, 'measured') == 'measured'


@dataclasses.dataclass(frozen=True)
class ForceRecord:
    """One continuous, uniformly sampled stretch of a log, ready for the regressions.

    Attributes
    ----------
    name
        where it comes from (bag name), for reports and provenance.
    t
        header stamps (N,) [s].
    nu
        body-FRD velocities (N, 6) ``u, v, w [m/s], p, q, r [rad/s]`` as logged.
    tau
        hydrodynamic wrench (N, 6) body FRD ``X, Y, Z [N], K, M, N [N m]``; NaN rows are
        not used (the ends of a filtered record).
    source
        ``'forces'`` (the /auv/hydrodynamic_forces topic) or ``'motion'``
        (reconstructed from the logged motion, see :mod:`auv_ident.motion`).
    kernel
        FIR weights (odd length, sum 1) already applied to ``tau``; the regressors are
        filtered with the same weights so the filtered equation stays exact. None: no
        filtering.
    noise
        how sensor noise propagates into ``tau`` (forces from motion), for the
        standard errors; None: unknown.
    saturated
        (N, 3) whether the rebuilt BAR, helm and thrust sit at their limits
        (forces from motion; for the identifiability diagnosis), or None.
    actuators
        per channel, where the actuator positions came from.
    """

    name: str
    t: np.ndarray
    nu: np.ndarray
    tau: np.ndarray
    source: str = 'forces'
    kernel: np.ndarray | None = None
    noise: NoisePropagation | None = None
    #: (N, 3) the rebuilt BAR, helm and thrust at their limits (forces from motion), or None
    saturated: np.ndarray | None = None
    #: which actuator positions were used, per channel (``bar``: ``measured fin position`` or
    #: ``command through the actuator model``); empty: not said
    actuators: dict[str, str] = dataclasses.field(default_factory=dict)
    #: (N, 6) the dive plane's wrench per unit coefficient (``CZbar`` on Z [N], ``CMbar`` on
    #: M [N m]; zero elsewhere), filtered like ``tau``, which excludes the plane's wrench
    #: (forces from motion); None: not available (the force topic)
    plane_unit: np.ndarray | None = None
    #: the logged state and commands of the record, for free runs (validation, output
    #: error); None: the log had no commands
    log: LoggedRun | None = None


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
