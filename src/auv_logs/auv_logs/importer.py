"""A map and a real log -> the contract's state and command streams, with the import report.

Steps (each recorded in the log's ``report``; nothing is resampled or filled silently):

1. Read the mapped fields/columns (:mod:`auv_logs.readers`); add each topic's clock
   offset; sort stamps that go back (counted); refuse header stamps of zero.
2. Convert each signal at its own source's stamps (units, scale, sign, frames: see
   :mod:`auv_logs.mapping`). A signal summed from fields of different topics (fins on
   separate topics) is evaluated at the union of their stamps, each term held from its latest
   earlier sample.
3. Bring the state onto one time base: the stamps of the ``time.base`` topic (every row of a
   text log). A state signal from another topic is the zero-order hold of its latest sample
   at or before the base stamp, if no older than ``time.max_age`` [s]; otherwise the sample is
   not usable (never extrapolated).
4. Split into segments (:mod:`auv_logs.segments`): gaps, surfaced, propeller off.
5. Derive, per segment, the state signals the map does not give
   (:mod:`auv_logs.derive`).
6. Commands (``bar``, ``helm``, ``thrust``) and measured fin positions stay event streams at
   their own stamps, as logged; the consumers hold them.

The result is a :class:`ContractLog`, turned into the same arrays as
:func:`auv_bag.read_arrays` gives for a contract bag
(:func:`auv_logs.contract_bag.contract_arrays`), or written as a contract bag
(:func:`auv_logs.contract_bag.write_contract_bag`) whose metadata carry the provenance.
"""
from __future__ import annotations

import dataclasses
import datetime
import math
import os
import pathlib
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from auv_logs.derive import body_rates, derive_missing
from auv_logs.errors import LogReadError, MapError, NoSegmentError
from auv_logs.mapping import SCALAR_ENU, STATE, LogMap, Scalar, Vector, load_map
from auv_logs.plausibility import Declared, Envelope, check_signals
from auv_logs.quality import (
    REPEAT_SHARE,
    fresh_samples,
    logged_step,
    onto,
    quantisation_sigma,
    repeat_share,
)
from auv_logs.readers import Table, file_time, log_kind, read_bag, read_text
from auv_logs.segments import resample, spacing_jitter, split
from auv_logs.units import UNITS
from auv_sim.frames import (
    Q_FRD_TO_FLU,
    Q_NED_TO_ENU,
    body_flu_to_frd,
    euler_to_quaternion,
    position_enu_to_ned,
    quaternion_conjugate,
    quaternion_multiply,
    quaternion_to_euler,
    rotate,
)

Series = tuple[np.ndarray, np.ndarray]
#: Stamps closer than this [s] are one instant: float64 seconds at epoch times (~1.7e9 s)
#: resolve 0.24 us, so a header stamp plus a clock offset can land an ulp after a stamp it
#: equals in nanoseconds.
SAME_INSTANT = 1e-6


@dataclasses.dataclass(frozen=True)
class ContractLog:
    """One imported log: state stamps ``t`` [s] (N; the segments one after the other),
    ``state`` (N x 12, NED/FRD, SI, rad), command and measured-actuator streams
    (name -> (stamps [s], values [rad or N])), the segments as (start, end [s], samples), and
    the ``report`` (derived signals, holds, what was left out, provenance)."""

    name: str
    t: np.ndarray
    state: np.ndarray
    commands: Mapping[str, Series]
    segments: tuple[tuple[float, float, int], ...]
    report: Mapping[str, Any]


# --------------------------------------------------------------------------------------------
# conversion of one signal

def _hold(src_t: np.ndarray, src_v: np.ndarray, at: np.ndarray,
          max_age: float | None) -> np.ndarray:
    """Zero-order hold: the latest sample at or before each of ``at`` (NaN where there is none
    or, with ``max_age`` [s], where it is older than that); stamps within
    :data:`SAME_INSTANT` count as the same instant."""
    i = _latest(src_t, at)
    ok = i >= 0
    out = np.full(at.shape, np.nan)
    out[ok] = src_v[i[ok]]
    if max_age is not None:
        out[_age(src_t, at) > max_age + SAME_INSTANT] = np.nan
    return out


