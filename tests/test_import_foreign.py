"""Logs written the way other people's tools write them (rosbags' own writers, plain Python
text), not by :mod:`auv_logs.synth`: each imported value is compared with numbers
worked out by hand from what was written.

* Text: a semicolon log without header with a UTF-8 byte-order mark (Windows tools), CRLF
  line ends, comment lines and a trailing empty line; time in ms, depth in cm, angles in
  degrees, rpm. A CSV whose header names carry units and are double-quoted (spreadsheets,
  pandas). A logger restart (time going back 150 s) is refused, not sorted into an
  interleaved log.
* sensor_msgs/Imu with orientation only: element 0 of ``angular_velocity_covariance`` is -1
  (the message's own convention for "no estimate"); taking its zeros as rates is refused.
* Scalars in a mixed frame (``ENU/FRD``): a body number follows the body frame only.
* A pressure sensor on a clock 0.12 s ahead whose corrected stamps coincide with the base
  stamps: the hold takes the coincident sample (float seconds at epoch times round an ulp
  either way).
* A misspelt topic in ``time.offsets`` is refused; a topic on another clock is named in the
  "no usable segment" error.
* rosbag2 MCAP compressed by the recorder (file and message compression, zstd) reads as the
  uncompressed bag; a bag cut short is one line naming the damage.
* A vendor message whose ``header`` is its own type (not std_msgs/Header): receive times,
  said in the notes, the same for MCAP, sqlite3 and ROS 1.
* A vendor fin message with an array of sub-messages (``fins[1].angle``, float32) whose
  publisher leaves the header stamps zero: refused with ``stamp: header``, read with
  ``stamp: log``; Odometry ENU/FLU worked by hand (heading south-west, nose down 15 deg,
  starboard side up 5 deg: ENU yaw -135 deg, FLU pitch +15 deg, FLU roll -5 deg ->
  NED/FRD phi -5 deg, theta -15 deg, psi -135 deg).
"""
from __future__ import annotations

import math
import pathlib
import shutil
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from auv_logs.errors import LogReadError, MapError, RealLogError
from auv_logs.importer import import_log
from auv_logs.mapping import load_map

T0 = 1_710_000_000          # s, the vehicle's epoch clock
RHO, P0, G = 1025.0, 101325.0, 9.80665
K = 0.05                    # N/(rev/s)^2, T = K n |n|
D = math.radians
Event = tuple[int, str, str, Any]


def _map(tmp: pathlib.Path, text: str, name: str = 'map.yaml') -> Any:
    path = tmp / name
    path.write_text(text)
    return load_map(path)


def _store(ros1: bool = False) -> Any:
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    for text, name in (('string name\nfloat32 angle\nfloat32 effort\n', 'lab_msgs/msg/FinState'),
                       ('std_msgs/Header header\nFinState[] fins\nuint8 mode\n',
                        'lab_msgs/msg/FinArray'),
                       ('uint64 stamp_us\nstring frame\n', 'vendor_msgs/msg/Header'),
                       ('vendor_msgs/Header header\nfloat64 depth_m\n', 'vendor_msgs/msg/Depth')):
        store.register(get_types_from_msg(text, name))
    return store


def _header(store: Any, ns: int | None, ros1: bool = False) -> Any:
    T = store.types
    sec, nsec = divmod(ns, 10**9) if ns is not None else (0, 0)
    return T['std_msgs/msg/Header'](**({'seq': 0} if ros1 else {}),
                                    stamp=T['builtin_interfaces/msg/Time'](sec=sec,
                                                                           nanosec=nsec),
                                    frame_id='')


