"""Trim and linearisation of the vertical plane (report sections 3.4-3.8), on the 6-DOF model.

The vertical-plane model holds the forward speed at ``u0`` (a speed loop does) and keeps
``v = p = r = phi = psi = 0``. Its states are ``X = (w, q, z, theta, int(z - z_ref))``
[m/s, rad/s, m, rad, m s] and its input is the dive-plane angle BAR [rad]::

    [w_dot, q_dot] = M_wq^-1 [Z, M]      (heave and pitch of the 6-DOF wrench, report 3.5)
    z_dot          = -u0 sin(theta) + w cos(theta)     ('full', the correct NED kinematics)
                     or w                               ('w', the report's section 4.2 model)
    theta_dot      = q,     d/dt int(z - z_ref) = z - z_ref

with ``M_wq`` the heave-pitch block of ``M = M_RB + M_A``. The forces come from the same
compiled kernel as the simulator (:func:`auv_sim.model.wrenches`), so trim and simulator agree
by construction of the physics, not by a second copy of it. Jacobians are complex-step
derivatives: exact to rounding, no step-size trade-off.
"""
from __future__ import annotations

import dataclasses
import importlib
from typing import Any, Literal

import numpy as np

from auv_sim.disk_cache import cached
from auv_sim.environment import Environment
from auv_sim.errors import TrimError
from auv_sim.model import NX, current_ned, rotation, wrenches
from auv_sim.params import VehicleParams, mass_matrix

Kinematics = Literal['full', 'w']
VERTICAL_STATES = ('w', 'q', 'z', 'theta', 'int_z')
_H = 1e-30  # complex step


@dataclasses.dataclass(frozen=True)
class Trim:
    """A vertical-plane equilibrium at forward speed ``u0`` [m/s] and depth ``z`` [m].

    ``w`` [m/s], ``theta`` [rad] (positive nose up), ``bar`` [rad], ``thrust`` [N] that holds
    ``u0``; ``q = 0``. ``kinematics`` names the depth kinematics it was solved with.
    """

    u0: float
    z: float
    w: float
    theta: float
    bar: float
    thrust: float
    kinematics: str

    def state(self, environment: Environment | None = None, psi: float = 0.0) -> np.ndarray:
        """The full 15-state vector of the simulator at this trim (x = y = 0, yaw ``psi``
        [rad]).

        The trim's velocities are through the water. With an ``environment``, the water's
        current at the trim depth at t = 0 (NED [m/s], turned into the body frame) is added,
        so that the state is over ground and the vehicle starts trimmed in the water it is
        in, with no surge transient.
        """
        x = np.zeros(NX)
        x[2], x[4], x[5], x[6], x[8], x[12], x[14] = self.z, self.theta, psi, self.u0, \
            self.w, self.bar, self.thrust
        if environment is not None:
            # evaluated once: the compiled functions' Python form (the same code, the same
            # numbers), so that a start does not wait ~0.3 s of CPU for numba's target
            # initialisation to evaluate them once
            c = np.array(current_ned.py_func(  # type: ignore[no-untyped-call]  # the kernel's
                0.0, float(self.z), environment.env_vector(), environment.profile())[:3],
                dtype=np.float64)
            R = np.array(rotation.py_func(  # type: ignore[no-untyped-call]  # the kernel's
                1.0, 0.0, np.cos(self.theta), np.sin(self.theta), np.cos(psi), np.sin(psi)),
                dtype=np.float64).reshape(3, 3)
            x[6:9] += R.T @ c
        return x


