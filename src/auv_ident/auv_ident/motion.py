"""Hydrodynamic forces from logs: the force topic, or reconstructed from the logged motion.

A simulator bag carries ``/auv/hydrodynamic_forces`` (body FRD, same stamps as the state);
a real vehicle's log does not. Without it, the hydrodynamic wrench is what the rest of the
model leaves of ``M nu_dot`` (Fossen's form, body FRD about the body origin)::

    tau_H = M nu_dot - (tau_coriolis + tau_restoring + tau_actuators)

with ``M`` the rigid-body plus added mass of the base vehicle (:func:`auv_sim.params.mass_matrix`)
and the other wrenches from :func:`auv_sim.model.wrench_series` on the logged attitude and
velocities and on actuator positions reconstructed from the logged commands through the
vehicle's own actuator model and integrator (:func:`auv_sim.model.actuator_steps`: the
simulator's RK4 of :func:`auv_sim.model.actuator_rates` (angle limit, rate limit, first-order
lag) on its step grid, so a simulated log is reproduced exactly).

Derivative and filter (the window choice). ``nu_dot`` is a Savitzky-Golay derivative
(``scipy.signal.savgol_filter``, ``deriv=1``, ``polyorder=2``) over a window of
:data:`WINDOW_S` = 1 s (the odd number of samples nearest to it: 51 at 50 Hz). For a quadratic
(or linear) fit the derivative at the window centre is the least-squares slope
``sum_k k nu_{t+k} / (dt sum_k k^2)``; by summation by parts this is exactly a weighted mean of
the velocity increments ``nu_{j+1} - nu_j = int nu_dot dt`` with parabolic weights
``c_j = (m(m+1) - j(j+1)) / 2``. So the derivative filter is a low-pass filter of the true
``nu_dot``, and every other term of the equation (and, in :mod:`auv_ident.identify`, every
regressor) is passed through the *same* low-pass (:func:`consistent_kernel`: those weights on
trapezoidal increments). The filtered equation then holds exactly, up to the trapezoid rule at
50 Hz, so the window trades only noise for bandwidth, without bias at the plane steps: 1 s
keeps the heave/pitch and sway/yaw dynamics (poles below 0.3 Hz, doublets of 2-10 s; the
kernel's -3 dB point is about 0.57 Hz) and cuts the derivative noise of 0.01 m/s velocity noise
to about 5 mm/s^2 (the least-squares slope over 51 samples).

Noise propagation (for the standard errors, :class:`auv_ident.identify.NoisePropagation`).
To first order, white noise on the logged state reaches the reconstructed wrench through the
derivative weights (``M`` times the velocity noise) and through the low-passed sensitivities
of the other wrenches (their Jacobian, by central differences of
:func:`auv_sim.model.wrenches`, sample by sample). The noise level of each channel is
estimated from the log itself (:func:`noise_sigma`: robust scale of third differences, which
cancel the smooth motion and leave ``20 sigma^2`` of white noise). Whether this model explains
the residual is checked in the fit (see :mod:`auv_ident.identify`). The same central
differences, with steps of one noise standard deviation, give the second-order mean shift of
the other wrenches of a noisy state, which the reconstruction removes.

Assumed: no water current (velocities over ground = through the water); actuators settled at
the first logged command when the log starts with no earlier command.
"""
from __future__ import annotations

import contextlib
import hashlib
import itertools
import math
from collections.abc import Iterator, Mapping, Sequence

import numpy as np
from numba import njit
from scipy.signal import savgol_coeffs, savgol_filter

from auv_contract import (
    COMMAND_TOPICS,
    FORCES_TOPIC,
    MEASURED_TOPICS,
    STATE_FIELDS,
    STATE_TOPIC,
)
from auv_ident.errors import IdentificationError
from auv_ident.identify import ForceRecord, LoggedRun, NoisePropagation
from auv_sim.environment import Environment
from auv_sim.model import NX, actuator_steps, wrench_series, wrenches
from auv_sim.params import VehicleParams, mass_matrix

