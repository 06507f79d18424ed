"""Logs as they come: cut-off rows, non-finite values, empty and surface-only logs, a slow
sensor repeated on the rows, values in steps, rows whose spacing jitters, a wrong unit.

Oracles are worked by hand: a 2 Hz text log whose rows and values are written from formulas
(the vehicle dives at a pitch that changes linearly, its depth the kinematics' integral), so
the number of rows, the left-out lines, the interpolated slow sensor and the ratios of the
plausibility checks are known exactly.
"""
from __future__ import annotations

import math
import pathlib
import subprocess
import sys

import numpy as np
import pytest

from auv_ident.errors import IdentificationError
from auv_logs.errors import LogReadError, MapError, NoSegmentError
from auv_logs.importer import import_log, import_logs
from auv_logs.mapping import load_map
from auv_logs.plausibility import Envelope, PlausibilityError, envelope_of
from auv_logs.quality import quantisation_sigma
from auv_logs.readers import file_time
from auv_logs.segments import spacing_jitter
from auv_sim.params import load_vehicle

ROOT = pathlib.Path(__file__).resolve().parents[1]
MAP = """format: auv-log-map/1
kind: text
text: {delimiter: whitespace, header: true}
time: {column: time, unit: s}
signals:
  z: {column: depth, unit: DEPTH_UNIT, frame: NED EXTRA_Z}
  theta: {column: pitch, unit: deg, frame: NED/FRD}
  psi: {column: heading, unit: deg, frame: NED}
  u: {column: speed, unit: m/s, frame: FRD EXTRA_U}
  q: {column: q, unit: Q_UNIT, frame: FRD}
  bar: {column: bar, unit: deg}
  thrust: {column: thrust, unit: N}
segments: {surface_depth: 0.3, min_duration: 10}
"""
HEADER = 'time depth pitch heading speed q bar thrust'


def _map(tmp: pathlib.Path, depth_unit: str = 'm', q_unit: str = 'rad/s', extra_z: str = '',
         extra_u: str = '') -> pathlib.Path:
    path = tmp / 'map.yaml'
    path.write_text(MAP.replace('DEPTH_UNIT', depth_unit).replace('Q_UNIT', q_unit)
                    .replace(' EXTRA_Z', extra_z).replace(' EXTRA_U', extra_u))
    return path


def _flight(t: np.ndarray) -> dict[str, np.ndarray]:
    """A dive and a climb at 1.5 m/s: pitch 0.2 sin(2 pi t / 40) rad, depth the integral of
    -u sin(pitch) from 6 m (w = 0), q the pitch's rate."""
    th = 0.2 * np.sin(2 * np.pi * t / 40.0)
    fine = np.linspace(0.0, t[-1], 20001)
    zdot = -1.5 * np.sin(0.2 * np.sin(2 * np.pi * fine / 40.0))
    z = 6.0 + np.interp(t, fine, np.concatenate([[0.0], np.cumsum(
        0.5 * np.diff(fine) * (zdot[1:] + zdot[:-1]))]))
    q = 0.2 * (2 * np.pi / 40.0) * np.cos(2 * np.pi * t / 40.0)
    return {'z': z, 'theta': th, 'q': q}


def _write(path: pathlib.Path, t: np.ndarray, *, depth_scale: float = 1.0,
           q_scale: float = 1.0, nan_row: int | None = None, cut: bool = False,
           speed: np.ndarray | None = None, depth_step: float = 0.0) -> None:
    f = _flight(t)
    u = np.full(t.size, 1.5) if speed is None else speed
    lines = [HEADER]
    for k, tk in enumerate(t):
        z = f['z'][k]
        if depth_step:
            z = round(z / depth_step) * depth_step
        fields = [f'{tk:.3f}', f'{z * depth_scale:.6f}', f'{math.degrees(f["theta"][k]):.6f}',
                  '90.0', 'nan' if k == nan_row else f'{u[k]:.6f}',
                  f'{f["q"][k] * q_scale:.6f}', '1.0', '20.0']
        lines.append(' '.join(fields))
    if cut:
        lines[-1] = lines[-1][:12]
    path.write_text('\n'.join(lines) + ('' if cut else '\n'))


