"""A map and a real log -> the contract's arrays and bag, with provenance.

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
:func:`auv_bag.read_arrays` gives for a contract bag (:func:`contract_arrays`), or written
as a contract bag (:func:`write_contract_bag`) whose metadata carry the provenance.
"""
from __future__ import annotations

import dataclasses
import datetime
import hashlib
import itertools
import json
import math
import os
import pathlib
import shutil
import tempfile
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from auv_contract import COMMAND_TOPICS, MEASURED_TOPICS, STATE_TOPIC, read_yaml
from auv_logs.derive import body_rates, derive_missing
from auv_logs.errors import LogReadError, MapError, RealLogError
from auv_logs.mapping import SCALAR_ENU, STATE, LogMap, Scalar, Vector, load_map
from auv_logs.readers import Table, log_kind, read_bag, read_text
from auv_logs.segments import resample, split
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

#: Map signal -> contract topic of the measured fin positions
#: (:data:`auv_contract.MEASURED_TOPICS`).
MEASURED_SIGNAL_TOPICS = {f'{ch}_measured': topic for ch, topic in MEASURED_TOPICS.items()}
NS = 1_000_000_000
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
                               '(the publisher does not stamp): use time: {stamp: log}')
    if offset:
        notes.append(f'{tab.source}: clock offset {offset:+.6g} s added to its stamps')
    steps = np.diff(t)
    back = int(np.count_nonzero(steps < 0))
    cols = dict(tab.columns)
    if back:
        k = int(np.argmin(steps))
        if -steps[k] > max(BACK_LIMIT, BACK_PERIODS * _period(t)):
            what = 'row' if stamp == 'column' else 'message'
            raise LogReadError(f'{tab.source}: time goes back by {-steps[k]:.6g} s at {what} '
                               f'{k + 2} ({t[k]:.6f} s, then {t[k + 1]:.6f} s): a clock reset '
                               'or a restart of the logger? split the log there')
        order = np.argsort(t, kind='stable')
        t = t[order]
        cols = {k: v[order] for k, v in cols.items()}
        notes.append(f'{tab.source}: {back} stamp(s) went back; messages sorted by stamp')
    return Table(tab.source, tab.msgtype, t, cols, tab.stamp_kind)


def read_tables(logmap: LogMap, path: str | os.PathLike[str],
                notes: list[str]) -> dict[str | None, Table]:
    """Read what ``logmap`` needs from the log at ``path`` (tables keyed by topic; a text
    log's table under ``None``)."""
    kind = log_kind(path)
    req = _requests(logmap)
    if logmap.kind == 'text':
        if kind != 'text':
            raise LogReadError(f'{path}: the map is for text logs, this is a {kind} bag')
        fmt = logmap.text
        assert fmt is not None and logmap.time.column is not None
        tab = read_text(path, req.get(None, []), logmap.time.column,
                        delimiter=fmt.delimiter, header=fmt.header, names=fmt.columns,
                        comment=fmt.comment)
        tab = Table(tab.source, tab.msgtype, tab.stamps * logmap.time.factor, tab.columns,
                    'column')
        return {None: _tidy(tab, 0.0, 'column', notes)}
    if kind == 'text':
        raise LogReadError(f'{path}: a text log, but the map is for bags (kind: bag)')
    raw = read_bag(path, {str(k): v for k, v in req.items()}, logmap.time.stamp)
    for tp, tab in raw.items():
        if tab.stamp_kind != logmap.time.stamp:
            notes.append(f'{tp} ({tab.msgtype}) has no header: its receive (log) times are '
                         'used as its stamps')
    return {tp: _tidy(tab, logmap.time.offsets.get(tp, 0.0), tab.stamp_kind, notes)
            for tp, tab in raw.items()}


# --------------------------------------------------------------------------------------------
# import

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


def _file_hash(path: pathlib.Path) -> dict[str, str]:
    files = sorted(p for p in path.rglob('*') if p.is_file()) if path.is_dir() else [path]
    out = {}
    for f in files:
        h = hashlib.sha256()
        with open(f, 'rb') as fh:
            for block in iter(lambda: fh.read(1 << 20), b''):
                h.update(block)
        out[str(f)] = h.hexdigest()
    return out