class VerticalPlane:
    """The vertical-plane model of one vehicle in one environment (see module docstring)."""

    def __init__(self, params: VehicleParams, environment: Environment | None = None) -> None:
        env = environment or Environment()
        self.params = env.apply_to(params)
        self._p = self.params.as_array()
        self._env = env.env_vector()
        self._prof = env.profile()
        m = mass_matrix(self.params)
        self._mwq_inv = np.linalg.inv(m[np.ix_([2, 4], [2, 4])])

    def warm_up(self) -> None:
        """Load what a trim and a force evaluation need, so that a later call (in a control
        step) does not pay for it: SciPy's root finder (imported where a trim is solved) and
        the compiled force kernel for complex states (numba's target initialisation at a
        process's first call); ~0.5-1 s of CPU, once per process."""
        importlib.import_module('scipy.optimize')
        self.wrench(self.full_state(0.0, 0.0, 0.0, 0.0, 0.0, 1.0))

    def full_state(self, w: complex, q: complex, z: complex, theta: complex, bar: complex,
                   u0: float, thrust: complex = 0.0) -> np.ndarray:
        x = np.zeros(NX, dtype=np.complex128)
        x[2], x[4], x[6], x[8], x[10], x[12], x[14] = z, theta, u0, w, q, bar, thrust
        return x

    def wrench(self, x: np.ndarray) -> np.ndarray:
        """Total body wrench (6) [N, N m] at the full state x (complex allowed)."""
        out = np.zeros((4, 6), dtype=x.dtype)
        wrenches(0.0, x, self._p, self._env, self._prof, out)
        total: np.ndarray = out.sum(axis=0)
        return total

    def rates(self, X: np.ndarray, bar: complex, u0: float, z_ref: float = 0.0,
              kinematics: Kinematics = 'full') -> np.ndarray:
        """``X_dot`` (5) of the vertical-plane model at ``X = (w, q, z, theta, int_z)``."""
        w, q, z, theta = X[0], X[1], X[2], X[3]
        f = self.wrench(self.full_state(w, q, z, theta, bar, u0))
        wq_dot = self._mwq_inv @ np.array([f[2], f[4]])
        z_dot = w if kinematics == 'w' else -u0 * np.sin(theta) + w * np.cos(theta)
        return np.array([wq_dot[0], wq_dot[1], z_dot, q, z - z_ref])

    def trim(self, u0: float, z: float = 0.0, kinematics: Kinematics = 'full') -> Trim:
        """Equilibrium at speed ``u0`` [m/s] and depth ``z`` [m]: ``w_dot = q_dot = z_dot = 0``.

        Unknowns (w, theta, BAR) for 'full' kinematics; (theta, BAR) with w = 0 for 'w'.
        Raises TrimError when no equilibrium exists within the plane's angle limit.
        """
        # scipy.optimize only where a trim is solved: importing it costs a node's start
        # ~0.5 s of CPU (it loads scipy.linalg, scipy.special and their docstring parsing)
        from scipy import optimize

        if not np.isfinite(u0) or abs(u0) < 1e-3:
            raise TrimError(f'trim needs a forward speed, got u0 = {u0} m/s')

        def residual(v: np.ndarray) -> np.ndarray:
            if kinematics == 'w':
                w, theta, bar = 0.0 * v[0], v[0], v[1]
            else:
                w, theta, bar = v[0], v[1], v[2]
            X = np.array([w, 0.0 * w, z + 0.0 * w, theta, 0.0 * w])
            rates = self.rates(X, bar, u0, z_ref=z, kinematics=kinematics)
            return rates[:3] if kinematics == 'full' else rates[:2]

        def jac(v: np.ndarray) -> np.ndarray:
            n = v.size
            out = np.empty((n, n))
            for j in range(n):
                vc = v.astype(np.complex128)
                vc[j] += 1j * _H
                out[:, j] = residual(vc).imag / _H
            return out

        v0 = np.zeros(2 if kinematics == 'w' else 3)
        sol = optimize.root(lambda v: residual(v).real, v0, jac=jac, method='hybr')
        v = sol.x
        for _ in range(3):  # polish with Newton steps on the exact Jacobian
            v = v - np.linalg.solve(jac(v), residual(v).real)
        if not np.all(np.isfinite(v)) or np.max(np.abs(residual(v).real)) > 1e-10:
            raise TrimError(f'no trim found at u0 = {u0} m/s, z = {z} m: {sol.message}')
        sol.x = v
        if kinematics == 'w':
            w, theta, bar = 0.0, float(sol.x[0]), float(sol.x[1])
        else:
            w, theta, bar = (float(s) for s in sol.x)
        if abs(bar) > self.params.bar_max:
            raise TrimError(f'trim at u0 = {u0} m/s needs BAR = {bar:.4f} rad, beyond the '
                            f'plane limit {self.params.bar_max:.4f} rad')
        thrust = -float(self.wrench(self.full_state(w, 0.0, z, theta, bar, u0)).real[0])
        return Trim(u0=float(u0), z=float(z), w=w, theta=theta, bar=bar, thrust=thrust,
                    kinematics=kinematics)

    def linearize(self, trim: Trim, kinematics: Kinematics | None = None,
                  ) -> tuple[np.ndarray, np.ndarray]:
        """``(A, B)`` of the vertical-plane model at ``trim``: complex-step Jacobians.

        A is 5 x 5 over ``(w, q, z, theta, int_z)``, B is 5 x 1 for BAR. ``kinematics``
        defaults to the one the trim was solved with.
        """
        kin: Kinematics = kinematics or trim.kinematics  # type: ignore[assignment]
        X0 = np.array([trim.w, 0.0, trim.z, trim.theta, 0.0], dtype=np.complex128)
        A = np.empty((5, 5))
        for j in range(5):
            X = X0.copy()
            X[j] += 1j * _H
            A[:, j] = self.rates(X, trim.bar, trim.u0, z_ref=trim.z, kinematics=kin).imag / _H
        B = (self.rates(X0, trim.bar + 1j * _H, trim.u0, z_ref=trim.z, kinematics=kin).imag
             / _H).reshape(5, 1)
        return A, B


