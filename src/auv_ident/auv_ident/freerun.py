"""Free runs of a vehicle model against windows of a log: the simulation error the
identification refines its coefficients on (:mod:`auv_ident.output_error`) and validates an
identified model with (:mod:`auv_ident.validate`).

A free run starts from a state at a window's start and integrates the model with the one RK4
of the simulator (:func:`auv_sim.model.rk4_prescribed`, the vehicle file's step ``dt``), in
still water, with the actuator positions of the log: the logged commands through the
vehicle's own actuator model (:func:`auv_ident.motion.actuator_track`, run from the start of
the log so the actuators' state at a window's start is their history's), or the measured fin
positions. Nothing of the log's motion feeds back: a model that predicts the window from its
first state is a model of the vehicle. The predicted states are interpolated (linearly) from
the integration grid to the log's stamps.

Windows: every record of the log is cut into windows of equal length
(:func:`window_length`: three e-folding times of the fastest unstable vertical-plane mode
of the base vehicle at most, 10-30 s; so a free run of an open-loop unstable vehicle does
not diverge from the small error of its initial state); :func:`split_windows` holds every
third one out.

Frames: NED world, FRD body, origin at the centre of buoyancy; SI units, radians; states in
:data:`auv_sim.model.STATE_NAMES` order.
"""
from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Sequence

import numpy as np
from numba import njit, prange

from auv_ident.identify import ForceRecord, LoggedRun
from auv_ident.motion import actuator_track
from auv_sim.model import ENV_SIZE, NB_EXTRA, NX, rk4_prescribed
from auv_sim.params import PARAM_NAMES, VehicleParams

#: Longest and shortest window [s] and the e-folding times of an unstable mode it spans.
WINDOW_MAX = 30.0
WINDOW_MIN = 10.0
UNSTABLE_FOLDS = 3.0
#: Windows a log is cut into at least (a short log gets shorter windows, not fewer).
WINDOWS_MIN = 6
#: Every ``HOLD_EVERY``-th window is held out (from the second on); at most this many
#: seconds of a long log are held out (every n-th window for a larger n).
HOLD_EVERY = 3
HOLD_MAX_S = 600.0
#: Seconds at the start of a record no window starts in: the actuators' state before the
#: first logged command is unknown (taken as settled at it) and forgotten after 5 of their
#: 1-s time constants.
SETTLE_S = 5.0
#: Longest RK4 step of the free runs [s] (see :func:`integration_step`).
STEP_MAX = 0.05


@njit(parallel=True, cache=True)
def _run_windows(P, X0, act, f0, t0, nsteps, out_base, dt, sub, out):  # type: ignore
    """Free runs of ``nv`` parameter vectors ``P`` (nv, NP) over ``nw`` windows, in parallel:
    window ``w`` from ``X0[v, w]`` (15) at ``t0[w]`` [s] for ``nsteps[w]`` outputs, ``sub`` RK4
    steps of ``dt`` [s] apart, actuator positions ``act`` (F, 3) from fine row ``f0[w]`` (half
    steps); the 12 vehicle states at every output go to ``out[v, out_base[w] + s]`` (NaN from
    a non-finite or diverged step on)."""
    nv = P.shape[0]
    nw = X0.shape[1]
    prof = np.zeros((0, 4))
    env = np.zeros(ENV_SIZE)
    C = np.zeros((NB_EXTRA, 6))
    for job in prange(nv * nw):
        v = job // nw
        w = job % nw
        x = X0[v, w].copy()
        row = out_base[w]
        for i in range(12):
            out[v, row, i] = x[i]
        bad = False
        for s in range(nsteps[w]):
            if not bad:
                status = rk4_prescribed(t0[w] + s * sub * dt, x, P[v], env, prof, dt, sub, C,
                                        act, f0[w] + 2 * s * sub)
                bad = status >= 0
                for i in range(12):
                    if not abs(x[i]) < 1.0e4:
                        bad = True
            for i in range(12):
                out[v, row + s + 1, i] = np.nan if bad else x[i]


@dataclasses.dataclass(frozen=True)
class Window:
    """Samples ``i0 .. i1 - 1`` of record ``record``; ``held_out``: not used by the fit."""

    record: int
    i0: int
    i1: int
    held_out: bool = False