def import_log(logmap: LogMap, path: str | os.PathLike[str],
               name: str | None = None) -> ContractLog:
    """Import one log through ``logmap`` (see the module docstring).

    Raises:
        LogReadError, MapError: bad log or map (one line naming the map key, file or row).
        RealLogError: a state signal is missing and cannot be derived, or nothing usable.
    """
    p = pathlib.Path(path)
    name = name or (p.stem if p.is_file() else p.name)
    notes: list[str] = []
    tables = read_tables(logmap, p, notes)
    series: dict[str, Series] = {}
    for vec in logmap.vectors:
        for sig, ser in _vector_series(vec, tables, notes).items():
            if sig not in logmap.scalars:
                series[sig] = ser
    for sig, sc in logmap.scalars.items():
        series[sig] = _scalar_series(sc, tables)
    source_topic: dict[str, str | None] = {}
    label: dict[str, str] = {}
    for vec in logmap.vectors:
        for sig in vec.gives:
            if sig not in logmap.scalars:
                source_topic[sig] = vec.topic
                label[sig] = f'{vec.topic or "columns"} ({vec.origin}, {vec.kind})'
    for sig, sc in logmap.scalars.items():
        tps = {term.topic for term in sc.terms}
        source_topic[sig] = tps.pop() if len(tps) == 1 else '(several topics)'
        label[sig] = ', '.join(dict.fromkeys(term.topic or f'column {term.path}'
                                             for term in sc.terms))
    # time base
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
    for sig in STATE:
        if sig not in series:
            continue
        st, sv = series[sig]
        if source_topic[sig] == base and len(st) == len(keep):
            state[sig] = sv[keep]
        else:
            state[sig] = _hold(st, sv, t, logmap.time.max_age)
            lost = int(np.count_nonzero(~np.isfinite(state[sig])))
            age = _age(st, t)[np.isfinite(state[sig])]
            holds.append(f'{sig} from {source_topic[sig]}: zero-order hold onto the '
                         f'{base} stamps, max age {logmap.time.max_age:g} s ({lost} samples '
                         'with no recent enough value: not usable)'
                         + (f'; held {np.median(age):.3g} s old on median' if len(age) else ''))
            stale[str(source_topic[sig])] = (float(np.median(age)) if len(age) else 0.0,
                                             _period(st))
    base_period = _period(t)
    for topic, (age, period) in stale.items():
        if age > 0.5 * base_period and period > 1.5 * base_period:
            notes.append(f'{topic} ({period:.3g} s period) is held onto the {base} stamps '
                         f'({base_period:.3g} s) {age:.3g} s old on median: a lag its '
                         'signals carry into the dynamics; with the slower topic as time.base '
                         'they are read at their own stamps')
    given = set(state)
    missing = set(STATE) - given
    usable = np.ones(len(t), bool)
    for sig in given:
        usable &= np.isfinite(state[sig])
    rules = logmap.segments
    counts: dict[str, int] = {}
    if rules['surface_depth'] is not None and 'z' in state:
        surf = np.isfinite(state['z']) & (state['z'] < float(rules['surface_depth']))
        counts['surfaced'] = int(np.count_nonzero(surf & usable))
        usable &= ~surf
    commands: dict[str, Series] = {}
    for ch in ('bar', 'helm', 'thrust', 'bar_measured', 'helm_measured'):
        if ch in series:
            commands[ch] = series[ch]
    if rules['thrust_off'] is not None:
        held = _hold(*commands['thrust'], t, None)
        off = ~(np.abs(held) >= float(rules['thrust_off']))
        counts['propeller off'] = int(np.count_nonzero(off & usable))
        usable &= ~off
    slices, seg_notes = split(t, usable, max_gap=rules['max_gap'],
                              min_duration=float(rules['min_duration'] or 0.0))
    for why, k in counts.items():
        if k:
            seg_notes.append(f'{k} sample(s) left out: {why}')
    if not slices:
        # a topic on another clock holds onto no base stamp: name it and both time spans
        dead: dict[str, list[str]] = {}
        for sig in (s for s in STATE if s in given):
            tp = source_topic[sig]
            if not np.any(np.isfinite(state[sig])) and tp in tables and tp != base:
                dead.setdefault(str(tp), []).append(sig)
        for tp, sigs in dead.items():
            st = tables[tp].stamps
            seg_notes.append(f'{" ".join(sigs)} from {tp}: no sample within max_age '
                             f'{logmap.time.max_age:g} s of any {base} stamp ({tp} stamps '
                             f'{st[0]:.3f} to {st[-1]:.3f} s, {base} {t[0]:.3f} to {t[-1]:.3f} '
                             's: another clock? see time.offsets)')
        raise RealLogError(f'{name}: no usable segment of {rules["min_duration"]:g} s or more '
                           f'({"; ".join(seg_notes) or "no usable samples"})')
    pieces_t, pieces_s, segs = [], [], []
    derived: list[str] = []
    lever_vectors = [v for v in logmap.vectors if v.lever_arm is not None and v.gives]
    lever_notes: set[str] = set()
    for sl in slices:
        ts = t[sl]
        seg = {sig: state[sig][sl].copy() for sig in given}
        for vec in lever_vectors:
            lever_notes.add(_lever_arm(vec, ts, seg))
        derived = list(dict.fromkeys(derived + derive_missing(ts, seg, set(missing))))
        rows = np.column_stack([seg[sig] for sig in STATE])
        if logmap.time.grid is not None:
            ts, rows = resample(ts, rows, logmap.time.grid)
        pieces_t.append(ts)
        pieces_s.append(rows)
        segs.append((float(ts[0]), float(ts[-1]), len(ts)))
    report = {
        'log': str(p),
        'map': logmap.path,
        'signals': {sig: 'derived' if sig in missing else label[sig] for sig in STATE}
        | {ch: label[ch] for ch in commands},
        'derived': derived,
        'origins': {sig: _origin(sig, derived) for sig in STATE},
        'time_base': (f'state at the stamps of {base} ({logmap.time.stamp} stamps)' if base
                      else 'state at every row of the log (time column '
                      f'{logmap.time.column!r})'),
        'holds': holds,
        'resampled': (f'state of each segment resampled onto a uniform {logmap.time.grid:g} s '
                      'grid by linear interpolation (roll, yaw unwrapped); not across segments'
                      if logmap.time.grid is not None else 'no: state at its own stamps'),
        'commands': 'as logged, at their own stamps (held by the consumers until the next)',
        'segments': [{'start': a, 'end': b, 'samples': n} for a, b, n in segs],
        'left_out': seg_notes,
        'notes': notes + sorted(lever_notes) + [
            f'{v.topic or "columns"}: velocity rotated from the sensor axes by roll, pitch, '
            f'yaw {", ".join(f"{math.degrees(a):.6g}" for a in v.mounting)} deg (mounting)'
            for v in logmap.vectors if v.mounting is not None],
    }
    return ContractLog(name, np.concatenate(pieces_t), np.vstack(pieces_s), commands,
                       tuple(segs), report)