def _latest(src_t: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Index of the latest of ``src_t`` at or before each of ``at`` (within
    :data:`SAME_INSTANT`; -1 where there is none)."""
    return np.searchsorted(src_t, at + SAME_INSTANT, side='right') - 1


def _scalar_series(sc: Scalar, tables: Mapping[str | None, Table]) -> Series:
    """A scalar signal at its source stamps, in SI and NED/FRD."""
    topics = list(dict.fromkeys(term.topic for term in sc.terms))
    if len(topics) == 1:
        tab = tables[topics[0]]
        t = tab.stamps
        v = sum((term.gain * tab.columns[term.path] for term in sc.terms), np.zeros(len(t)))
    else:
        t = np.unique(np.concatenate([tables[tp].stamps for tp in topics]))
        v = np.zeros(len(t))
        for term in sc.terms:
            tab = tables[term.topic]
            v = v + term.gain * _hold(tab.stamps, tab.columns[term.path], t, None)
        ok = np.isfinite(v)
        t, v = t[ok], v[ok]
    if sc.pressure is not None:
        v = (v - sc.pressure.surface) / (sc.pressure.density * sc.pressure.g)
    if sc.enu:
        sign, off = SCALAR_ENU[sc.name]
        v = off + sign * v
    if sc.law is not None:
        v = sc.law.k * v * np.abs(v)
    if sc.full_scale is not None:
        v = v * sc.full_scale
    return t, v + sc.offset


def _orientation_ned(q: np.ndarray, world: str, body: str) -> np.ndarray:
    """``q_world_body`` (N x 4, x y z w) -> ``q_ned_frd``."""
    if world == 'ENU':
        q = quaternion_multiply(quaternion_conjugate(Q_NED_TO_ENU), q)
    if body == 'FLU':
        q = quaternion_multiply(q, quaternion_conjugate(Q_FRD_TO_FLU))
    return q


def _age(src_t: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Age [s] of the sample :func:`_hold` takes at each of ``at`` (inf where none)."""
    i = _latest(src_t, at)
    return np.where(i >= 0, np.maximum(at - src_t[np.maximum(i, 0)], 0.0), np.inf)


def _period(t: np.ndarray) -> float:
    """Median step [s] of stamps ``t`` (0 with fewer than two)."""
    steps = np.diff(t)
    steps = steps[steps > 0]
    return float(np.median(steps)) if len(steps) else 0.0


def _vector_series(vec: Vector, tables: Mapping[str | None, Table],
                   notes: list[str]) -> dict[str, Series]:
    """The state signals of a vector at its source stamps, NED/FRD, SI (NaN where the
    message says it carries no estimate: ``vec.unset`` is -1)."""
    tab = tables[vec.topic]
    raw = np.column_stack([tab.columns[f] for f in vec.fields]) * vec.factor
    t = tab.stamps
    unset = np.zeros(len(t), bool)
    if vec.unset is not None:
        unset = tab.columns[vec.unset] == -1.0
        if np.all(unset):
            raise LogReadError(f'{vec.topic}: {vec.unset} is -1 in all {len(t)} messages: they '
                               f'carry no {vec.kind} ({tab.msgtype} convention); leave it out '
                               f'(use:) or map it from another source; {vec.where}')
        if np.any(unset):
            notes.append(f'{vec.topic}: {int(np.count_nonzero(unset))} message(s) with '
                         f'{vec.unset} -1 carry no {vec.kind}: not usable')
            raw[unset] = [0.0, 0.0, 0.0, 1.0] if vec.kind == 'orientation' else 0.0
    if vec.kind == 'position':
        out = position_enu_to_ned(raw) if vec.world == 'ENU' else raw
    elif vec.kind in ('orientation', 'euler'):
        q = raw if vec.kind == 'orientation' else euler_to_quaternion(raw[:, 0], raw[:, 1],
                                                                      raw[:, 2])
        norm = np.linalg.norm(q, axis=1)
        bad = ~(norm > 0.5) | ~(norm < 1.5)
        if np.any(bad):
            i = int(np.flatnonzero(bad)[0])
            raise LogReadError(f'{vec.topic or "log"}: orientation at {t[i]:.3f} s is not a '
                               f'unit quaternion (norm {norm[i]:.3g}); {vec.where}')
        out = np.column_stack(quaternion_to_euler(_orientation_ned(q, vec.world, vec.body)))
    else:   # body velocities and rates
        out = body_flu_to_frd(raw) if vec.body == 'FLU' else raw
        if vec.mounting is not None:    # sensor axes -> body axes
            out = rotate(euler_to_quaternion(*vec.mounting), out)
    out[unset] = np.nan
    return {name: (t, out[:, k]) for k, name in enumerate(vec.components) if name in vec.gives}


# --------------------------------------------------------------------------------------------
# reading

def _requests(logmap: LogMap) -> dict[str | None, list[str]]:
    req: dict[str | None, list[str]] = {}
    for sc in logmap.scalars.values():
        for term in sc.terms:
            req.setdefault(term.topic, [])
            if term.path not in req[term.topic]:
                req[term.topic].append(term.path)
    for vec in logmap.vectors:
        req.setdefault(vec.topic, [])
        for f in (*vec.fields, *([vec.unset] if vec.unset else [])):
            if f not in req[vec.topic]:
                req[vec.topic].append(f)
    return req


#: A stamp going back further than this [s] and than :data:`BACK_PERIODS` median periods is
#: no reordered message but a clock reset or a restart of the logger: sorting would interleave
#: two stretches of the log, so it is refused.
BACK_LIMIT = 1.0
BACK_PERIODS = 10.0


def _tidy(tab: Table, offset: float, stamp: str, notes: list[str]) -> Table:
    """Clock offset, zero stamps refused, stamps going back a little sorted (counted), a
    jump back (clock reset, logger restart; see :data:`BACK_LIMIT`) refused."""
    t = tab.stamps + offset
    if stamp == 'header':
        zero = np.count_nonzero(tab.stamps == 0.0)
        if zero:
            raise LogReadError(f'topic {tab.source}: {zero} of {len(t)} header stamps are zero '
                               '(the publisher does not stamp): take its receive times, '
                               f'time: {{stamps: {{{tab.source}: log}}}} in the map (or '
                               'stamp: log for every topic)')
    if offset:
        notes.append(f'{tab.source}: clock offset {offset:+.6g} s added to its stamps')
    steps = np.diff(t)
    back = int(np.count_nonzero(steps < 0))
    cols = dict(tab.columns)
    lines = tab.lines
    if back:
        k = int(np.argmin(steps))
        if -steps[k] > max(BACK_LIMIT, BACK_PERIODS * _period(t)):
            what = 'row' if stamp == 'column' else 'message'
            at = (f'line {int(lines[k + 1])}' if lines is not None else f'{what} {k + 2}')
            raise LogReadError(f'{tab.source}: time goes back by {-steps[k]:.6g} s at {at} '
                               f'({t[k]:.6f} s, then {t[k + 1]:.6f} s): a clock reset '
                               'or a restart of the logger? split the log there')
        order = np.argsort(t, kind='stable')
        t = t[order]
        cols = {k: v[order] for k, v in cols.items()}
        lines = None if lines is None else lines[order]
        notes.append(f'{tab.source}: {back} stamp(s) went back; messages sorted by stamp')
    return dataclasses.replace(tab, stamps=t, columns=cols, lines=lines)


def read_tables(logmap: LogMap, path: str | os.PathLike[str], notes: list[str],
                strict: bool = False) -> dict[str | None, Table]:
    """Read what ``logmap`` needs from the log at ``path`` (tables keyed by topic; a text
    log's table under ``None``). A text log's rows that do not parse are left out (their
    lines in the table's ``skipped``) unless ``strict``."""
    kind = log_kind(path)
    req = _requests(logmap)
    if logmap.kind == 'text':
        if kind != 'text':
            raise LogReadError(f'{path}: the map is for text logs, this is a {kind} bag')
        fmt = logmap.text
        assert fmt is not None and logmap.time.column is not None
        tab = read_text(path, req.get(None, []), logmap.time.column,
                        delimiter=fmt.delimiter, header=fmt.header, names=fmt.columns,
                        comment=fmt.comment, strict=strict)
        tab = dataclasses.replace(tab, stamps=tab.stamps * logmap.time.factor)
        return {None: _tidy(tab, 0.0, 'column', notes)}
    if kind == 'text':
        raise LogReadError(f'{path}: a text log, but the map is for bags (kind: bag)')
    stamps = {str(tp): logmap.time.stamp_of(tp) for tp in req}
    raw = read_bag(path, {str(k): v for k, v in req.items()}, stamps)
    for tp, tab in raw.items():
        if tab.stamp_kind != stamps[tp]:
            notes.append(f'{tp} ({tab.msgtype}) has no header: its receive (log) times are '
                         'used as its stamps')
        elif tab.stamp_kind == 'log' and logmap.time.stamp == 'header':
            notes.append(f'{tp}: its receive (log) times are used as its stamps (time.stamps)')
    return {tp: _tidy(tab, logmap.time.offsets.get(tp, 0.0), tab.stamp_kind, notes)
            for tp, tab in raw.items()}


# --------------------------------------------------------------------------------------------
# import: stages

def _origin(sig: str, derived: Sequence[str]) -> str:
    """``measured``, ``derived`` (computed from other logged signals) or ``assumed`` (not
    logged: a value was set), from the lines :func:`derive_missing` wrote."""
    line = next((d for d in derived if d.startswith(f'{sig}:')), None)
    if line is None:
        return 'measured'
    return 'assumed' if 'assumed' in line else 'derived'


def _lever_arm(vec: Vector, t: np.ndarray, seg: dict[str, np.ndarray]) -> str:
    """Move the velocity of a sensor at ``vec.lever_arm`` [m, body FRD] to the body origin,
    in place: ``v_origin = v_sensor - omega x r`` (rigid body), with ``omega = (p, q, r)`` as
    logged or, where not logged, from the attitude's rates (:func:`body_rates`; roll 0 if
    not logged). Returns the note saying so."""
    r = np.asarray(vec.lever_arm, float)
    zero = np.zeros_like(t)
    rates = body_rates(t, seg.get('phi', zero), seg['theta'], seg['psi'])
    omega = np.column_stack([seg[n] if n in seg else rates[k]
                             for k, n in enumerate(('p', 'q', 'r'))])
    corr = np.cross(omega, r)
    for k, name in enumerate(('u', 'v', 'w')):
        if name in vec.gives and name in seg:
            seg[name] = seg[name] - corr[:, k]
    how = 'logged' if all(n in seg for n in ('p', 'q', 'r')) else 'partly from the attitude'
    return (f'{vec.topic or "columns"}: velocity moved from the sensor at '
            f'({r[0]:g}, {r[1]:g}, {r[2]:g}) m (body FRD) to the body origin: '
            f'v - omega x r, omega {how}')


#: Stamps at or after this [s since the Unix epoch, 1990-01-01 UTC] are a date; earlier ones
#: a clock started with the log (a text log timed from 0).
EPOCH_MIN_S = 631_152_000.0


def utc(stamp: float) -> str | None:
    """An absolute stamp [s since the epoch] as ISO 8601 UTC, None for a clock started with
    the log (before :data:`EPOCH_MIN_S`)."""
    if not (math.isfinite(stamp) and stamp >= EPOCH_MIN_S):
        return None
    return datetime.datetime.fromtimestamp(stamp, datetime.UTC).isoformat(
        timespec='milliseconds').replace('+00:00', 'Z')


@dataclasses.dataclass(frozen=True)
class Signals:
    """Every mapped signal at its own source's stamps (SI, NED/FRD): ``series`` name ->
    (stamps [s], values); per signal the topic it comes from (``source_topic``), a label for
    the report, its declared update rate [Hz] and resolution [SI unit], and the map's unit
    of each signal (for the plausibility checks)."""

    series: dict[str, Series]
    source_topic: dict[str, str | None]
    label: dict[str, str]
    rate: dict[str, float]
    resolution: dict[str, float]
    declared: dict[str, Declared]


def convert_signals(logmap: LogMap, tables: Mapping[str | None, Table],
                    notes: list[str]) -> Signals:
    """Stage 2: every mapped signal converted at its source's stamps (see the module
    docstring; a vector's samples whose message says it carries no estimate are NaN)."""
    series: dict[str, Series] = {}
    source_topic: dict[str, str | None] = {}
    label: dict[str, str] = {}
    rate: dict[str, float] = {}
    resolution: dict[str, float] = {}
    declared: dict[str, Declared] = {}
    for vec in logmap.vectors:
        for sig, ser in _vector_series(vec, tables, notes).items():
            if sig in logmap.scalars:
                continue
            series[sig] = ser
            source_topic[sig] = vec.topic
            label[sig] = f'{vec.topic or "columns"} ({vec.origin}, {vec.kind})'
            if vec.rate is not None:
                rate[sig] = vec.rate
            if vec.resolution is not None:
                resolution[sig] = vec.resolution
            if vec.unit:
                u = UNITS[vec.unit]
                declared[sig] = Declared(vec.unit, u.dimension, u.factor, str(vec.where))
    for sig, sc in logmap.scalars.items():
        series[sig] = _scalar_series(sc, tables)
        tps = {term.topic for term in sc.terms}
        source_topic[sig] = tps.pop() if len(tps) == 1 else '(several topics)'
        label[sig] = ', '.join(dict.fromkeys(term.topic or f'column {term.path}'
                                             for term in sc.terms))
        if sc.rate is not None:
            rate[sig] = sc.rate
        if sc.resolution is not None:
            resolution[sig] = sc.resolution
        u = UNITS[sc.unit]
        declared[sig] = Declared(sc.unit, u.dimension, u.factor, str(sc.where))
    return Signals(series, source_topic, label, rate, resolution, declared)


def drop_nonfinite(signals: Signals, t_start: float, left_out: list[str]) -> Signals:
    """Stage 3: one line per signal with non-finite values. A state signal keeps them (the
    sample is then not usable, :func:`usable_samples`); a command or measured fin position
    loses them (the previous value holds, as for any event stream)."""
    series = dict(signals.series)
    for sig, (t, v) in signals.series.items():
        bad = ~np.isfinite(v)
        k = int(np.count_nonzero(bad))
        if not k:
            continue
        first = float(t[int(np.flatnonzero(bad)[0])]) - t_start
        where = signals.label[sig]
        if sig in STATE:
            left_out.append(f'{sig} ({where}): {k} non-finite value(s) (the first {first:.1f} '
                            's after the start): those samples are not usable')
        else:
            series[sig] = (t[~bad], v[~bad])
            left_out.append(f'{sig} ({where}): {k} non-finite value(s) (the first {first:.1f} '
                            's after the start) left out: the previous value holds')
    return dataclasses.replace(signals, series=series)


@dataclasses.dataclass(frozen=True)
class BaseState:
    """The state on the time base: stamps ``t`` [s], each given state signal (NaN where not
    usable), the holds and their notes, the signals the map gives, and each signal's noise
    floor [SI] from its resolution and its own update rate."""

    t: np.ndarray
    state: dict[str, np.ndarray]
    holds: list[str]
    given: set[str]
    noise_floor: dict[str, float]
    resolution: dict[str, float]


def base_state(logmap: LogMap, tables: Mapping[str | None, Table], signals: Signals,
               notes: list[str]) -> BaseState:
    """Stage 4: the state signals on the time base (the stamps of ``time.base``, every row
    of a text log): zero-order holds of other topics within ``max_age``; a signal whose map
    declares its update rate from its fresh samples (:func:`auv_logs.quality.onto`,
    said); resolution and repeats found or declared, said."""
    base = logmap.time.base if logmap.kind == 'bag' else None
    if base not in tables:
        raise MapError(f'{logmap.path}: time base {base} is not a topic the map reads '
                       f'({", ".join(str(k) for k in tables)})')
    t = tables[base].stamps
    keep = np.concatenate([[True], np.diff(t) > 0]) if len(t) else np.zeros(0, bool)
    if not np.all(keep):
        notes.append(f'time base {base or "rows"}: {int(np.count_nonzero(~keep))} repeated '
                     'stamp(s): the first sample of each kept')
    t = t[keep]
    holds: list[str] = []
    stale: dict[str, tuple[float, float]] = {}     # topic -> (median age, period) [s]
    state: dict[str, np.ndarray] = {}
    floor: dict[str, float] = {}
    resolution: dict[str, float] = {}
    for sig in STATE:
        if sig not in signals.series:
            continue
        st, sv = signals.series[sig]
        topic = signals.source_topic[sig]
        rate = signals.rate.get(sig)
        if rate is not None:
            fresh = fresh_samples(st, sv, rate)
            state[sig] = onto(st[fresh], sv[fresh], t, rate)
            state[sig][~np.isfinite(_hold(st, sv, t, None))] = np.nan
            d2 = np.diff(sv[fresh], 2)
            if d2.size >= 4:
                floor[sig] = float(1.4826 * np.median(np.abs(d2 - np.median(d2)))
                                   / math.sqrt(6.0))
            notes.append(f'{sig}: updated at {rate:g} Hz (map rate): its {fresh.size} fresh '
                         f'values of {len(st)} samples, each taken at the first stamp it '
                         'appears, linearly interpolated onto the state stamps (not across '
                         f'more than {2.0 / rate:g} s)')
        elif topic == base and len(st) == len(keep):
            state[sig] = sv[keep]
        else:
            state[sig] = _hold(st, sv, t, logmap.time.max_age)
            lost = int(np.count_nonzero(~np.isfinite(state[sig])))
            age = _age(st, t)[np.isfinite(state[sig])]
            holds.append(f'{sig} from {topic}: zero-order hold onto the '
                         f'{base} stamps, max age {logmap.time.max_age:g} s ({lost} samples '
                         'with no recent enough value: not usable)'
                         + (f'; held {np.median(age):.3g} s old on median' if len(age) else ''))
            stale[str(topic)] = (float(np.median(age)) if len(age) else 0.0, _period(st))
        step = signals.resolution.get(sig)
        unit = 'rad' if sig in ('phi', 'theta', 'psi') else (
            'rad/s' if sig in ('p', 'q', 'r') else 'm/s' if sig in 'uvw' else 'm')
        if step is None and rate is None:
            found = logged_step(sv)
            if found is not None:
                step = found
                notes.append(f'{sig}: logged in steps of {found:.3g} {unit}: its rounding '
                             f'({quantisation_sigma(found):.3g} {unit} RMS) is its least '
                             'noise (say resolution: in the map to declare it)')
            elif repeat_share(sv) > REPEAT_SHARE:
                notes.append(f'{sig}: the same value on {repeat_share(sv):.0%} of consecutive '
                             'samples: a sensor slower than the log? declare its update rate '
                             '(rate: in Hz, in the map), else its repeats count as data')
        elif step is not None:
            notes.append(f'{sig}: logged in steps of {step:.3g} {unit} (map resolution): its '
                         f'rounding ({quantisation_sigma(step):.3g} {unit} RMS) is its least '
                         'noise')
        if step is not None:
            resolution[sig] = step
            floor[sig] = max(floor.get(sig, 0.0), quantisation_sigma(step))
    base_period = _period(t)
    for topic, (age, period) in stale.items():
        if age > 0.5 * base_period and period > 1.5 * base_period:
            notes.append(f'{topic} ({period:.3g} s period) is held onto the {base} stamps '
                         f'({base_period:.3g} s) {age:.3g} s old on median: a lag its '
                         'signals carry into the dynamics; with the slower topic as time.base '
                         'they are read at their own stamps')
    if logmap.time.grid is None:
        jitter = spacing_jitter(t)
        if jitter is not None:
            notes.append(f'{base or "rows"}: {jitter} (auv ident needs it; auv gap '
                         'interpolates the rows onto their mean step)')
    return BaseState(t, state, holds, set(state), floor, resolution)


@dataclasses.dataclass(frozen=True)
class Usable:
    """Which base samples make segments: ``slices`` into the base stamps, the lines saying
    what was left out, and the stretches the segment rules set apart: surface passes and
    thruster-off coasts (see :func:`usable_samples`)."""

    slices: list[slice]
    left_out: list[str]
    surface: list[dict[str, Any]]
    coasts: list[dict[str, Any]]


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """``(start, stop)`` of the runs of True in ``mask``."""
    d = np.diff(np.r_[0, mask.astype(np.int8), 0])
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist()))


