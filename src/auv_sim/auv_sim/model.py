"""The nonlinear 6-DOF vehicle model (report section 3.2) as pure, compiled functions.

Fossen's form, all terms on the right-hand side as the report writes it::

    M nu_dot = tau_hydro(nu_r) + tau_coriolis(nu, nu_r) + tau_restoring(eta) + tau_actuators

* ``eta = (x, y, z, phi, theta, psi)``: NED position [m] and ZYX Euler angles [rad];
* ``nu = (u, v, w, p, q, r)``: body FRD velocities over ground [m/s, rad/s]; the body origin
  is the centre of buoyancy; ``nu_r = nu - nu_c`` is the velocity through the water;
* ``M = M_RB + M_A`` (see :func:`auv_sim.params.mass_matrix`).

The state vector ``x`` (15) is ``eta``, ``nu`` and the actuator positions
``(bar [rad], helm [rad], thrust [N])``; the command ``cmd`` (3) holds their set-points.
``f(t, x, cmd, P, env, prof)`` is pure; the one integrator (RK4, :func:`rk4_steps` and its
kin below) runs it or one of its constrained forms. Kernels are compiled with numba; they are
written so that complex arguments work too (``|a|`` continued as ``a sign(Re a)``), which
gives exact complex-step Jacobians.

Environment vector ``env`` (:data:`ENV_SIZE`, see :mod:`auv_sim.environment`) and the current
profile table ``prof`` (K x 4 rows ``z [m], v_n, v_e, v_d [m/s]``) describe the water.
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange
from numba.misc.special import literally

from auv_contract import CHANNELS, STATE_FIELDS
from auv_sim.params import PARAM_NAMES

_I = {name: i for i, name in enumerate(PARAM_NAMES)}
# Parameter indices, compile-time constants for the kernels.
I_RHO, I_NU, I_G = _I['rho'], _I['nu_water'], _I['g']
I_L, I_S = _I['L_ref'], _I['S_ref']
I_M, I_B = _I['m'], _I['B']
I_XG, I_YG, I_ZG, I_XB, I_YB, I_ZB = (_I[k] for k in ('xg', 'yg', 'zg', 'xb', 'yb', 'zb'))
I_IX, I_IY, I_IZ, I_IXZ = _I['Ix'], _I['Iy'], _I['Iz'], _I['Ixz']
I_XUD, I_YVD, I_ZWD, I_KPD, I_MQD, I_NRD = (
    _I[k] for k in ('Xudot', 'Yvdot', 'Zwdot', 'Kpdot', 'Mqdot', 'Nrdot'))
I_YRD, I_ZQD = _I['Yrdot'], _I['Zqdot']
I_KSH = _I['Ksh']
I_CZ0, I_CZUW, I_CZUQ = _I['CZ0'], _I['CZuw'], _I['CZuq']
I_CM0, I_CMUW, I_CMUQ = _I['CM0'], _I['CMuw'], _I['CMuq']
I_CYUV, I_CYUR, I_CNUV, I_CNUR, I_CLUP = (
    _I[k] for k in ('CYuv', 'CYur', 'CNuv', 'CNur', 'CLup'))
I_YVV, I_YRR, I_ZWW, I_ZQQ, I_MWW, I_MQQ, I_NVV, I_NRR = (
    _I[k] for k in ('Yvv', 'Yrr', 'Zww', 'Zqq', 'Mww', 'Mqq', 'Nvv', 'Nrr'))
I_CZBAR, I_CMBAR, I_CYHELM, I_CNHELM = (_I[k] for k in ('CZbar', 'CMbar', 'CYhelm', 'CNhelm'))
I_BARMAX, I_BARRATE, I_BARTAU = _I['bar_max'], _I['bar_rate'], _I['bar_tau']
I_HELMMAX, I_HELMRATE, I_HELMTAU = _I['helm_max'], _I['helm_rate'], _I['helm_tau']
I_TMAX, I_TMIN, I_TTAU = _I['thrust_max'], _I['thrust_min'], _I['thrust_tau']
I_MINV = len(PARAM_NAMES)

# Environment vector layout (see auv_sim.environment).
E_VC = 0            # 0..2 constant current, NED [m/s]
E_VAMP = 3          # 3..5 amplitude of a sinusoidal current, NED [m/s]
E_VPER = 6          # its period [s] (0: none)
E_BCOMP = 7         # buoyancy change with depth: B(z) = B (1 + k z) [1/m]
E_BARBIAS = 8       # dive-plane bias added to the BAR angle [rad]
E_ZWW, E_MQQ, E_YVV, E_NRR = 9, 10, 11, 12  # cross-flow drag [kg/m], [kg m^2]
E_SHEAR = 13        # 13..14 linear current shear: d(v_n, v_e)/dz [1/s], zero at the surface
E_DRIFT = 15        # 15..16 linear current drift in time: d(v_n, v_e)/dt [m/s^2] from t = 0
E_TGAIN = 17        # propeller thrust error: force = (1 + e) x thrust position [-]
E_TZ = 18           # thrust line below the body origin (body FRD z) [m]: pitch moment z T
E_STALL = 19        # plane lift saturation angle a [rad]: lift angle a tanh(bar / a) (0: none)
E_BDRIFT = 20       # buoyancy change in time: B(t) = B + rate t [N/s] from t = 0
E_HULL_CD = 21      # cross-flow drag coefficient of a strip-theory hull (0: none) [-]
E_HULL_XI = 22      # 22..22+HULL_STRIPS-1: its stations, forward of the body origin [m]
HULL_STRIPS = 24
E_HULL_W = E_HULL_XI + HULL_STRIPS  # their weights 2 r(xi) d xi [m^2]
ENV_SIZE = E_HULL_W + HULL_STRIPS

NX = 15
STATE_NAMES = STATE_FIELDS + CHANNELS
_INV_LN10 = 1.0 / np.log(10.0)
RE_MIN = 1.0e5  # below this the ITTC-1957 line is not valid; C_XF is held at its value here

#: Wrench rows of :func:`wrenches`: what each force/moment comes from.
WRENCH_NAMES = ('hydrodynamic', 'coriolis', 'restoring', 'actuators')


#: The hydrodynamic terms of the model, one per coefficient of the vehicle file (report
#: section 2 and the quadratic cross-flow drag): :func:`hydro_basis` gives the wrench
#: component each adds for a unit coefficient; :data:`HYDRO_AXIS` is that component
#: (0..5: X, Y, Z [N], K, M, N [N m], body FRD) and the hydrodynamic wrench is
#: ``tau_H[HYDRO_AXIS[k]] += coefficient_k * basis_k``.
HYDRO_TERMS = ('Ksh',
               'CYuv', 'CYur', 'Yvv', 'Yrr',
               'CZ0', 'CZuw', 'CZuq', 'Zww', 'Zqq',
               'CLup',
               'CM0', 'CMuw', 'CMuq', 'Mww', 'Mqq',
               'CNuv', 'CNur', 'Nvv', 'Nrr')
NH = len(HYDRO_TERMS)
HYDRO_AXIS = np.array([0, 1, 1, 1, 1, 2, 2, 2, 2, 2, 3, 4, 4, 4, 4, 4, 5, 5, 5, 5])
HYDRO_PARAM = np.array([_I[k] for k in HYDRO_TERMS])
#: The environment's cross-flow drag added to a coefficient (index into ``env``; -1: none).
HYDRO_ENV = np.array([E_YVV if k == 'Yvv' else E_ZWW if k == 'Zww' else E_MQQ if k == 'Mqq'
                      else E_NRR if k == 'Nrr' else -1 for k in HYDRO_TERMS])


@njit(cache=True)
def _sabs(a):  # type: ignore[no-untyped-def]
    """|a| continued analytically (exact for real a, complex-step friendly)."""
    return a if a.real >= 0.0 else -a


@njit(cache=True)
def rotation(cph, sph, cth, sth, cps, sps):  # type: ignore[no-untyped-def]
    """Entries r00, r01, ..., r22 of the rotation body FRD -> NED (ZYX Euler angles), from the
    cosines and sines of roll, pitch and yaw (Fossen 2011, eq. 2.18)."""
    return (cps * cth, -sps * cph + cps * sth * sph, sps * sph + cps * cph * sth,
            sps * cth, cps * cph + sph * sth * sps, -cps * sph + sth * sps * cph,
            -sth, cth * sph, cth * cph)


@njit(cache=True)
def current_ned(t, z, env, prof):  # type: ignore[no-untyped-def]
    """Water current at depth z [m] and time t [s]: (v_n, v_e, v_d, dv/dz (3), dv/dt (3)).

    The sum of a constant current, a linear shear ``s z`` (``env[E_SHEAR:E_SHEAR+2]``, north
    and east, zero at the surface), a linear drift in time ``d t`` (``env[E_DRIFT:E_DRIFT+2]``),
    a piecewise-linear depth profile (``prof`` rows ``z, v_n, v_e, v_d``, held constant outside
    its depth range) and a sinusoid in time.
    """
    shn = env[E_SHEAR]
    she = env[E_SHEAR + 1]
    vn = env[E_VC] + shn * z + env[E_DRIFT] * t
    ve = env[E_VC + 1] + she * z + env[E_DRIFT + 1] * t
    vd = env[E_VC + 2] + 0.0 * z
    gn = shn + 0.0 * z
    ge = she + 0.0 * z
    gd = 0.0 * z
    k = prof.shape[0]
    if k == 1:
        vn += prof[0, 1]
        ve += prof[0, 2]
        vd += prof[0, 3]
    elif k > 1:
        zr = z.real
        if zr <= prof[0, 0]:
            vn += prof[0, 1]
            ve += prof[0, 2]
            vd += prof[0, 3]
        elif zr >= prof[k - 1, 0]:
            vn += prof[k - 1, 1]
            ve += prof[k - 1, 2]
            vd += prof[k - 1, 3]
        else:
            i = 0
            while prof[i + 1, 0] < zr:
                i += 1
            dz = prof[i + 1, 0] - prof[i, 0]
            pn = (prof[i + 1, 1] - prof[i, 1]) / dz
            pe = (prof[i + 1, 2] - prof[i, 2]) / dz
            pd = (prof[i + 1, 3] - prof[i, 3]) / dz
            s = z - prof[i, 0]
            vn += prof[i, 1] + pn * s
            ve += prof[i, 2] + pe * s
            vd += prof[i, 3] + pd * s
            gn = gn + pn
            ge = ge + pe
            gd = gd + pd
    tn = env[E_DRIFT]
    te = env[E_DRIFT + 1]
    td = 0.0
    if env[E_VPER] > 0.0:
        om = 2.0 * np.pi / env[E_VPER]
        sn = np.sin(om * t)
        cs = np.cos(om * t)
        vn += env[E_VAMP] * sn
        ve += env[E_VAMP + 1] * sn
        vd += env[E_VAMP + 2] * sn
        tn += env[E_VAMP] * om * cs
        te += env[E_VAMP + 1] * om * cs
        td += env[E_VAMP + 2] * om * cs
    return vn, ve, vd, gn, ge, gd, tn, te, td


@njit(cache=True)
def hydro_basis(ur, vr, wr, p, q, r, P):  # type: ignore[no-untyped-def]
    """The hydrodynamic terms for unit coefficients, in the order of :data:`HYDRO_TERMS`.

    Velocities through the water ``nu_r = (ur, vr, wr [m/s], p, q, r [rad/s])`` (body FRD);
    with ``qs = 1/2 rho S_ref``, ``L = L_ref`` (report section 2; Prestero 2001, 3.3)::

        X: Ksh  -qs C_XF(Re) u|u|,  C_XF = 0.075 / (log10 Re - 2)^2,  Re = max(|u| L / nu_w, 1e5)
        Y: CYuv qs u v,    CYur qs L u r,    Yvv v|v|,  Yrr r|r|
        Z: CZ0  qs u|u|,   CZuw qs u w,      CZuq qs L u q,  Zww w|w|,  Zqq q|q|
        K: CLup qs L^2 u p
        M: CM0  qs L u|u|, CMuw qs L u w,    CMuq qs L^2 u q,  Mww w|w|,  Mqq q|q|
        N: CNuv qs L u v,  CNur qs L^2 u r,  Nvv v|v|,  Nrr r|r|

    in N (forces) or N m (moments) per unit coefficient; ``a|a|`` is continued as
    ``a^2 sign(Re a)`` (C1 at a = 0). Returns a tuple of :data:`NH` values.
    """
    L = P[I_L]
    qs = 0.5 * P[I_RHO] * P[I_S]
    aur = _sabs(ur)
    re = aur * L / P[I_NU]
    if re.real < RE_MIN:
        re = RE_MIN + 0.0 * re
    lg = np.log(re) * _INV_LN10 - 2.0
    cxf = 0.075 / (lg * lg)
    uu = qs * ur * aur
    uv = qs * ur * vr
    uw = qs * ur * wr
    up = qs * L * ur
    vv = vr * _sabs(vr)
    ww = wr * _sabs(wr)
    qq = q * _sabs(q)
    rr = r * _sabs(r)
    return (-cxf * uu,
            uv, up * r, vv, rr,
            uu, uw, up * q, ww, qq,
            up * L * p,
            L * uu, L * uw, up * L * q, ww, qq,
            L * uv, up * L * r, vv, rr)


@njit(cache=True)
def hydro_basis_series(NU, P, terms):  # type: ignore[no-untyped-def]
    """:func:`hydro_basis` for N velocities through the water ``NU`` (N x 6, body FRD
    [m/s, rad/s]), the terms of indices ``terms`` (into :data:`HYDRO_TERMS`) only: an
    N x len(terms) array, column j the wrench component ``HYDRO_AXIS[terms[j]]`` [N or N m]
    of a unit coefficient ``HYDRO_TERMS[terms[j]]``."""
    n = NU.shape[0]
    out = np.empty((n, terms.shape[0]))
    for i in range(n):
        b = hydro_basis(NU[i, 0], NU[i, 1], NU[i, 2], NU[i, 3], NU[i, 4], NU[i, 5], P)
        for j in range(terms.shape[0]):
            out[i, j] = b[terms[j]]
    return out


@njit(cache=True)
def wrenches(t, x, P, env, prof, out):  # type: ignore[no-untyped-def]
    """Fill ``out`` (4 x 6) with the body-FRD wrenches [N, N m] about the body origin.

    Rows: hydrodynamic (the terms of :func:`hydro_basis` in ``nu_r`` times the vehicle file's
    coefficients, the environment's cross-flow drag added to ``Yvv``, ``Zww``, ``Mqq``,
    ``Nrr``; with ``env[E_HULL_CD]`` > 0 the strip-theory cross-flow drag of the hull of
    :mod:`auv_sim.hull` on the stations in ``env``, coupled in sway and heave), Coriolis
    (rigid-body with
    ``nu``, added-mass with ``nu_r``, plus ``M_A nu_c_dot`` of a varying current), restoring
    (weight and buoyancy, the buoyancy changed with depth by ``env[E_BCOMP]`` and in time by
    ``env[E_BDRIFT]``), actuators (BAR, helm, propeller; the thrust times ``1 + env[E_TGAIN]``,
    acting on a line ``env[E_TZ]`` below the body origin; the BAR's lift angle saturating as
    ``a tanh(bar / a)`` with ``a = env[E_STALL]`` when it is positive).
    Their sum is ``M nu_dot``.
    Returns the attitude's (cos phi, sin phi, cos theta, sin theta, cos psi, sin psi).
    """
    rho = P[I_RHO]
    L = P[I_L]
    qs = 0.5 * rho * P[I_S]
    m = P[I_M]
    xg = P[I_XG]
    yg = P[I_YG]
    zg = P[I_ZG]
    phi = x[3]
    th = x[4]
    psi = x[5]
    u = x[6]
    v = x[7]
    w = x[8]
    p = x[9]
    q = x[10]
    r = x[11]
    cph = np.cos(phi)
    sph = np.sin(phi)
    cth = np.cos(th)
    sth = np.sin(th)
    cps = np.cos(psi)
    sps = np.sin(psi)
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = rotation(cph, sph, cth, sth, cps, sps)
    vcn, vce, vcd, gn, ge, gd, tn, te, td = current_ned(t, x[2], env, prof)
    ucb = r00 * vcn + r10 * vce + r20 * vcd
    vcb = r01 * vcn + r11 * vce + r21 * vcd
    wcb = r02 * vcn + r12 * vce + r22 * vcd
    ur = u - ucb
    vr = v - vcb
    wr = w - wcb
    aur = _sabs(ur)

    # --- hydrodynamic damping, lift and drag: the basis terms times their coefficients ---
    # (the sums of HYDRO_PARAM x basis on each HYDRO_AXIS, written out for speed)
    (b_ksh, b_cyuv, b_cyur, b_yvv, b_yrr, b_cz0, b_czuw, b_czuq, b_zww, b_zqq, b_clup,
     b_cm0, b_cmuw, b_cmuq, b_mww, b_mqq, b_cnuv, b_cnur, b_nvv, b_nrr) = hydro_basis(
        ur, vr, wr, p, q, r, P)
    out[0, 0] = P[I_KSH] * b_ksh
    out[0, 1] = (P[I_CYUV] * b_cyuv + P[I_CYUR] * b_cyur + (P[I_YVV] + env[E_YVV]) * b_yvv
                 + P[I_YRR] * b_yrr)
    out[0, 2] = (P[I_CZ0] * b_cz0 + P[I_CZUW] * b_czuw + P[I_CZUQ] * b_czuq
                 + (P[I_ZWW] + env[E_ZWW]) * b_zww + P[I_ZQQ] * b_zqq)
    out[0, 3] = P[I_CLUP] * b_clup
    out[0, 4] = (P[I_CM0] * b_cm0 + P[I_CMUW] * b_cmuw + P[I_CMUQ] * b_cmuq + P[I_MWW] * b_mww
                 + (P[I_MQQ] + env[E_MQQ]) * b_mqq)
    out[0, 5] = (P[I_CNUV] * b_cnuv + P[I_CNUR] * b_cnur + P[I_NVV] * b_nvv
                 + (P[I_NRR] + env[E_NRR]) * b_nrr)
    if env[E_HULL_CD] > 0.0:
        # a hull whose cross-flow drag is strip theory (auv_sim.hull): each strip at xi meets
        # (v + xi r, w - xi q) and takes -1/2 rho c_dc 2 r |V| V d xi against it
        kh = 0.5 * rho * env[E_HULL_CD]
        for i in range(HULL_STRIPS):
            xi = env[E_HULL_XI + i]
            vl = vr + xi * r
            wl = wr - xi * q
            drag = kh * env[E_HULL_W + i] * np.sqrt(vl * vl + wl * wl)
            out[0, 1] -= drag * vl
            out[0, 2] -= drag * wl
            out[0, 4] += xi * drag * wl
            out[0, 5] -= xi * drag * vl

    # --- Coriolis and centripetal ---
    # rigid body: f = -m (w x v + w x (w x r_g)), m_o = -(w x I_o w) - m r_g x (w x v)
    a0 = q * w - r * v
    a1 = r * u - p * w
    a2 = p * v - q * u
    b0 = q * zg - r * yg
    b1 = r * xg - p * zg
    b2 = p * yg - q * xg
    c0 = q * b2 - r * b1
    c1 = r * b0 - p * b2
    c2 = p * b1 - q * b0
    ix = P[I_IX]
    iy = P[I_IY]
    iz = P[I_IZ]
    ixz = P[I_IXZ]
    h0 = ix * p - ixz * r
    h1 = iy * q
    h2 = iz * r - ixz * p
    f0 = -m * (a0 + c0)
    f1 = -m * (a1 + c1)
    f2 = -m * (a2 + c2)
    m0 = -(q * h2 - r * h1) - m * (yg * a2 - zg * a1)
    m1 = -(r * h0 - p * h2) - m * (zg * a0 - xg * a2)
    m2 = -(p * h1 - q * h0) - m * (xg * a1 - yg * a0)
    # added mass (Fossen 2011 eq. 6.43): with a = A11 nu1_r + A12 nu2, b = A21 nu1_r + A22 nu2,
    # f = -(nu2 x a), m = -(nu1_r x a) - (nu2 x b)
    xa = -P[I_XUD]
    ya = -P[I_YVD]
    za = -P[I_ZWD]
    ka = -P[I_KPD]
    ma = -P[I_MQD]
    na = -P[I_NRD]
    yrd = P[I_YRD]
    zqd = P[I_ZQD]
    pa0 = xa * ur
    pa1 = ya * vr - yrd * r
    pa2 = za * wr - zqd * q
    pb0 = ka * p
    pb1 = ma * q - zqd * wr
    pb2 = na * r - yrd * vr
    f0 -= q * pa2 - r * pa1
    f1 -= r * pa0 - p * pa2
    f2 -= p * pa1 - q * pa0
    m0 -= (vr * pa2 - wr * pa1) + (q * pb2 - r * pb1)
    m1 -= (wr * pa0 - ur * pa2) + (r * pb0 - p * pb2)
    m2 -= (ur * pa1 - vr * pa0) + (p * pb1 - q * pb0)
    # M_A nu_c_dot for a current that varies along the path or in time
    zdot = r20 * u + r21 * v + r22 * w
    dn = gn * zdot + tn
    de = ge * zdot + te
    dd = gd * zdot + td
    nc0 = (r00 * dn + r10 * de + r20 * dd) - (q * wcb - r * vcb)
    nc1 = (r01 * dn + r11 * de + r21 * dd) - (r * ucb - p * wcb)
    nc2 = (r02 * dn + r12 * de + r22 * dd) - (p * vcb - q * ucb)
    f0 += xa * nc0
    f1 += ya * nc1
    f2 += za * nc2
    m1 += -zqd * nc2
    m2 += -yrd * nc1
    out[1, 0] = f0
    out[1, 1] = f1
    out[1, 2] = f2
    out[1, 3] = m0
    out[1, 4] = m1
    out[1, 5] = m2

    # --- restoring: -g(eta), Fossen 2011 eq. 4.6, buoyancy varying with depth ---
    wgt = m * P[I_G]
    buoy = P[I_B] * (1.0 + env[E_BCOMP] * x[2]) + env[E_BDRIFT] * t
    wb = wgt - buoy
    zgw = zg * wgt - P[I_ZB] * buoy
    ygw = yg * wgt - P[I_YB] * buoy
    xgw = xg * wgt - P[I_XB] * buoy
    out[2, 0] = -wb * sth
    out[2, 1] = wb * cth * sph
    out[2, 2] = wb * cth * cph
    out[2, 3] = ygw * cth * cph - zgw * cth * sph
    out[2, 4] = -zgw * sth - xgw * cth * cph
    out[2, 5] = xgw * cth * sph + ygw * sth

    # --- actuators: dive plane (BAR), helm, propeller ---
    bar = x[12] + env[E_BARBIAS]
    stall = env[E_STALL]
    if stall > 0.0:
        bar = stall * np.tanh(bar / stall)
    helm = x[13]
    dyn = qs * ur * aur
    thrust = x[14] * (1.0 + env[E_TGAIN])
    out[3, 0] = thrust
    out[3, 1] = dyn * P[I_CYHELM] * helm
    out[3, 2] = dyn * P[I_CZBAR] * bar
    out[3, 3] = 0.0 * dyn
    out[3, 4] = dyn * L * P[I_CMBAR] * bar + env[E_TZ] * thrust
    out[3, 5] = dyn * L * P[I_CNHELM] * helm
    return cph, sph, cth, sth, cps, sps


@njit(cache=True)
def _clip(a, lo, hi):  # type: ignore[no-untyped-def]
    if a.real < lo:
        return lo + 0.0 * a
    if a.real > hi:
        return hi + 0.0 * a
    return a


@njit(cache=True)
def actuator_rates(x, cmd, P, xdot):  # type: ignore[no-untyped-def]
    """Actuator dynamics into ``xdot[12:15]``: angle limit, rate limit, first-order lag.

    ``bar_dot = clip((clip(cmd, +-bar_max) - bar) / bar_tau, +-bar_rate)`` [rad/s], the same
    for the helm; thrust: a first-order lag towards ``clip(cmd, thrust_min, thrust_max)``.
    """
    bmax = P[I_BARMAX]
    brate = P[I_BARRATE]
    xdot[12] = _clip((_clip(cmd[0] + 0.0 * x[12], -bmax, bmax) - x[12]) / P[I_BARTAU],
                     -brate, brate)
    hmax = P[I_HELMMAX]
    hrate = P[I_HELMRATE]
    xdot[13] = _clip((_clip(cmd[1] + 0.0 * x[13], -hmax, hmax) - x[13]) / P[I_HELMTAU],
                     -hrate, hrate)
    xdot[14] = (_clip(cmd[2] + 0.0 * x[14], P[I_TMIN], P[I_TMAX]) - x[14]) / P[I_TTAU]


@njit(cache=True)
def kinematics(x, xdot):  # type: ignore[no-untyped-def]
    """eta_dot = J(eta) nu into ``xdot[0:6]`` (NED position rates, ZYX Euler-angle rates)."""
    _kinematics(x, xdot, np.cos(x[3]), np.sin(x[3]), np.cos(x[4]), np.sin(x[4]),
                np.cos(x[5]), np.sin(x[5]))


@njit(cache=True)
def _kinematics(x, xdot, cph, sph, cth, sth, cps, sps):  # type: ignore[no-untyped-def]
    """:func:`kinematics` with the attitude's cosines and sines given."""
    u = x[6]
    v = x[7]
    w = x[8]
    p = x[9]
    q = x[10]
    r = x[11]
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = rotation(cph, sph, cth, sth, cps, sps)
    xdot[0] = r00 * u + r01 * v + r02 * w
    xdot[1] = r10 * u + r11 * v + r12 * w
    xdot[2] = r20 * u + r21 * v + r22 * w
    xdot[3] = p + (q * sph + r * cph) * sth / cth
    xdot[4] = q * cph - r * sph
    xdot[5] = (q * sph + r * cph) / cth