TRIM_KIND = 'trim'
"""Kind (file prefix) of the trims kept in the disk cache (:func:`cached_trim`)."""


def _trim_from_data(data: dict[str, Any]) -> Trim:
    """A :class:`Trim` from its fields as stored; ValueError unless every number is finite."""
    numbers = {name: data[name] for name in ('u0', 'z', 'w', 'theta', 'bar', 'thrust')}
    if not all(isinstance(v, float) and np.isfinite(v) for v in numbers.values()) \
            or data['kinematics'] not in ('full', 'w'):
        raise ValueError('not a whole trim')
    return Trim(**numbers, kinematics=data['kinematics'])


def cached_trim(params: VehicleParams, u0: float, z: float = 0.0,
                kinematics: Kinematics = 'full') -> Trim:
    """``VerticalPlane(params).trim(u0, z, kinematics)``, kept in the disk cache.

    The same trim, number for number, without the solve (and SciPy's import) at a start
    whose vehicle, speed and depth were trimmed before (:mod:`auv_sim.disk_cache`: keyed by
    the vehicle's parameters as loaded, ``u0`` [m/s], ``z`` [m], the kinematics and the
    source of ``auv_sim``).

    Parameters
    ----------
    params : VehicleParams
        The vehicle (in still water, no environment).
    u0 : float
        Forward speed [m/s].
    z : float
        Depth [m, NED down].
    kinematics : {'full', 'w'}
        The depth kinematics (see :meth:`VerticalPlane.trim`).

    Returns
    -------
    Trim
        The equilibrium.

    Raises
    ------
    TrimError
        No equilibrium within the plane's angle limit (nothing is cached).
    """
    inputs = {'vehicle': {k: float(v) for k, v in sorted(params.values.items())},
              'u0': float(u0), 'z': float(z), 'kinematics': kinematics}
    return cached(TRIM_KIND, inputs, ('auv_sim',),
                  lambda: VerticalPlane(params).trim(u0, z=z, kinematics=kinematics),
                  dataclasses.asdict, _trim_from_data)