def usable_samples(logmap: LogMap, bs: BaseState, commands: Mapping[str, Series],
                   t_start: float) -> Usable:
    """Stage 5: usable samples (every mapped state signal there, submerged, propeller on, as
    the map's segment rules say) split into segments (:func:`split`). Surface passes (runs of
    at least 3 samples shallower than ``surface_depth``: the depth sensor's reading at the
    surface) and thruster-off stretches (held thrust below ``thrust_off``, or exactly zero
    without the rule) are summarised for the report, with times since ``t_start`` [s]."""
    t, state = bs.t, bs.state
    usable = np.ones(len(t), bool)
    for sig in bs.given:
        usable &= np.isfinite(state[sig])
    rules = logmap.segments
    counts: dict[str, int] = {}
    surface: list[dict[str, Any]] = []
    submerged = np.ones(len(t), bool)
    if rules['surface_depth'] is not None and 'z' in state:
        surf = np.isfinite(state['z']) & (state['z'] < float(rules['surface_depth']))
        counts['surfaced'] = int(np.count_nonzero(surf & usable))
        submerged = ~surf
        for a, b in _runs(surf):
            if b - a < 3:
                continue
            z = state['z'][a:b]
            q25, q50, q75 = (float(v) for v in np.quantile(z, [0.25, 0.5, 0.75]))
            surface.append({'from_s': float(t[a] - t_start), 'to_s': float(t[b - 1] - t_start),
                            'samples': b - a, 'depth_median': q50,
                            'depth_spread': (q75 - q25) / 1.349})
        usable &= ~surf
    held = _hold(*commands['thrust'], t, None)
    limit = float(rules['thrust_off']) if rules['thrust_off'] is not None else 0.0
    off = ~(np.abs(held) > limit) if limit > 0 else ~(np.abs(held) > 0.0)
    coasts = [{'from_s': float(t[a] - t_start), 'to_s': float(t[b - 1] - t_start),
               'samples': b - a, 'kept': rules['thrust_off'] is None}
              for a, b in _runs(off & submerged & np.isfinite(held)) if b - a >= 3]
    if rules['thrust_off'] is not None:
        counts['propeller off'] = int(np.count_nonzero(off & usable))
        usable &= ~off
    slices, left = split(t, usable, max_gap=rules['max_gap'],
                         min_duration=float(rules['min_duration'] or 0.0))
    for why, k in counts.items():
        if k:
            left.append(f'{k} sample(s) left out: {why}')
    return Usable(slices, left, surface, coasts)


