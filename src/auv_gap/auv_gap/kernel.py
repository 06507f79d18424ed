"""Compiled kernels of the gap diagnosis: actuator series, free runs and equation errors.

Free runs are integrated by the model's one RK4 (:func:`auv_sim.model.rk4_prescribed`: the
actuator positions prescribed, an extra wrench added).

The physics is the vehicle model of :mod:`auv_sim.model`: its wrench kernel (with the
water current of the model's environment vector: constant, linear shear with depth, linear
drift in time, handled exactly as the simulator handles them) and its kinematics. What a
candidate effect adds beyond the environment vector is implemented here, apart from the
simulator's effect code, through these primitives (see
:class:`auv_gap.catalogue.Perturbation`):

* the model's environment vector (current terms) and its parameter vector (coefficients
  scaled by a candidate, the mass matrix with them);
* an extra body wrench ``sum_j phi_j(x) C[j, :]`` over the model's basis functions
  (:func:`auv_sim.model.extra_basis`);
* actuator dynamics (transport delay, first-order lag, rate limit, angle limit), integrated
  from the logged commands apart from the vehicle (actuators do not feel the vehicle);
* sensor bias, scale and latency, applied outside the kernels (initial state and outputs).

Frames: NED world, FRD body, origin at the centre of buoyancy; SI units, radians. The state
layout is :data:`auv_sim.model.STATE_NAMES` (15: eta, nu, bar, helm, thrust).
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from auv_sim.model import (
    EXTRA_BASIS,
    NB_EXTRA,
    current_ned,
    extra_wrench,
    rk4_prescribed,
    rotation,
)

#: Basis functions of the extra wrench (the model's :data:`auv_sim.model.EXTRA_BASIS`).
BASIS_NAMES = EXTRA_BASIS
NB = NB_EXTRA
B_ONE, B_G, B_ZG, B_UU, B_WW, B_QQ, B_VV, B_RR = (
    BASIS_NAMES.index(k) for k in ('one', 'gx', 'z_gx', 'ur|ur|', 'wr|wr|', 'q|q|', 'vr|vr|',
                                   'r|r|'))
B_UW, B_UQ, B_UUBAR, B_THRUST, B_XDRAG = (
    BASIS_NAMES.index(k) for k in ('ur wr', 'ur q', 'ur|ur| bar', 'thrust', 'surge_drag/Ksh'))
OUT_STATES = 12  # eta and nu are written out


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
    """Free runs of ``nc`` model variants over ``nw`` windows, in parallel, each integrated by
    the model's own RK4 (:func:`auv_sim.model.rk4_prescribed`).

    ``P`` (nc, NP) the model's parameter vectors; ``X0`` (nc, nw, 15) initial states; ``act``
    (nc, F, 3) actuator positions on the fine grid of half integration steps (``dt / 2``),
    window ``w`` starting at ``fine_base[w]`` at time ``t0[w]`` [s]; ``nsamp[w]`` output
    samples spaced ``sub`` RK4 steps of ``dt`` [s]; ``env`` (nc, ENV_SIZE) the model's
    environment vectors (the water current); ``C`` (nc, NB, 6) extra-wrench coefficients.
    Fills ``out`` (nc, S, 12) at rows ``out_base[w]...``; a run that turns non-finite (or
    beyond 1e9) leaves NaN from there on.
    """
    nc = X0.shape[0]
    nw = X0.shape[1]
    prof0 = np.zeros((0, 4))
    for job in prange(nc * nw):
        c = job // nw
        w = job % nw
        x = X0[c, w].copy()
        row = out_base[w]
        for i in range(OUT_STATES):
            out[c, row, i] = x[i]
        bad = False
        for s in range(1, nsamp[w]):
            if not bad:
                f = fine_base[w] + 2 * (s - 1) * sub
                status = rk4_prescribed(t0[w] + (s - 1) * sub * dt, x, P[c], env[c], prof0, dt,
                                        sub, C[c], act[c], f)
                bad = status >= 0
                for i in range(12):
                    if abs(x[i]) > 1e9:
                        bad = True
            for i in range(OUT_STATES):
                out[c, row + s, i] = np.nan if bad else x[i]


@njit(cache=True)
def equation_terms(T, X, env, C, P):  # type: ignore[no-untyped-def]
    """Model wrench ``tau`` (N x 6) [N, N m] at N logged states ``X`` (N x 15, over ground,
    actuators set) at times ``T`` (N) [s], in the water of ``env`` with the extra wrench of
    ``C`` (:func:`auv_sim.model.extra_wrench`): the equation error is then
    ``M nu_dot - tau``."""
    n = X.shape[0]
    tau_out = np.empty((n, 6))
    prof0 = np.zeros((0, 4))
    work = np.empty((4, 6))
    phi = np.empty(NB)
    tau = np.empty(6)
    for k in range(n):
        extra_wrench(T[k], X[k], P, env, prof0, C, work, phi, tau)
        for i in range(6):
            tau_out[k, i] = tau[i]
    return tau_out


@njit(cache=True)
def water_sway(T, X, env):  # type: ignore[no-untyped-def]
    """The water's velocity along the body's y axis [m/s] (FRD, starboard positive) at N
    states ``X`` (N x >= 6: NED position [m] and roll, pitch, yaw [rad]) at times ``T`` (N)
    [s] in the water of ``env`` (:func:`auv_sim.model.current_ned`): the sway over ground of
    a vehicle that does not slide through the water sideways."""
    n = X.shape[0]
    out = np.empty(n)
    prof0 = np.zeros((0, 4))
    for k in range(n):
        c = current_ned(T[k], X[k, 2], env, prof0)
        r = rotation(np.cos(X[k, 3]), np.sin(X[k, 3]), np.cos(X[k, 4]), np.sin(X[k, 4]),
                     np.cos(X[k, 5]), np.sin(X[k, 5]))
        # column y of the rotation body -> NED: (r01, r11, r21)
        out[k] = r[1] * c[0] + r[4] * c[1] + r[7] * c[2]
    return out
