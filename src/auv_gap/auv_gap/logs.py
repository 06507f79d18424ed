"""Logs for the gap diagnosis: loading from bags, checking, smoothing.

A :class:`GapLog` is one continuous piece of a vehicle log on a uniform time grid: the
measured state (``/auv/state``: NED position and ZYX Euler angles, body-FRD velocities over
ground; SI units, radians) and the actuator commands as they were sent (time-stamped
set-points, held until the next one). No force topic is needed.

A log imported from a real vehicle's own format (:mod:`auv_logs`) may hold state
signals that were not measured: *derived* from other logged signals (``q`` from the pitch
angle's rate, ``w`` from the depth rate, ``u v`` from position fixes) or *assumed* (``phi`` =
0, ``v`` = 0). :attr:`GapLog.origins` keeps that mark (from the import report, or from the
provenance of a bag ``auv import`` wrote), and :func:`measurement_weighting` says which
free-run channels and equations the diagnosis must leave out so as not to count one
measurement twice (a derived ``w`` is the depth's own rate; a derived ``q`` the pitch's) or
test an assumption as if it were data (an assumed ``v`` = 0), and how that limits the answer.
"""
from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from scipy.signal import savgol_filter

from auv_contract import (
    CHANNELS,
    COMMAND_TOPICS,
    MEASURED_TOPICS,
    STATE_FIELDS,
    STATE_TOPIC,
)
from auv_gap.errors import GapError
from auv_logs.segments import GAP_SPLIT
from auv_sim.params import VehicleParams

#: A derived rate and the logged signal whose time derivative it mainly is (its noise).
DERIVED_FROM = {'p': 'phi', 'q': 'theta', 'r': 'psi', 'u': 'x', 'v': 'y', 'w': 'z'}


@dataclasses.dataclass(frozen=True)
class GapLog:
    """One continuous log piece: ``t`` (N) uniform [s], ``state`` (N x 12) as measured, and
    per channel the commands ``(stamps [s], values [rad or N])`` sorted by time."""

    name: str
    t: np.ndarray
    state: np.ndarray
    commands: Mapping[str, tuple[np.ndarray, np.ndarray]]
    notes: tuple[str, ...] = ()
    #: state signal -> ``'derived: how'`` or ``'assumed: what'`` for signals not measured
    #: (absent: measured)
    origins: Mapping[str, str] = dataclasses.field(default_factory=dict)
    #: channels whose ``commands`` are measured fin positions (not commands)
    measured_fins: tuple[str, ...] = ()
    #: channels logged only at the rows of a slow log, taken as linear between rows
    #: (:func:`first_order_hold`)
    linear_between_rows: tuple[str, ...] = ()
    #: the stamps the state was interpolated from onto ``t`` (the log's own rows: jittered
    #: or with dropped rows they are not ``t``); None: ``t`` itself
    rows: np.ndarray | None = None
    #: the rows themselves were resampled onto a grid by the import (``time.grid``): the
    #: logged rows are lost, commands logged at them are recognised by their spacing
    #: (:func:`sampled_commands`)
    irregular_rows: bool = False
    #: state signal -> the least white noise it can have [SI unit]: the rounding of a value
    #: logged in steps, or a slow sensor's own noise (from the import report's
    #: ``noise_floor``); :func:`smooth` never estimates less
    noise_floor: Mapping[str, float] = dataclasses.field(default_factory=dict)
    #: the log's start [s] (its first stamp, before any piece was cut off it) and that
    #: instant in UTC (ISO 8601; None for a clock started with the log and no file time):
    #: reports give times since this start
    origin: float = math.nan
    origin_utc: str | None = None
    #: the import's surface passes of the log (median depth reading, spread, samples; see
    #: :func:`auv_logs.importer.usable_samples`)
    surface_passes: tuple[Mapping[str, Any], ...] = ()

    @property
    def period(self) -> float:
        """Sample period [s]."""
        return float(self.t[1] - self.t[0])

    @property
    def duration(self) -> float:
        """Length [s]."""
        return float(self.t[-1] - self.t[0])