def _no_segment(name: str, logmap: LogMap, bs: BaseState, tables: Mapping[str | None, Table],
                signals: Signals, left_out: Sequence[str]) -> NoSegmentError:
    """The one-line refusal of a log with no usable segment, naming what removed its
    samples (and a topic on another clock that holds onto no base stamp)."""
    base = logmap.time.base if logmap.kind == 'bag' else None
    lines = list(left_out)
    dead: dict[str, list[str]] = {}
    for sig in (s for s in STATE if s in bs.given):
        tp = signals.source_topic[sig]
        if not np.any(np.isfinite(bs.state[sig])) and tp in tables and tp != base:
            dead.setdefault(str(tp), []).append(sig)
    for tp, sigs in dead.items():
        st = tables[tp].stamps
        lines.append(f'{" ".join(sigs)} from {tp}: no sample within max_age '
                     f'{logmap.time.max_age:g} s of any {base} stamp ({tp} stamps '
                     f'{st[0]:.3f} to {st[-1]:.3f} s, {base} {bs.t[0]:.3f} to {bs.t[-1]:.3f} '
                     's: another clock? see time.offsets)')
    return NoSegmentError(f'{name}: no usable segment of '
                          f'{logmap.segments["min_duration"]:g} s or more '
                          f'({"; ".join(lines) or "no usable samples"})')