def _write(path: pathlib.Path, store: Any, events: list[Event], kind: str = 'mcap',
           compression: str | None = None) -> None:
    """Write with rosbags' own writers: rosbag2 (``mcap``, ``sqlite3``) or ROS 1."""
    events = sorted(events, key=lambda e: e[0])
    if kind == 'ros1':
        from rosbags.rosbag1 import Writer as Writer1

        with Writer1(path) as w1:
            c1: dict[str, Any] = {}
            for ns, topic, mt, msg in events:
                if topic not in c1:
                    c1[topic] = w1.add_connection(topic, mt, typestore=store)
                w1.write(c1[topic], ns, store.serialize_ros1(msg, mt))
        return
    from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer

    w = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP if kind == 'mcap'
               else StoragePlugin.SQLITE3)
    if compression is not None:
        w.set_compression(CompressionMode[compression], CompressionFormat.ZSTD)
    with w:
        c2: dict[str, Any] = {}
        for ns, topic, mt, msg in events:
            if topic not in c2:
                c2[topic] = w.add_connection(topic, mt, typestore=store)
            w.write(c2[topic], ns, store.serialize_cdr(msg, mt))


def _float64(store: Any, value: float) -> Any:
    return store.types['std_msgs/msg/Float64'](data=value)


# --------------------------------------------------------------------------------------------
# text logs

#: rows (t [s], depth [m], roll, pitch, heading [deg], surge [m/s], bar [rad], thrust [N])
ROWS = [(0.1 * k, 10.0 + 0.01 * k, 1.5, -3.0 + 0.05 * k, 350.0 + 0.1 * k, 1.5, 0.02, 20.0)
        for k in range(300)]
TEXT_SIGNALS = """signals:
  z: {{column: {z}, unit: cm, frame: NED}}
  phi: {{column: {phi}, unit: deg, frame: NED/FRD}}
  theta: {{column: {theta}, unit: deg, frame: NED/FRD}}
  psi: {{column: {psi}, unit: deg, frame: NED}}
  u: {{column: {u}, unit: cm/s, frame: FRD}}
  bar: {{column: {bar}, unit: deg}}
  thrust: {{column: {rpm}, unit: rpm, law: {{coefficient: 0.05}}}}
segments: {{min_duration: 5}}
"""


def _rpm(thrust: float) -> float:
    return 60.0 * math.copysign(math.sqrt(abs(thrust) / K), thrust)


def _text_fields(row: tuple[float, ...]) -> list[str]:
    t, z, phi, th, psi, u, bar, thr = row
    return [f'{T0 * 1000 + round(t * 1000)}', f'{100 * z:.10g}', f'{phi:.10g}', f'{th:.10g}',
            f'{psi:.10g}', f'{100 * u:.10g}', f'{math.degrees(bar):.12g}', f'{_rpm(thr):.12g}']


def _check_text(log: Any) -> None:
    t = np.array([T0 + r[0] for r in ROWS])
    assert len(log.t) == len(ROWS)
    assert np.max(np.abs(log.t - t)) < 1e-6
    for k, col in ((2, 1), (3, 2), (4, 3), (6, 5)):
        want = np.array([r[col] for r in ROWS])
        want = want if k in (2, 6) else np.radians(want)
        assert np.max(np.abs(log.state[:, k] - want)) < 1e-9, k
    psi = np.radians([r[4] for r in ROWS])
    assert np.max(np.abs(np.angle(np.exp(1j * (log.state[:, 5] - psi))))) < 1e-9
    assert np.allclose(log.commands['bar'][1], 0.02, rtol=0, atol=1e-12)
    assert np.allclose(log.commands['thrust'][1], 20.0, rtol=1e-12)


def test_semicolon_log_without_header_bom_crlf_comments_trailing_blank(
        tmp_path: pathlib.Path) -> None:
    lines = ['# logger v2.1; depth cm; angles deg']
    for k, row in enumerate(ROWS):
        lines.append(';'.join(_text_fields(row)))
        if k == 40:
            lines.append('# fix lost')
    path = tmp_path / 'dive.csv'
    path.write_bytes(b'\xef\xbb\xbf' + ('\r\n'.join(lines) + '\r\n\r\n').encode())
    names = ['t', 'z', 'phi', 'theta', 'psi', 'u', 'bar', 'rpm']
    m = _map(tmp_path, 'format: auv-log-map/1\nkind: text\n'
             f'text: {{delimiter: semicolon, header: false, columns: [{", ".join(names)}]}}\n'
             'time: {column: t, unit: ms}\n' + TEXT_SIGNALS.format(
                 z='z', phi='phi', theta='theta', psi='psi', u='u', bar='bar', rpm='rpm'))
    _check_text(import_log(m, path))