def window_length(base: VehicleParams, logs: Sequence[LoggedRun],
                  folds: float = UNSTABLE_FOLDS) -> tuple[float, str]:
    """The free-run window [s] for ``base`` on ``logs`` and why (module docstring):
    ``folds`` e-folding times of an unstable vertical-plane mode at most."""
    from auv_sim.errors import TrimError
    from auv_sim.trim import VerticalPlane

    total = sum(float(lg.t[-1] - lg.t[0]) for lg in logs if len(lg.t) > 1)
    longest = WINDOW_MAX
    why = f'{WINDOW_MAX:g} s'
    u = np.concatenate([lg.state[:, 6] for lg in logs])
    z = np.concatenate([lg.state[:, 2] for lg in logs])
    u0, z0 = float(np.median(u)), float(np.median(z))
    if np.isfinite(u0) and u0 > 0.05:
        plane = VerticalPlane(base)
        try:
            A, _ = plane.linearize(plane.trim(u0, z=z0 if np.isfinite(z0) else 0.0))
            lam = float(np.max(np.linalg.eigvals(A[np.ix_([0, 1, 3], [0, 1, 3])]).real))
        except (TrimError, np.linalg.LinAlgError, ValueError):
            lam = 0.0
        if lam > 0.0:
            longest = folds / lam
            why = (f'{folds:g} e-folding times of the base vehicle\'s unstable '
                   f'vertical-plane mode (+{lam:.3g} 1/s at {u0:.3g} m/s)')
    length = min(longest, WINDOW_MAX)
    if total / WINDOWS_MIN < length:
        length = max(total / WINDOWS_MIN, min(WINDOW_MIN, length))
        why = f'the log\'s {total:.0f} s in {WINDOWS_MIN} windows or more'
    return float(length), why