@dataclasses.dataclass(frozen=True)
class Segments:
    """The usable segments as contract rows: stamps per segment [s], the 12-state rows
    (NED/FRD, SI), the derivation lines, and the lever-arm notes."""

    t: list[np.ndarray]
    rows: list[np.ndarray]
    derived: list[str]
    lever_notes: list[str]
    signals: list[tuple[np.ndarray, dict[str, np.ndarray]]]


def build_segments(logmap: LogMap, bs: BaseState, slices: Sequence[slice]) -> Segments:
    """Stage 6: per segment, the lever-arm correction, the missing state signals derived
    (:func:`derive_missing`), and the optional resampling onto ``time.grid``."""
    missing = set(STATE) - bs.given
    derived: list[str] = []
    lever_vectors = [v for v in logmap.vectors if v.lever_arm is not None and v.gives]
    lever_notes: set[str] = set()
    pieces_t, pieces_s, per_seg = [], [], []
    for sl in slices:
        ts = bs.t[sl]
        seg = {sig: bs.state[sig][sl].copy() for sig in bs.given}
        for vec in lever_vectors:
            lever_notes.add(_lever_arm(vec, ts, seg))
        derived = list(dict.fromkeys(derived + derive_missing(ts, seg, set(missing))))
        per_seg.append((ts, dict(seg)))
        rows = np.column_stack([seg[sig] for sig in STATE])
        if logmap.time.grid is not None:
            ts, rows = resample(ts, rows, logmap.time.grid)
        pieces_t.append(ts)
        pieces_s.append(rows)
    return Segments(pieces_t, pieces_s, derived, sorted(lever_notes), per_seg)


