"""Validation before a vehicle file is written: the identified model against the base file on
held-out windows of the log.

The identification fits on the windows that are not held out (:func:`auv_ident.freerun.
split_windows`); on the held-out ones both models, the base file's and the identified,
predict the log by a free run (:mod:`auv_ident.freerun`: the simulator's RK4 and actuator
model, no feedback from the log) from the same start:

each model's own initial state (depth, pitch, surge, heave velocity, pitch rate) fitted to
the measured channels over the first quarter of the window (at least 4 samples), the same
way for both (:mod:`auv_ident.output_error` with no coefficient free), and scored on the
rest: a single logged sample would start an open-loop-unstable vehicle's run from its noise
(the REMUS 100's exact model, started from states with the sensor noise of a navigation-grade
vehicle, is 0.3 m off after two e-folding times, 0.1 mm from the true states).

Scored on the depth (and on the heading when sway and yaw were identified): per window the
log of the ratio of the identified model's rms error to the base's, their mean ``r`` and its
standard error over the windows (robust to the few windows where an open-loop-unstable
vehicle's runs grow large, which would dominate a ratio of pooled errors; ``R = e^r``). The
identified model is **written** unless

* one of its held-out runs diverges (non-finite, or beyond 1e4 in a state) where the base's
  does not, or its pooled error exceeds the base's tenfold and 1 m (1 rad): ``diverges``;
* ``r > log 1.01`` on a scored channel (the point estimate: a short log's few windows cannot
  show significance either way, and the base file is the safe answer), and the pooled rms
  errors differ by more than :data:`RESOLUTION` (5 mm of depth, 0.1 deg of heading: below
  that, the difference is not one a log resolves): ``worse``.

Otherwise ``better`` (``r < -max(log 1.01, 2 standard errors)``: significantly) or
``as good``. The report
and the command's log line give the figures (the pooled rms errors, ``R`` and its margin);
a model not written leaves the base file as the answer.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from scipy import optimize

from auv_contract.blas import one_blas_thread
from auv_ident.freerun import FreeRuns, Window, parameter_vector
from auv_ident.identify.records import LoggedRun
from auv_ident.output_error import (
    CHANNEL_NAMES,
    FITTED_STATES,
    OUTPUTS,
    ShootingProblem,
    channel_sigma,
)
from auv_sim.params import VehicleParams

#: Smallest relative margin of the rms ratio before a model counts as worse.
MARGIN_MIN = 0.01
#: Standard errors of the ratio in the margin.
MARGIN_SE = 2.0
#: Initial state fitted on this share of a window when a rate or velocity is derived.
LEAD_SHARE = 0.25
LEAD_MIN = 4
SCORED = {'z': 2, 'theta': 4, 'psi': 5}
#: Differences of rms error below these are not differences (depth [m], heading [rad]).
RESOLUTION = {'z': 0.005, 'psi': math.radians(0.1)}
#: A run this many times worse than the base's and beyond 1 m (1 rad) has diverged.
DIVERGED_RATIO = 10.0


@dataclasses.dataclass
class Validation:
    """Outcome of :func:`validate`."""

    verdict: str                       # better, as good, worse, diverges, not validated
    written: bool
    rms: dict[str, dict[str, float]]   # model -> channel -> rms error over held-out samples
    ratio: dict[str, float]            # channel -> geometric mean of the windows' rms ratios
    margin: dict[str, float]           # channel -> margin of a significant improvement
    windows: int
    seconds: float
    initial_state: str
    message: str
    growth: dict[str, float] = dataclasses.field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        return dataclasses.asdict(self)


def not_validated(why: str) -> Validation:
    """The identified model is written without a held-out comparison, and why."""
    return Validation(verdict='not validated', written=True, rms={}, ratio={}, margin={},
                      windows=0, seconds=0.0, initial_state='', message=why)


def _initial_states(runs: FreeRuns, params: VehicleParams, logs: Sequence[LoggedRun],
                    tracks: dict[tuple[float, ...], np.ndarray] | None = None
                    ) -> tuple[np.ndarray, list[int], str]:
    """Initial states (nw, 15) of ``params`` for the windows of ``runs``, the first scored
    sample of each window, and how they were set (module docstring); ``tracks``: the
    actuator positions kept between free runs of ``logs`` (:class:`FreeRuns`)."""
    X0 = runs.initial_states()
    derived = [c for c in ('z', 'theta', 'u', 'w', 'q')
               if not all(lg.is_measured(c) for lg in logs)]
    leads = [max(LEAD_MIN, int(LEAD_SHARE * (w.i1 - w.i0))) for w in runs.windows]
    lead_windows = [dataclasses.replace(w, i1=min(w.i1, w.i0 + n))
                    for w, n in zip(runs.windows, leads)]
    lead_runs = FreeRuns(logs, lead_windows, params, tracks=tracks)
    outputs = [c for c in OUTPUTS if all(lg.is_measured(CHANNEL_NAMES[c]) for lg in logs)]
    prob = ShootingProblem(lead_runs, params, (), outputs,
                           {c: channel_sigma(logs, c) for c in outputs}, np.zeros(0),
                           np.ones(0))
    z0 = prob.start(np.zeros(0))
    res = optimize.least_squares(lambda x: prob.residuals(x[None])[0], z0,
                                 jac=lambda x: prob.jacobian(x), method='trf',
                                 x_scale='jac', max_nfev=30, tr_solver='lsmr')
    _, x0 = prob.split(res.x)
    X0 = X0.copy()
    X0[:, list(FITTED_STATES)] = x0
    why = f' ({", ".join(derived)} derived in the log, not fitted to)' if derived else ''
    return X0, leads, (f'each model\'s initial state fitted to the first {LEAD_SHARE:.0%} of '
                       f'each window{why}, scored after')


@one_blas_thread
def validate(logs: Sequence[LoggedRun], windows: Sequence[Window], base: VehicleParams,
             identified: VehicleParams, lateral: bool = False,
             tracks: dict[tuple[float, ...], np.ndarray] | None = None) -> Validation:
    """Compare ``identified`` with ``base`` on the held-out ``windows`` (module docstring);
    ``lateral``: sway and yaw were identified, so the heading is scored too; ``tracks``: the
    actuator positions kept between free runs of ``logs`` (:class:`FreeRuns`)."""
    held = [w for w in windows if w.held_out]
    if not held:
        return not_validated('the log is too short to hold a window out')
    channels = ['z'] + (['psi'] if lateral and all(lg.is_measured('psi') for lg in logs)
                        else [])
    errs: dict[str, dict[str, list[np.ndarray]]] = {}
    diverged: dict[str, int] = {}
    how = ''
    tracks = {} if tracks is None else tracks
    for label, params in (('base', base), ('identified', identified)):
        runs = FreeRuns(logs, held, params, tracks=tracks)
        X0, first, how = _initial_states(runs, params, logs, tracks)
        pred = runs.run(parameter_vector(params)[None], X0[None])
        errs[label] = {c: [] for c in SCORED}
        diverged[label] = 0
        for j, w in enumerate(held):
            meas = logs[w.record].state[w.i0:w.i1]
            p = pred[j][0]
            if not np.all(np.isfinite(p)):
                diverged[label] += 1
            for c, k in SCORED.items():
                d = p[first[j]:, k] - meas[first[j]:, k]
                if k == 5:
                    d = (d + math.pi) % (2.0 * math.pi) - math.pi
                errs[label][c].append(np.where(np.isfinite(d), d, 1e4))
    rms = {lab: {c: float(np.sqrt(np.mean(np.concatenate(v) ** 2))) for c, v in e.items()}
           for lab, e in errs.items()}
    ratio: dict[str, float] = {}
    margin: dict[str, float] = {}
    verdict = 'as good'
    for c in channels:
        a = np.array([math.sqrt(float(np.mean(e ** 2))) for e in errs['identified'][c]])
        b = np.array([math.sqrt(float(np.mean(e ** 2))) for e in errs['base'][c]])
        floor = 1e-3 * RESOLUTION[c]
        logs_ratio = np.log(np.maximum(a, floor) / np.maximum(b, floor))
        mean = float(logs_ratio.mean())
        se = float(np.std(logs_ratio, ddof=1)) / math.sqrt(len(a)) if len(a) > 1 else 0.0
        ratio[c] = math.exp(mean)
        margin[c] = math.exp(max(math.log(1.0 + MARGIN_MIN), MARGIN_SE * se)) - 1.0
    n_scored = sum(len(e) for e in errs['base']['z'])
    seconds = float(sum(logs[w.record].t[w.i1 - 1] - logs[w.record].t[w.i0] for w in held))
    diff = {c: rms['identified'][c] - rms['base'][c] for c in channels}
    pooled = {c: rms['identified'][c] / max(rms['base'][c], 1e-300) for c in channels}
    if diverged['identified'] > diverged['base'] or any(
            pooled[c] > DIVERGED_RATIO and rms['identified'][c] > 1.0 for c in channels):
        verdict = 'diverges'
    elif any(ratio[c] > 1.0 + MARGIN_MIN and diff[c] > RESOLUTION[c] for c in channels):
        verdict = 'worse'
    elif all(ratio[c] < 1.0 - margin[c] and -diff[c] > RESOLUTION[c] for c in channels):
        verdict = 'better'
    written = verdict in ('better', 'as good')
    z_id, z_b = rms['identified']['z'], rms['base']['z']
    figures = (f'held-out depth rms {z_id:.3g} m against the base file\'s {z_b:.3g} m '
               f'(window ratio {ratio["z"]:.3g}, margin {margin["z"]:.2g}) over {len(held)} '
               f'window(s), {seconds:.0f} s, {n_scored} samples')
    if 'psi' in ratio:
        figures += (f'; heading rms {math.degrees(rms["identified"]["psi"]):.3g} deg against '
                    f'{math.degrees(rms["base"]["psi"]):.3g} deg')
    if verdict == 'diverges':
        message = (f'not written: the identified model diverges on held-out data '
                   f'({diverged["identified"]} of {len(held)} free runs, the base file\'s '
                   f'{diverged["base"]}); {figures}')
    elif verdict == 'worse':
        message = f'not written: the identified model predicts held-out data worse; {figures}'
    else:
        message = f'validated ({verdict}): {figures}'
    return Validation(verdict=verdict, written=written, rms=rms, ratio=ratio, margin=margin,
                      windows=len(held), seconds=seconds, initial_state=how, message=message,
                      growth=_growth(logs, base, identified))


def _growth(logs: Sequence[LoggedRun], base: VehicleParams, identified: VehicleParams
            ) -> dict[str, float]:
    """Fastest vertical-plane mode (largest real part [1/s]) of each model, linearised at the
    logs' median speed and depth; NaN where there is no trim."""
    from auv_sim.errors import TrimError
    from auv_sim.trim import VerticalPlane

    u = float(np.median(np.concatenate([lg.state[:, 6] for lg in logs])))
    z = float(np.median(np.concatenate([lg.state[:, 2] for lg in logs])))
    out = {}
    for label, params in (('base', base), ('identified', identified)):
        try:
            plane = VerticalPlane(params)
            A, _ = plane.linearize(plane.trim(u, z=z))
            out[label] = float(np.max(np.linalg.eigvals(A[np.ix_([0, 1, 3], [0, 1, 3])]).real))
        except (TrimError, np.linalg.LinAlgError, ValueError):
            out[label] = math.nan
    return out