def log_period(t: np.ndarray) -> float:
    """The sample period [s] of stamps ``t`` (increasing): the median step, or, for rows
    whose spacing jitters (:func:`auv_logs.segments.spacing_jitter`: a logger writing
    rows 0.39 and 0.61 s apart), the mean step below :data:`GAP_SPLIT` median steps (the
    median of such rows is one of the two steps, not their rate), to two significant digits
    (0.5 s for a 2 Hz logger whose rows jitter: the grid the rows are interpolated onto, the
    same for every log of that logger)."""
    from auv_logs.segments import spacing_jitter

    d = np.diff(t)
    d = d[d > 0]
    med = float(np.median(d))
    if spacing_jitter(t) is None:
        return med
    mean = float(np.mean(d[d <= GAP_SPLIT * med]))
    return float(f'{mean:.2g}')     # the grid is ours: logs of one logger share it


def from_arrays(name: str, t: np.ndarray, state: np.ndarray,
                commands: Mapping[str, tuple[np.ndarray, np.ndarray]],
                notes: Sequence[str] = (), origins: Mapping[str, str] | None = None,
                measured_fins: Sequence[str] = (), irregular: bool = False,
                noise_floor: Mapping[str, float] | None = None,
                origin: float | None = None, origin_utc: str | None = None,
                surface_passes: Sequence[Mapping[str, Any]] = ()) -> list[GapLog]:
    """Check and regularise a log: split at pauses, resample onto a uniform grid (the
    period of :func:`log_period`).

    ``t`` (N) [s] must be non-decreasing and finite; ``state`` (N x 12) finite. Yaw is
    unwrapped before resampling. Channels missing from ``commands`` other than the helm are
    an error; a missing helm is held at 0 rad (and said so in ``notes``). ``origins``: the
    state signals that were derived or assumed (see :attr:`GapLog.origins`);
    ``measured_fins``: channels of ``commands`` that hold measured fin positions;
    ``irregular``: the stamps ``t`` were themselves resampled from the log's rows by the
    import (see :attr:`GapLog.irregular_rows`); ``noise_floor``, ``origin`` (default the
    first stamp), ``origin_utc``, ``surface_passes``: see :class:`GapLog`.
    """
    origins = dict(origins or {})
    unknown = sorted(set(origins) - set(STATE_FIELDS))
    if unknown:
        raise GapError(f'{name}: origins given for unknown state signals {unknown}')
    t = np.asarray(t, dtype=np.float64)
    state = np.asarray(state, dtype=np.float64)
    if t.ndim != 1 or state.shape != (t.size, 12):
        raise GapError(f'{name}: state must be N x 12 with N time stamps, got {state.shape}')
    if t.size < 20:
        raise GapError(f'{name}: only {t.size} state samples; a diagnosis needs a log of '
                       'a minute or more')
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(state))):
        bad = int(np.flatnonzero(~(np.isfinite(t) & np.all(np.isfinite(state), axis=1)))[0])
        raise GapError(f'{name}: non-finite state sample at index {bad}')
    dt = np.diff(t)
    if np.any(dt < 0):
        i = int(np.flatnonzero(dt < 0)[0]) + 1
        raise GapError(f'{name}: state time stamps go back at sample {i}')
    keep = np.concatenate([[True], dt > 0])
    t, state = t[keep], state[keep]
    notes = list(notes)
    start = float(t[0]) if origin is None else float(origin)
    from auv_logs.importer import utc
    origin_utc = utc(start) or origin_utc       # an absolute clock over a file's own time
    cmds: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for ch in CHANNELS:
        if ch not in commands or len(commands[ch][0]) == 0:
            if ch == 'helm':
                cmds[ch] = (np.array([t[0]]), np.array([0.0]))
                notes.append('no helm commands in the log: helm held at 0 rad')
                continue
            raise GapError(f'{name}: no {ch} commands ({COMMAND_TOPICS[ch]}) in the log')
        st = np.asarray(commands[ch][0], dtype=np.float64)
        va = np.asarray(commands[ch][1], dtype=np.float64)
        if not (np.all(np.isfinite(st)) and np.all(np.isfinite(va))):
            raise GapError(f'{name}: non-finite {ch} command')
        order = np.argsort(st, kind='stable')
        cmds[ch] = (st[order], va[order])
        if st.min() > t[0] + 1e-6:
            notes.append(f'{ch}: first command at {st.min() - t[0]:.2f} s after the log starts; '
                         'the first command is assumed before it')
    state = state.copy()
    state[:, 5] = np.unwrap(state[:, 5])
    period = log_period(t)
    cuts = np.flatnonzero(np.diff(t) > GAP_SPLIT * period) + 1
    pieces = []
    for k, (a, b) in enumerate(zip(np.r_[0, cuts], np.r_[cuts, t.size])):
        if b - a < 20:
            continue
        tp = t[a:b]
        n = int(np.floor((tp[-1] - tp[0]) / period + 1e-9)) + 1
        grid = tp[0] + period * np.arange(n)
        xs = np.empty((n, 12))
        for i in range(12):
            xs[:, i] = np.interp(grid, tp, state[a:b, i])
        label = name if len(cuts) == 0 else f'{name}#{k}'
        pieces.append(GapLog(label, grid, xs, cmds, tuple(notes), origins,
                             tuple(measured_fins), rows=tp, irregular_rows=irregular,
                             noise_floor=dict(noise_floor or {}), origin=start,
                             origin_utc=origin_utc, surface_passes=tuple(surface_passes)))
    if not pieces:
        raise GapError(f'{name}: no continuous stretch of 20 samples or more')
    return pieces


