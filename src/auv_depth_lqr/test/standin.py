"""Test stand-in for the vehicle model: the report's linear model, scaled with speed.

Not a vehicle model. It lets the controller be tested before the nonlinear model exists.

Source: report section 4.3 (``z_dot = -u0 sin(theta) + w cos(theta)`` linearised at
u0 = 2 m/s), state ``(w, q, z, theta, xi)``, input BAR:

    A = [[-0.4375, -0.6383, 0,   0,      0],
         [ 0.2385, -1.1326, 0,  -0.0391, 0],
         [ 1,       0,      0,  -u0,     0],
         [ 0,       1,      0,   0,      0],
         [ 0,       0,      1,   0,      0]]
    B = [-0.1136, -0.0888, 0, 0, 0]'

Speed scaling (assumed, the usual slender-body scalings): hydrodynamic damping and Coriolis
terms ~ u0, so rows w and q of columns (w, q) scale as ``s = u0 / 2``; plane authority
~ u0^2, so B scales as ``s^2``; the restoring moment (-0.0391) does not depend on speed.
Trim (report section 4.4 at 2 m/s: theta_e = 0.00689 rad, BAR_e = -0.08367 rad): the
out-of-trim force is speed independent and balanced by hydrodynamic terms ~ u0^2, so
theta_e and BAR_e scale as ``1 / s^2``; ``w_e = u0 tan(theta_e)`` makes ``z_dot = 0``.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import scipy.integrate
import scipy.linalg
from numpy.typing import NDArray

from auv_depth_lqr.controller import DepthController, PlaneState

A_REPORT_4_3 = np.array([
    [-0.4375, -0.6383, 0.0, 0.0, 0.0],
    [0.2385, -1.1326, 0.0, -0.0391, 0.0],
    [1.0, 0.0, 0.0, -2.0, 0.0],
    [0.0, 1.0, 0.0, 0.0, 0.0],
    [0.0, 0.0, 1.0, 0.0, 0.0],
])
B_REPORT = np.array([[-0.1136], [-0.0888], [0.0], [0.0], [0.0]])
THETA_E_2 = 0.00689   # rad, report 4.4 at 2 m/s
BAR_E_2 = -0.08367    # rad, report 4.4 at 2 m/s


def linearize(u0: float) -> tuple[NDArray[np.float64], float, NDArray[np.float64],
                                  NDArray[np.float64]]:
    """Stand-in ``linearize(u0) -> (x_e, u_e, A, B)`` (see the module docstring)."""
    s = u0 / 2.0
    A = A_REPORT_4_3.copy()
    A[0:2, 0:2] *= s
    A[2, 3] = -u0
    B = B_REPORT * s**2
    theta_e = THETA_E_2 / s**2
    x_e = np.array([u0 * math.tan(theta_e), 0.0, 0.0, theta_e, 0.0])
    return x_e, BAR_E_2 / s**2, A, B


class Run(NamedTuple):
    """Closed-loop time series, one row per sample."""

    t: NDArray[np.float64]      # s
    z: NDArray[np.float64]      # m, down
    theta: NDArray[np.float64]  # rad
    w: NDArray[np.float64]      # m/s
    q: NDArray[np.float64]      # rad/s
    bar: NDArray[np.float64]    # rad, command held over [t, t + Ts)


def simulate(
    controller: DepthController,
    u0: float,
    z0: float,
    z_ref: float,
    duration: float,
    exact_kinematics: bool = True,
) -> Run:
    """Closed loop of ``controller`` with the stand-in plant at constant surge ``u0``.

    Plant: the stand-in's heave and pitch dynamics (linear about the trim at ``u0``),
    depth kinematics ``z_dot = -u0 sin(theta) + w cos(theta)`` if ``exact_kinematics``
    (else its linearisation); continuous, integrated with RK45 (rtol 1e-8) over each
    sample with the BAR command held (zero-order hold). Starts at trim at depth ``z0``.
    """
    x_e, bar_e, A, B = linearize(u0)
    ts = controller.Ts
    n = int(round(duration / ts))
    x = np.array([x_e[0], 0.0, z0, x_e[3]])  # w, q, z, theta
    out = np.zeros((n, 6))

    def f(_t: float, s: NDArray[np.float64], bar: float) -> NDArray[np.float64]:
        dx = s - x_e[:4]
        acc = A[0:2, 0:4] @ dx + B[0:2, 0] * (bar - bar_e)
        if exact_kinematics:
            z_dot = -u0 * math.sin(s[3]) + s[0] * math.cos(s[3])
        else:
            z_dot = float(A[2, 0:4] @ dx)
        return np.array([acc[0], acc[1], z_dot, s[1]])

    for k in range(n):
        bar = controller.step(PlaneState(z=x[2], theta=x[3], w=x[0], q=x[1], u=u0), z_ref)
        out[k] = (k * ts, x[2], x[3], x[0], x[1], bar)
        sol = scipy.integrate.solve_ivp(f, (0.0, ts), x, args=(bar,), rtol=1e-8, atol=1e-10)
        x = sol.y[:, -1]
    return Run(*(out[:, i].copy() for i in range(6)))


def settling_time(t: NDArray[np.float64], z: NDArray[np.float64], z_ref: float,
                  band: float) -> float:
    """First time after which ``|z - z_ref| <= band`` for good [s]."""
    outside = np.nonzero(np.abs(z - z_ref) > band)[0]
    if outside.size == 0:
        return float(t[0])
    if outside[-1] + 1 >= t.size:
        return math.inf
    return float(t[outside[-1] + 1])


def discrete_plant(u0: float, ts: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """ZOH discretisation of the stand-in (all 5 states) at ``u0``, for pole checks."""
    _, _, A, B = linearize(u0)
    M = np.zeros((6, 6))
    M[:5, :5], M[:5, 5:] = A, B
    E = scipy.linalg.expm(M * ts)
    return E[:5, :5], E[:5, 5:]