# --------------------------------------------------------------------------------------------
# contract arrays and bag

def _ns(t: np.ndarray) -> np.ndarray:
    out: np.ndarray = np.round(np.asarray(t, float) * NS).astype(np.int64)
    return out


def _seconds(ns: np.ndarray) -> np.ndarray:
    """As :func:`auv_bag.read_arrays` computes stamps: ``sec + nanosec * 1e-9``."""
    sec, nsec = np.divmod(ns, NS)
    out: np.ndarray = sec.astype(np.float64) + nsec.astype(np.float64) * 1e-9
    return out


def contract_arrays(log: ContractLog) -> dict[str, np.ndarray]:
    """The arrays :func:`auv_bag.read_arrays` gives for the contract bag of ``log``
    (``/auv/state`` with ``t``, ``t_log`` and the 12 state fields; each command topic with
    ``t``, ``t_log``, ``value``), stamps rounded to the nanosecond as the bag stores them."""
    ts = _seconds(_ns(log.t))
    dtype = np.dtype([(n, '<f8') for n in ('t', 't_log', *STATE)])
    st = np.empty(len(ts), dtype)
    st['t'] = ts
    st['t_log'] = ts
    for k, sig in enumerate(STATE):
        st[sig] = log.state[:, k]
    out = {STATE_TOPIC: st}
    cdt = np.dtype([('t', '<f8'), ('t_log', '<f8'), ('value', '<f8')])
    for ch, topic in {**COMMAND_TOPICS, **MEASURED_SIGNAL_TOPICS}.items():
        if ch not in log.commands:
            continue
        ct, cv = log.commands[ch]
        arr = np.empty(len(ct), cdt)
        arr['t'] = _seconds(_ns(ct))
        arr['t_log'] = arr['t']
        arr['value'] = cv
        out[topic] = arr
    return out