@njit(cache=True)
def dynamics(t, x, cmd, P, env, prof, xdot, work):  # type: ignore[no-untyped-def]
    """The model ``x_dot = f(t, x, cmd)`` into ``xdot`` (15); ``work`` is a 4 x 6 scratch."""
    cph, sph, cth, sth, cps, sps = wrenches(t, x, P, env, prof, work)
    _kinematics(x, xdot, cph, sph, cth, sth, cps, sps)
    for i in range(6):
        acc = 0.0 * x[0]
        for j in range(6):
            acc += P[I_MINV + 6 * i + j] * (work[0, j] + work[1, j] + work[2, j] + work[3, j])
        xdot[6 + i] = acc
    actuator_rates(x, cmd, P, xdot)


@njit(cache=True)
def actuator_dynamics(t, x, cmd, P, env, prof, xdot, work):  # type: ignore[no-untyped-def]
    """The actuators alone: :func:`actuator_rates` into ``xdot[12:15]``, the vehicle held
    (``xdot[0:12] = 0``); the same arguments as :func:`dynamics`."""
    for i in range(12):
        xdot[i] = 0.0 * x[i]
    actuator_rates(x, cmd, P, xdot)


#: Basis functions of an extra body wrench ``sum_j phi_j(x) C[j, :]`` [N, N m] (model errors a
#: diagnosis fits against a log; :func:`extra_basis`), dimension per row:
EXTRA_BASIS = (
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
NB_EXTRA = len(EXTRA_BASIS)


@njit(cache=True)
def extra_basis(t, x, P, env, prof, surge_drag, phi):  # type: ignore[no-untyped-def]
    """Fill ``phi`` (:data:`NB_EXTRA`) at time ``t`` [s] and state ``x`` (over ground) in the
    water of ``env``/``prof``; ``surge_drag`` [N] is the model's hydrodynamic surge force
    (``wrenches`` row 0, axis X)."""
    vcn, vce, vcd, _, _, _, _, _, _ = current_ned(t, x[2], env, prof)
    cph = np.cos(x[3])
    sph = np.sin(x[3])
    cth = np.cos(x[4])
    sth = np.sin(x[4])
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = rotation(
        cph, sph, cth, sth, np.cos(x[5]), np.sin(x[5]))
    ur = x[6] - (r00 * vcn + r10 * vce + r20 * vcd)
    vr = x[7] - (r01 * vcn + r11 * vce + r21 * vcd)
    wr = x[8] - (r02 * vcn + r12 * vce + r22 * vcd)
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
    phi[7] = ur * abs(ur)
    phi[8] = wr * abs(wr)
    phi[9] = x[10] * abs(x[10])
    phi[10] = vr * abs(vr)
    phi[11] = x[11] * abs(x[11])
    phi[12] = ur * wr
    phi[13] = ur * x[10]
    phi[14] = ur * abs(ur) * x[12]
    phi[15] = x[14]
    phi[16] = surge_drag / P[I_KSH] if P[I_KSH] != 0.0 else 0.0


@njit(cache=True)
def extra_wrench(t, x, P, env, prof, C, work, phi, tau):  # type: ignore[no-untyped-def]
    """Total body wrench ``tau`` (6) [N, N m] at time ``t`` and state ``x``: the sum of
    :func:`wrenches` (left in ``work``) and the extra wrench ``phi(x)^T C``; returns the
    attitude's cosines and sines as :func:`wrenches`."""
    trig = wrenches(t, x, P, env, prof, work)
    extra_basis(t, x, P, env, prof, work[0, 0], phi)
    for i in range(6):
        acc = work[0, i] + work[1, i] + work[2, i] + work[3, i]
        for j in range(NB_EXTRA):
            acc += phi[j] * C[j, i]
        tau[i] = acc
    return trig


@njit(cache=True)
def dynamics_extra(t, x, P, env, prof, C, xdot, work, scratch):  # type: ignore
    """:func:`dynamics` with the extra wrench ``phi(x)^T C`` added and the actuators held
    (``xdot[12:15] = 0``: their positions are prescribed by the caller); ``scratch`` holds
    NB_EXTRA + 6 numbers."""
    phi = scratch[:NB_EXTRA]
    tau = scratch[NB_EXTRA:]
    cph, sph, cth, sth, cps, sps = extra_wrench(t, x, P, env, prof, C, work, phi, tau)
    _kinematics(x, xdot, cph, sph, cth, sth, cps, sps)
    for i in range(6):
        acc = 0.0 * x[0]
        for j in range(6):
            acc += P[I_MINV + 6 * i + j] * tau[j]
        xdot[6 + i] = acc
    xdot[12] = 0.0 * x[12]
    xdot[13] = 0.0 * x[13]
    xdot[14] = 0.0 * x[14]


@njit(cache=True)
def surge_held_dynamics(t, x, cmd, P, env, prof, xdot, work):  # type: ignore[no-untyped-def]
    """:func:`dynamics` with the surge speed held by a perfect speed loop: ``u_dot = 0``.

    The speed loop is a surge force ``lambda`` [N] (body FRD X) that takes whatever value
    keeps ``u`` constant: ``M nu_dot = tau + e_X lambda`` with ``u_dot = 0`` gives
    ``nu_dot = M^-1 tau - M^-1 e_X (M^-1 tau)_X / (M^-1)_XX`` (the other rows are then
    ``M' nu_dot' = tau'``, ``M'`` the mass matrix without the surge row and column). The
    thrust the loop needs is ``x[14] + lambda``; the propeller state itself is not used.
    The same arguments as :func:`dynamics`."""
    dynamics(t, x, cmd, P, env, prof, xdot, work)
    a = xdot[6] / P[I_MINV]
    for i in range(6):
        xdot[6 + i] -= P[I_MINV + 6 * i] * a


#: Integration modes of :func:`_rk4` (compile-time constants): the right-hand side
#: :func:`_rhs` evaluates.
MODE_ACTUATORS, MODE_VEHICLE, MODE_PRESCRIBED, MODE_SURGE_HELD = 0, 1, 2, 3
_NO_C = np.zeros((1, 6))
_NO_ACT = np.zeros((1, 3))
#: The classic RK4 tableau: stage times ``c`` [fraction of the step] and the weight ``a`` of
#: the previous stage in each stage's state (the output weights 1/6, 2/6, 2/6, 1/6 are
#: written out in :func:`_rk4`); and the row of the prescribed actuator grid (half steps)
#: each stage reads.
_RK4_C = (0.0, 0.5, 0.5, 1.0)
_RK4_A = (0.0, 0.5, 0.5, 1.0)
_RK4_ROW = (0, 1, 1, 2)


@njit(cache=True, inline='always')
def _rhs(mode, t, x, cmd, P, env, prof, C, xdot, work, scratch):  # type: ignore
    """The right-hand side ``xdot`` of integration ``mode`` at ``(t, x)``: :data:`MODE_VEHICLE`
    :func:`dynamics`, :data:`MODE_ACTUATORS` :func:`actuator_dynamics`, :data:`MODE_PRESCRIBED`
    :func:`dynamics_extra` (the extra wrench of ``C``; ``cmd`` unused), :data:`MODE_SURGE_HELD`
    :func:`surge_held_dynamics`."""
    if mode == MODE_SURGE_HELD:
        surge_held_dynamics(t, x, cmd, P, env, prof, xdot, work)
    elif mode == MODE_VEHICLE:
        dynamics(t, x, cmd, P, env, prof, xdot, work)
    elif mode == MODE_ACTUATORS:
        actuator_dynamics(t, x, cmd, P, env, prof, xdot, work)
    else:
        dynamics_extra(t, x, P, env, prof, C, xdot, work, scratch)


@njit(cache=True)
def _rk4(t0, x, cmd, P, env, prof, dt, nsteps, mode, C, act, f0):  # type: ignore
    """Classic RK4 (tableau :data:`_RK4_C`, :data:`_RK4_A`), the one integrator of the
    model; returns as :func:`rk4_steps`.

    ``mode`` (a compile-time constant: one specialisation each, the other branches of
    :func:`_rhs` pruned; a run-time branch costs the vehicle 30 % in speed) chooses the
    right-hand side. In :data:`MODE_PRESCRIBED` the actuator positions are read at each stage
    from ``act`` (row ``f0 + 2 s + _RK4_ROW[j]`` for stage ``j`` of step ``s``: a grid of half
    steps). The stages have the dtype of ``x``: a complex state (complex-step derivatives) is
    integrated in complex arithmetic.
    """
    literally(mode)
    n = x.shape[0]
    k = (np.empty_like(x), np.empty_like(x), np.empty_like(x), np.empty_like(x))
    xt = np.empty_like(x)
    work = np.zeros((4, 6)) + 0.0 * x[0]
    scratch = np.zeros(NB_EXTRA + 6) + 0.0 * x[0]
    for s in range(nsteps):
        t = t0 + s * dt
        for j in range(4):
            for i in range(n):
                xt[i] = x[i] if j == 0 else x[i] + _RK4_A[j] * dt * k[j - 1][i]
            if mode == MODE_PRESCRIBED:
                for i in range(3):
                    xt[12 + i] = act[f0 + 2 * s + _RK4_ROW[j], i]
            _rhs(mode, t + _RK4_C[j] * dt, xt, cmd, P, env, prof, C, k[j], work, scratch)
        ok = True
        for i in range(n):
            xt[i] = x[i] + dt / 6.0 * (k[0][i] + 2.0 * k[1][i] + 2.0 * k[2][i] + k[3][i])
            if not np.isfinite(xt[i]):
                ok = False
        if not ok:
            return s
        for i in range(n):
            x[i] = xt[i]
        if mode == MODE_PRESCRIBED:
            for i in range(3):
                x[12 + i] = act[f0 + 2 * s + 2, i]
    return -1


@njit(cache=True)
def rk4_steps(t0, x, cmd, P, env, prof, dt, nsteps):  # type: ignore[no-untyped-def]
    """Advance ``x`` in place by ``nsteps`` classic RK4 steps of ``dt`` [s], command held.

    Returns -1 on success, else the index of the first step whose result is non-finite
    (``x`` then holds the last finite state).
    """
    return _rk4(t0, x, cmd, P, env, prof, dt, nsteps, MODE_VEHICLE, _NO_C, _NO_ACT, 0)


@njit(cache=True)
def rk4_prescribed(t0, x, P, env, prof, dt, nsteps, C, act, f0):  # type: ignore
    """Advance the vehicle ``x`` (15) in place by ``nsteps`` RK4 steps of ``dt`` [s] from
    ``t0`` [s] with its actuator positions prescribed (BAR, helm [rad], thrust [N]: rows
    ``act[f0 + j]`` at ``t0 + j dt / 2``, a grid of half steps; ``x[12:15]`` ends at row
    ``f0 + 2 nsteps``) and the extra wrench ``phi(x)^T C`` (:func:`extra_basis`, ``C``
    NB_EXTRA x 6) added: the model a diagnosis runs against a log. Returns as
    :func:`rk4_steps`."""
    cmd = np.zeros(3)
    return _rk4(t0, x, cmd, P, env, prof, dt, nsteps, MODE_PRESCRIBED, C, act, f0)


@njit(cache=True)
def actuator_steps(x, cmd, P, dt, nsteps):  # type: ignore[no-untyped-def]
    """Advance the actuator positions ``x[12:15]`` (BAR, helm [rad], thrust [N]) of a state
    ``x`` (15) in place by ``nsteps`` steps of ``dt`` [s] of the same RK4 as
    :func:`rk4_steps`, command ``cmd`` held, the vehicle states ``x[0:12]`` unchanged; the
    actuator positions are bit for bit those of :func:`rk4_steps` (the actuator model does
    not depend on the vehicle states). Returns as :func:`rk4_steps`."""
    env = np.zeros(ENV_SIZE)
    prof = np.zeros((0, 4))
    return _rk4(0.0, x, cmd, P, env, prof, dt, nsteps, MODE_ACTUATORS, _NO_C, _NO_ACT, 0)


@njit(cache=True)
def surge_held_steps(t0, x, cmd, P, env, prof, dt, nsteps):  # type: ignore[no-untyped-def]
    """:func:`rk4_steps` of :func:`surge_held_dynamics` (the surge speed ``x[6]`` held by a
    perfect speed loop). ``x`` may be complex (complex-step derivatives). Returns as
    :func:`rk4_steps`."""
    return _rk4(t0, x, cmd, P, env, prof, dt, nsteps, MODE_SURGE_HELD, _NO_C, _NO_ACT, 0)


@njit(cache=True)
def rk4_batch(t0, X, CMD, P, env, prof, dt, nsteps):  # type: ignore[no-untyped-def]
    """Advance N vehicles (rows of ``X``, N x 15) with commands ``CMD`` (N x 3), same model.

    Returns an int array: -1 per vehicle on success, else its first non-finite step.
    """
    nveh = X.shape[0]
    status = np.empty(nveh, dtype=np.int64)
    for k in range(nveh):
        status[k] = rk4_steps(t0, X[k], CMD[k], P, env, prof, dt, nsteps)
    return status


@njit(cache=True, parallel=True)
def rk4_batch_parallel(t0, X, CMD, P, env, prof, dt, nsteps):  # type: ignore[no-untyped-def]
    """:func:`rk4_batch` with the vehicles spread over CPU threads (numba ``prange``).

    Each vehicle runs the same :func:`rk4_steps` as the serial batch, so results are identical
    bit for bit; only the order in which vehicles are computed differs.
    """
    nveh = X.shape[0]
    status = np.empty(nveh, dtype=np.int64)
    for k in prange(nveh):
        status[k] = rk4_steps(t0, X[k], CMD[k], P, env, prof, dt, nsteps)
    return status


@njit(cache=True)
def wrench_series(T, X, P, env, prof):  # type: ignore[no-untyped-def]
    """Wrench breakdown (N x 4 x 6) for N states ``X`` (N x 15) at times ``T`` (N)."""
    n = X.shape[0]
    out = np.empty((n, 4, 6))
    for k in range(n):
        wrenches(T[k], X[k], P, env, prof, out[k])
    return out