def test_csv_header_with_units_quoted_and_bom(tmp_path: pathlib.Path) -> None:
    head = ['Time [ms]', 'Depth (cm)', 'Roll [deg]', 'Pitch [deg]', 'Heading [deg]',
            'Speed [cm/s]', 'Plane [deg]', 'Prop [rpm]']
    path = tmp_path / 'dive.csv'
    text = ','.join(f'"{h}"' for h in head) + '\n' + '\n'.join(
        ','.join(_text_fields(r)) for r in ROWS) + '\n'
    path.write_bytes(b'\xef\xbb\xbf' + text.encode())
    m = _map(tmp_path, 'format: auv-log-map/1\nkind: text\n'
             'text: {delimiter: comma, header: true}\n'
             "time: {column: 'Time [ms]', unit: ms}\n" + TEXT_SIGNALS.format(
                 z="'Depth (cm)'", phi="'Roll [deg]'", theta="'Pitch [deg]'",
                 psi="'Heading [deg]'", u="'Speed [cm/s]'", bar="'Plane [deg]'",
                 rpm="'Prop [rpm]'"))
    _check_text(import_log(m, path))


def test_logger_restart_is_refused_a_reordered_row_is_sorted(tmp_path: pathlib.Path) -> None:
    names = ['t', 'z', 'phi', 'theta', 'psi', 'u', 'bar', 'rpm']
    m = _map(tmp_path, 'format: auv-log-map/1\nkind: text\n'
             f'text: {{delimiter: whitespace, header: false, columns: [{", ".join(names)}]}}\n'
             'time: {column: t, unit: ms}\n' + TEXT_SIGNALS.format(
                 z='z', phi='phi', theta='theta', psi='psi', u='u', bar='bar', rpm='rpm'))
    rows = [_text_fields(r) for r in ROWS]
    restart = [list(f) for f in rows]
    for k in range(150, 300):      # the logger restarts its clock at row 151
        restart[k][0] = str(T0 * 1000 + 25 + 100 * (k - 150))
    path = tmp_path / 'restart.txt'
    path.write_text('\n'.join(' '.join(f) for f in restart) + '\n')
    with pytest.raises(LogReadError, match=r'restart\.txt: time goes back by 14\.875 s at line '
                                           r'151 \(.*\): a clock reset or a restart of the '
                                           r'logger\? split the log there$'):
        import_log(m, path)
    rows[100], rows[101] = rows[101], rows[100]     # two rows written out of order
    path = tmp_path / 'swapped.txt'
    path.write_text('\n'.join(' '.join(f) for f in rows) + '\n')
    log = import_log(m, path)
    _check_text(log)
    assert any('1 stamp(s) went back' in n for n in log.report['notes'])


# --------------------------------------------------------------------------------------------
# bags

def _q(roll: float, pitch: float, yaw: float) -> tuple[float, float, float, float]:
    """q_z(yaw) q_y(pitch) q_x(roll) (x, y, z, w) [deg], by the product of the three
    half-angle quaternions written out."""
    cr, sr = math.cos(D(roll) / 2), math.sin(D(roll) / 2)
    cp, sp = math.cos(D(pitch) / 2), math.sin(D(pitch) / 2)
    cy, sy = math.cos(D(yaw) / 2), math.sin(D(yaw) / 2)
    return (cy * cp * sr - sy * sp * cr, cy * sp * cr + sy * cp * sr,
            sy * cp * cr - cy * sp * sr, cy * cp * cr + sy * sp * sr)


#: heading south-west, nose down 15 deg, starboard side up 5 deg, logged ENU/FLU
Q_SW = _q(-5.0, 15.0, -135.0)
NED_SW = (D(-5.0), D(-15.0), D(-135.0))