def test_cut_off_rows_non_finite_values_and_unusable_logs_are_left_out_and_said(
        tmp_path: pathlib.Path) -> None:
    t = np.arange(0.0, 60.0, 0.5)                       # 120 rows
    _write(tmp_path / 'a.txt', t, nan_row=30, cut=True)
    (tmp_path / 'empty.txt').write_text(HEADER + '\n')
    _write(tmp_path / 'surface.txt', t, depth_scale=0.0)
    m = _map(tmp_path)
    log = import_log(load_map(m), tmp_path / 'a.txt')
    left = log.report['left_out']
    # the cut last row (file line 121) and the nan at row 30 (15.0 s), one line each
    assert 'a.txt line 121: 2 fields, expected 8: left out (the last row, cut off ' \
           'mid-line?)' in left
    assert ('u (column speed): 1 non-finite value(s) (the first 15.0 s after the start): '
            'those samples are not usable') in left
    with pytest.raises(LogReadError, match=r'a\.txt line 121: 2 fields, expected 8'):
        import_log(load_map(m), tmp_path / 'a.txt', strict=True)
    skipped: list[str] = []
    _, logs = import_logs(m, [tmp_path / n for n in ('a.txt', 'empty.txt', 'surface.txt')],
                          skipped=skipped)
    assert [lg.name for lg in logs] == ['a']
    assert len(skipped) == 2
    assert skipped[0].endswith('empty.txt: left out: ' + str(tmp_path / 'empty.txt')
                               + ': no data rows')
    assert 'surface: no usable segment of 10 s or more' in skipped[1]
    assert '120 sample(s) left out: surfaced' in skipped[1]
    _write(tmp_path / 'b.txt', t)
    with pytest.raises(NoSegmentError, match='no usable segment'):
        import_logs(m, [tmp_path / 'b.txt', tmp_path / 'surface.txt'], strict=True,
                    skipped=[])
    # the command: the batch goes on, one line per log left out, nothing else on stderr
    proc = subprocess.run([sys.executable, '-m', 'auv_bringup.cli', 'import', '--map', str(m),
                           *(str(tmp_path / n) for n in ('a.txt', 'empty.txt', 'surface.txt')),
                           '--out', str(tmp_path / 'bag')], capture_output=True, text=True,
                          timeout=300, check=False)
    assert proc.returncode == 0, proc.stderr
    assert sum('left out:' in ln and ln.startswith(str(tmp_path))
               for ln in proc.stderr.splitlines()) == 2


def test_ident_leaves_unusable_logs_out_and_says_so(tmp_path: pathlib.Path) -> None:
    """``auv ident --map`` over a season folder: the empty and the surface-only log are left
    out with one line each (as ``auv gap`` and ``auv import`` do) and the flight is read;
    ``--strict`` refuses instead."""
    from auv_ident.job import load_records_from_map

    t = np.arange(0.0, 60.0, 0.5)
    _write(tmp_path / 'b.txt', t)
    (tmp_path / 'empty.txt').write_text(HEADER + '\n')
    _write(tmp_path / 'surface.txt', t, depth_scale=0.0)
    m = _map(tmp_path)   # the rudder held at zero (a column times 0): every command logged
    m.write_text(m.read_text().replace(
        '  thrust:', '  helm: {unit: deg, sum: [{column: bar, gain: 0.0}]}\n  thrust:'))
    logs = [str(tmp_path / n) for n in ('b.txt', 'empty.txt', 'surface.txt')]
    base = load_vehicle(ROOT / 'config' / 'a18m.yaml')
    said: list[str] = []
    skipped: list[str] = []
    records, imports = load_records_from_map(str(m), logs, base, progress=said.append,
                                             skipped=skipped)
    assert len(imports) == 1
    assert records and all(r.name.startswith('b') for r in records)
    assert len(skipped) == 2
    assert 'empty.txt: left out:' in skipped[0] and 'no data rows' in skipped[0]
    assert 'surface: no usable segment of 10 s or more' in skipped[1]
    assert all(line in said for line in skipped)
    with pytest.raises(NoSegmentError, match='no usable segment'):
        load_records_from_map(str(m), [logs[0], logs[2]], base, strict=True, skipped=[])


