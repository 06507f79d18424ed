"""Compiled kernels of the gap diagnosis: actuator series, free runs and equation errors.

The physics is the vehicle model of :mod:`auv_sim.model`: its wrench kernel (with the
water current of the model's environment vector: constant, linear shear with depth, linear
drift in time, handled exactly as the simulator handles them) and its kinematics. What a
candidate effect adds beyond the environment vector is implemented here, apart from the
simulator's effect code, through these primitives (see
:class:`auv_ident.gap.catalogue.Perturbation`):

* the model's environment vector (current terms) and its parameter vector (coefficients
  scaled by a candidate, the mass matrix with them);
* an extra body wrench ``sum_j phi_j(x) C[j, :]`` over the basis functions :func:`basis`;
* actuator dynamics (transport delay, first-order lag, rate limit, angle limit), integrated
  from the logged commands apart from the vehicle (actuators do not feel the vehicle);
* sensor bias, scale and latency, applied outside the kernels (initial state and outputs).

Frames: NED world, FRD body, origin at the centre of buoyancy; SI units, radians. The state
layout is :data:`auv_sim.model.STATE_NAMES` (15: eta, nu, bar, helm, thrust).
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from auv_sim.model import I_KSH, I_MINV, current_ned, kinematics, rotation, wrenches

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
def model_wrench(t, x, env, C, P, prof0, xr, work, phi, tau):  # type: ignore
    """Total wrench ``tau`` (6) [N, N m] at time ``t`` [s] and state ``x`` (over ground,
    actuator positions in x[12:15]): the model's wrenches in the water of ``env`` plus the
    extra wrench of ``C``. Leaves the through-water state in ``xr``."""
    for i in range(15):
        xr[i] = x[i]
    vcn, vce, vcd, _, _, _, _, _, _ = current_ned(t, x[2], env, prof0)
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = rotation(
        np.cos(x[3]), np.sin(x[3]), np.cos(x[4]), np.sin(x[4]), np.cos(x[5]), np.sin(x[5]))
    xr[6] -= r00 * vcn + r10 * vce + r20 * vcd
    xr[7] -= r01 * vcn + r11 * vce + r21 * vcd
    xr[8] -= r02 * vcn + r12 * vce + r22 * vcd
    wrenches(t, x, P, env, prof0, work)
    basis(x, xr, phi)
    if P[I_KSH] != 0.0:
        phi[B_XDRAG] = work[0, 0] / P[I_KSH]
    for i in range(6):
        acc = work[0, i] + work[1, i] + work[2, i] + work[3, i]
        for j in range(NB):
            acc += phi[j] * C[j, i]
        tau[i] = acc


@njit(cache=True)
def _rhs(t, x, env, C, P, prof0, xdot, xr, work, phi, tau):  # type: ignore
    model_wrench(t, x, env, C, P, prof0, xr, work, phi, tau)
    kinematics(x, xdot)
    for i in range(6):
        acc = 0.0
        for j in range(6):
            acc += P[I_MINV + 6 * i + j] * tau[j]
        xdot[6 + i] = acc
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
def free_run_batch(P, X0, act, fine_base, nsamp, out_base, t0, env, C, dt, sub, out):  # type: ignore
    """Free runs of ``nc`` model variants over ``nw`` windows, in parallel.

    ``P`` (nc, NP) the model's parameter vectors; ``X0`` (nc, nw, 15) initial states; ``act``
    (nc, F, 3) actuator positions on the fine grid of half integration steps (``dt / 2``),
    window ``w`` starting at ``fine_base[w]`` at time ``t0[w]`` [s]; ``nsamp[w]`` output
    samples spaced ``sub`` RK4 steps of ``dt`` [s]; ``env`` (nc, ENV_SIZE) the model's
    environment vectors (the water current); ``C`` (nc, NB, 6) extra-wrench coefficients.
    Fills ``out`` (nc, S, 12) at rows ``out_base[w]...``; a run that turns non-finite leaves
    NaN from there on.
    """
    nc = X0.shape[0]
    nw = X0.shape[1]
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
        tau = np.empty(6)
        cw = C[c]
        ev = env[c]
        pc = P[c]
        base = fine_base[w]
        row = out_base[w]
        for i in range(OUT_STATES):
            out[c, row, i] = x[i]
        bad = False
        for s in range(1, nsamp[w]):
            if not bad:
                for m in range(sub):
                    k = (s - 1) * sub + m
                    t = t0[w] + k * dt
                    f = base + 2 * k
                    for i in range(3):
                        x[12 + i] = act[c, f, i]
                    _rhs(t, x, ev, cw, pc, prof0, k1, xr, work, phi, tau)
                    for i in range(15):
                        xt[i] = x[i] + 0.5 * dt * k1[i]
                    for i in range(3):
                        xt[12 + i] = act[c, f + 1, i]
                    _rhs(t + 0.5 * dt, xt, ev, cw, pc, prof0, k2, xr, work, phi, tau)
                    for i in range(15):
                        xt[i] = x[i] + 0.5 * dt * k2[i]
                    for i in range(3):
                        xt[12 + i] = act[c, f + 1, i]
                    _rhs(t + 0.5 * dt, xt, ev, cw, pc, prof0, k3, xr, work, phi, tau)
                    for i in range(15):
                        xt[i] = x[i] + dt * k3[i]
                    for i in range(3):
                        xt[12 + i] = act[c, f + 2, i]
                    _rhs(t + dt, xt, ev, cw, pc, prof0, k4, xr, work, phi, tau)
                    for i in range(12):
                        x[i] = x[i] + dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
                for i in range(12):
                    if not np.isfinite(x[i]) or abs(x[i]) > 1e9:
                        bad = True
            for i in range(OUT_STATES):
                out[c, row + s, i] = np.nan if bad else x[i]


@njit(cache=True)
def equation_terms(T, X, env, C, P):  # type: ignore[no-untyped-def]
    """Model wrench ``tau`` (N x 6) [N, N m] at N logged states ``X`` (N x 15, over ground,
    actuators set) at times ``T`` (N) [s], in the water of ``env`` with the extra wrench of
    ``C``: the equation error is then ``M nu_dot - tau``."""
    n = X.shape[0]
    tau_out = np.empty((n, 6))
    prof0 = np.zeros((0, 4))
    xr = np.empty(15)
    work = np.empty((4, 6))
    phi = np.empty(NB)
    tau = np.empty(6)
    for k in range(n):
        model_wrench(T[k], X[k], env, C, P, prof0, xr, work, phi, tau)
        for i in range(6):
            tau_out[k, i] = tau[i]
    return tau_out