def _imu(store: Any, ns: int, quat: tuple[float, ...], rates_cov0: float,
         ros1: bool = False) -> Any:
    T = store.types
    V3 = T['geometry_msgs/msg/Vector3']
    cov = np.zeros(9)
    cov[0] = rates_cov0
    return T['sensor_msgs/msg/Imu'](
        header=_header(store, ns, ros1),
        orientation=T['geometry_msgs/msg/Quaternion'](x=quat[0], y=quat[1], z=quat[2],
                                                      w=quat[3]),
        orientation_covariance=np.full(9, 1e-6), angular_velocity=V3(x=0.0, y=0.0, z=0.0),
        angular_velocity_covariance=cov, linear_acceleration=V3(x=0.0, y=0.0, z=9.8),
        linear_acceleration_covariance=np.zeros(9))


def _imu_bag(path: pathlib.Path, cov0: Callable[[int], float]) -> None:
    """/imu 20 Hz (ENU/FLU orientation SW), /depth, /bar, /thrust as Float64, 30 s."""
    store = _store()
    ev: list[Event] = []
    for k in range(600):
        ns = T0 * 10**9 + k * 50_000_000
        ev.append((ns + 1_000_000, '/imu', 'sensor_msgs/msg/Imu',
                   _imu(store, ns, Q_SW, cov0(k))))
        ev.append((ns + 2_000_000, '/depth', 'std_msgs/msg/Float64', _float64(store, 12.0)))
    ev.append((T0 * 10**9, '/bar', 'std_msgs/msg/Float64', _float64(store, 0.05)))
    ev.append((T0 * 10**9, '/thrust', 'std_msgs/msg/Float64', _float64(store, 30.0)))
    _write(path, store, ev)


IMU_MAP = """format: auv-log-map/1
kind: bag
time: {{stamp: header, base: /imu, max_age: 0.1}}
sources:
  - {{preset: imu, topic: /imu, frame: ENU/FLU{use}}}
  - {{preset: float64, topic: /depth, signal: z, unit: m, frame: NED}}
signals:
  u: {{topic: /depth, field: data, unit: m/s, scale: 0.125, frame: FRD}}
  bar: {{topic: /bar, field: data, unit: rad}}
  thrust: {{topic: /thrust, field: data, unit: N}}
segments: {{min_duration: 5}}
"""


def test_imu_without_rates_is_not_read_as_zero_rates(tmp_path: pathlib.Path) -> None:
    _imu_bag(tmp_path / 'bag', lambda k: -1.0)
    m = _map(tmp_path, IMU_MAP.format(use=''))
    with pytest.raises(LogReadError, match=r'^/imu: angular_velocity_covariance\[0\] is -1 in '
                                           r'all 600 messages: they carry no angular_velocity'):
        import_log(m, tmp_path / 'bag')
    log = import_log(_map(tmp_path, IMU_MAP.format(use=', use: [orientation]')),
                     tmp_path / 'bag')
    assert np.max(np.abs(np.angle(np.exp(1j * (log.state[:, 3:6] - NED_SW))))) < 1e-12
    assert 'q: derived' in ' '.join(log.report['derived'])


def test_imu_messages_without_rates_are_not_usable(tmp_path: pathlib.Path) -> None:
    # rates flagged missing in messages 200-219 (1 s): those samples are left out
    _imu_bag(tmp_path / 'bag', lambda k: -1.0 if 200 <= k < 220 else 0.0)
    log = import_log(_map(tmp_path, IMU_MAP.format(use='')), tmp_path / 'bag')
    assert len(log.segments) == 2
    assert any('/imu: 20 message(s) with angular_velocity_covariance[0] -1' in n
               for n in log.report['notes'])
    stamps = np.round((log.t - T0) / 0.05).astype(int)
    assert not np.any((stamps >= 200) & (stamps < 220))
    assert np.all(log.state[:, 9:12] == 0.0)       # the logged rates (zero) where given