def load_bag(path: str | os.PathLike[str]) -> list[GapLog]:
    """Read a bag (directory or ``.mcap``) into log pieces (see :func:`from_arrays`)."""
    from auv_bag import bag_topics, read_arrays
    from auv_bag.errors import BagError

    try:
        present = bag_topics(path)
    except BagError as exc:
        raise GapError(str(exc)) from None
    if STATE_TOPIC not in present:
        raise GapError(f'bag {path} has no {STATE_TOPIC} topic')
    topics = [STATE_TOPIC] + [tp for tp in (*COMMAND_TOPICS.values(),
                                            *MEASURED_TOPICS.values()) if tp in present]
    try:
        arrays = read_arrays(path, topics)
    except BagError as exc:
        raise GapError(str(exc)) from None
    from auv_logs.contract_bag import read_provenance

    prov = read_provenance(path) if os.path.isdir(path) else None
    return from_contract_arrays(os.fspath(path), arrays,
                                prov.get('imports', ()) if prov else ())


def from_contract_arrays(name: str, arrays: Mapping[str, np.ndarray],
                         imports: Sequence[Mapping[str, Any]] = ()) -> list[GapLog]:
    """Log pieces from a contract bag's topic arrays (as :func:`auv_bag.read_arrays`
    or :func:`auv_logs.contract_bag.contract_arrays` give them); ``imports``: the import
    reports of the logs the arrays come from (their derived and assumed signals)."""
    st = arrays[STATE_TOPIC]
    state = np.column_stack([st[f] for f in STATE_FIELDS])
    commands = {ch: (arrays[tp]['t'], arrays[tp]['value'])
                for ch, tp in COMMAND_TOPICS.items() if tp in arrays}
    fins = [ch for ch, tp in MEASURED_TOPICS.items() if tp in arrays and len(arrays[tp])]
    for ch in fins:
        commands[ch] = (arrays[MEASURED_TOPICS[ch]]['t'], arrays[MEASURED_TOPICS[ch]]['value'])
    notes = [f'{ch}: measured fin positions ({MEASURED_TOPICS[ch]}) used in place of the '
             'commands; the actuator model passes them through (lag of one simulation step, '
             'no rate limit)' for ch in fins]
    resampled = any(not str(rep.get('resampled', 'no')).startswith('no') for rep in imports)
    floor: dict[str, float] = {}
    for rep in imports:
        for sig, value in (rep.get('noise_floor') or {}).items():
            floor[sig] = max(floor.get(sig, 0.0), float(value))
    starts = [float(rep['start']['stamp_s']) for rep in imports
              if (rep.get('start') or {}).get('stamp_s') is not None]
    clocks = [rep['start'].get('file_time_utc') for rep in imports
              if (rep.get('start') or {}).get('file_time_utc')]
    passes = [dict(p, log=str(rep.get('log', ''))) for rep in imports
              for p in rep.get('surface_passes') or []]
    pieces = from_arrays(name, st['t'], state, commands, notes,
                         origins=import_origins(imports), measured_fins=fins,
                         irregular=resampled, noise_floor=floor,
                         origin=min(starts) if starts else None,
                         origin_utc=clocks[0] if clocks and len(imports) == 1 else None,
                         surface_passes=passes)
    return [first_order_hold(lg) for lg in pieces]