def test_a_sensor_slower_than_the_rows_and_values_in_steps(tmp_path: pathlib.Path) -> None:
    """The DVL updates at 1 Hz on 2 Hz rows (each value on two rows): declared ``rate: 1``,
    its fresh values are interpolated linearly onto the rows (hand: the row between two
    fresh values gets their mean); undeclared, a note names the repeats. Depth in 0.1 m
    steps: its least noise is 0.1 / sqrt(12) m, declared or found."""
    t = np.arange(0.0, 60.0, 0.5)
    fresh = 1.5 + 0.1 * np.sin(2 * np.pi * np.floor(t) / 13.0)     # held over each second
    _write(tmp_path / 'dvl.txt', t, speed=fresh, depth_step=0.1)
    plain = import_log(load_map(_map(tmp_path)), tmp_path / 'dvl.txt')
    notes = ' '.join(plain.report['notes'])
    assert 'u: the same value on 50% of consecutive samples' in notes
    assert 'z: logged in steps of 0.1 m' in notes
    assert plain.report['noise_floor']['z'] == pytest.approx(0.1 / math.sqrt(12.0), rel=1e-9)
    declared = import_log(load_map(_map(tmp_path, extra_z=', resolution: 0.1',
                                        extra_u=', rate: 1')), tmp_path / 'dvl.txt')
    assert declared.report['resolution']['z'] == pytest.approx(0.1)
    assert quantisation_sigma(0.1) == pytest.approx(0.0288675134595, abs=1e-12)
    u = declared.state[:, 6]
    t_state = declared.t
    k = np.flatnonzero(np.isclose(t_state, 20.5))[0]        # between fresh values at 20, 21 s
    assert u[k] == pytest.approx(0.5 * (fresh[40] + fresh[42]), abs=1e-6)   # 6 decimals
    assert 'u: updated at 1 Hz (map rate)' in ' '.join(declared.report['notes'])


def test_jittered_rows_name_the_cause_and_the_grid(tmp_path: pathlib.Path) -> None:
    t = np.cumsum(np.resize([0.39, 0.61], 241))[:-1]
    why = spacing_jitter(t)
    assert why is not None and 'row spacing jitter' in why
    assert 'time: {grid: 0.5} in the map' in why
    assert spacing_jitter(np.arange(0.0, 100.0, 0.5)) is None
    # the identification's derivative window: its one message names the cause and the fix
    from auv_ident.motion import records_from_topics

    # 240 rows, 239 steps: the median step is one of the two, every other step departs from
    # it by more than a quarter
    state = np.zeros(t.size, [(n, '<f8') for n in ('t', 'x', 'y', 'z', 'phi', 'theta', 'psi',
                                                   'u', 'v', 'w', 'p', 'q', 'r')])
    state['t'] = t
    state['u'] = 1.5
    cmd = np.zeros(1, [('t', '<f8'), ('value', '<f8')])
    arrays = {'/auv/state': state, '/auv/bar_command': cmd, '/auv/helm_command': cmd,
              '/auv/thrust_command': cmd}
    with pytest.raises(IdentificationError, match=r'no stretch of /auv/state is long enough '
                                                  r'for the 1 s derivative window: row '
                                                  r'spacing jitter.*time: \{grid: 0\.5\}'):
        records_from_topics(arrays, load_vehicle(ROOT / 'config' / 'a18m.yaml'),
                            source='motion')