def test_scalars_in_a_mixed_frame_follow_their_own_axis(tmp_path: pathlib.Path) -> None:
    path = tmp_path / 'log.txt'
    path.write_text('t z w q th\n' + '\n'.join(f'{k} 5 0.1 0.02 3' for k in range(20)) + '\n')
    head = ('format: auv-log-map/1\nkind: text\ntext: {delimiter: whitespace}\n'
            'time: {column: t, unit: s}\nsegments: {min_duration: 5}\nsignals:\n'
            '  u: {column: z, unit: m/s, frame: FRD}\n'
            '  bar: {column: q, unit: rad}\n  thrust: {column: z, unit: N}\n'
            '  psi: {column: q, unit: rad, frame: NED}\n')
    m = _map(tmp_path, head + '  z: {column: z, unit: m, frame: NED/FLU}\n'
             '  theta: {column: th, unit: deg, frame: ENU/FLU}\n'
             '  w: {column: w, unit: m/s, frame: ENU/FRD}\n'
             '  q: {column: q, unit: rad/s, frame: ENU/FRD}\n')
    log = import_log(m, path)
    # world NED: depth as logged; body FRD: w and q as logged; ENU/FLU pitch: sign changed
    assert np.allclose(log.state[:, 2], 5.0) and np.allclose(log.state[:, 8], 0.1)
    assert np.allclose(log.state[:, 10], 0.02) and np.allclose(log.state[:, 4], D(-3.0))
    with pytest.raises(MapError, match=r'signals\.theta\.frame \(line \d+\): theta in the '
                                       r'mixed frame ENU/FRD is not a change of one axis'):
        _map(tmp_path, head + '  z: {column: z, unit: m, frame: NED}\n'
             '  theta: {column: th, unit: deg, frame: ENU/FRD}\n', 'bad.yaml')


def _odom(store: Any, ns: int, ros1: bool = False) -> Any:
    """Odometry ENU/FLU: position ENU (100, 50, -20) m, orientation SW, FLU velocity (1.5,
    0.2, 0.1) m/s and rates (0.01, 0.02, 0.03) rad/s."""
    T = store.types
    V3 = T['geometry_msgs/msg/Vector3']
    return T['nav_msgs/msg/Odometry'](
        header=_header(store, ns, ros1), child_frame_id='base_link',
        pose=T['geometry_msgs/msg/PoseWithCovariance'](
            pose=T['geometry_msgs/msg/Pose'](
                position=T['geometry_msgs/msg/Point'](x=100.0, y=50.0, z=-20.0),
                orientation=T['geometry_msgs/msg/Quaternion'](x=Q_SW[0], y=Q_SW[1],
                                                              z=Q_SW[2], w=Q_SW[3])),
            covariance=np.zeros(36)),
        twist=T['geometry_msgs/msg/TwistWithCovariance'](
            twist=T['geometry_msgs/msg/Twist'](linear=V3(x=1.5, y=0.2, z=0.1),
                                               angular=V3(x=0.01, y=0.02, z=0.03)),
            covariance=np.zeros(36)))


def _pressure(store: Any, ns: int, depth: float) -> Any:
    return store.types['sensor_msgs/msg/FluidPressure'](
        header=_header(store, ns), fluid_pressure=P0 + RHO * G * depth, variance=0.0)


CLOCK_MAP = """format: auv-log-map/1
kind: bag
time: {{stamp: header, base: /odom, max_age: 0.15, offsets: {{{offsets}}}}}
sources:
  - {{preset: odometry, topic: /odom, frame: ENU/FLU, skip: [z]}}
  - {{preset: fluid_pressure, topic: /pressure, density: 1025}}
signals:
  bar: {{topic: /bar, field: data, unit: rad}}
  thrust: {{topic: /thrust, field: data, unit: N}}
segments: {{min_duration: 5}}
"""