def on_file_clock(tables: Mapping[str | None, Table], base: str | None, path: pathlib.Path,
                  notes: list[str]) -> dict[str | None, Table]:
    """Stage 1b: a log timed from its own start (its first stamp before
    :data:`EPOCH_MIN_S`) whose file states its start time (:func:`file_time`: a header
    comment or its name) is placed on that clock: every stamp plus the file's time less the
    first stamp, said in ``notes``. Logs of one season then follow one another in time."""
    clock = file_time(path)
    first = tables[base].stamps[0] if base in tables and len(tables[base].stamps) else None
    if clock is None or first is None or first >= EPOCH_MIN_S:
        return dict(tables)
    shift = float(clock) - float(first)
    notes.append(f'timed from its start: its stamps placed on the time its file states '
                 f'(a header comment or its name), {utc(clock)}: {shift:+.3f} s')
    return {k: dataclasses.replace(tab, stamps=tab.stamps + shift) for k, tab in tables.items()}


def import_log(logmap: LogMap, path: str | os.PathLike[str], name: str | None = None, *,
               strict: bool = False, envelope: Envelope | None = None) -> ContractLog:
    """Import one log through ``logmap`` (see the module docstring), in stages that each
    return their data: read, convert, non-finite values, the time base, usable samples and
    segments, derivation, plausibility.

    ``strict``: refuse a text row that does not parse instead of leaving it out and saying
    so. ``envelope``: the vehicle's (:func:`auv_logs.plausibility.envelope_of`) for
    the plausibility checks; default the physical limits.

    Raises
    ------
    LogReadError, MapError
        bad log or map (one line naming the map key, file or row).
    NoSegmentError
        no usable segment.
    PlausibilityError
        a signal that cannot be in the unit or frame the map says.
    RealLogError
        a state signal is missing and cannot be derived.
    """
    p = pathlib.Path(path)
    name = name or (p.stem if p.is_file() else p.name)
    notes: list[str] = []
    tables = read_tables(logmap, p, notes, strict)
    left_out: list[str] = [line for tab in tables.values() for line in tab.skipped]
    base = logmap.time.base if logmap.kind == 'bag' else None
    tables = on_file_clock(tables, base, p, notes)
    signals = convert_signals(logmap, tables, notes)
    t_start = float(tables[base].stamps[0]) if base in tables and len(tables[base].stamps) \
        else 0.0
    signals = drop_nonfinite(signals, t_start, left_out)
    bs = base_state(logmap, tables, signals, notes)
    commands: dict[str, Series] = {
        ch: signals.series[ch] for ch in ('bar', 'helm', 'thrust', 'bar_measured',
                                          'helm_measured') if ch in signals.series}
    use = usable_samples(logmap, bs, commands, t_start)
    if not use.slices:
        raise _no_segment(name, logmap, bs, tables, signals, [*left_out, *use.left_out])
    segs = build_segments(logmap, bs, use.slices)
    origins = {sig: _origin(sig, segs.derived) for sig in STATE}
    checks = check_signals(name, segs.signals, origins, signals.declared, envelope)
    spans = [(float(ts[0]), float(ts[-1]), len(ts)) for ts in segs.t]
    report = {
        'log': str(p),
        'map': logmap.path,
        'start': {'stamp_s': t_start, 'utc': utc(t_start), 'file_time_s': file_time(p),
                  'file_time_utc': utc(ft) if (ft := file_time(p)) is not None else None},
        'signals': {sig: 'derived' if sig not in bs.given else signals.label[sig]
                    for sig in STATE} | {ch: signals.label[ch] for ch in commands},
        'derived': segs.derived,
        'origins': origins,
        'time_base': (f'state at the stamps of {base} ({logmap.time.stamp} stamps)' if base
                      else 'state at every row of the log (time column '
                      f'{logmap.time.column!r})'),
        'holds': bs.holds,
        'resampled': (f'state of each segment resampled onto a uniform {logmap.time.grid:g} s '
                      'grid by linear interpolation (roll, yaw unwrapped); not across segments'
                      if logmap.time.grid is not None else 'no: state at its own stamps'),
        'commands': 'as logged, at their own stamps (held by the consumers until the next)',
        'segments': [{'start': a, 'end': b, 'samples': n, 'from_s': a - t_start,
                      'to_s': b - t_start} for a, b, n in spans],
        'left_out': [*left_out, *use.left_out],
        'surface_passes': use.surface,
        'coasts': use.coasts,
        'resolution': bs.resolution,
        'noise_floor': bs.noise_floor,
        'checks': checks,
        'notes': notes + segs.lever_notes + [
            f'{v.topic or "columns"}: velocity rotated from the sensor axes by roll, pitch, '
            f'yaw {", ".join(f"{math.degrees(a):.6g}" for a in v.mounting)} deg (mounting)'
            for v in logmap.vectors if v.mounting is not None],
    }
    return ContractLog(name, np.concatenate(segs.t), np.vstack(segs.rows), commands,
                       tuple(spans), report)


