"""Frame conversions of the import (ENU/FLU -> NED/FRD, REP-103/105) against hand-worked cases.

Each case is a vehicle pose worked out by hand, written in a real bag (rosbags' rosbag2
writer, MCAP) or text log, imported through a map, and compared with the NED/FRD numbers
worked out by hand (not with the code's own conversion):

* heading east, nose up 10 deg, in ENU/FLU: ENU yaw 0 (x east), FLU pitch -10 deg (a
  positive rotation about the left axis dips the nose), so ``q_enu_flu = (0, sin(-5 deg), 0,
  cos(5 deg))``; NED/FRD: phi 0, theta +10 deg, psi +90 deg. Position ENU (100, 50, -20) m ->
  NED (50, 100, 20) m; FLU velocity (1.5, 0.2, 0.1) m/s -> FRD (1.5, -0.2, -0.1); FLU rates
  (0.01, 0.02, 0.03) rad/s -> FRD (0.01, -0.02, -0.03).
* heading north-west, starboard side 20 deg down: ENU yaw 135 deg, FLU roll +20 deg
  (the left side rises), ``q = q_z(135) q_x(20) = (c67.5 s10, s67.5 s10, s67.5 c10,
  c67.5 c10)``; NED/FRD: phi +20 deg, theta 0, psi -45 deg.
"""
from __future__ import annotations

import math
import pathlib
from typing import Any

import numpy as np
import pytest

from auv_logs.importer import import_log
from auv_logs.mapping import load_map

D = math.radians
S5, C5 = math.sin(D(5)), math.cos(D(5))
C675, S675, C10, S10 = math.cos(D(67.5)), math.sin(D(67.5)), math.cos(D(10)), math.sin(D(10))

MAP_ODOM = """format: auv-log-map/1
kind: bag
time: {{stamp: header, base: /odom}}
sources:
  - {{preset: odometry, topic: /odom, frame: {frame}}}
signals:
  bar: {{topic: /bar, field: data, unit: rad}}
  thrust: {{topic: /thrust, field: data, unit: N}}
segments: {{min_duration: 1}}
"""