def _clock_bag(path: pathlib.Path, ahead_ns: int, every: int = 1,
               compression: str | None = None) -> None:
    """/odom at 10 Hz; /pressure at every ``every``-th of the same instants on a clock
    ``ahead_ns`` ahead, depth 20 + 0.01 k m at the k-th instant (a sample early or late is
    0.01 m off); ``compression``: the recorder's mode (FILE, MESSAGE)."""
    store = _store()
    ev: list[Event] = []
    for k in range(300):
        ns = T0 * 10**9 + k * 100_000_000
        ev.append((ns + 3_000_000, '/odom', 'nav_msgs/msg/Odometry', _odom(store, ns)))
        if k % every == 0:
            ev.append((ns + 1_000_000, '/pressure', 'sensor_msgs/msg/FluidPressure',
                       _pressure(store, ns + ahead_ns, 20.0 + 0.01 * k)))
    ev.append((T0 * 10**9, '/bar', 'std_msgs/msg/Float64', _float64(store, 0.05)))
    ev.append((T0 * 10**9, '/thrust', 'std_msgs/msg/Float64', _float64(store, 30.0)))
    _write(path, store, ev, compression=compression)


def test_clock_offset_onto_coincident_stamps_and_hand_worked_odometry(
        tmp_path: pathlib.Path) -> None:
    _clock_bag(tmp_path / 'bag', 120_000_000)
    log = import_log(_map(tmp_path, CLOCK_MAP.format(offsets='/pressure: -0.12')),
                     tmp_path / 'bag')
    assert len(log.t) == 300
    k = np.round((log.t - T0) / 0.1)
    assert np.max(np.abs(log.state[:, 2] - (20.0 + 0.01 * k))) < 1e-9
    # ENU (100, 50, -20) -> NED (50, 100, .); SW pose; FLU -> FRD velocity and rates
    want = [50.0, 100.0, None, *NED_SW, 1.5, -0.2, -0.1, 0.01, -0.02, -0.03]
    for i, w in enumerate(want):
        if w is not None:
            d = log.state[:, i] - w
            d = np.angle(np.exp(1j * d)) if i in (3, 5) else d
            assert np.max(np.abs(d)) < 1e-12, i


def test_misspelt_offset_topic_and_a_topic_on_another_clock(tmp_path: pathlib.Path) -> None:
    _clock_bag(tmp_path / 'bag', -T0 * 10**9 + 5 * 10**9)      # seconds since boot + 5 s
    with pytest.raises(MapError, match=r'time\.offsets \(line 3\): /presure is not a topic '
                                       r'the map reads \(/bar, /odom, /pressure, /thrust\)'):
        _map(tmp_path, CLOCK_MAP.format(offsets='/presure: -0.12'))
    m = _map(tmp_path, CLOCK_MAP.format(offsets='/odom: 0'))
    with pytest.raises(RealLogError, match=r'z from /pressure: no sample within max_age 0\.15 s'
                                           r' of any /odom stamp \(/pressure stamps 5\.000 to '
                                           r'34\.900 s, /odom 1710000000\.000 to 1710000029\.900'
                                           r' s: another clock\? see time\.offsets\)'):
        import_log(m, tmp_path / 'bag')


def test_a_slow_depth_held_onto_a_fast_base_says_how_old_it_is(tmp_path: pathlib.Path) -> None:
    """/odom at 10 Hz, /pressure at 2.5 Hz on the same clock (every 4th instant): held onto
    the odometry stamps the depth is 0, 0.1, 0.2, 0.3 s old in turn, 0.15 s on median; with
    /pressure as the base it is read at its own stamps."""
    _clock_bag(tmp_path / 'bag', 0, every=4)
    fast = CLOCK_MAP.format(offsets='').replace('max_age: 0.15', 'max_age: 0.35')
    log = import_log(_map(tmp_path, fast), tmp_path / 'bag')
    assert len(log.t) == 300
    k = np.round((log.t - T0) / 0.1)
    assert np.max(np.abs(log.state[:, 2] - (20.0 + 0.04 * np.floor(k / 4)))) < 1e-9
    hold = next(h for h in log.report['holds'] if h.startswith('z from /pressure'))
    assert hold.endswith('held 0.15 s old on median')
    note = next(n for n in log.report['notes'] if n.startswith('/pressure (0.4 s period)'))
    assert 'held onto the /odom stamps (0.1 s) 0.15 s old on median' in note
    slow = fast.replace('base: /odom', 'base: /pressure')
    log = import_log(_map(tmp_path, slow, 'slow.yaml'), tmp_path / 'bag')
    assert len(log.t) == 75
    assert np.max(np.abs(log.state[:, 2] - (20.0 + 0.01 * np.round((log.t - T0) / 0.1)))) \
        < 1e-9
    assert not [n for n in log.report['notes'] if 'old on median' in n]