FORCE_FIELDS = tuple(f'hydrodynamic_{k}_{a}' for k in ('force', 'torque') for a in 'xyz')
#: Savitzky-Golay window [s] (see module docstring).
WINDOW_S = 1.0
#: Longest sub-step [s] over which the actuator wrench is integrated inside a sample
#: interval (see :func:`actuator_interval_means`); at 20 Hz and faster: the samples alone.
SUBSTEP_S = 0.05
POLYORDER = 2
SOURCES = ('auto', 'forces', 'motion')
#: State channels that are angles (unwrapped before differencing).
ANGLE_CHANNELS = (3, 4, 5)


def window_samples(dt: float, window_s: float = WINDOW_S) -> int:
    """Odd window length [samples] nearest to ``window_s`` [s] at sample period ``dt`` [s]
    (at least 5)."""
    n = int(round(window_s / dt))
    n = n + 1 if n % 2 == 0 else n
    return max(5, n)


def consistent_kernel(window: int) -> np.ndarray:
    """Weights (``window`` = 2m+1, sum 1) of the low-pass that the Savitzky-Golay derivative
    (``polyorder`` 1 or 2) applies to ``nu_dot``: parabolic weights on trapezoidal increments,
    ``w_k = (c_{k-1} + c_k) / (2 sum_j j^2)``, ``c_j = (m(m+1) - j(j+1)) / 2`` (0 outside)."""
    m = window // 2
    j = np.arange(-m - 1, m + 1)
    c = (m * (m + 1) - j * (j + 1)) / 2.0
    c[0] = 0.0   # c_{-m-1}
    c[-1] = 0.0  # c_m
    w = (c[:-1] + c[1:]) / 2.0
    kernel: np.ndarray = w / w.sum()
    return kernel


def noise_sigma(state: np.ndarray) -> np.ndarray:
    """Standard deviation of white noise on each column of ``state`` (N, k), in its units.

    Third differences remove a smooth signal (to ``dt^3`` times its third derivative, far
    below the noise at tens of Hz) and leave ``20 sigma^2`` of white noise; the scale is the
    median absolute deviation (times 1.4826), robust to the few samples around actuator
    steps. Angle columns (:data:`ANGLE_CHANNELS` of a 12-column state) are unwrapped first.
    """
    x = np.array(state, float)
    if x.shape[1] == 12:
        for c in ANGLE_CHANNELS:
            x[:, c] = np.unwrap(x[:, c])
    if len(x) < 8:
        return np.zeros(x.shape[1])
    d3 = np.diff(x, n=3, axis=0)
    mad = np.median(np.abs(d3 - np.median(d3, axis=0)), axis=0)
    sigma: np.ndarray = 1.4826 * mad / math.sqrt(20.0)
    return sigma


