"""Compiled kernels of the gap diagnosis: actuator series, free runs and equation errors.

The nominal physics is the vehicle model of :mod:`auv_sim.model` (its wrench kernel and its
kinematics, with calm water). Everything a candidate effect adds is implemented here, apart
from the simulator's effect code, through four primitives (see
:class:`auv_ident.gap.catalogue.Perturbation`):

* water current: a constant current ``v_c`` in NED [m/s]. The model is evaluated at the
  velocity through the water ``nu_r = nu - (R^T v_c, 0)`` for every term (Fossen 2011,
  property 8.1: for a constant, irrotational current the rigid-body and added-mass terms
  written in ``nu_r`` are exact), so ``M nu_r_dot = tau(nu_r)`` and, since
  ``d/dt (R^T v_c) = -omega x R^T v_c``, ``nu_dot = nu_r_dot - omega x (R^T v_c)``;
* an extra body wrench ``sum_j phi_j(x) C[j, :]`` over the basis functions :func:`basis`;
* actuator dynamics (transport delay, first-order lag, rate limit, angle limit), integrated
  from the logged commands apart from the vehicle (actuators do not feel the vehicle);
* measurement biases, applied outside the kernels (initial state and outputs).

Frames: NED world, FRD body, origin at the centre of buoyancy; SI units, radians. The state
layout is :data:`auv_sim.model.STATE_NAMES` (15: eta, nu, bar, helm, thrust).
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from auv_sim.model import ENV_SIZE, I_KSH, I_MINV, kinematics, rotation, wrenches

#: Basis functions of the extra wrench, in :func:`basis` order (dimension given per row).
BASIS_NAMES = (
    'one',                      # 1
    'gx', 'gy', 'gz',           # gravity direction in body FRD: (-s_th, c_th s_ph, c_th c_ph)
    'z_gx', 'z_gy', 'z_gz',     # depth [m] times the gravity direction
    'ur|ur|',                   # [m^2/s^2], surge speed through the water
    'wr|wr|', 'q|q|', 'vr|vr|', 'r|r|',  # cross-flow quadratic terms
    'ur wr', 'ur q',            # [m^2/s^2], [m/s^2]: the model's own heave/pitch damping terms
    'ur|ur| bar',               # [m^2/s^2 rad]: the dive plane's lift (plane position x[12])
    'thrust',                   # [N]: the propeller's thrust (position x[14])
    'surge_drag/Ksh',           # [N]: the model's surge drag per unit of its Ksh
)
NB = len(BASIS_NAMES)
B_ONE, B_G, B_ZG, B_UU, B_WW, B_QQ, B_VV, B_RR = 0, 1, 4, 7, 8, 9, 10, 11
B_UW, B_UQ, B_UUBAR, B_THRUST, B_XDRAG = 12, 13, 14, 15, 16
OUT_STATES = 12  # eta and nu are written out


@njit(cache=True)
def basis(x, xr, phi):  # type: ignore[no-untyped-def]
    """Fill ``phi`` (NB) at state ``x`` (over ground) and ``xr`` (velocities through water)."""
    sth = np.sin(x[4])
    cth = np.cos(x[4])
    sph = np.sin(x[3])
    cph = np.cos(x[3])
    gx = -sth
    gy = cth * sph
    gz = cth * cph
    z = x[2]
    phi[0] = 1.0
    phi[1] = gx
    phi[2] = gy
    phi[3] = gz
    phi[4] = z * gx
    phi[5] = z * gy
    phi[6] = z * gz
    phi[7] = xr[6] * abs(xr[6])
    phi[8] = xr[8] * abs(xr[8])
    phi[9] = x[10] * abs(x[10])
    phi[10] = xr[7] * abs(xr[7])
    phi[11] = x[11] * abs(x[11])
    phi[12] = xr[6] * xr[8]
    phi[13] = xr[6] * x[10]
    phi[14] = xr[6] * abs(xr[6]) * x[12]
    phi[15] = x[14]
    phi[16] = 0.0  # set by model_wrench from the model's own surge drag


@njit(cache=True)
def current_body(x, cur, out):  # type: ignore[no-untyped-def]
    """``out`` (3) = R(eta)^T cur: an NED current [m/s] in body FRD axes."""
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = rotation(
        np.cos(x[3]), np.sin(x[3]), np.cos(x[4]), np.sin(x[4]), np.cos(x[5]), np.sin(x[5]))
    out[0] = r00 * cur[0] + r10 * cur[1] + r20 * cur[2]
    out[1] = r01 * cur[0] + r11 * cur[1] + r21 * cur[2]
    out[2] = r02 * cur[0] + r12 * cur[1] + r22 * cur[2]


@njit(cache=True)
def model_wrench(x, cur, C, P, env0, prof0, xr, work, phi, ncb, tau):  # type: ignore
    """Total wrench ``tau`` (6) [N, N m] at state ``x`` (actuator positions in x[12:15]).

    Also leaves ``nu_c`` in body axes in ``ncb`` (3) and the through-water state in ``xr``.
    """
    for i in range(15):
        xr[i] = x[i]
    current_body(x, cur, ncb)
    xr[6] -= ncb[0]
    xr[7] -= ncb[1]
    xr[8] -= ncb[2]
    wrenches(0.0, xr, P, env0, prof0, work)
    basis(x, xr, phi)
    if P[I_KSH] != 0.0:
        phi[B_XDRAG] = work[0, 0] / P[I_KSH]
    for i in range(6):
        acc = work[0, i] + work[1, i] + work[2, i] + work[3, i]
        for j in range(NB):
            acc += phi[j] * C[j, i]
        tau[i] = acc


@njit(cache=True)
def _rhs(x, cur, C, P, env0, prof0, xdot, xr, work, phi, ncb, tau):  # type: ignore
    model_wrench(x, cur, C, P, env0, prof0, xr, work, phi, ncb, tau)
    kinematics(x, xdot)
    for i in range(6):
        acc = 0.0
        for j in range(6):
            acc += P[I_MINV + 6 * i + j] * tau[j]
        xdot[6 + i] = acc
    # nu_dot = nu_r_dot - omega x nu_c (constant NED current seen from the turning body)
    p = x[9]
    q = x[10]
    r = x[11]
    xdot[6] -= q * ncb[2] - r * ncb[1]
    xdot[7] -= r * ncb[0] - p * ncb[2]
    xdot[8] -= p * ncb[1] - q * ncb[0]
    xdot[12] = 0.0
    xdot[13] = 0.0
    xdot[14] = 0.0


@njit(cache=True)
def actuator_series(t0, h, n, stamps, values, delay, tau, rate, lo, hi, a0):  # type: ignore
    """Actuator position at ``t0 + j h`` (j < n) driven by logged commands.

    Commands are held from their stamp plus ``delay`` [s] (zero-order hold; the command before
    the first stamp is the first one); the position follows
    ``a_dot = clip((clip(c, lo, hi) - a) / tau, -rate, rate)``. Over each step the command is
    averaged exactly (a switch inside a step moves the result continuously with the delay),
    the lag is integrated exactly and the rate limit caps each step's change at ``rate h``.
    """
    out = np.empty(n)
    a = a0
    out[0] = a
    m = stamps.shape[0]
    k = 0  # commands with stamp + delay <= current time are in effect: index of next one
    ta = t0
    while k < m and stamps[k] + delay <= ta:
        k += 1
    decay = np.exp(-h / tau)
    for j in range(1, n):
        tb = t0 + j * h
        # exact mean of the held, clipped command over [ta, tb]
        cur_v = values[k - 1] if k > 0 else values[0]
        cur_v = min(max(cur_v, lo), hi)
        acc = 0.0
        t_prev = ta
        while k < m and stamps[k] + delay <= tb:
            ts = stamps[k] + delay
            acc += cur_v * (ts - t_prev)
            t_prev = ts
            cur_v = min(max(values[k], lo), hi)
            k += 1
        acc += cur_v * (tb - t_prev)
        c = acc / h
        step = (c - a) * (1.0 - decay)
        lim = rate * h
        if step > lim:
            step = lim
        elif step < -lim:
            step = -lim
        a += step
        out[j] = a
        ta = tb
    return out


@njit(parallel=True, cache=True)
def free_run_batch(P, X0, act, fine_base, nsamp, out_base, cur, C, dt, sub, out):  # type: ignore
    """Free runs of ``nc`` model variants over ``nw`` windows, in parallel.

    ``X0`` (nc, nw, 15) initial states; ``act`` (nc, F, 3) actuator positions on the fine grid
    of half integration steps (``dt / 2``), window ``w`` starting at ``fine_base[w]``;
    ``nsamp[w]`` output samples spaced ``sub`` RK4 steps of ``dt`` [s]; ``cur`` (nc, 3) NED
    current [m/s]; ``C`` (nc, NB, 6) extra-wrench coefficients. Fills ``out`` (nc, S, 12) at
    rows ``out_base[w]...``; a run that turns non-finite leaves NaN from there on.
    """
    nc = X0.shape[0]
    nw = X0.shape[1]
    env0 = np.zeros(ENV_SIZE)
    prof0 = np.zeros((0, 4))
    for job in prange(nc * nw):
        c = job // nw
        w = job % nw
        x = X0[c, w].copy()
        k1 = np.empty(15)
        k2 = np.empty(15)
        k3 = np.empty(15)
        k4 = np.empty(15)
        xt = np.empty(15)
        xr = np.empty(15)
        work = np.empty((4, 6))
        phi = np.empty(NB)
        ncb = np.empty(3)
        tau = np.empty(6)
        cw = C[c]
        cu = cur[c]
        base = fine_base[w]
        row = out_base[w]
        for i in range(OUT_STATES):
            out[c, row, i] = x[i]
        bad = False
        for s in range(1, nsamp[w]):
            if not bad:
                for m in range(sub):
                    f = base + 2 * ((s - 1) * sub + m)
                    for i in range(3):
                        x[12 + i] = act[c, f, i]
                    _rhs(x, cu, cw, P, env0, prof0, k1, xr, work, phi, ncb, tau)
                    for i in range(15):
                        xt[i] = x[i] + 0.5 * dt * k1[i]
                    for i in range(3):
                        xt[12 + i] = act[c, f + 1, i]
                    _rhs(xt, cu, cw, P, env0, prof0, k2, xr, work, phi, ncb, tau)
                    for i in range(15):
                        xt[i] = x[i] + 0.5 * dt * k2[i]
                    for i in range(3):
                        xt[12 + i] = act[c, f + 1, i]
                    _rhs(xt, cu, cw, P, env0, prof0, k3, xr, work, phi, ncb, tau)
                    for i in range(15):
                        xt[i] = x[i] + dt * k3[i]
                    for i in range(3):
                        xt[12 + i] = act[c, f + 2, i]
                    _rhs(xt, cu, cw, P, env0, prof0, k4, xr, work, phi, ncb, tau)
                    for i in range(12):
                        x[i] = x[i] + dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
                for i in range(12):
                    if not np.isfinite(x[i]) or abs(x[i]) > 1e9:
                        bad = True
            for i in range(OUT_STATES):
                out[c, row + s, i] = np.nan if bad else x[i]


@njit(cache=True)
def equation_terms(X, cur, C, P):  # type: ignore[no-untyped-def]
    """Model wrench and current turn term at N logged states ``X`` (N x 15, actuators set).

    Returns ``tau`` (N x 6) [N, N m], the total wrench of the model through the water, and
    ``oxc`` (N x 3) [m/s^2], ``omega x (R^T v_c)``: the equation error is then
    ``M (nu_dot + (oxc, 0)) - tau``.
    """
    n = X.shape[0]
    tau_out = np.empty((n, 6))
    oxc = np.empty((n, 3))
    env0 = np.zeros(ENV_SIZE)
    prof0 = np.zeros((0, 4))
    xr = np.empty(15)
    work = np.empty((4, 6))
    phi = np.empty(NB)
    ncb = np.empty(3)
    tau = np.empty(6)
    for k in range(n):
        x = X[k]
        model_wrench(x, cur, C, P, env0, prof0, xr, work, phi, ncb, tau)
        for i in range(6):
            tau_out[k, i] = tau[i]
        p = x[9]
        q = x[10]
        r = x[11]
        oxc[k, 0] = q * ncb[2] - r * ncb[1]
        oxc[k, 1] = r * ncb[0] - p * ncb[2]
        oxc[k, 2] = p * ncb[1] - q * ncb[0]
    return tau_out, oxc