#: Steps per row of the first-order hold of commands logged at a slow log's rows.
FOH_STEPS = 10


def first_order_hold(log: GapLog) -> GapLog:
    """A log whose commands were logged only at its (slow) state rows
    (:func:`sampled_commands`), with those commands taken as varying linearly between rows
    (first-order hold, :data:`FOH_STEPS` held steps per row) instead of held at each row's
    value until the next. Held, a command that changed at a random time between two rows
    would act on average half a row late (0.25 s at 2 Hz), which the diagnosis would read as
    a plane delay or as changed plane coefficients; the linear hold has no such mean lag. The
    logged values at the rows are kept; the change is said in the notes."""
    chans = sampled_commands([log])
    if not chans:
        return log
    cmds = dict(log.commands)
    for ch in chans:
        cmds[ch] = _linear(*cmds[ch])
    note = (f'{", ".join(chans)} commands logged only at the rows (every {log.period:.3g} s): '
            'taken as varying linearly between rows (first-order hold) rather than held, '
            'which would delay them by half a row on average')
    return dataclasses.replace(log, commands=cmds, notes=(*log.notes, note),
                               linear_between_rows=tuple(chans))


def _linear(st: np.ndarray, va: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Commands held at stamps ``st`` [s] with values ``va`` as :data:`FOH_STEPS` held steps
    per interval, varying linearly from each value to the next."""
    frac = np.arange(FOH_STEPS) / FOH_STEPS
    t_new = (st[:-1, None] + np.diff(st)[:, None] * frac[None, :]).ravel()
    v_new = (va[:-1, None] + np.diff(va)[:, None] * frac[None, :]).ravel()
    return np.r_[t_new, st[-1]], np.r_[v_new, va[-1]]


def other_hold(log: GapLog) -> GapLog | None:
    """The same log with the commands it records only at its state rows (at any period,
    ``sampled_commands(..., min_period=0)``, or already taken as linear between rows)
    reconstructed the other way: held at each row's value where :func:`first_order_hold`
    made them linear, linear where they are held. What the commands did between rows is
    not in the log; the two reconstructions bracket it, and the diagnosis counts their
    difference in the noise floor. None when the log's commands carry their own stamps."""
    cmds = dict(log.commands)
    for ch in log.linear_between_rows:
        st, va = cmds[ch]
        cmds[ch] = (st[::FOH_STEPS], va[::FOH_STEPS])
    held = [ch for ch in sampled_commands([log], min_period=0.0)
            if ch not in log.linear_between_rows]
    for ch in held:
        cmds[ch] = _linear(*cmds[ch])
    if not (held or log.linear_between_rows):
        return None
    return dataclasses.replace(log, commands=cmds)


def measured_fins_vehicle(vehicle: VehicleParams, logs: Sequence[GapLog]) -> VehicleParams:
    """The vehicle whose actuator model passes the measured fin positions of ``logs`` through
    (a channel of :attr:`GapLog.measured_fins` in any log): its lag set to one simulation step
    (the shortest the model allows) and its rate limit lifted (1000 rad/s), so that the
    nominal model's plane follows the measured fin, not the command. An actuator effect the
    diagnosis then finds (delay, lag, rate limit) is one of the fin sensor, on top of it."""
    fins = {ch for lg in logs for ch in lg.measured_fins}
    change: dict[str, float] = {}
    for ch in fins:
        change[f'{ch}_tau'] = float(vehicle.dt)
        change[f'{ch}_rate'] = 1000.0
    return vehicle.replace(**change) if change else vehicle


def import_origins(imports: Sequence[Mapping[str, Any]]) -> dict[str, str]:
    """State signals that some imported log did not measure: name -> ``'derived: how'`` or
    ``'assumed: what'`` (the import report's own line). Of several logs the least measured
    wins (assumed over derived over measured): the diagnosis pools them."""
    out: dict[str, str] = {}
    rank = {'measured': 0, 'derived': 1, 'assumed': 2}
    for rep in imports:
        lines = {d.split(':', 1)[0]: d.split(':', 1)[1].strip() for d in rep.get('derived', ())}
        origins = rep.get('origins') or {sig: ('derived' if v == 'derived' else 'measured')
                                         for sig, v in rep.get('signals', {}).items()
                                         if sig in STATE_FIELDS}
        for sig, kind in origins.items():
            if kind == 'measured':
                continue
            old = out.get(sig, 'measured:').split(':', 1)[0]
            if rank[kind] >= rank[old]:
                out[sig] = f'{kind}: {lines.get(sig, kind)}'
    return out


#: Log period [s] from which on commands logged only at the state rows are taken as linear
#: between rows and named as a limit (a 10 Hz log is slow whatever the rounding of its
#: stamps' difference: compared with a relative tolerance of 1e-3).
SAMPLED_PERIOD = 0.1


def sampled_commands(logs: Sequence[GapLog], min_period: float = SAMPLED_PERIOD
                     ) -> list[str]:
    """Command channels that a slow log (period of ``min_period`` [s] or more) records
    only at its state rows (nearly every row carries one: a vendor log's command columns),
    not when they changed. The rows are the stamps the state was logged at
    (:attr:`GapLog.rows`: jittered rows or dropped rows are not on the uniform ``t``). Where
    the import resampled the rows onto a grid (:attr:`GapLog.irregular_rows`) they are lost:
    there a channel whose stamps inside the piece are as many as its rows (within 10 %) with a
    median spacing within 25 % of the period counts as logged at the rows."""
    out = []
    for ch in ('bar', 'thrust'):
        for lg in logs:
            if ch in lg.measured_fins or lg.period < min_period * (1.0 - 1e-3):
                continue
            # at a row: within a thousandth of the period (epoch stamps of 1.7e9 s carry
            # rounding errors of 2.4e-7 s)
            tol = 1e-3 * lg.period
            rows = lg.t if lg.rows is None else np.asarray(lg.rows)
            st = np.asarray(lg.commands[ch][0])
            inside = st[(st >= rows[0] - tol) & (st <= rows[-1] + tol)]
            if inside.size < 0.9 * rows.size:
                continue
            i = np.clip(np.searchsorted(rows, inside), 1, rows.size - 1)
            gap = np.minimum(np.abs(rows[i] - inside), np.abs(rows[i - 1] - inside))
            at_rows = bool(np.mean(gap < tol) > 0.9)
            if not at_rows and lg.irregular_rows and inside.size <= 1.1 * rows.size:
                at_rows = abs(float(np.median(np.diff(inside))) / lg.period - 1.0) < 0.25
            if at_rows:
                out.append(ch)
                break
    return out


@dataclasses.dataclass(frozen=True)
class Weighting:
    """What the diagnosis leaves out because a signal was derived or assumed.

    ``channels``: free-run channels (names of ``z theta u w q v r``) left out of the cost,
    the gap channels and the scores; ``equations``: equation-error rows left out of the fits
    and the residual tests (their noise level set to infinity: weight zero); ``report``: the
    signals' origins, what was left out and why, and how it limits the answer (the gap
    report's ``signals``); ``statement``: that in one or two sentences (empty when every
    signal was measured)."""

    channels: tuple[str, ...]
    equations: tuple[str, ...]
    report: dict[str, Any]
    statement: str

    def channel_mask(self, names: Sequence[str]) -> np.ndarray:
        """True for the channels of ``names`` left out."""
        return np.array([n in self.channels for n in names])

    def equation_mask(self, names: Sequence[str]) -> np.ndarray:
        """True for the equations of ``names`` left out."""
        return np.array([n in self.equations for n in names])


#: A rate a slow log may lack -> (its name, the logged signal it is differenced from, the
#: sensor that measures it).
RATE_SOURCES = {'w': ('heave velocity', 'depth', 'the heave velocity (DVL)'),
                'q': ('pitch rate', 'pitch', 'the pitch rate (gyro)')}


def measurement_weighting(logs: Sequence[GapLog]) -> Weighting:
    """Free-run channels and equations to leave out for the derived and assumed signals of
    ``logs`` (pooled: a signal derived in one log is treated as derived in all).

    Rules (each is in ``report['left_out']`` with its reason):

    * ``w`` derived from the depth rate: the free-run ``w`` channel is left out (its error is
      the depth error's rate: depth would count twice) and so is the depth-kinematics
      equation (it holds by construction);
    * ``q`` derived from the pitch angle: the free-run ``q`` channel is left out (pitch's own
      rate); the pitch equation stays (``q_dot`` is then the pitch angle's second derivative,
      the only information on it);
    * ``v`` assumed 0: the free-run ``v`` and ``r`` channels and the sway and yaw equations are
      left out (a value that was never measured, and the horizontal-plane model needs it);
    * other derived signals (``u v`` from position fixes, ``p r`` from the attitude) are kept
      and listed; ``phi`` assumed 0 and dead-reckoned ``x y`` are listed with their limits.
    """
    fins = sorted({ch for lg in logs for ch in lg.measured_fins})
    origins: dict[str, str] = {}
    for lg in logs:
        for sig, why in lg.origins.items():
            if sig not in origins or why.startswith('assumed'):
                origins[sig] = why
    kind = {sig: why.split(':', 1)[0] for sig, why in origins.items()}
    channels: dict[str, str] = {}
    equations: dict[str, str] = {}
    limits: list[str] = []
    if kind.get('w') == 'derived':
        channels['w'] = ('derived from the depth rate: its free-run error is the depth '
                         "error's rate, so depth would count twice")
        equations['depth_kinematics'] = 'holds by construction when w is derived from the depth'
    if kind.get('q') == 'derived':
        channels['q'] = ("derived from the pitch angle's rate: its free-run error is the pitch "
                         "error's rate, so pitch would count twice")
    if kind.get('v') == 'assumed':
        why = 'v was not logged (assumed 0): the horizontal-plane model needs it'
        channels['v'] = 'assumed 0, never measured'
        channels['r'] = why
        equations['sway'] = why
        equations['yaw'] = why
        limits.append('with v assumed 0 the horizontal plane is not diagnosed: a current '
                      'across the track or a sway-yaw model error is not seen (a current '
                      'along the track still shows in u)')
    if kind.get('w') == 'derived' or kind.get('q') == 'derived':
        period = max((lg.period for lg in logs), default=math.nan)
        # what was differenced from what, and the sensor that would measure it
        which = [s for s in ('w', 'q') if kind.get(s) == 'derived']
        both = len(which) == 2
        rates = ' and '.join(RATE_SOURCES[s][0] for s in which)
        angles = ' and '.join(RATE_SOURCES[s][1] for s in which)
        fix = ' and '.join(RATE_SOURCES[s][2] for s in reversed(which))
        limits.append(f'{rates} {"come" if both else "comes"} from {angles} differenced '
                      f'at the {period:.3g} s sample period: '
                      + ('the vertical plane is seen only through depth and pitch, and an '
                         if both else 'an ')
                      + 'actuator delay or lag shorter than about one sample period cannot be '
                      f'identified; the free runs start from a {rates} fitted by each model '
                      f'to the first seconds of {angles}, whose uncertainty is in the noise '
                      f'floor: log {fix}')
    if kind.get('phi') == 'assumed':
        limits.append('roll was not logged (assumed 0): a roll offset or banking in turns is '
                      'not seen, and its share of the restoring moment would appear as a '
                      'heave or pitch gap')
    if kind.get('u') == 'derived':
        limits.append('u is the speed over ground from position fixes: a current along the '
                      'track is inseparable from a speed error between fixes')
    for sig in ('x', 'y'):
        if kind.get(sig) == 'derived':
            limits.append('x and y were dead-reckoned: not used by the diagnosis')
            break
    sampled = list(dict.fromkeys([*sampled_commands(logs),
                                  *(ch for lg in logs for ch in lg.linear_between_rows)]))
    if sampled:
        period = max(lg.period for lg in logs)
        linear = any(lg.linear_between_rows for lg in logs)
        limits.append(f'the {", ".join(sampled)} commands are logged only at the state rows '
                      f'(every {period:.3g} s)'
                      + (', taken as linear between rows' if linear else '')
                      + ': what they did between rows is not in the log, so the timing of '
                      'the plane is known to a sample period; coefficient factors of the plane '
                      'or actuator effects found on these logs may stand for that, not for the '
                      'vehicle')
    for ch in fins:
        limits.append(f'{ch}: the measured fin positions drive the model in place of the '
                      'commands through the actuator model; a delay, lag or rate limit found '
                      'on it is then the fin sensor\'s, not the servo\'s')
    report = {
        'actuators': {ch: ('measured fin position' if ch in fins else
                           'command through the actuator model')
                      for ch in CHANNELS},
        'derived': {s: w.split(':', 1)[1].strip() for s, w in origins.items()
                    if kind[s] == 'derived'},
        'assumed': {s: w.split(':', 1)[1].strip() for s, w in origins.items()
                    if kind[s] == 'assumed'},
        'left_out': {'free_run': channels, 'equations': equations},
        'limits': limits,
    }
    statement = ''
    if origins or fins:
        statement = ('Not measured: ' + ', '.join(
            f'{s} ({kind[s]})' for s in STATE_FIELDS if s in kind) + '.') if origins else ''
        if fins:
            statement += (' Measured fin positions used for ' + ', '.join(fins)
                          + ' in place of the commands.')
        if channels or equations:
            statement += (' Left out so that no measurement counts twice: '
                          + ', '.join([*(f'free-run {c}' for c in channels),
                                       *(f'{e} equation' for e in equations)]) + '.')
        if limits:
            statement += ' Limits: ' + '; '.join(limits) + '.'
    return Weighting(tuple(channels), tuple(equations), report, statement)


@dataclasses.dataclass(frozen=True)
class Smoothed:
    """Savitzky-Golay smoothed state (N x 12), its time derivative (N x 12) [unit/s], and
    the white measurement noise per state (12) estimated from second differences."""

    state: np.ndarray
    rate: np.ndarray
    noise: np.ndarray
    deriv_gain: float   # ||h||_2 of the derivative filter [1/s]: noise std -> derivative std
    smooth_gain: float  # ||h||_2 of the smoothing filter: noise std -> smoothed std
    length: int         # filter length [samples]


def smooth(log: GapLog, window: float = 1.0, order: int = 3) -> Smoothed:
    """Smooth a log with a Savitzky-Golay filter of ``window`` [s] and polynomial ``order``.

    The white noise of each state is estimated from second differences, never below its
    :attr:`GapLog.noise_floor` (a value logged in 0.1 m steps has second differences of zero
    between its steps, not zero noise); for a rate the
    import derived by central differences (:attr:`GapLog.origins`, :data:`DERIVED_FROM`) it
    is set to the level of white noise that leaves the same error after the smoothing as its
    source's noise, differenced, does (``sigma_src ||h_s * d|| / ||h_s||``, ``d`` the central
    difference); second differences would take the differenced noise for a white one many
    times larger at a fast log."""
    n = max(order + 2, int(round(window / log.period)) | 1)
    if n % 2 == 0:
        n += 1
    n = min(n, log.t.size - (1 - log.t.size % 2))
    xs = savgol_filter(log.state, n, order, axis=0, mode='interp')
    xd = savgol_filter(log.state, n, order, deriv=1, delta=log.period, axis=0, mode='interp')
    d2 = np.diff(log.state, 2, axis=0)
    mad = np.median(np.abs(d2 - np.median(d2, axis=0)), axis=0)
    noise = 1.4826 * mad / np.sqrt(6.0)
    for sig, least in log.noise_floor.items():     # a rounding the estimate cannot see
        k = STATE_FIELDS.index(sig)
        noise[k] = max(noise[k], float(least))
    imp = np.zeros(n)
    imp[n // 2] = 1.0
    hd = savgol_filter(imp, n, order, deriv=1, delta=log.period, mode='interp')
    hs = savgol_filter(imp, n, order, mode='interp')
    # a derived rate carries its source's noise differenced, not white noise: the level of
    # white noise that gives the same smoothed error (the smoothed state's noise is what the
    # noise floor and the initial states of free runs use)
    diff = np.array([1.0, 0.0, -1.0]) / (2.0 * log.period)
    gain = float(np.linalg.norm(np.convolve(hs, diff)) / np.linalg.norm(hs))
    for sig, src in DERIVED_FROM.items():
        if log.origins.get(sig, '').startswith('derived'):
            k, j = STATE_FIELDS.index(sig), STATE_FIELDS.index(src)
            noise[k] = noise[j] * gain
    return Smoothed(xs, xd, noise, float(np.sqrt(np.sum(hd ** 2))),
                    float(np.sqrt(np.sum(hs ** 2))), n)