def import_logs(map_path: str | os.PathLike[str],
                logs: Sequence[str | os.PathLike[str]]) -> tuple[LogMap, list[ContractLog]]:
    """Load the map and import every log."""
    logmap = load_map(map_path)
    return logmap, [import_log(logmap, lg) for lg in logs]


def provenance(logmap: LogMap, logs: Sequence[ContractLog]) -> dict[str, Any]:
    """What the contract bag was made from: source files and their SHA-256, the map text,
    and each log's import report."""
    files: dict[str, str] = {}
    for lg in logs:
        files.update(_file_hash(pathlib.Path(str(lg.report['log']))))
    return {
        'tool': 'auv import',
        'created': datetime.datetime.now(datetime.UTC).isoformat(timespec='seconds'),
        'map_path': logmap.path,
        'map_sha256': hashlib.sha256(logmap.text_source.encode()).hexdigest(),
        'map': logmap.text_source,
        'sources': files,
        'imports': [dict(lg.report) for lg in logs],
    }


def write_contract_bag(out: str | os.PathLike[str], logmap: LogMap,
                       logs: Sequence[ContractLog]) -> dict[str, Any]:
    """Write the logs as one contract bag at ``out`` (a directory; written to a temporary
    directory beside it and renamed, so nothing is left half written). Returns the provenance
    stored in ``metadata.yaml`` (``custom_data.auv_provenance``, JSON) and in the MCAP file.

    Raises:
        RealLogError: ``out`` exists, or the logs overlap in time (import them one by one).
    """
    from auv_bag import BagWriter, typestore

    dest = pathlib.Path(out)
    if dest.exists():
        raise RealLogError(f'output {dest} exists already')
    spans = sorted((float(lg.t[0]), float(lg.t[-1]), lg.name) for lg in logs)
    for (_a0, a1, an), (b0, _, bn) in itertools.pairwise(spans):
        if b0 <= a1:
            raise RealLogError(f'logs {an} and {bn} overlap in time: import them into separate '
                               'bags')
    prov = provenance(logmap, logs)
    store = typestore()
    T = store.types
    Header, Time = T['std_msgs/msg/Header'], T['builtin_interfaces/msg/Time']
    State, Setpoint = T['auv_msgs/msg/VehicleState'], T['auv_msgs/msg/ActuatorSetpoint']
    dest.parent.mkdir(parents=True, exist_ok=True)
    tmp = pathlib.Path(tempfile.mkdtemp(prefix=f'.{dest.name}.', dir=dest.parent))
    work = tmp / dest.name
    try:
        events: list[tuple[int, int, str, Any]] = []

        def header(ns: int, frame: str) -> Any:
            return Header(stamp=Time(sec=int(ns // NS), nanosec=int(ns % NS)), frame_id=frame)

        for lg in logs:
            for ns, row in zip(_ns(lg.t).tolist(), lg.state):
                fields = {k: float(v) for k, v in zip(STATE, row)}
                events.append((ns, 1, STATE_TOPIC, State(header=header(ns, 'ned'), **fields)))
            for ch, topic in {**COMMAND_TOPICS, **MEASURED_SIGNAL_TOPICS}.items():
                if ch not in lg.commands:
                    continue
                ct, cv = lg.commands[ch]
                for ns, v in zip(_ns(ct).tolist(), cv.tolist()):
                    events.append((ns, 0, topic, Setpoint(header=header(ns, ch), value=v)))
        events.sort(key=lambda e: (e[0], e[1]))
        meta = {'auv_provenance': json.dumps(prov)}
        with BagWriter(work, custom_data=meta) as bag:
            bag.add_topic(STATE_TOPIC, 'auv_msgs/msg/VehicleState')
            for topic in sorted({e[2] for e in events}):
                bag.add_topic(topic, 'auv_msgs/msg/ActuatorSetpoint' if topic != STATE_TOPIC
                              else 'auv_msgs/msg/VehicleState')
            for ns, _, topic, msg in events:
                bag.write(topic, msg, log_time_ns=max(ns, 0))
        work.rename(dest)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return prov


def read_provenance(bag: str | os.PathLike[str]) -> dict[str, Any] | None:
    """The provenance an imported bag carries (None for a bag not made by ``auv import``)."""
    meta = pathlib.Path(bag) / 'metadata.yaml'
    if not meta.exists():
        return None
    info = read_yaml(meta).get('rosbag2_bagfile_information', {})
    raw = (info.get('custom_data') or {}).get('auv_provenance')
    return None if raw is None else dict(json.loads(raw))

