"""What a hand analysis reads off a log's quiet stretches: thruster-off coasts and surface
passes.

With the propeller stopped and the vehicle slowed down, the hydrodynamic forces fade (they
grow with the speed through the water) and the weight, the buoyancy and their moments are
left: the vehicle rises or sinks at its net buoyancy and hangs at the pitch where the moment
of its centre of gravity about the centre of buoyancy balances the righting moment of the
vertical distance between them. So the heave and pitch equations at the *coast samples*
(held thrust zero, surge below :data:`COAST_SPEED` of the logs' median, from
:data:`COAST_SETTLE` seconds after the propeller stopped) identify a buoyancy offset ``dB``
[N] and the centre of gravity's longitudinal offset ``dxg`` [m] almost without the model's
hydrodynamics: the equation error of the nominal model there (``M nu_dot - tau``, body FRD,
:meth:`auv_gap.problem.Problem.equation_error`) is fitted by the two catalogue effects
(``buoyancy_offset``, ``cg_offset``), linear in both, by weighted least squares. Hanging at
pitch ``theta`` at rest: ``W dxg cos(theta) = -(zg W - zb B) sin(theta) - (xg W - xb B)
cos(theta)`` (Fossen 2011, eq. 4.6), so a nose-down hang is a centre of gravity forward.

Uncertainty (1.96 standard errors): per coast, the noise of the two smoothed velocities
whose difference over the coast's length is the mean acceleration, and the scatter of the
model's wrench over the coast; plus, added whole, what :data:`HYDRO_SHARE` of the hydrodynamic
and Coriolis wrench (the added mass's Munk moment) the file gives at those samples moves the
estimate (the file's low-speed
hydrodynamics, e.g. its quadratic cross-flow drag, may be off by that much); the centre of
gravity's offset also scales with the file's ``zg``, said.

At the surface the depth sensor reads its own depth below the waterline plus its zero error:
the import's surface passes (``surface_passes`` of the import report: the median reading
and its spread per pass) give the depth sensor's zero, to within that mounting depth.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from scipy import stats

from auv_gap.catalogue import Perturbation
from auv_gap.problem import EQUATIONS, EffectSet, Problem

#: Coast samples: surge below this share of the logs' median surge speed (dynamic pressure
#: below a sixteenth of cruise) ...
COAST_SPEED = 0.25
#: ... from this long [s] after the propeller stopped (its thrust decays) ...
COAST_SETTLE = 5.0
#: ... and at least this many of them.
MIN_SAMPLES = 8
#: Share of the file's hydrodynamic wrench at the coast samples taken as uncertain.
HYDRO_SHARE = 0.5


@dataclasses.dataclass(frozen=True)
class Finding:
    """A value read off the log's quiet stretches: catalogue effect and parameter, value and
    95 % interval [unit], whether the interval excludes zero, and the sentence."""

    effect: str
    param: str
    value: float
    lo: float
    hi: float
    unit: str
    significant: bool
    text: str
    source: str

    def as_dict(self) -> dict[str, Any]:
        """For the report."""
        return dataclasses.asdict(self)


def _held(stamps: np.ndarray, values: np.ndarray, t: np.ndarray) -> np.ndarray:
    i = np.searchsorted(stamps, t, side='right') - 1
    return np.asarray(values)[np.clip(i, 0, len(values) - 1)]


def coast_mask(pr: Problem) -> tuple[np.ndarray, np.ndarray]:
    """Equation samples of the problem on a coast (see the module docstring), and the coast
    each belongs to (an index per stretch, -1 elsewhere)."""
    mask = np.zeros(pr.eq_index.size, bool)
    u_med = float(np.median(np.abs(pr.eq_state[:, 6])))
    for li, lg in enumerate(pr.logs):
        rows = np.flatnonzero(pr.eq_log == li)
        if not rows.size:
            continue
        st, va = lg.commands['thrust']
        t = pr.eq_t[rows]
        scale = float(np.max(np.abs(va))) if len(va) else 0.0
        off = np.abs(_held(st, va, t)) <= 1e-6 * max(scale, 1.0)
        # time since the propeller last ran: the last stamp with thrust before t
        on_t = np.asarray(st)[np.abs(va) > 1e-6 * max(scale, 1.0)]
        j = np.searchsorted(on_t, t, side='right') - 1
        since = np.where(j >= 0, t - on_t[np.clip(j, 0, max(len(on_t) - 1, 0))]
                         if len(on_t) else np.inf, np.inf)
        slow = np.abs(pr.eq_state[rows, 6]) <= COAST_SPEED * u_med
        mask[rows] = off & slow & (since >= COAST_SETTLE)
    stretch = np.full(mask.size, -1)
    k = -1
    for i in range(mask.size):
        if mask[i]:
            new = i == 0 or not mask[i - 1] or pr.eq_log[i] != pr.eq_log[i - 1] or \
                pr.eq_t[i] - pr.eq_t[i - 1] > 3.0 * pr.smooth_window
            k += int(new)
            stretch[i] = k
    return mask, stretch


def coast_findings(pr: Problem, e_nom: np.ndarray) -> list[Finding]:
    """Net buoyancy and the centre of gravity's longitudinal offset from the coasts (see the
    module docstring); none without :data:`MIN_SAMPLES` coast samples. ``e_nom``: the
    nominal model's equation error at the problem's equation samples.

    Each coast's heave and pitch equations are averaged over it: the mean of ``M nu_dot`` is
    then ``M (nu_end - nu_start) / T``, whose noise is two smoothed velocity samples' over the
    coast's length ``T`` (not the differenced noise of every sample), and the two averaged
    equations give ``dB`` and ``dxg`` (weighted least squares over the coasts)."""
    mask, stretch = coast_mask(pr)
    n = int(mask.sum())
    if n < MIN_SAMPLES:
        return []
    vehicle = pr.vehicle
    rows = [EQUATIONS.index('heave'), EQUATIONS.index('pitch')]
    es = EffectSet(['buoyancy_offset', 'cg_offset'], vehicle)
    nom = Perturbation.nominal(vehicle)
    names = ('dB', 'dxg')
    idx = [next(i for i, (_, p) in enumerate(es.params) if p.name == nm) for nm in names]
    J = np.empty((pr.eq_index.size, 2, 2))
    for c, i in enumerate(idx):       # the equation error is linear in dB and dxg
        probe = np.zeros(len(es.params))
        probe[i] = es.scale[i]
        e1 = pr.equation_error(es.perturbation(probe))
        J[:, :, c] = (e1[:, rows] - e_nom[:, rows]) / es.scale[i]
    terms = pr.wrench_terms(nom)
    # hydrodynamic, Coriolis (the added mass's Munk moment) and actuator terms: what the
    # file's low-speed hydrodynamics and the noisy slow velocities put in
    hydro = (terms[:, 0] + terms[:, 1] + terms[:, 3])[:, [2, 4]]
    M = pr.M
    vel_noise = pr.noise[[8, 10]] * pr.smooth_gain          # smoothed w [m/s], q [rad/s]
    A_all, b_all, se_all, h_all = [], [], [], []
    for k in np.unique(stretch[mask]):
        m = stretch == k
        t = pr.eq_t[m]
        span = max(float(t[-1] - t[0]), pr.eq_step)
        A_all.append(np.mean(J[m], axis=0))
        b_all.append(-np.mean(e_nom[m][:, rows], axis=0))
        h_all.append(np.mean(hydro[m], axis=0))
        # the mean of M nu_dot: two smoothed velocities over the span; the mean of the
        # wrench: its scatter over the coast's samples
        dyn = np.array([math.hypot(M[2, 2] * vel_noise[0], M[2, 4] * vel_noise[1]),
                        math.hypot(M[4, 2] * vel_noise[0], M[4, 4] * vel_noise[1])])
        dyn = dyn * math.sqrt(2.0) / span
        spread = np.std(hydro[m], axis=0) / math.sqrt(max(int(m.sum()) / 3.0, 1.0))
        se_all.append(np.hypot(dyn, spread))
    A = np.vstack([a / s[:, None] for a, s in zip(A_all, se_all)])
    b = np.concatenate([bb / s for bb, s in zip(b_all, se_all)])
    x, *_ = np.linalg.lstsq(A, b, rcond=None)
    cov = np.linalg.pinv(A.T @ A)
    # the file's hydrodynamics at the coast samples, taken as uncertain by HYDRO_SHARE
    hb = np.concatenate([HYDRO_SHARE * hh / s for hh, s in zip(h_all, se_all)])
    shift, *_ = np.linalg.lstsq(A, hb, rcond=None)
    half = 1.96 * np.sqrt(np.maximum(np.diag(cov), 0.0)) + np.abs(shift)
    pitch = float(np.degrees(np.median(pr.eq_state[mask, 4])))
    w_down = float(np.median(pr.eq_state[mask, 8] * np.cos(pr.eq_state[mask, 4])
                             - pr.eq_state[mask, 6] * np.sin(pr.eq_state[mask, 4])))
    stretches = len(A_all)
    what = (f'{stretches} thruster-off coast(s), {n} samples at under {COAST_SPEED:.0%} of '
            'the median speed')
    out = []
    for c, nm in enumerate(names):
        v, h = float(x[c]), float(half[c])
        sig = abs(v) > h
        if nm == 'dB':
            how = ('more' if v > 0 else 'less') + ' buoyant than the file'
            rises = ('rises' if w_down < 0 else 'sinks') + f' at {abs(w_down):.2g} m/s'
            text = (f'net buoyancy {v:+.3g} N (95 % interval {v - h:+.3g} to {v + h:+.3g}) '
                    f'against the file: {how if sig else "consistent with the file"} (it '
                    f'{rises} with the thruster off)')
            out.append(Finding('buoyancy_offset', 'dB', v, v - h, v + h, 'N', sig, text, what))
        else:
            where = 'forward' if v > 0 else 'aft'
            mm = 1000.0
            text = (f'the centre of gravity {abs(v) * mm:.3g} mm {where} of the file\'s (95 % '
                    f'interval {(v - h) * mm:+.3g} to {(v + h) * mm:+.3g} mm, forward '
                    f'positive): {"an offset" if sig else "consistent with the file"} (it hangs '
                    f'{abs(pitch):.0f} deg nose {"down" if pitch < 0 else "up"} at rest; the '
                    f'estimate scales with the file\'s zg = {vehicle.zg * mm:.3g} mm)')
            out.append(Finding('cg_offset', 'dxg', v, v - h, v + h, 'm', sig, text, what))
    return out


def surface_finding(passes: Sequence[Mapping[str, Any]], noise: float = 0.0
                    ) -> Finding | None:
    """The depth sensor's reading at the surface from the import's surface passes (median
    reading, robust spread and samples per pass), or None without one: the mean of the
    passes' medians, with a Student interval over the passes (one pass: its spread over the
    square root of its samples), never narrower than twice the depth's white noise
    ``noise`` [m] (a reading in 0.1 m steps of a constant depth is off by up to half a step
    whatever the number of samples)."""
    good = [p for p in passes if p.get('samples', 0) >= 3]
    if not good:
        return None
    med = np.array([float(p['depth_median']) for p in good])
    spread = np.array([float(p.get('depth_spread') or 0.0) for p in good])
    count = np.array([float(p['samples']) for p in good])
    value = float(np.mean(med))
    within = float(np.sqrt(np.sum((spread / np.sqrt(count)) ** 2))) / len(good)
    if len(good) >= 2:
        se = math.hypot(float(np.std(med, ddof=1)) / math.sqrt(len(good)), within)
        tq = float(stats.t.ppf(0.975, len(good) - 1))
    else:
        se, tq = within, 2.0
    half = max(tq * se, 2.0 * noise, 1e-3)
    sig = abs(value) > half
    text = (f'the depth sensor reads {value:+.3g} m at the surface (95 % interval '
            f'{value - half:+.3g} to {value + half:+.3g}, {len(good)} surface pass(es)): '
            + ('its zero error, or its depth below the waterline afloat' if sig else
               'no zero error'))
    return Finding('depth_sensor_bias', 'bias', value, value - half, value + half, 'm', sig,
                   text, f'{len(good)} surface pass(es), {int(count.sum())} samples')