# --------------------------------------------------------------------------------------------
# batch import

#: Errors for which a batch import leaves one log out (said) and goes on: the log cannot be
#: read as the map says, or holds nothing usable. A wrong unit or a bad map is the map's, for
#: every log: it stops the batch.
SKIPPABLE: tuple[type[Exception], ...] = (LogReadError, NoSegmentError)


def import_logs(map_path: str | os.PathLike[str], logs: Sequence[str | os.PathLike[str]],
                *, strict: bool = False, envelope: Envelope | None = None,
                skipped: list[str] | None = None) -> tuple[LogMap, list[ContractLog]]:
    """Load the map and import every log (:func:`import_log`).

    With ``skipped`` (a list), a log that cannot be read or holds no usable segment is left
    out and its one-line reason appended there (the batch goes on); without it, with
    ``strict``, or for a single log, the first such log raises.

    Raises
    ------
    RealLogError
        as :func:`import_log`; when every log is left out, one line naming
        them.
    """
    logmap = load_map(map_path)
    out: list[ContractLog] = []
    reasons: list[str] = []
    for lg in logs:
        try:
            out.append(import_log(logmap, lg, strict=strict, envelope=envelope))
        except SKIPPABLE as exc:
            if skipped is None or strict or len(logs) == 1:
                raise
            reasons.append(f'{lg}: left out: {str(exc).splitlines()[0]}')
    if not out:
        raise NoSegmentError('every log was left out: ' + '; '.join(reasons))
    if skipped is not None:
        skipped.extend(reasons)
    return logmap, out