@pytest.mark.parametrize('mode', ['FILE', 'MESSAGE'])
def test_compressed_rosbag2_reads_as_the_uncompressed(tmp_path: pathlib.Path,
                                                      mode: str) -> None:
    _clock_bag(tmp_path / 'plain', 0)
    _clock_bag(tmp_path / 'zstd', 0, compression=mode)
    m = _map(tmp_path, CLOCK_MAP.format(offsets=''))
    a, b = import_log(m, tmp_path / 'plain'), import_log(m, tmp_path / 'zstd')
    assert np.array_equal(a.t, b.t) and np.array_equal(a.state, b.state)
    assert np.allclose(b.state[:, 2], 20.0 + 0.01 * np.arange(300), rtol=0, atol=1e-9)


def test_bag_cut_short_is_one_line(tmp_path: pathlib.Path) -> None:
    _clock_bag(tmp_path / 'bag', 0)
    cut = tmp_path / 'cut'
    shutil.copytree(tmp_path / 'bag', cut)
    f = next(cut.glob('*.mcap'))
    f.write_bytes(f.read_bytes()[: f.stat().st_size * 6 // 10])
    m = _map(tmp_path, CLOCK_MAP.format(offsets=''))
    with pytest.raises(LogReadError, match=r'is truncated at byte \d+ .*whole messages before '
                                           r'the damage were read; `auv bag repair BAG --out '
                                           r'NEW` writes'):
        import_log(m, cut)
    bare = tmp_path / 'empty.mcap'
    bare.write_bytes(b'')
    with pytest.raises(LogReadError, match=r'cannot read MCAP file .*empty\.mcap: \S'):
        import_log(m, bare)


@pytest.mark.parametrize('kind', ['mcap', 'sqlite3', 'ros1'])
def test_vendor_header_type_gives_receive_times(tmp_path: pathlib.Path, kind: str) -> None:
    ros1 = kind == 'ros1'
    store = _store(ros1)
    T = store.types
    ev: list[Event] = []
    for k in range(100):
        ns = T0 * 10**9 + k * 100_000_000
        ev.append((ns + 7_000, '/depth', 'vendor_msgs/msg/Depth', T['vendor_msgs/msg/Depth'](
            header=T['vendor_msgs/msg/Header'](stamp_us=ns // 1000 - 10**6, frame='d'),
            depth_m=10.0 + 0.5 * k)))
    ev.append((T0 * 10**9, '/bar', 'std_msgs/msg/Float64', _float64(store, 0.05)))
    ev.append((T0 * 10**9, '/thrust', 'std_msgs/msg/Float64', _float64(store, 30.0)))
    path = tmp_path / ('log.bag' if ros1 else 'bag')
    _write(path, store, ev, kind)
    m = _map(tmp_path, 'format: auv-log-map/1\nkind: bag\ntime: {stamp: header}\n'
             'signals:\n  z: {topic: /depth, field: depth_m, unit: m, frame: NED}\n'
             '  theta: {topic: /depth, field: depth_m, unit: deg, scale: 0, frame: NED}\n'
             '  psi: {topic: /depth, field: depth_m, unit: deg, scale: 0, frame: NED}\n'
             '  u: {topic: /depth, field: depth_m, unit: m/s, scale: 0, offset: 1.5, '
             'frame: FRD}\n'
             '  bar: {topic: /bar, field: data, unit: rad}\n'
             '  thrust: {topic: /thrust, field: data, unit: N}\nsegments: {min_duration: 5}\n')
    log = import_log(m, path)
    assert np.allclose(log.t - T0, 0.1 * np.arange(100) + 7e-6, rtol=0, atol=1e-6)
    assert np.allclose(log.state[:, 2], 10.0 + 0.5 * np.arange(100), rtol=0, atol=1e-12)
    assert any(n.startswith('/depth (vendor_msgs/msg/Depth) has no header')
               for n in log.report['notes'])


FIN_MAP = """format: auv-log-map/1
kind: bag
time: {{stamp: {stamp}, base: /odom, max_age: 0.15}}
sources:
  - {{preset: odometry, topic: /odom, frame: ENU/FLU}}
signals:
  bar:
    unit: rad
    sum:
      - {{topic: /fins, field: 'fins[1].angle', gain: 0.5}}
      - {{topic: /fins, field: 'fins[3].angle', gain: -0.5}}
  helm: {{topic: /fins, field: 'fins[0].angle', unit: rad}}
  thrust: {{topic: /thrust, field: data, unit: rpm, law: {{coefficient: 0.05}}}}
segments: {{min_duration: 5}}
"""


@pytest.mark.parametrize('kind', ['mcap', 'sqlite3', 'ros1'])
def test_fin_array_of_submessages_unstamped_and_enu_odometry(tmp_path: pathlib.Path,
                                                             kind: str) -> None:
    ros1 = kind == 'ros1'
    store = _store(ros1)
    T = store.types
    ev: list[Event] = []
    fins = []
    for k in range(200):
        ns = T0 * 10**9 + k * 100_000_000
        ev.append((ns + 3_000_000, '/odom', 'nav_msgs/msg/Odometry', _odom(store, ns, ros1)))
        if k % 5 == 0:      # 2 Hz; float32 angles exact in binary: upper, port, lower, stbd
            a = (0.0625 * (k % 3), 0.125 - 0.03125 * (k % 4), -0.0625 * (k % 3),
                 -0.125 + 0.03125 * (k % 4) + 0.0078125)
            ev.append((ns + 1_000_000, '/fins', 'lab_msgs/msg/FinArray', T[
                'lab_msgs/msg/FinArray'](header=_header(store, None, ros1), mode=1, fins=[
                    T['lab_msgs/msg/FinState'](name=n, angle=np.float32(v),
                                               effort=np.float32(0.5))
                    for n, v in zip(('upper', 'port', 'lower', 'stbd'), a)])))
            ev.append((ns + 2_000_000, '/thrust', 'std_msgs/msg/Float64',
                       _float64(store, 1200.0)))
            fins.append((ns + 1_000_000, a))
    path = tmp_path / ('log.bag' if ros1 else 'bag')
    _write(path, store, ev, kind)
    with pytest.raises(LogReadError, match=r'^topic /fins: 40 of 40 header stamps are zero '
                                           r'\(the publisher does not stamp\): take its receive '
                                           r'times, time: \{stamps: \{/fins: log\}\} in the map'):
        import_log(_map(tmp_path, FIN_MAP.format(stamp='header')), path)
    # per topic: the fins at their receive times, the odometry at its header stamps
    mixed = import_log(_map(tmp_path, FIN_MAP.format(stamp='header, stamps: {/fins: log}')),
                       path)
    assert np.allclose(mixed.t - T0, 0.1 * np.arange(200), rtol=0, atol=1e-6)
    assert any('/fins: its receive (log) times are used' in n for n in mixed.report['notes'])
    log = import_log(_map(tmp_path, FIN_MAP.format(stamp='log')), path)
    assert np.array_equal(mixed.commands['bar'][0], log.commands['bar'][0])
    st, bar = log.commands['bar']
    assert np.allclose(st - T0, [(n - T0 * 10**9) * 1e-9 for n, _ in fins], rtol=0, atol=1e-6)
    assert np.array_equal(bar, [0.5 * a[1] - 0.5 * a[3] for _, a in fins])
    assert np.array_equal(log.commands['helm'][1], [a[0] for _, a in fins])
    assert np.allclose(log.commands['thrust'][1], K * 20.0**2, rtol=1e-12)  # 1200 rpm
    want = [50.0, 100.0, 20.0, *NED_SW, 1.5, -0.2, -0.1, 0.01, -0.02, -0.03]
    for i, w in enumerate(want):
        d = log.state[:, i] - w
        d = np.angle(np.exp(1j * d)) if i in (3, 5) else d
        assert np.max(np.abs(d)) < 1e-12, i