def _odometry_bag(path: pathlib.Path, pos: tuple[float, ...], quat: tuple[float, ...],
                  lin: tuple[float, ...], ang: tuple[float, ...], n: int = 30) -> None:
    """``n`` identical Odometry messages at 10 Hz, and a BAR and a thrust command."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.LATEST)
    T = store.types
    V3 = T['geometry_msgs/msg/Vector3']
    cov = np.zeros(36)
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        c_odom = w.add_connection('/odom', 'nav_msgs/msg/Odometry', typestore=store)
        c_bar = w.add_connection('/bar', 'std_msgs/msg/Float64', typestore=store)
        c_thr = w.add_connection('/thrust', 'std_msgs/msg/Float64', typestore=store)
        w.write(c_bar, 10**9, store.serialize_cdr(T['std_msgs/msg/Float64'](data=0.1),
                                                  'std_msgs/msg/Float64'))
        w.write(c_thr, 10**9, store.serialize_cdr(T['std_msgs/msg/Float64'](data=20.0),
                                                  'std_msgs/msg/Float64'))
        for k in range(n):
            ns = 10**9 + k * 10**8
            msg = T['nav_msgs/msg/Odometry'](
                header=T['std_msgs/msg/Header'](stamp=T['builtin_interfaces/msg/Time'](
                    sec=ns // 10**9, nanosec=ns % 10**9), frame_id='odom'),
                child_frame_id='base_link',
                pose=T['geometry_msgs/msg/PoseWithCovariance'](pose=T['geometry_msgs/msg/Pose'](
                    position=T['geometry_msgs/msg/Point'](x=pos[0], y=pos[1], z=pos[2]),
                    orientation=T['geometry_msgs/msg/Quaternion'](x=quat[0], y=quat[1],
                                                                  z=quat[2], w=quat[3])),
                    covariance=cov),
                twist=T['geometry_msgs/msg/TwistWithCovariance'](
                    twist=T['geometry_msgs/msg/Twist'](linear=V3(x=lin[0], y=lin[1], z=lin[2]),
                                                       angular=V3(x=ang[0], y=ang[1],
                                                                  z=ang[2])),
                    covariance=cov))
            w.write(c_odom, ns, store.serialize_cdr(msg, 'nav_msgs/msg/Odometry'))


def _import(tmp: pathlib.Path, frame: str, **pose: Any) -> np.ndarray:
    _odometry_bag(tmp / 'bag', **pose)
    (tmp / 'map.yaml').write_text(MAP_ODOM.format(frame=frame))
    log = import_log(load_map(tmp / 'map.yaml'), tmp / 'bag')
    assert log.report['derived'] == []
    row: np.ndarray = log.state[0]
    assert np.allclose(log.state, row)
    return row


def test_heading_east_nose_up_10_degrees_enu_flu(tmp_path: pathlib.Path) -> None:
    row = _import(tmp_path, 'ENU/FLU', pos=(100.0, 50.0, -20.0), quat=(0.0, -S5, 0.0, C5),
                  lin=(1.5, 0.2, 0.1), ang=(0.01, 0.02, 0.03))
    expected = [50.0, 100.0, 20.0, 0.0, D(10), D(90), 1.5, -0.2, -0.1, 0.01, -0.02, -0.03]
    assert row == pytest.approx(expected, abs=1e-12)


def test_heading_north_west_starboard_down_20_degrees_enu_flu(tmp_path: pathlib.Path) -> None:
    row = _import(tmp_path, 'ENU/FLU', pos=(0.0, 0.0, -5.0),
                  quat=(C675 * S10, S675 * S10, S675 * C10, C675 * C10),
                  lin=(1.0, 0.0, 0.0), ang=(0.0, 0.0, 0.0))
    assert row[3:6] == pytest.approx([D(20), 0.0, D(-45)], abs=1e-12)
    assert row[2] == pytest.approx(5.0)


def test_ned_frd_odometry_is_taken_as_it_is(tmp_path: pathlib.Path) -> None:
    # q_ned_frd of phi 20, theta 0, psi -45 deg: q_z(-45) q_x(20), worked like the case above
    c, s = math.cos(D(-22.5)), math.sin(D(-22.5))
    row = _import(tmp_path, 'NED/FRD', pos=(50.0, 100.0, 20.0),
                  quat=(c * S10, s * S10, s * C10, c * C10), lin=(1.5, -0.2, -0.1),
                  ang=(0.01, -0.02, -0.03))
    expected = [50.0, 100.0, 20.0, D(20), 0.0, D(-45), 1.5, -0.2, -0.1, 0.01, -0.02, -0.03]
    assert row == pytest.approx(expected, abs=1e-12)


def test_scalar_columns_in_enu_flu_convention(tmp_path: pathlib.Path) -> None:
    """A text log in the ENU/FLU convention: altitude -20 m (20 m deep), pitch -10 deg
    (nose up), yaw 0 deg (east), left speed 0.2 m/s, up speed 0.1 m/s, rates."""
    rows = ['t alt pitch yaw u vl wu p q r bar T']
    rows += [f'{0.5 * k} -20 -10 0 1.5 0.2 0.1 0.01 0.02 0.03 1 20' for k in range(20)]
    (tmp_path / 'log.csv').write_text('\n'.join(rows) + '\n')
    names = {'z': 'alt', 'phi': None, 'theta': 'pitch', 'psi': 'yaw', 'u': 'u', 'v': 'vl',
             'w': 'wu', 'p': 'p', 'q': 'q', 'r': 'r'}
    units = {'z': 'm', 'theta': 'deg', 'psi': 'deg', 'u': 'm/s', 'v': 'm/s', 'w': 'm/s',
             'p': 'rad/s', 'q': 'rad/s', 'r': 'rad/s'}
    lines = ['format: auv-log-map/1', 'kind: text', 'text: {delimiter: whitespace}',
             'time: {column: t}', 'signals:']
    lines += [f'  {k}: {{column: {c}, unit: {units[k]}, frame: ENU/FLU}}'
              for k, c in names.items() if c]
    lines += ['  bar: {column: bar, unit: deg}', '  thrust: {column: T, unit: N}',
              'segments: {min_duration: 1}']
    (tmp_path / 'map.yaml').write_text('\n'.join(lines) + '\n')
    log = import_log(load_map(tmp_path / 'map.yaml'), tmp_path / 'log.csv')
    row = log.state[0]
    assert row[2:12] == pytest.approx([20.0, 0.0, D(10), D(90), 1.5, -0.2, -0.1, 0.01, -0.02,
                                       -0.03], abs=1e-12)
    assert 'phi: not logged, assumed 0 rad (wings level)' in log.report['derived']