def test_a_wrong_unit_is_one_clear_line(tmp_path: pathlib.Path) -> None:
    """Hand-worked ratios: depth logged in cm but declared m changes 100 times as much as the
    kinematics make it; a gyro logging raw counts (131 per deg/s) declared rad/s is
    131 x 180/pi = 7506 times the attitude's rate; the A18M's envelope (300 m rated) catches
    depth in m logged in mm (6000 m)."""
    t = np.arange(0.0, 120.0, 0.5)
    _write(tmp_path / 'right.txt', t)
    _write(tmp_path / 'cm.txt', t, depth_scale=100.0)
    _write(tmp_path / 'counts.txt', t, q_scale=131.0 * 180.0 / math.pi)
    right = import_log(load_map(_map(tmp_path)), tmp_path / 'right.txt')
    ratio = next(c for c in right.report['checks'] if c.startswith('depth change'))
    assert abs(float(ratio.split('= ')[1]) - 1.0) < 0.01
    q_ratio = next(c for c in right.report['checks'] if c.startswith('q /'))
    assert abs(float(q_ratio.split('= ')[1]) - 1.0) < 0.01
    with pytest.raises(PlausibilityError, match=r'^cm: z changes 100 times as much as u, w and '
                                                r'pitch make it change .*\(map signals\.z '
                                                r'\(line 6\) says m\): is its unit or frame '
                                                r'right\?; in cm it would fit$'):
        import_log(load_map(_map(tmp_path)), tmp_path / 'cm.txt')
    with pytest.raises(PlausibilityError, match=r'q is 75\d\d times the rate of the logged '
                                                r'pitch .*raw sensor counts\?'):
        import_log(load_map(_map(tmp_path)), tmp_path / 'counts.txt')
    # the vehicle's envelope: a depth of 6000 m on a vehicle rated for 300 m
    deep = tmp_path / 'deep.txt'
    _write(deep, t, depth_scale=1000.0)
    a18m = envelope_of(load_vehicle(ROOT / 'config' / 'a18m.yaml'))
    assert a18m.depth_max == pytest.approx(360.0)
    with pytest.raises(PlausibilityError, match=r'z reaches (6000|5\d{3}) m, beyond 360 m .*'
                                                r'in cm it would be (60|59\.\d+) m$'):
        import_log(load_map(_map(tmp_path)), deep, envelope=a18m)
    assert Envelope().depth_max == 11_000.0


def test_the_files_own_start_time(tmp_path: pathlib.Path) -> None:
    named = tmp_path / 'dive_2025-04-10_14-33-41.txt'
    named.write_text(HEADER + '\n')
    assert file_time(named) == 1744295621.0             # 2025-04-10 14:33:41 UTC
    header = tmp_path / 'log07.txt'
    header.write_text('# logger v2, start 2025-04-10T16:00:00+02:00\n' + HEADER + '\n')
    assert file_time(header) == 1744293600.0            # 14:00:00 UTC
    assert file_time(tmp_path / 'mission_003.txt') is None


def test_per_topic_stamps_need_a_topic_the_map_reads(tmp_path: pathlib.Path) -> None:
    text = ('format: auv-log-map/1\nkind: bag\ntime: {stamp: header, stamps: {/imu: log}}\n'
            'signals:\n  z: {topic: /depth, field: data, unit: m, frame: NED}\n'
            '  bar: {topic: /bar, field: data, unit: rad}\n'
            '  thrust: {topic: /thrust, field: data, unit: N}\n')
    (tmp_path / 'm.yaml').write_text(text)
    with pytest.raises(MapError, match=r'/imu is not a topic the map reads'):
        load_map(tmp_path / 'm.yaml')
    (tmp_path / 'n.yaml').write_text(text.replace('/imu: log', '/depth: receive'))
    with pytest.raises(MapError, match=r'stamps of /depth must be header or log'):
        load_map(tmp_path / 'n.yaml')
