"""Plausibility of imported signals: a wrong unit or frame caught with one line.

A map that declares depth in metres for a column in centimetres imports a vehicle at 6000 m
whose depth changes at 24 m/s; raw gyro counts declared as rad/s give pitch rates thousands of
times the pitch angle's own rate. The signals of one log are not independent: the depth's rate
is what the surge, heave and pitch give (``z_dot = -u sin(theta) + v cos(theta) sin(phi) +
w cos(theta) cos(phi)``, NED/FRD), and a body rate is what the Euler angles' rates give (the
kinematic inverse). Each check is a regression
through the origin of the logged quantity on the one the others give, over every segment of
the log: the ratio ``k = sum(a b) / sum(b^2)`` of a right log is 1 within the angle of
attack's share (the heave velocity is small against the surge) and the noise; a unit off by
a factor ``f`` gives ``k ~ f``, a frame off by a sign ``k ~ -1``. A check runs only where the
quantity it compares against moves (more than :data:`MIN_MOTION` of its noise-free scale), so
a log of level flight is not judged on noise.

The vehicle's envelope (its file's rated depth, the speed its thrust can reach) bounds depth
and surge. A failed check is a :class:`PlausibilityError` naming the signal, the map key that
declares its unit, what was found and the unit that would fit.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence

import numpy as np

from auv_logs.errors import RealLogError
from auv_logs.units import UNITS

#: Ratio of a logged quantity to the one the other signals give beyond which a unit or frame
#: is taken as wrong (an angle of attack or a noisy derivative never moves it this far).
RATIO_LIMIT = 3.0
#: A check needs the compared quantity to move: RMS of at least this [m/s for the depth rate,
#: rad/s for a body rate] over at least :data:`MIN_SAMPLES` samples.
MIN_MOTION = {'depth_rate': 0.03, 'body_rate': math.radians(0.5)}
MIN_SAMPLES = 20
#: ... and the two must share their motion: |correlation| (about zero) of at least this.
MIN_CORRELATION = 0.3
#: Depth no vehicle reaches [m] (the Challenger Deep, 10 935 m, rounded up), and a surge speed
#: no survey AUV makes [m/s], bounds used when no vehicle file is given.
DEPTH_LIMIT = 11_000.0
SPEED_LIMIT = 15.0
#: Share of a signal's samples allowed beyond the envelope (a glitch is not a wrong unit).
OUTLIER_SHARE = 0.005


class PlausibilityError(RealLogError):
    """An imported signal cannot be what the map says it is (a wrong unit or frame)."""


@dataclasses.dataclass(frozen=True)
class Envelope:
    """Bounds of a vehicle's motion: rated depth ``depth_max`` [m] and the highest surge speed
    ``speed_max`` [m/s] it can reach; ``source`` names where they come from."""

    depth_max: float = DEPTH_LIMIT
    speed_max: float = SPEED_LIMIT
    source: str = 'physical limits (no vehicle file)'


def envelope_of(params: object) -> Envelope:
    """The envelope of a vehicle file (:class:`auv_sim.params.VehicleParams`): its rated
    depth plus 20 %, and twice the steady speed its largest thrust gives in level flight
    (its surge drag, :func:`auv_sim.model.wrench_series`, equal to ``thrust_max``)."""
    from auv_sim.environment import Environment
    from auv_sim.model import NX, wrench_series

    p = params
    P = p.as_array()        # type: ignore[attr-defined]
    env = Environment()

    def drag(u: float) -> float:
        x = np.zeros((1, NX))
        x[0, 6] = u
        w = wrench_series(np.zeros(1), x, P, env.env_vector(), env.profile())
        return float(-w[0, 0, 0])

    lo, hi = 0.0, 50.0
    thrust = float(p.thrust_max)        # type: ignore[attr-defined]
    if drag(hi) < thrust:
        speed = hi
    else:
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if drag(mid) < thrust else (lo, mid)
        speed = hi
    name = getattr(p, 'path', None) or getattr(p, 'name', 'vehicle')
    return Envelope(1.2 * float(p.depth_max), 2.0 * speed,  # type: ignore[attr-defined]
                    f'the vehicle file {name}: rated depth {float(p.depth_max):g} m '  # type: ignore[attr-defined]
                    f'(+20 %), twice its top speed {speed:.3g} m/s at its largest thrust')


@dataclasses.dataclass(frozen=True)
class Declared:
    """What the map says of a signal: its unit's name, dimension and SI factor, and where
    (map key and line)."""

    unit: str
    dimension: str
    factor: float
    where: str


def _better_unit(declared: Declared, ratio: float) -> str:
    """The unit of the same dimension that would bring a ratio of ``ratio`` nearest 1, as
    text (``'; in cm it would fit'``), or a hint when none does."""
    best, err = None, math.inf
    for name, u in UNITS.items():
        if u.dimension != declared.dimension or name == declared.unit:
            continue
        r = abs(ratio) * u.factor / declared.factor
        e = abs(math.log(r)) if r > 0 else math.inf
        if e < err:
            best, err = name, e
    if best is not None and err < math.log(RATIO_LIMIT / 1.5):
        return f'; in {best} it would fit'
    if abs(ratio) > 100.0:
        return ('; no unit fits: raw sensor counts? give the sensor\'s scale (scale: 1 / '
                'counts per unit)')
    return ''


def _within_unit(declared: Declared, value: float, limit: float, unit: str) -> str:
    """The unit of the same dimension, smaller than the declared one, that would bring
    ``value`` (SI, as imported) within ``limit``, as text with the value it would give."""
    fits = [(u.factor, n) for n, u in UNITS.items() if u.dimension == declared.dimension
            and u.factor < declared.factor and value * u.factor / declared.factor <= limit]
    if not fits:
        return ''
    factor, name = max(fits)
    return f'; in {name} it would be {value * factor / declared.factor:.4g} {unit}'


def _ratio(a: np.ndarray, b: np.ndarray, floor: float) -> float | None:
    """``sum(a b) / sum(b^2)`` over finite samples; None when ``b`` moves too little or the
    two do not share their motion (correlation below :data:`MIN_CORRELATION`: a log whose
    signals do not follow one another at all is no evidence of a scale)."""
    ok = np.isfinite(a) & np.isfinite(b)
    a, b = a[ok], b[ok]
    if a.size < MIN_SAMPLES or float(np.sqrt(np.mean(b ** 2))) < floor:
        return None
    den = float(np.sqrt(np.dot(a, a) * np.dot(b, b)))
    if den == 0.0 or abs(float(np.dot(a, b))) / den < MIN_CORRELATION:
        return None
    return float(np.dot(a, b) / np.dot(b, b))


#: Span [s] of the increments compared (at least 4 samples): long enough that the noise of
#: an angle or depth difference is small against its change, short enough to follow manoeuvres.
SPAN = 4.0


def _increments(t: np.ndarray, x: np.ndarray, rate: np.ndarray) -> tuple[np.ndarray,
                                                                          np.ndarray]:
    """Over consecutive spans of about :data:`SPAN` seconds of one segment: the change of
    ``x`` and the integral of ``rate`` (trapezoidal rule) [unit of x]."""
    n = len(t)
    dt = float(np.median(np.diff(t))) if n > 1 else 1.0
    step = max(4, int(round(SPAN / dt)))
    edges = np.arange(0, n, step)
    if n - 1 - edges[-1] >= step // 2:
        edges = np.r_[edges, n - 1]
    elif len(edges) > 1:
        edges[-1] = n - 1
    integral = np.r_[0.0, np.cumsum(0.5 * np.diff(t) * (rate[1:] + rate[:-1]))]
    return np.diff(x[edges]), np.diff(integral[edges])


def check_signals(name: str, segments: Sequence[tuple[np.ndarray, Mapping[str, np.ndarray]]],
                  origins: Mapping[str, str], declared: Mapping[str, Declared],
                  envelope: Envelope | None = None) -> list[str]:
    """Check one imported log's state (``segments``: per segment its stamps [s] and state
    signals, NED/FRD, SI) against its own kinematics and ``envelope``.

    The kinematics are compared on increments over spans of :data:`SPAN` seconds (the
    change of depth against the integral of ``-u sin(theta) + v cos(theta) sin(phi) +
    w cos(theta) cos(phi)``; the change of pitch against the integral of ``q cos(phi) -
    r sin(phi)``, of roll against ``p + (q sin(phi) + r cos(phi)) tan(theta)``, of yaw
    against ``(q sin(phi) + r cos(phi)) / cos(theta)``): integrals and differences carry far
    less noise than a differenced angle, whose noise would pull a ratio towards zero.
    Without a logged heave velocity the depth is compared in flight only (surge above 30 %
    of its median): a vehicle rising or sinking slowly moves in w alone.

    ``origins``: ``measured``, ``derived`` or ``assumed`` per state signal (only measured
    signals are judged); ``declared``: the map's unit of each mapped signal.

    Returns the checks that ran, one line each (for the import report).

    Raises
    ------
    PlausibilityError
        one line naming the signal, what was found, the map key that
        declares its unit, and the unit that would fit.
    """
    env = envelope or Envelope()
    ran: list[str] = []

    def fail(sig: str, what: str, ratio: float | None = None,
             bound: tuple[float, float, str] | None = None) -> PlausibilityError:
        dec = declared.get(sig)
        says = f' ({dec.where} says {dec.unit})' if dec is not None else ''
        hint = ''
        if dec is not None and ratio is not None:
            hint = _better_unit(dec, ratio)
        elif dec is not None and bound is not None:
            hint = _within_unit(dec, *bound)
        return PlausibilityError(f'{name}: {sig} {what}{says}: is its unit or frame right?'
                                 f'{hint}')

    measured = {s for s, o in origins.items() if o == 'measured'}
    zs: list[np.ndarray] = []
    us: list[np.ndarray] = []
    inc: dict[str, tuple[list[np.ndarray], list[np.ndarray]]] = {
        k: ([], []) for k in ('z', 'phi', 'theta', 'psi')}
    for t, s in segments:
        if len(t) < 8:
            continue
        zs.append(s['z'])
        us.append(s['u'])
        ph, th = s['phi'], s['theta']
        if {'z', 'theta', 'u'} <= measured:
            w = s['w'] if 'w' in measured else np.zeros_like(t)
            kin = -s['u'] * np.sin(th) + s['v'] * np.cos(th) * np.sin(ph) \
                + w * np.cos(th) * np.cos(ph)
            keep = np.ones(len(t), bool)
            if 'w' not in measured:
                keep = np.abs(s['u']) >= 0.3 * np.nanmedian(np.abs(s['u']))
            for a, b in _runs_of(keep):
                if b - a >= 8:
                    dz, ik = _increments(t[a:b], s['z'][a:b], kin[a:b])
                    inc['z'][0].append(dz)
                    inc['z'][1].append(ik)
        for ang, rate in (('theta', s['q'] * np.cos(ph) - s['r'] * np.sin(ph)),
                          ('phi', s['p'] + (s['q'] * np.sin(ph) + s['r'] * np.cos(ph))
                           * np.tan(th)),
                          ('psi', (s['q'] * np.sin(ph) + s['r'] * np.cos(ph)) / np.cos(th))):
            x = np.unwrap(s[ang]) if ang != 'theta' else s[ang]
            da, ir = _increments(t, x, rate)
            inc[ang][0].append(da)
            inc[ang][1].append(ir)
    if zs:
        z = np.concatenate(zs)
        z = z[np.isfinite(z)]
        deep = float(np.quantile(np.abs(z), 1.0 - OUTLIER_SHARE)) if z.size else 0.0
        if 'z' in measured and deep > env.depth_max:
            raise fail('z', f'reaches {deep:.4g} m, beyond {env.depth_max:.4g} m ({env.source})',
                       bound=(deep, env.depth_max, 'm'))
        u = np.concatenate(us)
        u = u[np.isfinite(u)]
        fast = float(np.quantile(np.abs(u), 1.0 - OUTLIER_SHARE)) if u.size else 0.0
        if 'u' in measured and fast > env.speed_max:
            raise fail('u', f'reaches {fast:.4g} m/s, beyond {env.speed_max:.4g} m/s '
                       f'({env.source})', bound=(fast, env.speed_max, 'm/s'))
        ran.append(f'depth within {env.depth_max:.4g} m and surge within {env.speed_max:.4g} '
                   f'm/s ({env.source})')
    if inc['z'][0]:
        k = _ratio(np.concatenate(inc['z'][0]), np.concatenate(inc['z'][1]),
                   MIN_MOTION['depth_rate'] * SPAN)
        if k is not None:
            if not 1.0 / RATIO_LIMIT <= k <= RATIO_LIMIT:
                raise fail('z', f'changes {k:.3g} times as much as u, w and pitch make it '
                           'change (depth increments against the kinematics)', k)
            ran.append(f'depth change / kinematic depth change (u, w, pitch) = {k:.3g}')
    for ang, axis, what in (('theta', 'q', 'pitch'), ('phi', 'p', 'roll'),
                            ('psi', 'r', 'yaw')):
        if axis not in measured or ang not in measured or not inc[ang][0]:
            continue
        k = _ratio(np.concatenate(inc[ang][0]), np.concatenate(inc[ang][1]),
                   MIN_MOTION['body_rate'] * SPAN)
        if k is None or k == 0.0:
            continue
        scale = 1.0 / k      # the logged rate against the attitude's own
        if not 1.0 / RATIO_LIMIT <= scale <= RATIO_LIMIT:
            raise fail(axis, f'is {scale:.4g} times the rate of the logged {what} (the '
                       f'{what} change against the integrated body rates)', scale)
        ran.append(f'{axis} / rate of the logged {what} = {scale:.3g}')
    return ran


def _runs_of(mask: np.ndarray) -> list[tuple[int, int]]:
    """``(start, stop)`` of the runs of True in ``mask``."""
    d = np.diff(np.r_[0, mask.astype(np.int8), 0])
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist()))