def other_jacobian(t: np.ndarray, X: np.ndarray, params: VehicleParams, env: Environment,
                   sigma: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Sensitivity of ``tau_other`` = Coriolis + restoring + actuator wrench to state noise.

    Central differences of :func:`auv_sim.model.wrenches` with steps ``+-sigma_c`` on
    each of the 12 state channels (``1e-6 (1 + max|x_c|)`` where ``sigma_c`` is smaller):
    ``(f(x + s) - f(x - s)) / 2 s`` is the Jacobian (N, 6, 12) [N or N m per unit of each
    channel] and, summed over the channels, ``(f(x + s) + f(x - s) - 2 f(x)) / 2`` (scaled by
    ``(sigma_c / s)^2``) is ``1/2 sum_c sigma_c^2 d^2 f / d x_c^2``, the mean shift white noise
    gives the wrench of a noisy state to second order (N, 6) [N, N m]. ``t`` (N,) [s], ``X``
    (N, 15) the simulator's state with the actuator positions; ``sigma`` (12,) in the state's
    units (None: zero).
    """
    sig = np.zeros(12) if sigma is None else np.asarray(sigma, float)
    steps = np.array([max(float(sig[c]), 1e-6 * (1.0 + float(np.max(np.abs(X[:, c])))))
                      for c in range(12)])
    weights = (sig[:12] / steps) ** 2
    jac: np.ndarray
    shift: np.ndarray
    jac, shift = _other_differences(np.ascontiguousarray(t, dtype=np.float64),
                                    np.ascontiguousarray(X, dtype=np.float64),
                                    params.as_array(), env.env_vector(), env.profile(),
                                    steps, weights)
    return jac, shift


@njit(cache=True)
def _other_differences(T, X, P, env, prof, steps, weights):  # type: ignore[no-untyped-def]
    """The central differences of :func:`other_jacobian` (its Jacobian (N, 6, 12) and mean
    shift (N, 6)) for states ``X`` (N, 15) at times ``T`` (N) [s], steps ``steps`` (12,) and
    shift weights ``weights`` = ``(sigma_c / step_c)^2`` (12,), sample by sample (no
    perturbed copy of the log): the wrenches of :func:`auv_sim.model.wrenches`, the rows
    Coriolis + restoring + actuators summed in that order."""
    n = X.shape[0]
    jac = np.zeros((n, 6, 12))
    shift = np.zeros((n, 6))
    x = np.empty(X.shape[1])
    w0 = np.empty((4, 6))
    wu = np.empty((4, 6))
    wd = np.empty((4, 6))
    f0 = np.empty(6)
    for k in range(n):
        for i in range(X.shape[1]):
            x[i] = X[k, i]
        wrenches(T[k], x, P, env, prof, w0)
        for a in range(6):
            f0[a] = w0[1, a] + w0[2, a] + w0[3, a]
        for c in range(12):
            h = steps[c]
            x[c] = X[k, c] + h
            wrenches(T[k], x, P, env, prof, wu)
            x[c] = X[k, c] - h
            wrenches(T[k], x, P, env, prof, wd)
            x[c] = X[k, c]
            for a in range(6):
                fu = wu[1, a] + wu[2, a] + wu[3, a]
                fd = wd[1, a] + wd[2, a] + wd[3, a]
                jac[k, a, c] = (fu - fd) / (2.0 * h)
                shift[k, a] += 0.5 * (fu + fd - 2.0 * f0[a]) * weights[c]
    return jac, shift


def segments(t: np.ndarray, tolerance: float = 0.25) -> list[slice]:
    """Uniformly sampled stretches of stamps ``t`` [s]: split where a step departs from the
    median step by more than ``tolerance`` of it (a lost message, a pause)."""
    if len(t) < 2:
        return [slice(0, len(t))]
    d = np.diff(t)
    dt = float(np.median(d))
    cut = np.flatnonzero(np.abs(d - dt) > tolerance * dt) + 1
    edges = [0, *cut.tolist(), len(t)]
    return [slice(a, b) for a, b in itertools.pairwise(edges) if b > a]


@njit(cache=True)
def _integrate_actuators(x0, ev_step, ev_channel, ev_value,  # type: ignore[no-untyped-def]
                         cmd0, P, dt, nsteps):
    """Actuator positions (nsteps+1, 3) on the grid ``k dt`` by the simulator's RK4 and
    actuator model (:func:`auv_sim.model.actuator_steps`); command events take effect at
    their step."""
    out = np.empty((nsteps + 1, 3))
    x = np.zeros(NX)
    x[12:15] = x0
    cmd = cmd0.copy()
    e = 0
    ne = ev_step.shape[0]
    for s in range(nsteps + 1):
        while e < ne and ev_step[e] <= s:
            cmd[ev_channel[e]] = ev_value[e]
            e += 1
        out[s, 0] = x[12]
        out[s, 1] = x[13]
        out[s, 2] = x[14]
        if s < nsteps:
            actuator_steps(x, cmd, P, dt, 1)
    return out


#: The actuator integrations kept by :func:`shared_actuator_tracks` (innermost last).
_SHARED: list[dict[bytes, np.ndarray]] = []
#: Seconds a kept integration runs on after the last stamp asked for (the free runs' grid of
#: a log ends up to two of their steps, 0.1 s at most, after its last sample).
TRACK_BEYOND_S = 1.0


@contextlib.contextmanager
def shared_actuator_tracks() -> Iterator[None]:
    """Inside it, :func:`actuator_positions` integrates the actuators of a log once and
    reuses the run (by the digest of its inputs: initial positions, command events, the
    vehicle's parameters, the step): one identification rebuilds them at the log's stamps and
    again on the free runs' grid. Outside it, every call integrates anew."""
    _SHARED.append({})
    try:
        yield
    finally:
        _SHARED.pop()


def actuator_positions(t: np.ndarray, commands: Mapping[str, tuple[np.ndarray, np.ndarray]],
                       params: VehicleParams) -> np.ndarray:
    """Reconstructed BAR [rad], helm [rad] and thrust [N] at stamps ``t`` [s] (N, 3).

    ``commands`` maps ``bar``/``helm``/``thrust`` to (stamps [s], set-points). A command acts
    from the first integration step (``params.dt``, grid from ``t[0]``) at or after its
    stamp, as in the simulator; the actuators start settled at the last command at or before
    ``t[0]`` (or the first command, if none is earlier).
    """
    dt = float(params.dt)
    t0 = float(t[0])
    nsteps = int(math.ceil((float(t[-1]) - t0) / dt - 1e-9))
    limits = ((-params.bar_max, params.bar_max), (-params.helm_max, params.helm_max),
              (params.thrust_min, params.thrust_max))
    x0 = np.zeros(3)
    steps, chans, vals = [], [], []
    for c, name in enumerate(('bar', 'helm', 'thrust')):
        times, values = commands[name]
        if len(times) == 0:
            raise IdentificationError(f'no {name} command in the log: the {name} position '
                                      f'cannot be reconstructed')
        before = np.flatnonzero(times <= t0 + 1e-9)
        first = int(before[-1]) if len(before) else 0
        x0[c] = min(max(float(values[first]), limits[c][0]), limits[c][1])
        later = slice(first + 1, None)
        k = np.ceil((times[later] - t0) / dt - 1e-9).astype(np.int64)
        steps.append(np.maximum(k, 0))
        chans.append(np.full(len(k), c, np.int64))
        vals.append(np.asarray(values[later], float))
    ev_step = np.concatenate(steps)
    order = np.argsort(ev_step, kind='stable')
    events = (ev_step[order], np.concatenate(chans)[order], np.concatenate(vals)[order])
    P = params.as_array()
    if not _SHARED:
        grid = _integrate_actuators(x0, *events, x0.copy(), P, dt, nsteps)
    else:
        kept = _SHARED[-1]
        digest = hashlib.blake2b(digest_size=16)
        for a in (x0, *events, P, np.array([dt])):
            digest.update(np.ascontiguousarray(a).tobytes())
        key = digest.digest()
        if key not in kept or len(kept[key]) < nsteps + 1:
            # the integration is causal (a longer run's first steps are a shorter one's):
            # run on for TRACK_BEYOND_S, so that a call that ends a little later reuses it
            more = nsteps + int(math.ceil(TRACK_BEYOND_S / dt))
            kept[key] = _integrate_actuators(x0, *events, x0.copy(), P, dt, more)
        grid = kept[key][:nsteps + 1]
    tg = t0 + dt * np.arange(nsteps + 1)
    return np.column_stack([np.interp(t, tg, grid[:, c]) for c in range(3)])


#: Measured actuator topics of the contract and the channel each replaces.
Series = tuple[np.ndarray, np.ndarray]


def actuator_track(t: np.ndarray, commands: Mapping[str, Series], params: VehicleParams,
                   measured: Mapping[str, Series] | None = None) -> np.ndarray:
    """BAR [rad], helm [rad] and thrust [N] at stamps ``t`` [s] (N, 3): the commands through
    the vehicle's actuator model (:func:`actuator_positions`) or, for a channel in
    ``measured`` (stamps [s], fin positions [rad]), the measured positions, linearly
    interpolated between their samples (held before the first and after the last)."""
    out = actuator_positions(t, commands, params)
    for c, ch in enumerate(('bar', 'helm')):
        if measured and ch in measured and len(measured[ch][0]):
            st, va = measured[ch]
            out[:, c] = np.interp(t, st, va)
    return out


def actuator_sources(measured: Mapping[str, Series] | None,
                     sampled: Sequence[str] = ()) -> dict[str, str]:
    """Per channel, where :func:`actuator_track` takes the positions from (``sampled``:
    channels whose commands were sampled at the log's rows, see :func:`sampled_commands`)."""
    out = {}
    for ch in ('bar', 'helm', 'thrust'):
        if measured and ch in measured and len(measured[ch][0]):
            out[ch] = (f'measured fin position ({MEASURED_TOPICS[ch]}, linearly interpolated '
                       'between its samples)')
        else:
            out[ch] = 'command through the actuator model (delay-free, lag, rate and angle limits)'
            if ch in sampled:
                out[ch] += ('; the command was sampled at the log\'s rows and changes at most '
                            'of them: taken as linear between rows (held, it would lag by half '
                            'a row)')
    return out


#: A command series counts as sampled at the log's rows when its stamps are among the state's,
#: it has a sample on at least this share of the rows and changes value at this share of them,
#: and the rows are slower than :data:`SAMPLED_RATE_HZ` (a pilot runs at 5-10 Hz: at that rate
#: or faster, a command at every row is the pilot's own step, held).
SAMPLED_SHARE = 0.5
SAMPLED_RATE_HZ = 5.0


def sampled_commands(t: np.ndarray, commands: Mapping[str, Series], dt: float
                     ) -> tuple[dict[str, Series], list[str]]:
    """Commands logged as samples at the slow rows of a log (below :data:`SAMPLED_RATE_HZ`)
    of a command that moves between them (a pilot's, sent faster than the rows:
    :data:`SAMPLED_SHARE`) taken as linear between rows,
    as events every ``dt`` [s] (the vehicle's step), instead of held from each row (which
    delays them by half a row on average); other series (change events, steps) as they are.
    Returns the commands and the channels changed."""
    out = dict(commands)
    changed: list[str] = []
    if len(t) < 3 or float(np.median(np.diff(t))) < 1.0 / SAMPLED_RATE_HZ:
        return out, changed
    rows = set(np.round(np.asarray(t, float), 6).tolist())
    for ch, (st, va) in commands.items():
        st = np.asarray(st, float)
        va = np.asarray(va, float)
        if len(st) < 3 or len(st) < SAMPLED_SHARE * len(t):
            continue
        on_rows = np.mean([round(float(x), 6) in rows for x in st])
        moves = float(np.mean(np.diff(va) != 0.0))
        if on_rows < 0.9 or moves < SAMPLED_SHARE:
            continue
        dense = np.arange(float(st[0]), float(st[-1]) + 0.5 * dt, dt)
        out[ch] = (dense, np.interp(dense, st, va))
        changed.append(ch)
    return out, changed


def actuator_interval_means(t: np.ndarray, X: np.ndarray, commands: Mapping[str, Series],
                            params: VehicleParams, env: Environment, sub: int,
                            measured: Mapping[str, Series] | None = None) -> np.ndarray:
    """Mean of the actuator wrench (body FRD [N, N m]) over each sample interval
    ``[t_j, t_j+1]`` (N - 1, 6), by the trapezoid rule on ``sub`` sub-steps per interval:
    actuator positions from :func:`actuator_positions` at the sub-steps, the state linearly
    interpolated between its samples (it is smooth on the scale of a sample period; a
    thrust or fin actuator that settles within a period is not).

    Why: the consistent low-pass (:func:`consistent_kernel`) integrates every term over each
    sample interval by the trapezoid rule, exact to ``dt^2 f''``. At a low log rate (2 Hz)
    the actuators move within one interval (a 0.5 s thrust lag after a step): the trapezoid
    rule on the samples then misses part of the thrust impulse, which biased Ksh by +1.4
    standard errors on a noise-free 2 Hz log of the surge mission.
    """
    n = len(t)
    idx = np.arange((n - 1) * sub + 1) / sub
    tf = np.interp(idx, np.arange(n), t)
    Xf = np.empty((len(tf), NX))
    for c in range(12):
        Xf[:, c] = np.interp(idx, np.arange(n), X[:, c])
    Xf[:, 12:15] = actuator_track(tf, commands, params, measured)
    Wf = wrench_series(np.ascontiguousarray(tf), Xf, params.as_array(), env.env_vector(),
                       env.profile())[:, 3]
    w = np.ones(sub + 1)
    w[0] = w[-1] = 0.5
    w /= sub
    blocks = np.lib.stride_tricks.sliding_window_view(Wf, sub + 1, axis=0)[::sub]
    means: np.ndarray = np.einsum('jck,k->jc', blocks, w)
    return means


def _interval_filter(means: np.ndarray, window: int) -> np.ndarray:
    """The consistent low-pass of :func:`consistent_kernel` applied to interval means
    (N - 1, 6) instead of trapezoids of samples: ``sum_j c_j M_{t+j} / sum_j c_j`` over the
    intervals ``j = -m .. m-1`` of the window (N, 6; NaN over the first and last ``m``)."""
    m = window // 2
    j = np.arange(-m, m)
    c = (m * (m + 1) - j * (j + 1)) / 2.0
    c /= c.sum()
    n = len(means) + 1
    out = np.full((n, means.shape[1]), np.nan)
    if n > 2 * m:
        acc = np.zeros((n - 2 * m, means.shape[1]))
        for i in range(2 * m):
            acc += c[i] * means[i:n - 2 * m + i]
        out[m:n - m] = acc
    return out


def reconstruct(t: np.ndarray, state: np.ndarray,
                commands: Mapping[str, tuple[np.ndarray, np.ndarray]], params: VehicleParams,
                name: str = 'log', window_s: float = WINDOW_S,
                measured: Mapping[str, Series] | None = None,
                sampled: Sequence[str] = ()) -> ForceRecord:
    """Hydrodynamic wrench from motion for one uniformly sampled stretch.

    Parameters
    ----------
    t
        stamps (N,) [s], uniformly spaced.
    state
        (N, 12) ``x, y, z [m] NED, phi, theta, psi [rad], u, v, w [m/s], p, q, r
        [rad/s]`` body FRD, as logged.
    commands
        ``bar``/``helm``/``thrust`` -> (stamps [s], set-points [rad, rad, N]).
    params
        the base vehicle (mass, added mass, restoring, actuators).
    name
        record name.
    window_s
        Savitzky-Golay window [s].
    measured
        measured fin positions ``bar``/``helm`` -> (stamps [s], angles [rad]),
        used in place of the commands run through the actuator model.
    sampled
        channels whose commands were sampled at the rows (said in the record's
        actuator sources; see :func:`sampled_commands`).

    Returns
    -------
    A ForceRecord with the filtered wrench (NaN over the first and last half window), its
    kernel (so the regressors get the same filter) and how sensor noise propagates into
    it (noise levels estimated from ``state``).
    """
    n = len(t)
    dt = float(np.median(np.diff(t))) if n > 1 else math.nan
    window = window_samples(dt, window_s) if n > 1 else 5
    if n < window + 2:
        raise IdentificationError(f'{name}: {n} samples is too short for the {window}-sample '
                                  f'derivative window')
    m = window // 2
    nu = state[:, 6:12]
    nu_dot = savgol_filter(nu, window, POLYORDER, deriv=1, delta=dt, axis=0, mode='interp')
    X = np.zeros((n, NX))
    X[:, :12] = state
    X[:, 12:15] = actuator_track(t, commands, params, measured)
    env = Environment()
    tc = np.ascontiguousarray(t, dtype=np.float64)
    W = wrench_series(tc, X, params.as_array(), env.env_vector(), env.profile())
    sigma = noise_sigma(state)
    jac, shift = other_jacobian(tc, X, params, env, sigma)
    # the other wrenches of the noisy state, less their second-order mean shift from the noise
    other = W[:, 1] + W[:, 2] + W[:, 3] - shift
    kernel = consistent_kernel(window)
    other_f = np.empty_like(other)
    sub = max(1, int(math.ceil(dt / SUBSTEP_S - 1e-9)))
    if sub > 1:   # the actuator wrench's own interval means (see actuator_interval_means)
        other -= W[:, 3]
        act_f = _interval_filter(actuator_interval_means(t, X, commands, params, env, sub,
                                                         measured), window)
    for j in range(6):
        other_f[:, j] = np.convolve(other[:, j], kernel, mode='same')
    if sub > 1:
        other_f += act_f
    # the plane's wrench per unit CZbar / CMbar, as subtracted (linear in each; no thrust-line
    # term in the identification's still water)
    plane_unit = np.zeros((n, 6))
    for axis, coefficient in ((2, 'CZbar'), (4, 'CMbar')):
        value = float(params.values[coefficient])
        subtracted = act_f[:, axis] if sub > 1 else np.convolve(W[:, 3, axis], kernel,
                                                                mode='same')
        plane_unit[:, axis] = subtracted / value if value != 0.0 else np.nan
    M = mass_matrix(params)
    tau = nu_dot @ M.T - other_f
    tau[:m] = np.nan
    tau[n - m:] = np.nan
    noise = NoisePropagation(sigma=sigma, other_jacobian=jac, mass=M,
                             derivative_kernel=savgol_coeffs(window, POLYORDER, deriv=1,
                                                             delta=dt))
    limits = np.array([params.bar_max, params.helm_max])
    saturated = np.zeros((n, 3), bool)
    saturated[:, :2] = np.abs(X[:, 12:14]) >= limits * (1.0 - 1e-3)
    saturated[:, 2] = (X[:, 14] >= params.thrust_max * (1.0 - 1e-3)) | (
        X[:, 14] <= params.thrust_min + 1e-3 * abs(params.thrust_min))
    log = LoggedRun(t=np.asarray(t, float), state=np.asarray(state, float),
                    commands=dict(commands), measured=dict(measured or {}))
    return ForceRecord(name=name, t=np.asarray(t, float), nu=np.asarray(nu, float), tau=tau,
                       source='motion', kernel=kernel, noise=noise, saturated=saturated,
                       actuators=actuator_sources(measured, sampled), plane_unit=plane_unit,
                       log=log)


def _columns(arr: np.ndarray, fields: tuple[str, ...], topic: str) -> np.ndarray:
    names = arr.dtype.names or ()
    missing = [f for f in fields if f not in names]
    if missing:
        raise IdentificationError(f'topic {topic} has no field {missing[0]!r}')
    return np.column_stack([np.asarray(arr[f], float) for f in fields]) if len(arr) else (
        np.empty((0, len(fields))))


def choose_source(topics: Mapping[str, object] | set[str], source: str = 'auto') -> str:
    """``forces`` if requested or (``auto``) if the force topic is there, else ``motion``."""
    if source not in SOURCES:
        raise IdentificationError(f'unknown force source {source!r} (known: {SOURCES})')
    if source == 'auto':
        return 'forces' if FORCES_TOPIC in topics else 'motion'
    return source


def needed_topics(source: str) -> list[str]:
    """Topics a log must hold for ``source`` (``forces`` or ``motion``)."""
    if source == 'forces':
        return [STATE_TOPIC, FORCES_TOPIC]
    return [STATE_TOPIC, *COMMAND_TOPICS.values()]


def records_from_topics(arrays: Mapping[str, np.ndarray], params: VehicleParams,
                        source: str = 'auto', name: str = 'log',
                        window_s: float = WINDOW_S) -> list[ForceRecord]:
    """Force records from a log's topic arrays (as :func:`auv_bag.read_arrays` gives:
    structured arrays with ``t`` = header stamp [s] and one field per message field).

    The log is split into uniformly sampled stretches (see :func:`segments`); stretches too
    short for the derivative window are left out.

    Raises
    ------
    IdentificationError
        a needed topic is missing or empty, stamps go back, the force
        stamps do not match the state stamps, a value is not finite.
    """
    source = choose_source(set(arrays), source)
    for topic in needed_topics(source):
        if topic not in arrays:
            what = 'the force topic' if source == 'forces' else 'motion'
            raise IdentificationError(f'{name}: topic {topic} is missing (needed for forces '
                                      f'from {what})')
    st = arrays[STATE_TOPIC]
    if len(st) < 2:
        raise IdentificationError(f'{name}: topic {STATE_TOPIC} has {len(st)} message(s)')
    t = np.asarray(st['t'], float)
    back = np.flatnonzero(np.diff(t) <= 0)
    if len(back):
        i = int(back[0]) + 1
        raise IdentificationError(f'{name}: {STATE_TOPIC} stamps out of order at message {i} '
                                  f'({t[i - 1]:.6f} s, then {t[i]:.6f} s)')
    state = _columns(st, STATE_FIELDS, STATE_TOPIC)
    bad = ~np.all(np.isfinite(state), axis=1)
    if np.any(bad):
        i = int(np.flatnonzero(bad)[0])
        raise IdentificationError(f'{name}: non-finite {STATE_TOPIC} at t = {t[i]:.3f} s')
    parts = segments(t)
    records: list[ForceRecord] = []
    if source == 'forces':
        fo = arrays[FORCES_TOPIC]
        tf = np.asarray(fo['t'], float)
        tau_all = _columns(fo, FORCE_FIELDS, FORCES_TOPIC)
        idx = np.clip(np.searchsorted(tf, t), 0, max(len(tf) - 1, 0))
        if len(tf):
            prev = np.clip(idx - 1, 0, len(tf) - 1)
            idx = np.where(np.abs(tf[prev] - t) < np.abs(tf[idx] - t), prev, idx)
            match = np.abs(tf[idx] - t) <= 1e-6
        else:
            match = np.zeros(len(t), bool)
        if np.count_nonzero(match) < 0.5 * len(t):
            raise IdentificationError(
                f'{name}: only {np.count_nonzero(match)} of {len(t)} {STATE_TOPIC} stamps have '
                f'a {FORCES_TOPIC} message with the same stamp')
        tau = np.where(match[:, None], tau_all[idx] if len(tf) else np.nan, np.nan)
        logged = _logged_commands(arrays, name)
        for k, sl in enumerate(parts):
            log = None if logged is None else LoggedRun(
                t=t[sl], state=state[sl], commands=logged[0], measured=logged[1])
            records.append(ForceRecord(name=name if len(parts) == 1 else f'{name}#{k}',
                                       t=t[sl], nu=state[sl, 6:12], tau=tau[sl],
                                       source='forces', log=log))
        return records
    logged = _logged_commands(arrays, name)
    if logged is None:
        empty = next(ch for ch, tp in COMMAND_TOPICS.items() if not len(arrays[tp]))
        raise IdentificationError(f'no {empty} command in the log: the {empty} position '
                                  'cannot be reconstructed')
    commands, measured = logged
    commands, sampled = sampled_commands(t, commands, float(params.dt))
    dt = float(np.median(np.diff(t)))
    for k, sl in enumerate(parts):
        if sl.stop - sl.start < window_samples(dt, window_s) + 2:
            continue
        records.append(reconstruct(t[sl], state[sl], commands, params,
                                   name if len(parts) == 1 else f'{name}#{k}', window_s,
                                   measured, sampled))
    if not records:
        from auv_logs.segments import spacing_jitter

        why = spacing_jitter(t)
        raise IdentificationError(f'{name}: no stretch of {STATE_TOPIC} is long enough for the '
                                  f'{window_s:g} s derivative window'
                                  + (f': {why}' if why else ''))
    return records


def _logged_commands(arrays: Mapping[str, np.ndarray], name: str
                     ) -> tuple[dict[str, Series], dict[str, Series]] | None:
    """The command topics (channel -> (stamps [s], set-points), sorted by stamp) and the
    measured fin positions of a log's arrays; None when a command topic is missing."""
    if any(topic not in arrays or not len(arrays[topic]) for topic in COMMAND_TOPICS.values()):
        return None
    commands = {}
    for ch, topic in COMMAND_TOPICS.items():
        arr = arrays[topic]
        times = np.asarray(arr['t'], float)
        values = np.asarray(arr['value'], float)
        if not np.all(np.isfinite(values)):
            raise IdentificationError(f'{name}: non-finite value on {topic}')
        order = np.argsort(times, kind='stable')
        commands[ch] = (times[order], values[order])
    measured = {}
    for ch, tp in MEASURED_TOPICS.items():
        if tp not in arrays or not len(arrays[tp]):
            continue
        st, va = np.asarray(arrays[tp]['t'], float), np.asarray(arrays[tp]['value'], float)
        if not (np.all(np.isfinite(va)) and np.all(np.isfinite(st))):
            raise IdentificationError(f'{name}: non-finite value on {tp}')
        order = np.argsort(st, kind='stable')
        measured[ch] = (st[order], va[order])
    return commands, measured
