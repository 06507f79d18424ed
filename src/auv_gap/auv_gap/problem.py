"""The data of one diagnosis prepared for fast model runs: windows, actuator series, the
equation-error samples, and the model evaluated for any set of effects.

Windows: every log piece is cut into windows of ``window`` seconds; a free run restarts at
each window from the smoothed logged state (so a long log never drifts far from the data and
every window is an independent run). Whole windows are held out to score the effects.

Actuator positions at a window's start come from the log's history: each candidate's actuator
model is driven by the logged commands from the start of the log piece, and the first
``ACT_SETTLE`` seconds of a piece (where the plane's position before the first command is
unknown) start no window.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np
from scipy.signal import savgol_filter

from auv_contract import CHANNELS, STATE_FIELDS
from auv_gap.catalogue import (
    CATALOGUE,
    Parameter,
    Perturbation,
    check_declared,
    get_effect,
)
from auv_gap.errors import GapError
from auv_gap.kernel import actuator_series, equation_terms, free_run_batch, water_sway
from auv_gap.logs import DERIVED_FROM, GapLog, Smoothed, smooth
from auv_gap.ranges import Ranges, default_ranges
from auv_sim.model import ENV_SIZE
from auv_sim.params import VehicleParams, mass_matrix

#: Equations of the equation error: body wrench rows (surge, heave, pitch, sway, yaw) and the
#: depth kinematics ``z_dot = -u s_th + v c_th s_ph + w c_th c_ph`` (m/s).
EQUATIONS = ('surge', 'heave', 'pitch', 'sway', 'yaw', 'depth_kinematics')
EQ_ROWS = (0, 2, 4, 1, 5)
EQ_UNITS = ('N', 'N', 'N m', 'N', 'N m', 'm/s')
#: States compared in free runs: z, theta, u, w, q, v, r (indices into the 12-state).
CH_INDEX = (2, 4, 6, 8, 10, 7, 11)
CH_NAMES = ('z', 'theta', 'u', 'w', 'q', 'v', 'r')
#: Seconds at the start of each log piece for the actuator models to forget their unknown
#: initial position (5 time constants of a 1-s lag).
ACT_SETTLE = 5.0
#: Longest window [s] (and the free-run length of a vehicle whose vertical-plane motion is
#: stable without feedback).
STABLE_WINDOW = 60.0
#: e-folding times of the fastest unstable vertical-plane mode that a window spans (a free
#: run from a state a little off grows about e^4 = 55-fold), and the shortest window [s].
UNSTABLE_FOLDS = 4.0
MIN_WINDOW = 10.0
#: Shortest free run [s] of a vehicle unstable without feedback (within a window).
MIN_RUN = 5.0
#: Windows the data should give at least (two training, one held out): the window is the
#: longest, up to :data:`STABLE_WINDOW`, that gives them.
MIN_WINDOWS = 3
#: Shortest window [s] made at the end of a log piece (a shorter tail joins the window before
#: it, or starts none).
MIN_TAIL = 4.0


def window_starts(n: int, step: float, window: float, settle: float = ACT_SETTLE,
                  min_tail: float = MIN_TAIL, m: int = 1) -> list[tuple[int, int]]:
    """``(i0, i1)`` sample ranges (``i1`` inclusive) of the windows of ``window`` [s] in a log
    piece of ``n`` samples ``step`` [s] apart (each ``m`` log samples), from ``settle`` [s]
    on; a tail shorter than half a window joins the window before it, and a piece shorter
    than ``min_tail`` [s] after ``settle`` starts none."""
    last = n - 1
    first = int(np.ceil(settle / step - 1e-9))
    nwin = max(2, int(round(window / step)))
    if last - first < max(2, min_tail / step):
        return []
    starts = list(range(first, last, nwin))
    if len(starts) > 1 and (last - starts[-1]) * m < (nwin * m) // 2:
        starts.pop()
    return [(a, (starts[j + 1] if j + 1 < len(starts) else last))
            for j, a in enumerate(starts)]


def data_window(logs: Sequence[GapLog]) -> tuple[float, str]:
    """The window [s] chosen from the data alone (so that diagnoses of the same logs with two
    vehicle files compare): the longest up to :data:`STABLE_WINDOW`, and at least
    :data:`MIN_WINDOW`, whose windows the log pieces give at least :data:`MIN_WINDOWS` of
    (each piece gives its own windows: a piece shorter than the window is one window); and
    why, in words."""
    period = float(np.median([lg.period for lg in logs]))
    durations = [lg.duration for lg in logs]

    def count(w: float) -> int:
        return sum(len(window_starts(lg.t.size, period, w)) for lg in logs)

    chosen = STABLE_WINDOW
    if count(STABLE_WINDOW) < MIN_WINDOWS:
        best = max(np.arange(STABLE_WINDOW, MIN_WINDOW - 1e-9, -1.0),
                   key=lambda w: (min(count(float(w)), MIN_WINDOWS), w))
        chosen = float(best)
    n = count(chosen)
    short = sum(d - ACT_SETTLE < chosen for d in durations)
    return chosen, (f'{chosen:g} s, chosen from the data: {len(logs)} log piece(s) of '
                    f'{min(durations):.3g}-{max(durations):.3g} s give {n} window(s)'
                    + (f' ({short} piece(s) shorter than a window are one window each)'
                       if short else ''))


def free_run_window(vehicle: VehicleParams, logs: Sequence[GapLog],
                    shortest: float = MIN_WINDOW) -> tuple[float, str]:
    """The longest free run [s] for ``vehicle`` on ``logs``, and why.

    A free run restarts from the log at every window; on a vehicle that is unstable without
    feedback (the REMUS 100: a vertical-plane pair at +0.39 +- 0.38j 1/s at 1.5 m/s) a run of
    :data:`STABLE_WINDOW` seconds diverges from any start, and every effect looks alike. The
    run spans :data:`UNSTABLE_FOLDS` e-folding times ``1/lambda`` of the fastest unstable
    mode of the nominal vertical plane (``w, q, theta``; linearised at the logs' median surge
    speed and depth), within [``shortest``, :data:`STABLE_WINDOW`]; :data:`STABLE_WINDOW`
    when no mode is unstable or no trim exists there. The diagnosis cuts the data into
    windows chosen from the data alone (:func:`data_window`) and restarts the free runs of
    such a vehicle within them.
    """
    from auv_sim.errors import TrimError
    from auv_sim.trim import VerticalPlane

    u = np.concatenate([lg.state[:, 6] for lg in logs])
    z = np.concatenate([lg.state[:, 2] for lg in logs])
    u0, z0 = float(np.nanmedian(u)), float(np.nanmedian(z))
    if not (np.isfinite(u0) and u0 > 0.0):
        return STABLE_WINDOW, f'no forward speed in the logs: {STABLE_WINDOW:g} s'
    plane = VerticalPlane(vehicle)
    try:
        A, _ = plane.linearize(plane.trim(u0, z=z0 if np.isfinite(z0) else 0.0))
    except TrimError:
        return STABLE_WINDOW, f'no level trim at {u0:.3g} m/s: {STABLE_WINDOW:g} s'
    lam = float(np.max(np.linalg.eigvals(A[np.ix_([0, 1, 3], [0, 1, 3])]).real))
    if lam <= 0.0:
        return STABLE_WINDOW, (f'vertical plane stable without feedback at {u0:.3g} m/s: '
                               f'{STABLE_WINDOW:g} s')
    window = float(np.clip(UNSTABLE_FOLDS / lam, shortest, STABLE_WINDOW))
    return window, (f'vertical plane unstable without feedback at {u0:.3g} m/s (mode '
                    f'+{lam:.3g} 1/s): {UNSTABLE_FOLDS:g} e-folding times, {window:.3g} s')


#: Seconds at the start of each window over which derived initial states are fitted to the
#: measured outputs (:meth:`Problem.estimate_initial`), and the fewest output samples used.
INITIAL_FIT = 3.0
INITIAL_FIT_MIN = 6


@dataclasses.dataclass(frozen=True)
class Window:
    """``n`` samples of log piece ``log`` from sample ``i0``; ``held_out`` for scoring."""

    log: int
    i0: int
    n: int
    held_out: bool
    t0: float
    t1: float


class EffectSet:
    """Several catalogue effects as one model: parameters concatenated in effect order, with
    the typical and possible ranges of ``ranges`` (default: :func:`default_ranges`)."""

    def __init__(self, names: Sequence[str], vehicle: VehicleParams,
                 ranges: Ranges | None = None) -> None:
        self.names = tuple(names)
        self.effects = [get_effect(n) for n in self.names]
        for e in self.effects:
            check_declared(e, vehicle)
        self.vehicle = vehicle
        table = ranges if ranges is not None else default_ranges()
        self.params: list[tuple[str, Parameter]] = [
            (e.name, p) for e in self.effects
            for p in table.apply(e.name, e.parameters(vehicle), vehicle)]
        self.absent = np.array([p.absent for _, p in self.params])
        self.lo = np.array([p.lo for _, p in self.params])
        self.hi = np.array([p.hi for _, p in self.params])
        self.scale = np.array([p.scale for _, p in self.params])
        #: parameters of each effect, in order (what :meth:`perturbation` slices)
        self.counts = [len(e.parameters(vehicle)) for e in self.effects]

    @property
    def label(self) -> str:
        """``name`` or ``name1+name2``."""
        return '+'.join(self.names)

    def perturbation(self, values: np.ndarray) -> Perturbation:
        """The model change for parameter ``values`` (all parameters, set order)."""
        pert = Perturbation.nominal(self.vehicle)
        k = 0
        for e, n in zip(self.effects, self.counts):
            e.apply(pert, np.asarray(values[k:k + n], dtype=np.float64), self.vehicle)
            k += n
        return pert


class Problem:
    """Logs, windows and the model of one vehicle, ready for free runs and equation errors.

    Parameters
    ----------
    vehicle
        the nominal model.
    logs
        log pieces (see :mod:`auv_gap.logs`).
    window
        window length [s] (the unit held out whole); None: chosen from the data,
        :func:`data_window` (kept with its reason in ``window`` and ``window_why``). On
        a vehicle unstable without feedback the free runs restart within each window
        every :func:`free_run_window` seconds (``run``, ``run_why``).
    held_out_logs
        indices of logs held out entirely; if empty, every third window
        (the 2nd, 5th, ...) is held out.
    eq_period
        spacing of equation-error samples [s].
    smooth_window
        Savitzky-Golay window [s] for states and derivatives.
    cost_period
        spacing of the free-run samples compared with the log [s].
    max_step
        largest integration step of the vehicle [s]; the actuators are integrated
        apart on a finer grid, so the step only has to resolve the vehicle's own motion.
    left_out
        equations (of :data:`EQUATIONS`) left out of the fits and tests (their
        noise set to infinity: weight zero), e.g. the depth kinematics when ``w`` was
        derived from the depth.
    fitted_initial
        derived rates (``w``, ``q``) whose initial values every free run
        fits to the measured depth and pitch (:meth:`estimate_initial`).
    ranges
        the typical and possible ranges of the effects' parameters
        (:mod:`auv_gap.ranges`; default the ranges file).
    sway_with_water
        the sway ``v`` was not logged (assumed 0): take the vehicle's sway through the water
        as zero instead, its sway over ground being the water's (:meth:`with_water_sway`).
        A vehicle in straight flight does not slide sideways through the water (nothing
        holds a side-slip): across a current it crabs with the water. Without this a
        current across the heading would make the model fly the vehicle sideways through
        the water at the current's speed, a side-slip the logs never showed.
    """

    def __init__(self, vehicle: VehicleParams, logs: Sequence[GapLog],
                 window: float | None = None,
                 held_out_logs: Sequence[int] = (), eq_period: float = 0.5,
                 smooth_window: float = 1.0, cost_period: float = 0.2,
                 max_step: float = 0.05, left_out: Sequence[str] = (),
                 fitted_initial: Sequence[str] = (), ranges: Ranges | None = None,
                 sway_with_water: bool = False) -> None:
        if not logs:
            raise GapError('no logs to diagnose')
        self.sway_with_water = sway_with_water
        self.window_why = 'given'
        if window is None:
            window, self.window_why = data_window(logs)
        self.window = window
        if not window > 0:
            raise GapError(f'window must be > 0 s, got {window}')
        run, self.run_why = free_run_window(vehicle, logs, MIN_RUN)
        #: free-run length [s]: the window, or shorter on a vehicle unstable without feedback
        self.run = min(run, window)
        self.vehicle = vehicle
        self.logs = list(logs)
        self.P = vehicle.as_array()
        self.M = mass_matrix(vehicle)
        self._param_cache: dict[tuple[tuple[str, float], ...], tuple[np.ndarray, np.ndarray]] = {
            (): (self.P, self.M)}
        #: time origin of the kernels [s]: the start of the first log (a current drift is
        #: zero here)
        self.t_ref = float(self.logs[0].t[0])
        periods = np.array([lg.period for lg in self.logs])
        if np.ptp(periods) > 1e-6 * periods.max():
            raise GapError('all logs must have the same state sample period '
                           f'(got {sorted(set(np.round(periods, 6)))} s)')
        self.period = float(periods[0])
        # free runs output every ``m`` log samples, each output interval ``sub`` RK4 steps
        if self.period <= max_step:
            self.m, self.sub = max(1, int(np.floor(max_step / self.period + 1e-9))), 1
        else:
            self.m, self.sub = 1, int(np.ceil(self.period / max_step - 1e-9))
        self.dt = self.m * self.period / self.sub
        self.h = self.dt / 2.0
        self.smoothed: list[Smoothed] = [smooth(lg, smooth_window) for lg in self.logs]
        # initial states of free runs: a wider smoother (the initial pitch error is what a
        # free run integrates longest), its bias removed by twicing: x0 = S x + (S x - S S x)
        wide = [smooth(lg, 2.0 * smooth_window) for lg in self.logs]
        twice = [savgol_filter(s.state, s.length, 3, axis=0, mode='interp') for s in wide]
        self.initial = [2.0 * s.state - s2 for s, s2 in zip(wide, twice)]
        # what twicing changed: the estimated bias of the plain smoother at the window starts
        self.initial_bias = [s2 - s.state for s, s2 in zip(wide, twice)]
        n = wide[0].length
        imp = np.zeros(2 * n)
        imp[n] = 1.0
        h1 = savgol_filter(imp, n, 3, mode='interp')
        self.initial_gain = float(np.linalg.norm(2.0 * h1 - savgol_filter(h1, n, 3,
                                                                          mode='interp')))
        self.smooth_window = smooth_window
        #: states whose initial values are fitted (:meth:`estimate_initial`), and per window
        #: (all windows) the nominal model's fit covariance (None: not fitted)
        self.x0_cov: list[np.ndarray | None] = []
        self.x0_states: tuple[int, ...] = ()
        self._x0_outs: list[int] = []
        self._x0_nfit = 0
        self.noise = np.median(np.array([s.noise for s in self.smoothed]), axis=0)
        self.deriv_gain = float(np.median([s.deriv_gain for s in self.smoothed]))
        self.smooth_gain = float(np.median([s.smooth_gain for s in self.smoothed]))
        # fine actuator grids, one per log, concatenated
        self.fine_n = [((lg.t.size - 1) // self.m) * self.sub * 2 + 1 for lg in self.logs]
        self.fine_off = np.r_[0, np.cumsum(self.fine_n)[:-1]].astype(np.int64)
        self.windows = self._windows(window, self.run, held_out_logs)
        #: windows left out of the free runs (:meth:`exclude`)
        self.excluded: frozenset[int] = frozenset()
        self.x0_cov = [None] * len(self.windows)
        if not any(w.held_out for w in self.windows) or all(w.held_out for w in self.windows):
            raise GapError('the logs are too short to hold out whole windows: need at least '
                           f'two windows of {window:g} s')
        self.cost_every = max(1, int(round(cost_period / (self.m * self.period))))
        self._eq_taps: tuple[np.ndarray, ...] | None = None
        self._act_cache: dict[bytes, np.ndarray] = {}
        self._eq_act_cache: dict[bytes, np.ndarray] = {}
        self._eq_samples(eq_period, smooth_window)
        self.ranges = ranges
        sigma: np.ndarray = np.where(np.isin(EQUATIONS, list(left_out)), np.inf,
                                     self.equation_sigma(self.M))
        self.eq_sigma = sigma
        self.estimate_initial(list(fitted_initial))

    def effect_set(self, names: Sequence[str]) -> EffectSet:
        """The effects ``names`` on this problem's vehicle, with its ranges."""
        return EffectSet(names, self.vehicle, self.ranges)

    # -- windows -----------------------------------------------------------------------------
    def _windows(self, window: float, run: float, held_out_logs: Sequence[int]
                 ) -> list[Window]:
        """Windows of ``window`` [s] per log piece (every third held out, or the pieces of
        ``held_out_logs``), each cut into free runs of ``run`` [s] that share its flag."""
        wins: list[Window] = []
        step = self.period * self.m
        k = 0
        for li, lg in enumerate(self.logs):
            n_out = (lg.t.size - 1) // self.m + 1       # samples on the output grid
            for a, b in window_starts(n_out, step, window, m=self.m):
                held = (li in held_out_logs) if held_out_logs else (k % 3 == 1)
                k += 1
                for ra, rb in window_starts(b - a + 1, step, run, settle=0.0,
                                            min_tail=0.0, m=self.m):
                    i0, i1 = (a + ra) * self.m, (a + rb) * self.m + 1
                    wins.append(Window(li, i0, i1 - i0, held, float(lg.t[i0]),
                                       float(lg.t[i1 - 1])))
        return wins

    def select(self, held_out: bool | None) -> list[int]:
        """Indices of the held-out (True), training (False) or all (None) windows, less the
        :attr:`excluded` ones."""
        return [i for i, w in enumerate(self.windows)
                if (held_out is None or w.held_out == held_out) and i not in self.excluded]

    def exclude(self, windows: Sequence[int]) -> bool:
        """Leave ``windows`` out of every later :meth:`select` (free-run fits, scores and
        tests; the equation error keeps their samples), unless that would leave no training
        or no held-out window; returns whether they were left out."""
        left = set(windows) | self.excluded
        keep = [w for i, w in enumerate(self.windows) if i not in left]
        if not any(w.held_out for w in keep) or all(w.held_out for w in keep):
            return False
        self.excluded = frozenset(left)
        return True

    # -- actuators ---------------------------------------------------------------------------
    def actuators(self, pert: Perturbation) -> np.ndarray:
        """Actuator positions (F x 3) on the fine grids of all logs for ``pert`` (cached:
        do not modify the result)."""
        key = np.concatenate([pert.delay, pert.tau, pert.rate]).tobytes()
        hit = self._act_cache.get(key)
        if hit is not None:
            return hit
        out = self.actuators_of(self.logs, pert)
        if len(self._act_cache) > 8:
            self._act_cache.clear()
        self._act_cache[key] = out
        return out

    def actuators_of(self, logs: Sequence[GapLog], pert: Perturbation) -> np.ndarray:
        """Actuator positions (F x 3) driven by the commands of ``logs`` (the problem's logs
        or the same logs with their commands reconstructed otherwise) for ``pert``."""
        out = np.empty((int(sum(self.fine_n)), 3))
        v = self.vehicle
        lims = ((-v.bar_max, v.bar_max), (-v.helm_max, v.helm_max),
                (v.thrust_min, v.thrust_max))
        for li, lg in enumerate(logs):
            a, n = int(self.fine_off[li]), self.fine_n[li]
            for c, ch in enumerate(CHANNELS):
                st, va = lg.commands[ch]
                lo, hi = lims[c]
                a0 = min(max(float(va[0]), lo), hi)
                out[a:a + n, c] = actuator_series(
                    float(lg.t[0]), self.h, n, st, va, float(pert.delay[c]), float(pert.tau[c]),
                    float(pert.rate[c]), lo, hi, a0)
        return out

    # -- free runs ---------------------------------------------------------------------------
    def free_run(self, perts: Sequence[Perturbation], windows: Sequence[int],
                 x0_noise: np.ndarray | None = None, x0_bias: bool = False,
                 act_override: np.ndarray | None = None,
                 x0_cov: list[np.ndarray | None] | None = None
                 ) -> tuple[np.ndarray, np.ndarray]:
        """Predicted measurements (nc x S x 12) of each model over ``windows``, and the
        log (S x 12) smoothed over ``smooth_window`` (white sensor noise removed, which no
        model can explain); rows are the windows' outputs, concatenated.

        ``x0_noise`` (nc x nw x 12) is added to the initial states (Monte Carlo of the
        initial-state uncertainty); ``x0_bias`` starts from the plain smoother instead of
        its twiced estimate (to size the initial-state bias); ``act_override`` (F x 3)
        replaces every model's actuator positions (:meth:`actuators_of`). After
        :meth:`estimate_initial` the derived rates' initial states are fitted for each model
        (``x0_cov`` receives the first model's fit covariances).
        """
        nc, nw = len(perts), len(windows)
        wins = [self.windows[i] for i in windows]
        nsamp = np.array([self.outputs(w) for w in wins], dtype=np.int64)
        out_base = np.r_[0, np.cumsum(nsamp)[:-1]].astype(np.int64)
        fine_base = np.array([self.fine_off[w.log] + (w.i0 // self.m) * self.sub * 2
                              for w in wins], dtype=np.int64)
        X0 = np.zeros((nc, nw, 15))
        env = np.empty((nc, ENV_SIZE))
        C = np.empty((nc, *perts[0].C.shape))
        P = np.empty((nc, self.P.size))
        t0 = np.array([float(self.logs[w.log].t[w.i0]) - self.t_ref for w in wins])
        act = np.empty((nc, int(sum(self.fine_n)), 3))
        for c, pert in enumerate(perts):
            act[c] = self.actuators(pert) if act_override is None else act_override
            env[c] = pert.env_vector()
            C[c] = pert.C
            P[c] = self.model_arrays(pert)[0]
            for k, w in enumerate(wins):
                src = self.initial[w.log]
                if x0_bias:
                    src = src + self.initial_bias[w.log]
                X0[c, k, :12] = self.true_state(src, np.array([float(w.i0)]), pert)[0]
                X0[c, k, 12:] = act[c, fine_base[k]]
            if self.sway_with_water and np.any(env[c] != 0.0):
                X0[c, :, 7] = self.with_water_sway(t0, X0[c], env[c])
        if self.x0_states:
            self._fit_initial(perts, wins, X0, P, act, fine_base, t0, env, C, x0_cov)
        if x0_noise is not None:
            X0[:, :, :12] += x0_noise
        out = np.empty((nc, int(nsamp.sum()), 12))
        free_run_batch(P, X0, act, fine_base, nsamp, out_base, t0, env, C, self.dt, self.sub,
                       out)
        meas = np.concatenate([self.smoothed[w.log].state[w.i0:w.i0 + w.n:self.m]
                               for w in wins])
        step = self.m * self.period
        for c, pert in enumerate(perts):
            if pert.sensors_exact:
                out[c] += pert.bias
                continue
            for k in np.flatnonzero(pert.latency > 0.0).tolist():
                # the sensor reads the state of ``latency`` ago: before the window's start
                # that is the logged state itself
                for r0, n in zip(out_base.tolist(), nsamp.tolist()):
                    tj = np.arange(n) * step
                    y = out[c, r0:r0 + n, k]
                    late = tj - pert.latency[k]
                    out[c, r0:r0 + n, k] = np.where(
                        late >= 0.0, np.interp(late, tj, y),
                        (meas[r0:r0 + n, k] - pert.bias[k]) / pert.scale[k])
            out[c] = out[c] * pert.scale + pert.bias
        return out, meas

    # -- initial states of derived rates -----------------------------------------------------
    def estimate_initial(self, derived: Sequence[str], seconds: float = INITIAL_FIT) -> None:
        """Fit, from now on, the initial values of the ``derived`` rates (``w``, ``q``: not
        measured, differenced from depth and pitch) and of their sources (``z``, ``theta``)
        at every window's start, for each model a free run is asked of, to the measured
        sources over the window's first ``seconds`` (at least ``INITIAL_FIT_MIN`` outputs):
        the initial-state estimate of output-error methods (:meth:`_fit_initial`). A
        differenced rate's noise would otherwise start every free run off.

        Sets :attr:`x0_cov` (the nominal model's fit covariance per window, which
        :meth:`initial_noise` draws from). The smoother's bias no longer applies to the
        estimated states."""
        if not derived:
            return
        self.x0_states = tuple(sorted({STATE_FIELDS.index(s) for s in derived}
                                      | {STATE_FIELDS.index(DERIVED_FROM[s]) for s in derived}))
        self._x0_outs = sorted({STATE_FIELDS.index(DERIVED_FROM[s]) for s in derived})
        self._x0_nfit = max(INITIAL_FIT_MIN, int(round(seconds / (self.m * self.period))) + 1)
        for li in range(len(self.logs)):
            self.initial_bias[li][:, list(self.x0_states)] = 0.0
        wins = self.select(None)
        cov: list[np.ndarray | None] = [None] * len(wins)
        self.free_run([Perturbation.nominal(self.vehicle)], wins, x0_cov=cov)
        for i, c in zip(wins, cov):
            self.x0_cov[i] = c

    def _fit_initial(self, perts: Sequence[Perturbation], wins: Sequence[Window],
                     X0: np.ndarray, P: np.ndarray, act: np.ndarray, fine_base: np.ndarray,
                     t0: np.ndarray, env: np.ndarray, C: np.ndarray,
                     cov: list[np.ndarray | None] | None = None) -> None:
        """Fit ``X0[c, k, x0_states]`` (nc x nw x 15, modified) of each model ``c`` and window
        ``k`` to the measured sources (``z``, ``theta``) over the window's first outputs:
        weighted least squares (weights: their white noise), two Gauss-Newton steps on
        finite-difference sensitivities of short free runs of that model, its sensors'
        scale and bias applied. A window whose run is not finite keeps its start. ``cov``
        (nw), if given, receives the last fit's covariance of the first model."""
        unknown, outs = list(self.x0_states), self._x0_outs
        nu, nc, nw = len(unknown), X0.shape[0], X0.shape[1]
        nfit = np.array([min(self.outputs(w), self._x0_nfit) for w in wins], dtype=np.int64)
        base = np.r_[0, np.cumsum(nfit)[:-1]].astype(np.int64)
        raw = [self.logs[w.log].state[w.i0:w.i0 + int(n) * self.m:self.m][:, outs]
               for w, n in zip(wins, nfit)]
        sigma = np.maximum(self.noise[outs], 1e-9)
        scale = np.array([p.scale[outs] for p in perts])
        bias = np.array([p.bias[outs] for p in perts])
        eps = 1e-4
        runs = np.empty((1 + nu, nc, int(nfit.sum()), 12))
        for _ in range(2):
            for j in range(1 + nu):
                Xj = X0.copy()
                if j:
                    Xj[:, :, unknown[j - 1]] += eps
                free_run_batch(P, Xj, act, fine_base, nfit, base, t0, env, C, self.dt,
                               self.sub, runs[j])
            y = runs[:, :, :, outs] * scale[None, :, None, :] + bias[None, :, None, :]
            for c in range(nc):
                for k in range(nw):
                    sl = slice(int(base[k]), int(base[k] + nfit[k]))
                    y0 = y[0, c, sl]
                    J = ((y[1:, c, sl] - y0[None]) / eps / sigma).reshape(nu, -1).T
                    res = ((raw[k] - y0) / sigma).ravel()
                    if not (np.all(np.isfinite(J)) and np.all(np.isfinite(res))):
                        continue
                    step, *_ = np.linalg.lstsq(J, res, rcond=None)
                    X0[c, k, unknown] += step
                    if cov is not None and c == 0:
                        cov[k] = np.linalg.pinv(J.T @ J)

    def initial_noise(self, rng: np.random.Generator, runs: int, windows: Sequence[int]
                      ) -> np.ndarray:
        """Draws (runs x nw x 12) of the initial-state error of ``windows``: the smoothed
        state's noise (``noise x initial_gain``), and for the states :meth:`estimate_initial`
        estimated, its covariance."""
        draw: np.ndarray = rng.standard_normal((runs, len(windows), 12)) * (
            self.noise * self.initial_gain)
        unknown = list(self.x0_states)
        for k, i in enumerate(windows):
            cov = self.x0_cov[i]
            if cov is not None:
                L = np.linalg.cholesky(cov + 1e-18 * np.eye(len(unknown)))
                draw[:, k, unknown] = rng.standard_normal((runs, len(unknown))) @ L.T
        return draw

    def model_arrays(self, pert: Perturbation) -> tuple[np.ndarray, np.ndarray]:
        """The model's parameter vector and mass matrix with the factors of ``pert`` (cached:
        do not modify the results)."""
        key = pert.params_key()
        hit = self._param_cache.get(key)
        if hit is None:
            v = self.vehicle.replace(**{k: f * float(getattr(self.vehicle, k)) for k, f in key})
            hit = (v.as_array(), mass_matrix(v))
            if len(self._param_cache) > 16:
                self._param_cache = {(): (self.P, self.M)}
            self._param_cache[key] = hit
        return hit

    def true_state(self, series: np.ndarray, index: np.ndarray, pert: Perturbation
                   ) -> np.ndarray:
        """The true state (n x 12) behind a measured series (N x 12, one log on its sample
        grid) at fractional sample positions ``index`` (n): the sensors of ``pert`` read
        ``scale x(t - latency) + bias``, so ``x(t) = (y(t + latency) - bias) / scale``."""
        if pert.sensors_exact and np.all(index == np.round(index)):
            out: np.ndarray = series[index.astype(np.int64)] - pert.bias
            return out
        grid = np.arange(series.shape[0], dtype=np.float64)
        pos = index[:, None] + pert.latency[None, :] / self.period
        out = np.empty((index.size, 12))
        for k in range(12):
            out[:, k] = np.interp(pos[:, k], grid, series[:, k])
        true: np.ndarray = (out - pert.bias) / pert.scale
        return true

    def with_water_sway(self, t: np.ndarray, X: np.ndarray, env: np.ndarray) -> np.ndarray:
        """The sway [m/s] (body y, FRD) of states ``X`` (n x >= 6) at kernel times ``t`` (n)
        [s] when :attr:`sway_with_water`: the water's in the environment ``env``, so the
        sway through the water is zero; otherwise the states' own sway (``X[:, 7]``)."""
        if not self.sway_with_water:
            return np.array(X[:, 7], dtype=np.float64)
        sway: np.ndarray = water_sway(np.ascontiguousarray(t, dtype=np.float64),
                                      np.ascontiguousarray(X[:, :6], dtype=np.float64), env)
        return sway

    def outputs(self, w: Window) -> int:
        """Number of free-run outputs of window ``w`` (every ``m``-th log sample)."""
        return (w.n - 1) // self.m + 1

    def output_times(self, windows: Sequence[int]) -> np.ndarray:
        """Log times [s] of the rows of :meth:`free_run`."""
        return np.concatenate([self.logs[self.windows[i].log].t[
            self.windows[i].i0:self.windows[i].i0 + self.windows[i].n:self.m] for i in windows])

    def window_rows(self, windows: Sequence[int]) -> list[slice]:
        """Row slices of each window in the arrays of :meth:`free_run`."""
        rows, a = [], 0
        for i in windows:
            n = self.outputs(self.windows[i])
            rows.append(slice(a, a + n))
            a += n
        return rows

    # -- equation error ----------------------------------------------------------------------
    def _eq_samples(self, eq_period: float, smooth_window: float) -> None:
        every = max(1, int(round(eq_period / self.period)))
        #: spacing of the equation samples [s] (every log piece alike)
        self.eq_step = every * self.period
        edge = int(round(0.5 * smooth_window / self.period)) + 1
        idx, logi, win = [], [], []
        for wi, w in enumerate(self.windows):
            lg = self.logs[w.log]
            lo = max(w.i0, edge)
            hi = min(w.i0 + w.n - 1, lg.t.size - edge)
            if wi + 1 < len(self.windows) and self.windows[wi + 1].log == w.log:
                hi = min(hi, self.windows[wi + 1].i0)
            ii = np.arange(lo + (-lo) % every, hi, every)
            idx.append(ii)
            logi.append(np.full(ii.size, w.log))
            win.append(np.full(ii.size, wi))
        self.eq_index = np.concatenate(idx).astype(np.int64)
        self.eq_log = np.concatenate(logi).astype(np.int64)
        self.eq_window = np.concatenate(win).astype(np.int64)
        self.eq_held = np.array([self.windows[w].held_out for w in self.eq_window])
        xs = np.empty((self.eq_index.size, 12))
        xd = np.empty((self.eq_index.size, 12))
        tt = np.empty(self.eq_index.size)
        fine = np.empty(self.eq_index.size)
        for li, sm in enumerate(self.smoothed):
            m = self.eq_log == li
            xs[m] = sm.state[self.eq_index[m]]
            xd[m] = sm.rate[self.eq_index[m]]
            tt[m] = self.logs[li].t[self.eq_index[m]]
            fine[m] = self.fine_off[li] + self.eq_index[m] * (self.sub * 2.0 / self.m)
        self.eq_t, self.eq_state, self.eq_rate, self.eq_fine = tt, xs, xd, fine
        # noise of each equation: velocity noise through the derivative filter and M
        self.eq_sigma = self.equation_sigma(self.M)

    def equation_sigma(self, M: np.ndarray) -> np.ndarray:
        """Noise (1 sigma) of each equation of the equation error with mass matrix ``M``
        [N, N m, m/s]: the velocity noise through the derivative filter and ``M``."""
        sd = self.noise[6:12] * self.deriv_gain
        sig = np.sqrt((M ** 2) @ (sd ** 2))
        sz = np.hypot(self.noise[2] * self.deriv_gain, self.noise[8] * self.smooth_gain)
        return np.array([sig[r] for r in EQ_ROWS] + [sz])

    def equation_error(self, pert: Perturbation, act: np.ndarray | None = None) -> np.ndarray:
        """Equation error (n x 6) at the equation samples: ``M nu_dot - tau`` for surge,
        heave, pitch, sway, yaw [N, N m] (``M`` and ``tau`` of the model with the factors,
        water and extra wrench of ``pert``) and the depth-kinematics error [m/s], with the
        states and their rates corrected for the sensors of ``pert`` (bias, scale, latency).
        The depth-kinematics error is ``y_z_dot(t) - scale z_dot(t - latency)``: the logged
        depth rate against the rate the depth sensor of ``pert`` reads."""
        if act is None:
            act = self.actuators(pert)
        X = np.empty((self.eq_index.size, 15))
        kin = X
        depth_rate = self.eq_rate[:, 2]
        if pert.sensors_exact:
            X[:, :12] = self.eq_state - pert.bias
            rate = self.eq_rate
        else:
            rate = np.empty_like(self.eq_rate)
            kin = np.empty((self.eq_index.size, 12))
            for li, sm in enumerate(self.smoothed):
                m = self.eq_log == li
                idx = self.eq_index[m].astype(np.float64)
                X[m, :12] = self.true_state(sm.state, idx, pert)
                # rates: shifted and scaled alike, no bias
                rate[m] = self.true_state(sm.rate, idx, dataclasses.replace(
                    pert, bias=np.zeros(12)))
                # the true states at the instant the depth sensor reads (t - latency)
                kin[m] = self.true_state(sm.state, idx - pert.latency[2] / self.period, pert)
        key = np.concatenate([pert.delay, pert.tau, pert.rate]).tobytes()
        eq_act = self._eq_act_cache.get(key)
        if eq_act is None:
            eq_act = self._smoothed_actuators(act)
            if len(self._eq_act_cache) > 8:
                self._eq_act_cache.clear()
            self._eq_act_cache[key] = eq_act
        X[:, 12:] = eq_act
        P, M = self.model_arrays(pert)
        env = pert.env_vector()
        if self.sway_with_water and np.any(env != 0.0):
            X[:, 7] = self.with_water_sway(self.eq_t - self.t_ref, X, env)
        tau = equation_terms(self.eq_t - self.t_ref, X, env, pert.C, P)
        lhs = rate[:, 6:12] @ M.T
        e = np.empty((X.shape[0], 6))
        for k, r in enumerate(EQ_ROWS):
            e[:, k] = lhs[:, r] - tau[:, r]
        # depth kinematics in the depth sensor's terms: the logged depth rate at its own
        # samples against the rate the sensor reads, ``scale z_dot(t - latency)``. The noisy
        # measured rate is never shifted by a candidate latency (shifting it moves its noise
        # with the parameter and makes the cost as rough as the noise in the latency: an
        # estimate off by its noise's correlation time with an interval far too narrow);
        # the smooth, nearly noise-free kinematic states are read at ``t - latency`` instead
        th, ph = kin[:, 4], kin[:, 3]
        zdot = (-kin[:, 6] * np.sin(th) + kin[:, 7] * np.cos(th) * np.sin(ph)
                + kin[:, 8] * np.cos(th) * np.cos(ph))
        e[:, 5] = depth_rate - pert.scale[2] * zdot
        return e

    def wrench_terms(self, pert: Perturbation) -> np.ndarray:
        """The model's wrench at the equation samples by term (n x 4 x 6: hydrodynamic,
        Coriolis, restoring, actuators; body FRD [N, N m]) for ``pert``'s model and water,
        at the smoothed logged states (:func:`auv_sim.model.wrench_series`; the extra wrench
        of ``pert`` is not in it)."""
        from auv_sim.model import wrench_series

        key = np.concatenate([pert.delay, pert.tau, pert.rate]).tobytes()
        eq_act = self._eq_act_cache.get(key)
        if eq_act is None:
            eq_act = self._smoothed_actuators(self.actuators(pert))
        X = np.empty((self.eq_index.size, 15))
        X[:, :12] = self.eq_state - pert.bias
        X[:, 12:] = eq_act
        out: np.ndarray = wrench_series(self.eq_t - self.t_ref, X, self.model_arrays(pert)[0],
                                        pert.env_vector(), np.zeros((0, 4)))
        return out

    def _smoothed_actuators(self, act: np.ndarray) -> np.ndarray:
        """Actuator positions at the equation samples, smoothed by the same filter as the
        logged velocities (both sides of the equation see the same low-pass)."""
        if self._eq_taps is None:
            n = self.smoothed[0].length
            imp = np.zeros(n)
            imp[n // 2] = 1.0
            taps = savgol_filter(imp, n, 3, mode='interp')[::-1]
            offs = np.arange(n) - n // 2
            stride = 2 * self.sub / self.m  # fine points per log sample
            pos = (self.fine_off[self.eq_log][:, None]
                   + (self.eq_index[:, None] + offs[None, :]) * stride)
            j0 = np.clip(np.floor(pos).astype(np.int64), 0, act.shape[0] - 1)
            self._eq_taps = (taps, j0, np.minimum(j0 + 1, act.shape[0] - 1), pos - j0)
        taps, j0, j1, frac = self._eq_taps
        out = np.empty((self.eq_index.size, 3))
        for c in range(3):
            a = act[:, c]
            out[:, c] = ((a[j0] * (1.0 - frac) + a[j1] * frac) @ taps)
        return out


def known_effects() -> list[str]:
    """Names of the registered effects."""
    return list(CATALOGUE)