def split_windows(logs: Sequence[LoggedRun], length: float, hold: bool = True
                  ) -> list[Window]:
    """Every record cut into windows of ``length`` [s] from :data:`SETTLE_S` after its start
    (the remainder joins the last window of a record); with ``hold``, every
    :data:`HOLD_EVERY`-th window from the second on is held out, fewer on a long log (at most
    :data:`HOLD_MAX_S` seconds)."""
    out: list[Window] = []
    for k, lg in enumerate(logs):
        if len(lg.t) < 4:
            continue
        start = float(lg.t[0]) + SETTLE_S
        dur = float(lg.t[-1]) - start
        if dur < min(length, WINDOW_MIN):
            continue
        n = max(1, int(dur // length))
        edges = np.searchsorted(lg.t, start + length * np.arange(n + 1), side='left')
        edges[-1] = len(lg.t)
        for a, b in itertools.pairwise(edges):
            if b - a >= 4:
                out.append(Window(k, int(a), int(b)))
    if not hold or len(out) < 2:
        return out
    total = sum(float(logs[w.record].t[w.i1 - 1] - logs[w.record].t[w.i0]) for w in out)
    every = max(HOLD_EVERY, int(math.ceil(total / HOLD_MAX_S)))
    return [dataclasses.replace(w, held_out=(j % every == 1)) for j, w in enumerate(out)]


def shooting_segments(windows: Sequence[Window], logs: Sequence[LoggedRun], length: float
                      ) -> list[Window]:
    """``windows`` cut into pieces of ``length`` [s] or less (at least 4 samples each)."""
    out: list[Window] = []
    for w in windows:
        t = logs[w.record].t
        start = w.i0
        while start < w.i1:
            stop = int(np.searchsorted(t, t[start] + length, side='left'))
            stop = min(max(stop, start + 4), w.i1)
            if w.i1 - stop < 4:
                stop = w.i1
            out.append(dataclasses.replace(w, i0=start, i1=stop))
            start = stop
    return out


def use_masks(records: Sequence[ForceRecord], windows: Sequence[Window]
              ) -> list[np.ndarray | None]:
    """Per record, the samples a fit may use: False inside held-out windows."""
    masks: list[np.ndarray | None] = []
    for k, rec in enumerate(records):
        held = [w for w in windows if w.record == k and w.held_out]
        if not held:
            masks.append(None)
            continue
        m = np.ones(len(rec.t), bool)
        for w in held:
            m[w.i0:w.i1] = False
        masks.append(m)
    return masks


class FreeRuns:
    """The windows of a log prepared for fast free runs of any number of model variants.

    Parameters
    ----------
    logs
        the logged runs (one per record).
    windows
        the windows to run.
    params
        the vehicle whose actuator model rebuilds the actuator positions (its ``dt``
        is the integration step).
    """

    def __init__(self, logs: Sequence[LoggedRun], windows: Sequence[Window],
                 params: VehicleParams, step: float | None = None) -> None:
        self.logs = list(logs)
        self.windows = list(windows)
        self.params = params
        periods = [float(np.median(np.diff(lg.t))) for lg in self.logs if len(lg.t) > 1]
        period = min(periods) if periods else float(params.dt)
        self.dt = integration_step(params, period) if step is None else float(step)
        #: RK4 steps between two outputs (about one log period)
        self.sub = max(1, int(round(period / self.dt)))
        h = self.sub * self.dt
        acts: list[np.ndarray] = []
        f0, t0, nsteps, out_base = [], [], [], []
        self.act0 = np.zeros((len(self.windows), 3))
        fine_start: dict[int, tuple[int, np.ndarray]] = {}
        offset = 0
        rows = 0
        for k in sorted({w.record for w in self.windows}):
            lg = self.logs[k]
            n_fine = 2 * int(math.ceil((float(lg.t[-1]) - float(lg.t[0])) / self.dt)) + 3
            tg = float(lg.t[0]) + 0.5 * self.dt * np.arange(n_fine)
            grid = actuator_track(tg, lg.commands, params, lg.measured)
            fine_start[k] = (offset, grid)
            acts.append(grid)
            offset += n_fine
        self.sample_times: list[np.ndarray] = []
        self.grid_times: list[np.ndarray] = []
        for j, w in enumerate(self.windows):
            lg = self.logs[w.record]
            base_row, grid = fine_start[w.record]
            j0 = 2 * int(round((float(lg.t[w.i0]) - float(lg.t[0])) / self.dt))
            ts = float(lg.t[0]) + 0.5 * self.dt * j0
            steps = int(math.ceil((float(lg.t[w.i1 - 1]) - ts) / h - 1e-9)) + 1
            steps = min(steps, (len(grid) - 1 - j0) // (2 * self.sub))
            f0.append(base_row + j0)
            t0.append(ts)
            nsteps.append(steps)
            out_base.append(rows)
            rows += steps + 1
            self.act0[j] = grid[j0]
            self.sample_times.append(np.asarray(lg.t[w.i0:w.i1], float))
            self.grid_times.append(ts + h * np.arange(steps + 1))
        self.act = np.ascontiguousarray(np.concatenate(acts)) if acts else np.zeros((1, 3))
        self.f0 = np.array(f0, np.int64)
        self.t0 = np.array(t0, float)
        self.nsteps = np.array(nsteps, np.int64)
        self.out_base = np.array(out_base, np.int64)
        self.rows = rows

    def initial_states(self) -> np.ndarray:
        """(nw, 15): the logged state at each window's first sample and the rebuilt
        actuator positions there."""
        X0 = np.zeros((len(self.windows), NX))
        for j, w in enumerate(self.windows):
            X0[j, :12] = self.logs[w.record].state[w.i0]
            X0[j, 12:15] = self.act0[j]
        return X0

    def run(self, P: np.ndarray, X0: np.ndarray) -> list[np.ndarray]:
        """Free runs of parameter vectors ``P`` (nv, NP) from initial states ``X0`` (nv, nw,
        15); per window the predicted states at the log's stamps (nv, n_w, 12), NaN where a
        run diverged."""
        P = np.ascontiguousarray(np.atleast_2d(P), dtype=np.float64)
        X0 = np.ascontiguousarray(X0, dtype=np.float64)
        out = np.empty((P.shape[0], self.rows, 12))
        if len(self.windows):
            _run_windows(P, X0, self.act, self.f0, self.t0, self.nsteps, self.out_base,
                         self.dt, self.sub, out)
        result = []
        for j in range(len(self.windows)):
            a = int(self.out_base[j])
            g = out[:, a:a + int(self.nsteps[j]) + 1]
            tg, ts = self.grid_times[j], self.sample_times[j]
            pos = np.clip((ts - tg[0]) / (self.sub * self.dt), 0.0, len(tg) - 1.0)
            i = np.minimum(pos.astype(int), len(tg) - 2) if len(tg) > 1 else np.zeros(
                len(ts), int)
            f = (pos - i)[None, :, None]
            if len(tg) > 1:
                result.append(g[:, i] * (1.0 - f) + g[:, i + 1] * f)
            else:
                result.append(np.repeat(g[:, :1], len(ts), axis=1))
        return result


def integration_step(params: VehicleParams, period: float) -> float:
    """The RK4 step of the free runs [s]: the vehicle file's ``dt`` times the largest whole
    number that keeps it within :data:`STEP_MAX` and the log period ``period`` [s] (the
    actuator positions are prescribed, so the step needs to resolve the vehicle's own modes
    only, below 3 rad/s on the vehicles here: RK4's error at 0.05 s is below 1e-5 of a
    window's motion)."""
    dt = float(params.dt)
    k = max(1, int(math.floor(min(STEP_MAX, period) / dt + 1e-9)))
    return k * dt


def parameter_vector(params: VehicleParams, values: dict[str, float] | None = None
                     ) -> np.ndarray:
    """The model's parameter vector of ``params`` with ``values`` (coefficients that do not
    enter the mass matrix) replaced."""
    P = params.as_array().copy()
    for name, v in (values or {}).items():
        P[PARAM_NAMES.index(name)] = float(v)
    return P
